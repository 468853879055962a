"""Where a planning record's field came from: the words its comment and the terminal say, and
what kind of source it is, kept apart so that no caller reads the kind back from the words.

A field's source was a sentence ("default: absent (the data show no such term)", "diagnosis:
subtransient_dynamics t_q0pp"), and the record's defaults, the constants left absent, the limits
widened and the effect parameter behind a field were found by string prefixes. A ``Source`` is
still that sentence (a ``str``: the JSON, the table and the record's comment print it as before)
and carries its ``origin`` and, for a field an effect's parameter gave, that ``effect``.
"""

from __future__ import annotations

from enum import Enum

FLAG = " NOT IDENTIFIED"


class Origin(Enum):
    IDENTIFIED = "identified"  # from the recordings (flagged where they did not determine it)
    HELD = "held"  # by the user (--fix, --saturation) or by the model's structure
    DIAGNOSIS = "diagnosis"  # the diagnosis's refit or one of its effects' parameters
    KEPT = "kept"  # from the unit's existing record (phid export --base)
    DEFAULT = "default"  # nothing determined it
    UNREACHED = "unreached"  # a limit the recordings never reached: its default
    WIDENED = "widened"  # ... widened to what the recordings reached
    ABSENT = "absent"  # a term the data do not show: at the value where it vanishes
    MOOT = "moot"  # within a term that is absent


DEFAULTS = frozenset({Origin.DEFAULT, Origin.UNREACHED, Origin.WIDENED, Origin.ABSENT, Origin.MOOT})


class Source(str):
    """A field's source: the sentence said of it, with its ``origin``, the ``effect`` parameter
    (effect, parameter) that gave it where one did, and whether it is ``flagged`` (not identified)."""

    origin: Origin
    effect: tuple[str, str] | None
    flagged: bool

    def __new__(
        cls, text: str, origin: Origin, *, effect: tuple[str, str] | None = None, flagged: bool = False
    ) -> Source:
        made = super().__new__(cls, text + (FLAG if flagged and not text.endswith(FLAG) else ""))
        made.origin, made.effect, made.flagged = origin, effect, flagged
        return made

    def __getnewargs_ex__(self) -> tuple[tuple[str, Origin], dict[str, object]]:
        # pickled (a fleet's worker hands its records back) and copied with its kind, not as bare words
        return (str(self), self.origin), {"effect": self.effect, "flagged": self.flagged}

    @classmethod
    def of_effect(cls, effect: str, parameter: str) -> Source:
        """A field an effect's parameter gave: "diagnosis: <effect> <parameter>"."""
        return cls(f"diagnosis: {effect} {parameter}", Origin.DIAGNOSIS, effect=(effect, parameter))

    def flag(self) -> Source:
        """The same source, flagged: the recordings (or the diagnosis) did not determine it."""
        return Source(str(self), self.origin, effect=self.effect, flagged=True)

    @property
    def is_default(self) -> bool:
        return self.origin in DEFAULTS
