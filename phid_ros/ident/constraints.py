"""What the user tells the estimation: values held (a datasheet's), bounds, starting values.

``--fix NAME=VALUE`` holds a parameter: every stage uses the value and estimates the others
with it (the held column leaves the regression, so the free parameters' uncertainty is
recomputed without it); a held parameter is reported as held, with no error bar of its own.
``--bounds NAME=LO:HI`` confines an estimate: a stage whose data pull it beyond a bound
holds it at the bound, re-estimates the rest, and flags it not identified (the data and the
bound disagree; the number is the user's, not the data's). ``--start NAME=VALUE`` seeds the
searches that have a start (the paper's DE and L-BFGS-B); the fast method's searches are
global over their bounds and need none.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import overload

from phid_ros.errors import ParameterError
from phid_ros.ident.results import Estimate
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME


@dataclass(frozen=True)
class Constraints:
    fixed: dict[str, float] = field(default_factory=dict)
    bounds: dict[str, tuple[float, float]] = field(default_factory=dict)
    start: dict[str, float] = field(default_factory=dict)
    # the machine's open-circuit saturation S(1.0), S(1.2) from its datasheet (--saturation): what
    # gives the field current's base where the no-load tests are all above the knee
    saturation: tuple[float, float] | None = None

    def __bool__(self) -> bool:
        return bool(self.fixed or self.bounds or self.start or self.saturation)

    @overload
    def limits(self, name: str, default: tuple[float, float]) -> tuple[float, float]: ...
    @overload
    def limits(self, name: str, default: None = None) -> tuple[float, float] | None: ...
    def limits(self, name: str, default: tuple[float, float] | None = None) -> tuple[float, float] | None:
        """The user's bounds on ``name`` within ``default`` (a stage's own search range), or None."""
        b = self.bounds.get(name)
        if b is None:
            return default
        if default is None:
            return b
        lo, hi = max(b[0], default[0]), min(b[1], default[1])
        return (lo, hi) if lo < hi else b

    def clip(self, name: str, value: float) -> float:
        b = self.bounds.get(name)
        return value if b is None else min(max(value, b[0]), b[1])

    def outside(self, name: str, value: float) -> bool:
        b = self.bounds.get(name)
        return b is not None and not b[0] <= value <= b[1]

    def as_dict(self) -> dict[str, object]:
        out: dict[str, object] = {
            "fixed": self.fixed,
            "bounds": {k: list(v) for k, v in self.bounds.items()},
            "start": self.start,
        }
        if self.saturation is not None:
            out["saturation"] = {"S10": self.saturation[0], "S12": self.saturation[1]}
        return out


NONE = Constraints()


def held(name: str, value: float) -> Estimate:
    """A held parameter: the user's value, no error bar, not a finding of the data."""
    return Estimate(value, 0.0, identifiable=True, note=f"{name} held at {value:g} (--fix)")


def at_user_bound(est: Estimate, name: str, wanted: float, bound: float) -> Estimate:
    """An estimate the data pushed onto a user's bound: the number is the bound's, so not identified."""
    est.at_bound = True
    pull = f"to {wanted:.4g}, beyond" if math.isfinite(wanted) else "onto"
    est.disqualify(f"{name}: the data pull it {pull} the bound {bound:g} (--bounds); held at the bound")
    return est


def _pairs(items: Sequence[str], option: str) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or not value.strip():
            raise ParameterError(f"{option} {item!r}: expected NAME=...")
        if name not in SPECS_BY_NAME:
            raise ParameterError(f"{option} {item!r}: unknown parameter {name!r}; one of {', '.join(PARAMETER_NAMES)}")
        if (twice := next((v for n, v in out if n == name), None)) is not None:
            # the last would win silently, and the user meant one of them
            raise ParameterError(f"{option} {name} is given twice ({name}={twice}, {item.strip()}); give it once")
        out.append((name, value.strip()))
    return out


def _number(text: str, where: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ParameterError(f"{where}: {text!r} is not a number") from None
    if not math.isfinite(v):
        raise ParameterError(f"{where}: {text!r} is not finite")
    return v


def _in_range(name: str, v: float, where: str) -> None:
    spec = SPECS_BY_NAME[name]
    if not spec.contains(v):
        raise ParameterError(f"{where}: {name}={v:g} {spec.unit} lies outside its physical range {spec.range_text()}")


def parse_saturation(text: str) -> tuple[float, float]:
    """``S10,S12`` (--saturation): the open-circuit curve's S(1.0) and S(1.2), S(1.2) > S(1.0) > 0
    (the planning models' quadratic form through the two needs both)."""
    parts = text.split(",")
    if len(parts) != 2:
        raise ParameterError(f"--saturation {text!r}: expected S10,S12 (S(1.0) and S(1.2)), e.g. 0.1,0.4")
    s10, s12 = (_number(p.strip(), "--saturation") for p in parts)
    if not 0 < s10 < s12:
        raise ParameterError(f"--saturation {text}: needs S(1.2) > S(1.0) > 0 (got S(1.0) = {s10:g}, S(1.2) = {s12:g})")
    return s10, s12


def parse_constraints(
    fix: Sequence[str] = (), bounds: Sequence[str] = (), start: Sequence[str] = (), saturation: str | None = None
) -> Constraints:
    """``NAME=VALUE`` (fix, start), ``NAME=LO:HI`` (bounds) and ``S10,S12`` (saturation) as the
    command line gives them."""
    fixed: dict[str, float] = {}
    for name, text in _pairs(fix, "--fix"):
        fixed[name] = _number(text, f"--fix {name}")
        _in_range(name, fixed[name], "--fix")
    lims: dict[str, tuple[float, float]] = {}
    for name, text in _pairs(bounds, "--bounds"):
        lo_s, sep, hi_s = text.partition(":")
        if not sep:
            raise ParameterError(f"--bounds {name}={text}: expected LO:HI")
        lo, hi = _number(lo_s, f"--bounds {name}"), _number(hi_s, f"--bounds {name}")
        if not lo < hi:
            raise ParameterError(f"--bounds {name}={text}: LO must be below HI")
        if name in fixed:
            raise ParameterError(f"--bounds {name}: {name} is held by --fix; give one or the other")
        lims[name] = (lo, hi)
    starts: dict[str, float] = {}
    for name, text in _pairs(start, "--start"):
        starts[name] = _number(text, f"--start {name}")
        _in_range(name, starts[name], "--start")
        if name in lims and not lims[name][0] <= starts[name] <= lims[name][1]:
            raise ParameterError(f"--start {name}={starts[name]:g} lies outside its --bounds {lims[name]}")
    for small, large in (("X_d_prime", "X_d"), ("X_q_prime", "X_q")):
        if small in fixed and large in fixed and not fixed[small] < fixed[large]:
            raise ParameterError(f"--fix: {small}={fixed[small]:g} must be below {large}={fixed[large]:g}")
    return Constraints(fixed, lims, starts, parse_saturation(saturation) if saturation is not None else None)
