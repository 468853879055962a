"""CSV scenario sets: a manifest.json and one CSV file per scenario, imported and exported.

The names other parts of phid use, importable from here; each module has the rest."""

from __future__ import annotations

from phid_ros.io.csvset.csv_export import write_csv_set
from phid_ros.io.csvset.csv_import import (
    CSV_COLUMNS,
    KINDS,
    ROLES,
    CsvImportError,
    ScenarioTable,
    decimal_comma_fields,
    import_csv_set,
    is_number,
    read_scenario_csv,
    recording_from_tables,
)

__all__ = [
    "CSV_COLUMNS",
    "CsvImportError",
    "KINDS",
    "ROLES",
    "ScenarioTable",
    "decimal_comma_fields",
    "import_csv_set",
    "is_number",
    "read_scenario_csv",
    "recording_from_tables",
    "write_csv_set",
]
