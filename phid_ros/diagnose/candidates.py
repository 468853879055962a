"""The candidate library: one model extension per physical effect, behind one small base class.

Each candidate wraps the simulator's effect of the same name (its equations live
once, in :mod:`phid_ros.sim.effects`) and adds what a fit needs: which parameters
are free and in which bounds (the effect's realistic ranges), how to scale them,
a screening grid that finds a good start for a local fit, and the signature the
effect leaves in the gap (where a plant engineer should see it). Every registered
plant effect is a candidate with the default behaviour; a candidate class is only
written where the default is not good enough (a torsional frequency needs a dense
grid, a latency needs one search per stream). Adding an effect means registering
one plant effect and, if needed, one candidate here; nothing else changes.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.model.bounds import Bounded
from phid_ros.model.equations import reconstruct_fluxes
from phid_ros.sim.effects import REGISTRY as EFFECTS
from phid_ros.sim.effects import EffectParameter, PlantEffect, RotorContext, leakage_default

Array = NDArray[np.float64]


@dataclass(frozen=True)
class FreeParameter(Bounded):
    """One fitted parameter: its bounds and whether it is searched on a log scale."""

    name: str
    low: float
    high: float
    log: bool

    def to_x(self, v: Any) -> Any:
        return np.log(v) if self.log else np.asarray(v, float)

    def from_x(self, x: Any) -> Any:
        return np.exp(x) if self.log else x

    @property
    def x_bounds(self) -> tuple[float, float]:
        return (float(self.to_x(self.low)), float(self.to_x(self.high)))


class Candidate:
    """A model extension the diagnosis may add. Subclass only to change the defaults."""

    effect: ClassVar[type[PlantEffect]]
    signature: ClassVar[str] = ""
    screen_points: ClassVar[int] = 24

    @classmethod
    def name(cls) -> str:
        return cls.effect.name

    @classmethod
    def free(cls) -> tuple[FreeParameter, ...]:
        return tuple(_free(p) for p in cls.effect.parameters if not p.choices)

    @classmethod
    def choices(cls) -> list[dict[str, str]]:
        """Every combination of the effect's discrete settings (one fit each)."""
        discrete = [p for p in cls.effect.parameters if p.choices]
        return [
            dict(zip((p.name for p in discrete), combo)) for combo in itertools.product(*(p.choices for p in discrete))
        ]

    @classmethod
    def screen(cls, runs: Sequence[Any] = ()) -> dict[str, Array]:
        """Trial values for the free parameters: a stratified (Latin hypercube) sample, fixed seed.

        ``runs`` is the current model's play-in (residual = sim - meas) for candidates that
        place their grid from their signature.
        """
        rng = np.random.default_rng(0)
        n = cls.screen_points
        out = {}
        for p in cls.free():
            u = (rng.permutation(n) + 0.5) / n
            lo, hi = p.x_bounds
            out[p.name] = p.from_x(lo + u * (hi - lo))
        return out

    @classmethod
    def admissible(cls, values: dict[str, Array], base: dict[str, float]) -> NDArray[np.bool_]:
        """Which trial values respect the effect's own ordering rules."""
        return np.ones(len(next(iter(values.values()))), bool) if values else np.ones(1, bool)

    @classmethod
    def physical(cls, values: dict[str, Any], base: dict[str, float]) -> bool:
        """Whether fitted values describe a machine (the orderings the effect's equations need)."""
        return True

    @classmethod
    def unresolvable(cls, values: dict[str, Any], step_s: float) -> str | None:
        """Why fitted values are below what the play-in can tell from its own discretisation
        (a step of ``step_s``), or None: such an effect is never named, whatever it gains."""
        return None

    @classmethod
    def searched(cls) -> tuple[str, ...]:
        """Parameters set by the screening search alone (held in the local fit; they count in BIC)."""
        return ()

    @classmethod
    def refine(cls, best: dict[str, Any]) -> dict[str, Array] | None:
        """A finer grid around the best screened values, or None."""
        return None

    @classmethod
    def basin_free(cls) -> tuple[FreeParameter, ...]:
        """Searched parameters freed (continuous) in a first fit that only locates their basin.

        The grid search of a searched parameter holds the base model; when the base has
        compensated for the effect, the true value and the found one lie along a valley of
        base and effect together that a one-parameter search does not follow, a joint fit does.
        """
        return ()

    @classmethod
    def presence(cls, values: dict[str, Any], std: dict[str, float], base: dict[str, float]) -> float | None:
        """How many standard deviations the fitted effect stands from its absence, or None.

        The largest over the parameters that declare the value at which the effect vanishes
        (``EffectParameter.absent``) and have a standard deviation; None when none can say
        (a searched latency, a torsional mode: there the information criteria decide alone).
        """
        z = []
        bounds = {p.name: p for p in cls.free()}
        for p in cls.effect.parameters:
            if p.absent is None or p.name not in std or not std[p.name] > 0:
                continue
            null = float(base[p.absent] if isinstance(p.absent, str) else p.absent)
            v = float(values[p.name])
            # pressed onto the bound on the side of its absence (r_a at its 0.001 floor, X'' at its
            # ceiling below X'): the data pull it towards "absent", whatever its interval says
            fp = bounds.get(p.name)
            edge = None if fp is None else (fp.low if null < v else fp.high)
            if edge is not None and abs(v - edge) <= 1e-6 * max(abs(edge), 1e-12) + 1e-12:
                z.append(0.0)
                continue
            z.append(abs(v - null) / std[p.name])
        return max(z) if z else None

    @classmethod
    def joint_screen(
        cls, base: dict[str, float], pre: dict[str, float], setting: dict[str, str] | None = None
    ) -> tuple[dict[str, Any], dict[str, Array]] | None:
        """Trial values of the effect *and* of the base parameters it distorts, or None.

        For an effect that breaks the three-stage identification itself (its estimates land
        far from any model a local fit can start from), the screen also re-grids the base
        parameters it corrupts. ``pre`` holds the mean pre-event terminal quantities, ``setting``
        the effect's discrete settings the screen chose.
        """
        return None


def _free(p: EffectParameter) -> FreeParameter:
    assert p.low is not None and p.high is not None, f"{p.name} needs a realistic range to be fitted"
    return FreeParameter(p.name, float(p.low), float(p.high), log=p.low > 0)


CANDIDATES: dict[str, type[Candidate]] = {}


def register(cls: type[Candidate]) -> type[Candidate]:
    CANDIDATES[cls.name()] = cls
    return cls


def candidate(name: str) -> type[Candidate]:
    """The candidate for an effect name; a plain plant effect gets the default behaviour."""
    if name not in CANDIDATES:
        effect = EFFECTS[name]
        CANDIDATES[name] = type(f"{effect.__name__}Candidate", (Candidate,), {"effect": effect})
    return CANDIDATES[name]


def library() -> list[type[Candidate]]:
    return [candidate(n) for n in sorted(EFFECTS)]


@register
class StatorResistanceCandidate(Candidate):
    effect = EFFECTS["stator_resistance"]
    signature = "rotor angle and reactive power offsets growing with current; slow band, settling"
    screen_points = 8


@register
class SaturationCandidate(Candidate):
    effect = EFFECTS["magnetic_saturation"]
    signature = "field-flux drift after voltage changes: rotor angle, I_d and Q, slow band, settling and steady state"

    @classmethod
    def admissible(cls, values: dict[str, Array], base: dict[str, float]) -> NDArray[np.bool_]:
        return values["s12"] > values["s10"]

    @classmethod
    def physical(cls, values: dict[str, Any], base: dict[str, float]) -> bool:
        return bool(values["s12"] > values["s10"])

    # Disturbances around one operating point see S(psi) only near that flux, where the quadratic
    # and the exponential curve fit alike: on ANDES's quadratic GENROU the screen chose the
    # exponential, fitted with S(1.0) = 0.137 for the true 0.07, and so exported a wrong S(1.0).
    # The diagnosis therefore fits the planning models' own quadratic (GENROU, GENSAL) and
    # chooses only the form; the exponential curve (GENROE, GENSAE) is for simulation.
    @classmethod
    def choices(cls) -> list[dict[str, str]]:
        return [c for c in super().choices() if c["curve"] == "quadratic"]

    # Saturation adds S psi''_d to the field-flux balance (and, in GENROU's form, S psi''_q to the
    # q-axis one), a steady offset on V_f that makes stage 3 place T'_d0 an order of magnitude too
    # long (+900 % seen with S(1.0) = 0.07), stage 2 X_d 15 % too large and, on GENROU's q axis,
    # X_q 20 % too small; a local fit from there stays there. So the d-axis parameters are
    # screened with the saturation curve: X'_d and T'_d0 on a grid, X_d and X_q from the pre-event
    # balances V_f = E'_q + (X_d - X'_d) I_d + loss_d and E'_d = (X_q - X'_q) I_q - loss_q.
    @classmethod
    def joint_screen(
        cls, base: dict[str, float], pre: dict[str, float], setting: dict[str, str] | None = None
    ) -> tuple[dict[str, Any], dict[str, Array]] | None:  # trial values, and the effect's settings by name
        s10, s12, xdp, td0 = (
            a.ravel()
            for a in np.meshgrid(
                [0.03, 0.08, 0.15],
                [0.2, 0.4, 0.7],
                base["X_d_prime"] * np.array([0.4, 0.55, 0.7, 0.85, 1.0]),
                [0.5, 1.0, 2.0, 4.0, 8.0],
                indexing="ij",
            )
        )
        setting = setting or {p.name: p.default for p in cls.effect.parameters if p.choices}
        effect = cls.effect.from_arrays(s10=s10, s12=s12, **setting)
        e_q, e_d = reconstruct_fluxes(pre["v_d"], pre["v_q"], pre["i_d"], pre["i_q"], xdp, base["X_q_prime"])
        x_l = leakage_default(np.minimum(xdp, base["X_q_prime"]))
        # at rest, as the losses see it (the angle and the speed's rate do not enter them)
        p_m, nan = pre["p_m"], math.nan
        ctx = RotorContext(nan, 1.0, e_q, e_d, pre["i_d"], pre["i_q"], e_q, e_d, p_m, p_m, 0.0, x_l, nan)
        xd, xq = np.full_like(xdp, base["X_d"]), np.full_like(xdp, base["X_q"])
        for _ in range(3):  # the q-axis share (X_q - X_l)/(X_d - X_l) depends on both: a few passes
            loss_d, loss_q = effect.transient_losses(np.empty(0), ctx, _Reactances(xd, xq))
            xd = xdp + (pre["v_f"] - e_q - loss_d) / pre["i_d"]
            xq = np.broadcast_to(base["X_q_prime"] + (e_d + loss_q) / pre["i_q"], xdp.shape)
        ok = (s12 > s10) & (xd > 1.05 * xdp) & (xq > 1.05 * base["X_q_prime"])
        if not ok.any():  # no trial keeps the orderings: the plain screen alone
            return None
        trial_base = {k: np.full(ok.sum(), v) for k, v in base.items()}
        trial_base.update(X_d_prime=xdp[ok], T_d0_prime=td0[ok], X_d=xd[ok], X_q=xq[ok])
        return {"s10": s10[ok], "s12": s12[ok], **setting}, trial_base


@dataclass(frozen=True)
class _Reactances:
    """The synchronous reactances an effect's losses read, one value per trial."""

    X_d: Any
    X_q: Any


@register
class SensorDelayCandidate(Candidate):
    effect = EFFECTS["sensor_delay"]
    signature = "errors proportional to the rate of change of one stream: largest right after the event, all bands"

    # The latency is searched in whole samples and then held: a fractional shift interpolates
    # between samples, which low-passes that stream's noise and "improves" the fit for no
    # physical reason (seen on data without any delay: 1.4 ms on the PMU fitted 5 % of chi-square).
    @classmethod
    def free(cls) -> tuple[FreeParameter, ...]:
        return ()

    @classmethod
    def searched(cls) -> tuple[str, ...]:
        return ("delay_ms",)

    # A 64 ms PT/CT latency was found at 42 ms by search and refit alternating (the base had
    # absorbed the rest); the continuous fit follows the valley, whole samples are then searched.
    @classmethod
    def basin_free(cls) -> tuple[FreeParameter, ...]:
        return (FreeParameter("delay_ms", 1.0, 100.0, log=True),)

    @classmethod
    def screen(cls, runs: Sequence[Any] = ()) -> dict[str, Array]:
        return {
            "delay_ms": np.concatenate((np.arange(1.0, 10.0), np.arange(10.0, 30.0, 2.0), np.arange(30.0, 100.1, 5.0)))
        }

    # A delay shorter than the play-in step is what the step's own discretisation error looks like
    # (the inputs are staged at half steps): 1 ms on PT/CT was named on a STEPS GENSAL set and on
    # ANDES's GENROU with strong dampers, machines without any delay, gaining 1-21 % held out.
    @classmethod
    def unresolvable(cls, values: dict[str, Any], step_s: float) -> str | None:
        d = float(values["delay_ms"])
        if d <= 1000.0 * step_s:
            return f"a {d:g} ms delay is not beyond the play-in step of {1000 * step_s:g} ms, whose error mimics it"
        return None

    @classmethod
    def refine(cls, best: dict[str, Any]) -> dict[str, Array] | None:
        d = float(np.round(best["delay_ms"]))  # whole samples, also after a continuous basin fit
        fine = np.arange(d - 4.0, d + 4.1, 1.0)
        return {"delay_ms": fine[(fine >= 1.0) & (fine <= 100.0)]}


@register
class SubtransientCandidate(Candidate):
    effect = EFFECTS["subtransient_dynamics"]
    signature = "current and power errors in the first 100 ms after each switching; fast band"

    # X_l is held at its planning default min(0.15, 0.8 X''): it only sets how GENROU splits the
    # flux between the transient and damper windings, which terminal measurements barely see
    @classmethod
    def free(cls) -> tuple[FreeParameter, ...]:
        return tuple(p for p in super().free() if p.name != "x_l")

    @classmethod
    def admissible(cls, values: dict[str, Array], base: dict[str, float]) -> NDArray[np.bool_]:
        return (values["x_dpp"] < 0.95 * base["X_d_prime"]) & (values["x_qpp"] < 0.95 * base["X_q_prime"])

    @classmethod
    def physical(cls, values: dict[str, Any], base: dict[str, float]) -> bool:
        return bool(values["x_dpp"] < base["X_d_prime"] and values["x_qpp"] < base["X_q_prime"])

    # A salient-pole machine has no q-axis field winding: the fourth-order model's q axis takes the
    # damper (STEPS's GENSAL: X'_q 0.2199 = its X'' 0.22, T'_q0 0.080 = its T''_q0 0.08). A damper
    # added from there must lie below that X'_q, which it does not: with SEXS and TGOV1 in the loop
    # the fit stalled with X''_q above X'_q (no machine, not named) and a spurious 4 ms delay was
    # named instead. So the screen also tries the q axis as a salient pole's: X'_q up to just below
    # X_q (no transient circuit), the damper where the identified q axis was; beside it the round
    # rotor's grid with the identified q axis kept. The fit starts from the better of the two.
    SALIENT_X_Q_PRIME = 0.98  # of X_q: the q transient circuit absent, the orderings kept

    @classmethod
    def joint_screen(
        cls, base: dict[str, float], pre: dict[str, float], setting: dict[str, str] | None = None
    ) -> tuple[dict[str, Any], dict[str, Array]] | None:
        xdp, xqp, tq = base["X_d_prime"], base["X_q_prime"], base["T_q0_prime"]
        d_axis = (xdp * np.array([0.5, 0.65, 0.8]), np.array([0.02, 0.04, 0.08]))
        round_rotor = np.meshgrid(*d_axis, xqp * np.array([0.5, 0.65, 0.8]), [0.02, 0.04, 0.08], indexing="ij")
        salient = np.meshgrid(*d_axis, xqp * np.array([0.9, 1.0, 1.1]), tq * np.array([0.7, 1.0, 1.4]), indexing="ij")
        x_dpp, t_d0pp, x_qpp, t_q0pp = (np.concatenate([r.ravel(), s.ravel()]) for r, s in zip(round_rotor, salient))
        x_q_prime = np.concatenate(
            [np.full(round_rotor[0].size, xqp), np.full(salient[0].size, cls.SALIENT_X_Q_PRIME * base["X_q"])]
        )
        ok = (x_dpp < 0.95 * xdp) & (x_qpp < 0.95 * x_q_prime) & (x_qpp >= 0.12) & (x_qpp <= 0.5) & (t_q0pp <= 0.2)
        if not ok.any():  # a base no damper fits below (X'' at its 0.12 floor): the plain screen alone
            return None
        trial_base = {k: np.full(ok.sum(), v) for k, v in base.items()}
        trial_base["X_q_prime"] = x_q_prime[ok]
        values = {"x_dpp": x_dpp[ok], "x_qpp": x_qpp[ok], "t_d0pp": t_d0pp[ok], "t_q0pp": t_q0pp[ok]}
        return values, trial_base


@register
class ShaftTorsionCandidate(Candidate):
    effect = EFFECTS["shaft_torsion"]
    signature = "a lightly damped oscillation in the speed after torque or power changes; 3-40 Hz band"

    @classmethod
    def screen(cls, runs: Sequence[Any] = ()) -> dict[str, Array]:
        # A local fit does not cross between torsional frequencies and a grid fine enough for a
        # ring-down of seconds is thousands of models; the mode shows as a peak in the speed
        # residual's spectrum, so the grid is placed around that peak (its signature).
        f0 = torsional_peak(runs)
        if f0 is None:  # no mode stands out: a coarse look, for the record
            f, frac, d = np.arange(5.0, 40.01, 1.0), np.array([0.45, 0.7]), np.array([0.5])
        else:
            f, frac, d = f0 + np.arange(-1.0, 1.01, 0.1), np.array([0.3, 0.45, 0.6, 0.75]), np.array([0.3, 1.5])
        f = f[(f >= 5.0) & (f <= 40.0)]
        ff, rr, dd = (a.ravel() for a in np.meshgrid(f, frac, d, indexing="ij"))
        return {"f_torsion_hz": ff, "turbine_fraction": rr, "d_shaft": dd}


def torsional_peak(runs: Sequence[Any], band: tuple[float, float] = (4.0, 42.0)) -> float | None:
    """Frequency of the largest peak of the speed residual's spectrum after the events, or None."""
    spectra, freqs = [], None
    for r in runs:
        k0 = int(np.searchsorted(r.t, r.scenario.k_event * r.scenario.dt))
        x = r.sim["omega"][k0:, 0] - r.meas["omega"][k0:, 0]
        if len(x) < 64:
            continue
        n = len(x)
        h = float(r.t[1] - r.t[0])
        f = np.fft.rfftfreq(4 * n, h)  # zero-padded: a finer grid for the peak
        p = np.abs(np.fft.rfft((x - x.mean()) * np.hanning(n), 4 * n)) ** 2
        band_mask = (f >= band[0]) & (f <= band[1])
        spectra.append(np.interp(np.linspace(band[0], band[1], 2000), f[band_mask], p[band_mask]))
        freqs = np.linspace(band[0], band[1], 2000)
    if not spectra or freqs is None:
        return None
    total = np.sum(spectra, axis=0)
    k = int(np.argmax(total))
    # a peak must stand out of the residual's own floor; otherwise there is no mode to place
    return float(freqs[k]) if total[k] > 20.0 * np.median(total) else None
