"""The diagnosis's options (what counts as evidence, how wide it searches) and its refusal."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from phid_ros.errors import PhidError
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ


@dataclass
class DiagnoseOptions:
    pre_s: float = 1.0  # window before the event (the play-in's steady start)
    post_s: float = 6.0  # window after it: several T'_d0, the whole electromechanical swing
    per_kind: int = 2  # fit scenarios per disturbance kind (the rest and role=validate are held out)
    bic_margin: float = 200.0
    min_heldout_drop: float = 0.05  # held-out unexplained mean square must fall by this (noise variances)
    min_presence_sigma: float = 3.0  # an effect's estimate must stand this many stds from its absence
    min_remaining_share: float = 0.25  # after the first effect: share of what remains a further one must explain
    # held-out unexplained error (noise sigma) above which the final model's base parameters are not
    # trusted at all: they absorb what the model still misses (studies end at 0.3-0.7)
    max_unexplained: float = 1.0
    shortlist: int = 5  # candidates fitted fully per round, best screened first (the screen holds the
    # base model fixed, which misranks effects the base had compensated, e.g. saturation via X_d)
    max_effects: int = 3
    max_nfev: int = 40
    # Dask worker processes for the candidates of a round (phid_ros.cluster); 0: one per core.
    # One by default: worker processes are spawned, which re-imports the calling script, so a
    # script must guard its entry (``if __name__ == "__main__":``) to use them; `phid diagnose`
    # uses every core. Inside a fleet task any value but 1 sends them to the fleet's cluster.
    workers: int = 1
    scheduler: str | None = None  # an existing Dask cluster instead of a local one
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ
    # base parameters whose identified value carries no information (at a search bound of its
    # stage): every fit frees them over their whole physical range (phid_ros.diagnose.fit.base_free)
    wide: tuple[str, ...] = ()
    # base parameters held at their identified values in every fit. The CLI holds D when stage 1
    # identified it: the swing integral uses the measured electrical power, so no missing
    # electrical effect biases it, while output error biases D upward by the noise on the driving
    # terminal voltage (+10 % and +19 % on ANDES's GENROU, where stage 1 had -3 %)
    held: tuple[str, ...] = ()

    @classmethod
    def after(cls, identification: Any, **settings: Any) -> DiagnoseOptions:
        """The options that belong to an identification (``IdentificationResult``): what it left
        at a search bound is ``wide``, D is ``held`` when stage 1 identified it. phid diagnose, phid
        fleet and the studies build their options here. Without these, D refits free and absorbs
        what it should not: on bags/saturation a spurious shaft_torsion was named beside saturation.
        """
        return cls(wide=identification.at_bound(), held=identification.stage1_held(), **settings)


class DiagnoseError(PhidError):
    """Measurements the diagnosis cannot weigh honestly."""
