"""The exciter's and the governor's planning records, from identify's ``controls``.

Each named control model (:mod:`phid_ros.controls.models`) becomes a record of its PSS/E
constants in their declared order, each with where its value came from: identified, or a stated
default where the recordings do not determine it. A limit the recordings reached (an exciter's
ceiling in a fault) is written as identified; one never reached is the model's declared default,
said so in the record's comment; a constant fitted but not determined is refused, as a machine parameter is, unless
``--allow-flagged``, except at the value where its block is absent (a turbine damping D_t of 0).
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from phid_ros.controls.models import MODELS, ControlParameter
from phid_ros.errors import PhidError
from phid_ros.export.source import Origin, Source


class ControlExportError(PhidError):
    """identify's ``controls`` cannot become a planning record as asked."""


@dataclass
class ControlRecord:
    model: str
    kind: str
    values: dict[str, float]
    sources: dict[str, Source]
    flagged: list[str] = field(default_factory=list)
    kept_from: str = ""  # the existing record it was kept from (phid export --base), not identified
    icons: dict[str, int] = field(default_factory=dict)  # PSS/E's integers (none: the model's own, MODELS[m].icons)

    def icon_values(self) -> list[int]:
        """PSS/E's integers before the constants: the existing record's where it gave them (a
        stabiliser's remote bus), else the ones phid simulates."""
        return [self.icons.get(n, v) for n, v in MODELS[self.model].icons]

    @property
    def defaults(self) -> list[str]:
        return [n for n, s in self.sources.items() if s.is_default]

    @property
    def absent(self) -> list[str]:
        """Constants at the value where their term vanishes: the data show no such term."""
        return [n for n, s in self.sources.items() if s.origin is Origin.ABSENT]

    def comment(self) -> str:
        return comment_text(self._comment_parts())

    def _comment_parts(self) -> list[str]:
        if self.kept_from:
            return [f"phid_ros export: {self.kind} kept from {self.kept_from} (the recordings named none)"]
        parts = [f"phid_ros export: {self.kind} identified from the recordings"]
        if self.flagged:
            parts.append("NOT IDENTIFIED: " + ", ".join(self.flagged))
        widened = [n for n, s in self.sources.items() if s.origin is Origin.WIDENED]
        unreached = [n for n in self.defaults if n not in self.absent and n not in widened]
        if unreached:
            parts.append("defaults (not reached in the recordings): " + ", ".join(unreached))
        if widened:
            parts.append("not reached, at least what the recordings reached: " + ", ".join(widened))
        if self.absent:
            parts.append("absent (the recordings show no such term): " + ", ".join(self.absent))
        return parts


def comment_text(parts: list[str]) -> str:
    """A record's comment on one line: a control character in a name (a result file's path) would
    end the comment, and the next line of a .dyr or .dyd would be read as a record."""
    return re.sub(r"[\x00-\x1f\x7f]", "?", "; ".join(parts))


def build_control_records(
    result: Mapping[str, Any], source: str, *, allow_flagged: bool = False
) -> list[ControlRecord]:
    """A record for each control system identify named (none where it named none)."""
    controls = result.get("controls") or {}
    if not isinstance(controls, Mapping):
        raise ControlExportError(f"{source}: 'controls' is not an object")
    out = []
    for kind, doc in controls.items():
        name = doc.get("model") if isinstance(doc, Mapping) else None
        if name is None:
            continue
        model = MODELS.get(name)
        if model is None:
            raise ControlExportError(
                f"{source}: controls.{kind}: model {name!r} is not one phid knows ({sorted(MODELS)})"
            )
        params, ident = doc.get("parameters") or {}, doc.get("identifiable") or {}
        seen = doc.get("limits_seen") or {}
        # a limit fitted because the recordings reached it, determined or not (a ceiling's loading
        # fitted with it): written as fitted, flagged where not determined, never as a default
        reached = set(doc.get("limits_reached") or [])
        upper = model.output_limits[1] if model.output_limits else None
        values: dict[str, float] = {}
        sources: dict[str, Source] = {}
        flagged = []
        for p in model.parameters:
            v = params.get(p.name)
            if p.held:
                values[p.name] = float(v) if isinstance(v, (int, float)) else p.default
                sources[p.name] = Source("held by the model's structure", Origin.HELD)
                continue
            parent = next((q for q in model.parameters if q.name == p.within), None)
            if parent is not None and parent.absent is not None and _is_absent(params.get(parent.name), parent):
                values[p.name], sources[p.name] = (
                    p.default,
                    Source(f"default: moot ({parent.name} absent)", Origin.MOOT),
                )
                continue
            if v is None or (p.limit and not ident.get(p.name) and p.name not in reached):
                values[p.name] = p.default
                sources[p.name] = Source("default (a limit the recordings never reached)", Origin.UNREACHED)
                least = seen.get(p.name)
                sign = 1.0 if p.name == upper else -1.0
                if isinstance(least, (int, float)) and math.isfinite(least) and sign * least > sign * p.default:
                    # the default would cut what was recorded: the least the limit can be instead
                    values[p.name] = float(least)
                    sources[p.name] = Source(
                        "default: widened to what the recordings reached (a limit never reached)", Origin.WIDENED
                    )
                continue
            if not isinstance(v, (int, float)) or not math.isfinite(float(v)):
                raise ControlExportError(f"{source}: controls.{kind}.{p.name} = {v!r}: not a number")
            if (problem := p.outside(float(v))) is not None:
                raise ControlExportError(f"{source}: controls.{kind}.{problem} (the fit's search range)")
            values[p.name] = float(v)
            if ident.get(p.name):
                sources[p.name] = Source("identified", Origin.IDENTIFIED)
            elif _is_absent(v, p):
                # the fit pressed onto the value where the term vanishes (D_t 8e-12): absent
                values[p.name] = float(p.absent or 0.0)
                sources[p.name] = Source("default: absent (the data show no such term)", Origin.ABSENT)
            else:
                sources[p.name] = Source("identified, NOT determined", Origin.IDENTIFIED)
                flagged.append(p.name)
        if flagged and not allow_flagged:
            raise ControlExportError(
                f"{source}: {name} {', '.join(flagged)} not identified; refusing to export it "
                "(--allow-flagged writes it anyway, marked in the record's comment)"
            )
        out.append(ControlRecord(name, kind, values, sources, flagged))
    return out


def _is_absent(v: Any, p: ControlParameter) -> bool:
    """The fit pressed onto the value where the constant's term vanishes (D_t 8e-12, K_F 1e-9)."""
    if p.absent is None or not isinstance(v, (int, float)):
        return False
    return abs(float(v) - p.absent) <= 1e-6 * max(1.0, abs(p.high))
