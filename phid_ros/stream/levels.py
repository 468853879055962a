"""A status's level: diagnostic_msgs/DiagnosticStatus's four, ordered by how bad, merged by max.

diagnostic_updater merges its tasks' levels by taking the largest byte; one type here does the
same for the streams' health, a recalibration's outcome and the record on file, so no caller
writes the order by hand (``"WARN" if level == "OK" else level``) or parses it back from text.
Printed and written to JSON by name ("WARN"), published as its byte.
"""

from __future__ import annotations

from enum import IntEnum


class Level(IntEnum):
    OK = 0
    WARN = 1
    ERROR = 2
    STALE = 3

    def __str__(self) -> str:
        return self.name

    def __format__(self, spec: str) -> str:
        return format(self.name, spec)


def worst(*levels: Level) -> Level:
    """The worst of ``levels`` (OK when none): how diagnostic_updater merges its tasks' levels."""
    return max(levels, default=Level.OK)
