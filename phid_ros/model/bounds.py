"""A named value with a valid range: the one check every such declaration shares.

Four kinds of declaration carry a range: a machine's parameter (``model.parameters.ParameterSpec``),
an effect's (``sim.effects.EffectParameter``), a fitted one's (``diagnose.candidates.FreeParameter``)
and a node's setting (``stream.params.Tunable``). Each keeps its own fields; what a range means (either
end may be open, both ends belong to it) and how a value outside it is reported live here.
"""

from __future__ import annotations

from collections.abc import Callable


def _g(x: float) -> str:
    return f"{x:g}"


class Bounded:
    """Mixin for a declaration with ``name``, ``low`` and ``high`` (None: open) and maybe ``unit``."""

    # (no class attribute for unit: a dataclass would take it for its field's default)
    name: str
    low: float | None
    high: float | None

    def contains(self, value: float) -> bool:
        """Whether ``value`` is not beyond either end. NaN is not: what it means is the caller's to say
        (a parameter set refuses it as not finite first; an effect's NaN asks for its derived default)."""
        return not ((self.low is not None and value < self.low) or (self.high is not None and value > self.high))

    def range_text(self, number: Callable[[float], str] = _g) -> str:
        low = "-inf" if self.low is None else number(self.low)
        high = "inf" if self.high is None else number(self.high)
        return f"[{low}, {high}]"

    def outside(self, value: float, number: Callable[[float], str] = _g) -> str | None:
        """None when ``value`` lies in the range, else ``name=value unit outside [low, high]``."""
        if self.contains(value):
            return None
        unit = getattr(self, "unit", "")
        unit = f" {unit}" if unit else ""
        return f"{self.name}={number(value)}{unit} outside {self.range_text(number)}"
