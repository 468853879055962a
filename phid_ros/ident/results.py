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

    def as_dict(self) -> dict:
        return {
            "value": self.value,
            "std": self.std,
            "identifiable": self.identifiable,
            "drivers": self.drivers,
            "note": self.note,
            "at_bound": self.at_bound,
        }


# a parameter whose relative standard deviation exceeds this is flagged as not identified
MAX_RELATIVE_STD = 0.10


def flag(est: Estimate, name: str) -> Estimate:
    if not math.isfinite(est.value):
        est.identifiable = False
        est.note = est.note or f"{name} could not be computed"
    elif math.isfinite(est.std) and abs(est.value) > 0 and est.std / abs(est.value) > MAX_RELATIVE_STD:
        est.identifiable = False
        est.note = (est.note + "; " if est.note else "") + (
            f"{name} poorly identified: std is {100 * est.std / abs(est.value):.0f} % of the value"
        )
    return est
