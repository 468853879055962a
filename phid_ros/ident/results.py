"""Result types of the identification stages (plain data, JSON-ready)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field


@dataclass
class Estimate:
    """One identified parameter: value, one standard deviation, and what drove it."""

    value: float
    std: float = math.nan
    identifiable: bool = True
    drivers: list[str] = field(default_factory=list)  # scenarios carrying most of the information
    note: str = ""
    at_bound: bool = False
    # the random part of ``std`` (noise only, no bias allowance): what differs between two
    # estimates of one plant under the same conditions, where a common bias cancels
    std_random: float = math.nan
    # "at least" or "at most" where the data bound the parameter without giving it (then never
    # identifiable): a table prints the bound as a bound, never as a value with a std
    bound: str = ""

    def add_note(self, note: str) -> None:
        self.note = f"{self.note}; {note}" if self.note else note

    def disqualify(self, note: str) -> None:
        """Not identified, and why (added to what is already noted)."""
        self.identifiable = False
        self.add_note(note)

    @property
    def random_std(self) -> float:
        return self.std_random if math.isfinite(self.std_random) else self.std

    def as_dict(self) -> dict:
        return {
            "value": self.value,
            "std": self.std,
            "identifiable": self.identifiable,
            "drivers": self.drivers,
            "note": self.note,
            "at_bound": self.at_bound,
            "bound": self.bound or None,
        }


# a parameter whose relative standard deviation exceeds this is flagged as not identified
MAX_RELATIVE_STD = 0.10

# The stages' standard deviations come from linearised, cluster-robust least squares. The
# coverage study (benchmarks/bench_coverage.py: new sensor noise on one plant, 20 seeds) found
# them too small: the spread of (estimate - truth)/std was about 1.4-1.6 for H, X'_d and T'_d0
# instead of 1, because the filtered residuals stay correlated beyond the 1 s blocks. The
# reported std is scaled by this measured factor so that +-2 std covers the truth >= 90 % of
# the time; rerun the study after changing a stage.
STD_CALIBRATION = 1.7


def flag(est: Estimate, name: str) -> Estimate:
    if not math.isfinite(est.value):
        est.identifiable = False
        est.note = est.note or f"{name} could not be computed"
    elif not math.isfinite(est.std) or est.std <= 0:
        # a fit with no residual degrees of freedom has no error bar: its number cannot be trusted
        est.disqualify(f"{name} has no standard deviation (too few data to judge)")
    elif math.isfinite(est.std) and abs(est.value) > 0 and est.std / abs(est.value) > MAX_RELATIVE_STD:
        est.disqualify(f"{name} poorly identified: std is {100 * est.std / abs(est.value):.0f} % of the value")
    return est
