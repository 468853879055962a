"""Which module does each ``phid`` command (the parser: :mod:`phid_ros.cli.parser`).

Each command is one module's ``<name>_command(args, console) -> exit status``, imported when the
command runs, so that ``phid --help`` does not load the identification. A command parses nothing
and computes nothing of its own beyond its printing: the work is in :mod:`phid_ros.api` and below.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Callable

from rich.console import Console

Command = Callable[[argparse.Namespace, Console], int]

# command -> (module under phid_ros.cli, function)
COMMANDS: dict[str, tuple[str, str]] = {
    "simulate": ("simulate", "simulate_command"),
    "import-csv": ("imports", "import_csv_command"),
    "import-comtrade": ("imports", "import_comtrade_command"),
    "import-pmu": ("imports", "import_pmu_command"),
    "info": ("info", "info_command"),
    "identify": ("identify", "identify_command"),
    "diagnose": ("diagnose", "diagnose_command"),
    "replay": ("replay", "replay_command"),
    "track": ("track", "track_command"),
    "fleet": ("fleet", "fleet_command"),
    "history": ("fleet", "history_command"),
    "export": ("export", "export_command"),
    "validate": ("validate", "validate_command"),
    "characterise": ("characterise", "characterise_command"),
}


def command(name: str) -> Command:
    """The function that runs command ``name``, its module imported only when it runs."""
    module, function = COMMANDS[name]

    def run_command(args: argparse.Namespace, console: Console) -> int:
        found: Command = getattr(importlib.import_module(f"phid_ros.cli.{module}"), function)
        return found(args, console)

    run_command.__name__ = function
    return run_command
