"""Error types of phid_ros.

Every error a user can cause (a missing file, a bad column, a truncated bag,
a parameter out of range) is a :class:`PhidError`. The command line prints its
message on one line, without a traceback; anything else is a bug and keeps
its traceback.
"""

from __future__ import annotations


class PhidError(Exception):
    """Base of all errors caused by input, configuration or data."""


class ParameterError(PhidError, ValueError):
    """A generator parameter set violates its physical ranges or orderings."""


class StageError(PhidError):
    """A stage of the identification cannot run on these scenarios (each stage's error is one)."""


class SimulationError(PhidError):
    """A scenario cannot be simulated as specified (unstable, bad settings)."""


class SchemaError(PhidError):
    """The message schemas in msg_schemas/ cannot be loaded."""


class BagError(PhidError):
    """A bag is missing, truncated, corrupt, or lacks the expected topics/types."""


class CsvImportError(PhidError):
    """A CSV scenario set (manifest or CSV file) is malformed."""


class ResultsError(PhidError):
    """A results or truth JSON file is malformed."""
