"""Field recordings: COMTRADE (C37.111), PMU and trend-log CSV exports through a channel map, the field
channels' base, a laboratory's test sheet.

The names other parts of phid use, importable from here; each module has the rest."""

from __future__ import annotations

from phid_ros.io.field.channel_map import ChannelMapError, load_channel_map
from phid_ros.io.field.clock_check import clock_problems, pmu_lag_s, pt_ct_lag_s
from phid_ros.io.field.comtrade_dat import ComtradeImportError, open_recording, read_samples
from phid_ros.io.field.comtrade_import import import_comtrade
from phid_ros.io.field.phasors import positive_sequence
from phid_ros.io.field.pmu_csv import PmuImportError, import_pmu_csv
from phid_ros.io.field.test_sheet import SheetError, load_test_sheet

__all__ = [
    "ChannelMapError",
    "ComtradeImportError",
    "ComtradeImportError",
    "PmuImportError",
    "SheetError",
    "clock_problems",
    "import_comtrade",
    "import_pmu_csv",
    "load_channel_map",
    "load_test_sheet",
    "open_recording",
    "pmu_lag_s",
    "positive_sequence",
    "pt_ct_lag_s",
    "read_samples",
]
