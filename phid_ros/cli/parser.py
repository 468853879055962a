"""``phid``'s command line: the parser of every command, its options and their checks.

What each command does is in :mod:`phid_ros.cli.commands` and the modules it calls; the
documentation's command reference is generated from :func:`build_parser`.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable, Mapping

from phid_ros import __version__
from phid_ros.cli.commands import command
from phid_ros.controls.models import KINDS_IN_ORDER, of_kind
from phid_ros.fleet.history import DRIFT_SIGMAS
from phid_ros.io.recording import DEFAULT_BLOCK_SIZE

EXIT_USER_ERROR = 2


class Parser(argparse.ArgumentParser):
    """argparse with the one error format of the tool: ``phid: error: ...`` on one line, exit 2."""

    commands: Mapping[str, argparse.ArgumentParser]  # the top level's: each command's own parser

    def error(self, message: str) -> None:  # type: ignore[override]
        command = self.prog.removeprefix("phid").strip()  # the top-level parser's is "phid" alone
        where = f"{command}: " if command else ""
        print(f"phid: error: {where}{message} (see {self.prog} --help)", file=sys.stderr)
        raise SystemExit(EXIT_USER_ERROR)


def _number(kind: type, *, low: float, inclusive: bool = False) -> Callable[[str], float | int]:
    """An argparse type: a number above ``low`` (or at it, with ``inclusive``), refused at parse time."""

    def parse(text: str) -> float | int:
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a {'whole ' if kind is int else ''}number") from None
        if value != value or value in (float("inf"), float("-inf")) or value < low or (value == low and not inclusive):
            raise argparse.ArgumentTypeError(f"{text} must be {'at least' if inclusive else 'greater than'} {low:g}")
        return value

    parse.__name__ = kind.__name__  # argparse names the type in its messages
    return parse


POSITIVE = _number(float, low=0.0)
POSITIVE_INT = _number(int, low=1, inclusive=True)


def add_step_thresholds(p: argparse.ArgumentParser) -> None:
    from phid_ros.ident.scenario import MIN_FIELD_STEP, MIN_TORQUE_STEP, MIN_VOLTAGE_STEP

    p.add_argument(
        "--min-torque-step",
        type=POSITIVE,
        default=MIN_TORQUE_STEP,
        metavar="PU",
        help=f"smallest P_m step taken as a disturbance where no marker or manifest kind says so "
        f"(default {MIN_TORQUE_STEP})",
    )
    p.add_argument(
        "--min-voltage-step",
        type=POSITIVE,
        default=MIN_VOLTAGE_STEP,
        metavar="PU",
        help=f"smallest V_t step taken as a disturbance where nothing says so (default {MIN_VOLTAGE_STEP})",
    )
    p.add_argument(
        "--min-field-step",
        type=POSITIVE,
        default=MIN_FIELD_STEP,
        metavar="PU",
        help=f"smallest V_f step (exciter/AVR reference step) taken where nothing says so (default {MIN_FIELD_STEP})",
    )


# -- entry point -----------------------------------------------------------------
Subparsers = argparse._SubParsersAction


def _add_recording_output(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--out",
        required=True,
        help="output: a rosbag2 folder, a file ending in .mcap, or DIR/manifest.json for a CSV scenario set",
    )


def _add_block_size(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--block-size",
        type=POSITIVE_INT,
        default=DEFAULT_BLOCK_SIZE,
        help=f"samples per sensor message (default {DEFAULT_BLOCK_SIZE})",
    )


def _utc_stamp(text: str) -> int:
    from phid_ros.model.conventions import stamp_of_utc

    try:
        return stamp_of_utc(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _add_simulate(sub: Subparsers) -> None:
    p = sub.add_parser("simulate", help="simulate the scenario catalogue (or some scenarios) into a bag")
    _add_recording_output(p)
    p.add_argument(
        "--catalogue",
        choices=("paper", "validation"),
        default="paper",
        help="paper: 15 identification + 3 validation scenarios (default); validation: the 3 only",
    )
    p.add_argument(
        "--scenario", action="append", metavar="NAME", help="one scenario by name or id (S04, V3, ...); repeatable"
    )
    p.add_argument("--duration", type=POSITIVE, help="override every scenario's analysis window, s")
    p.add_argument("--seed", type=int, default=0, help="sensor noise seed (default 0)")
    p.add_argument("--noiseless", action="store_true", help="write the true signals, no sensor noise")
    p.add_argument("--f-nominal", type=POSITIVE, default=50.0, help="nominal frequency, Hz (default 50)")
    p.add_argument(
        "--start",
        type=_utc_stamp,
        metavar="DATE[THH:MM:SSZ]",
        help="the recording's first stamp, ISO 8601 in UTC (default 2026-01-01T00:00:00Z): recordings of one unit "
        "on different days, for phid fleet and phid history",
    )
    _add_block_size(p)
    p.add_argument(
        "--effect",
        action="append",
        metavar="NAME[=k=v,...]",
        help=f"switch on a plant effect, repeatable; NAME is one of: {', '.join(effect_names())}",
    )
    p.add_argument("--force", action="store_true", help="replace existing outputs (the bag and its .truth.json)")
    p.add_argument(
        "--ambient",
        type=POSITIVE,
        metavar="SECONDS",
        help="instead of the catalogue: one long run with ambient load/voltage noise and small steps",
    )
    p.add_argument(
        "--drift",
        action="append",
        metavar="NAME=REL@START-END",
        help="with --ambient: drift a parameter, e.g. T_d0_prime=0.1@300-1500 (+10 %% from 300 s to 1500 s)",
    )


def _add_import_csv(sub: Subparsers) -> None:
    p = sub.add_parser("import-csv", help="turn a CSV scenario set (manifest.json) into a bag")
    p.add_argument("manifest", help="the set's manifest.json (scenarios, their CSV files, kinds and roles)")
    _add_recording_output(p)
    p.add_argument("--strict", action="store_true", help="refuse extra columns instead of ignoring them")
    _add_block_size(p)


def _add_field_imports(sub: Subparsers) -> None:
    for name, what, helptext in (
        (
            "import-comtrade",
            "REC.cfg",
            "COMTRADE recordings (.cfg+.dat or .cff), one scenario each, through a channel map",
        ),
        (
            "import-pmu",
            "EXPORT.csv",
            "CSV exports (PMU data concentrators, trend logs, polled logs), one scenario each, through a channel map",
        ),
    ):
        p = sub.add_parser(name, help=helptext)
        p.add_argument("recordings", nargs="+", metavar=what, help="the recordings (several make one scenario set)")
        p.add_argument(
            "--map",
            required=True,
            action="append",
            metavar="MAP.yaml",
            help="channel map (YAML or JSON; docs/guide/field-recordings.md); repeat for a unit's no-load and "
            "on-line maps: each recording is read through the fullest map it fits",
        )
        _add_recording_output(p)
        _add_block_size(p)


def _add_identify(sub: Subparsers) -> None:
    p = sub.add_parser("identify", help="three-stage identification of the eight parameters")
    p.add_argument(
        "input",
        nargs="+",
        help="rosbag2 folder, .mcap file, or CSV manifest.json; several recordings of one unit make one scenario set",
    )
    p.add_argument("--json", metavar="OUT", help="write the results JSON here")
    p.add_argument(
        "--method",
        choices=("fast", "paper"),
        default="fast",
        help="stage 3 optimiser: fast (variable projection, default) or paper (differential evolution)",
    )
    p.add_argument("--truth", metavar="TRUTH.json", help="true parameters (e.g. <bag>.truth.json) for errors")
    p.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report")
    p.add_argument(
        "--sister",
        action="append",
        default=[],
        metavar="RESULT.json",
        help="a sister unit's result (one design, identified from its own recordings): each parameter "
        "both identify further apart than 2 combined stds is said, and kept in the JSON; repeatable",
    )
    p.add_argument("--no-baseline", action="store_true", help="skip the IEEE 115 baseline column")
    p.add_argument("--seed", type=int, default=0, help="seed of the stochastic optimisers (default 0)")
    p.add_argument(
        "--paper-maxiter", type=POSITIVE_INT, default=300, help="generations of the paper's DE (default 300)"
    )
    add_step_thresholds(p)
    p.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="hold a parameter at a known (datasheet) value in every stage, repeatable; e.g. --fix H=3.5",
    )
    p.add_argument(
        "--bounds",
        action="append",
        default=[],
        metavar="NAME=LO:HI",
        help="confine a parameter, repeatable; an estimate the data push onto a bound is flagged",
    )
    p.add_argument(
        "--start",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="starting value for the searches that take one (--method paper), repeatable",
    )
    p.add_argument(
        "--saturation",
        metavar="S10,S12",
        help="the machine's open-circuit saturation S(1.0),S(1.2) from its datasheet, held: the field "
        "current's base where every no-load test is above the knee (e.g. --saturation 0.1,0.4)",
    )
    p.add_argument(
        "--start-from",
        metavar="UNIT.dyr",
        help="the unit's existing PSS/E record: its machine constants start the searches (as --start), "
        "its exciter, governor and stabiliser models are the candidates and their constants start the fits",
    )
    for kind in KINDS_IN_ORDER:
        names = [m.name for m in of_kind(kind)]
        p.add_argument(
            f"--{kind}",
            action="append",
            choices=names,
            metavar="MODEL",
            help=f"the unit's {kind} model, if known (repeatable: the candidates; default all: {', '.join(names)})",
        )


def _add_diagnose(sub: Subparsers) -> None:
    p = sub.add_parser("diagnose", help="find and name the physics the fourth-order model is missing")
    p.add_argument("input", help="rosbag2 folder, .mcap file, or CSV manifest.json")
    p.add_argument("--json", metavar="OUT", help="write the diagnosis JSON here")
    p.add_argument("--report", metavar="OUT.html", help="write a self-contained HTML report with the figures")
    p.add_argument("--truth", metavar="TRUTH.json", help="true parameters (e.g. <bag>.truth.json) for errors")
    p.add_argument(
        "--workers", type=int, default=0, help="processes for the candidate fits (default 0: every core; 1: none)"
    )
    p.add_argument(
        "--scheduler", metavar="tcp://HOST:8786", help="fit the candidates on an existing Dask cluster instead"
    )
    add_step_thresholds(p)


def _add_replay(sub: Subparsers) -> None:
    p = sub.add_parser("replay", help="play a bag through the online pipeline (detection, recalibration, energy)")
    p.add_argument("bag", help="rosbag2 folder or .mcap file")
    p.add_argument("--out", required=True, help="output bag for every published message (.mcap or folder)")
    p.add_argument("--rate", type=POSITIVE, help="play at R x real time (default: as fast as possible)")
    p.add_argument("--store", metavar="EVENTS.sqlite", help="keep the event store in this file (default: memory)")
    p.add_argument(
        "--force",
        action="store_true",
        help="replace an existing OUT_BAG even if phid replay did not write it (its own outputs are replaced anyway)",
    )
    p.add_argument(
        "--unit",
        help="the generating unit the recording is of (default: the recording's 'unit' metadata); "
        "a store holds one unit's events and refuses another's",
    )
    p.add_argument(
        "--report", metavar="OUT.html", help="write an HTML report: events, parameters and stream health over time"
    )
    p.add_argument(
        "--record",
        metavar="UNIT.dyr",
        help="the unit's record on file (machine, exciter, governor, stabiliser), played into every usable event "
        "as phid validate plays it; verdicts on model_validation and /diagnostics (the node's record parameter)",
    )
    p.add_argument(
        "--fix",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="hold a datasheet value in every recalibration, repeatable (the node's held parameter)",
    )
    p.add_argument(
        "--saturation",
        metavar="S10,S12",
        help="the machine's open-circuit curve from its datasheet (the node's saturation parameter)",
    )


def _add_track(sub: Subparsers) -> None:
    p = sub.add_parser("track", help="sliding-window tracking of parameter drift over a recording")
    p.add_argument("bag", help="rosbag2 folder or .mcap file")
    p.add_argument("--window", type=POSITIVE, default=300.0, help="window length, s (default 300)")
    p.add_argument("--hop", type=POSITIVE, default=60.0, help="hop between estimates, s (default 60)")
    p.add_argument(
        "--base",
        metavar="PARAMS.json",
        help="this machine's parameters (phid identify --json), for X_d and X_q, which ambient data cannot give; "
        "without it the paper's Table 1 values are used, with a warning",
    )
    p.add_argument("--out", help="write the tracked parameters to this bag (.mcap or folder)")
    p.add_argument(
        "--report", metavar="OUT.html", help="write an HTML report: parameters over time with ±2σ, alarms, health"
    )


def _add_fleet(sub: Subparsers) -> None:
    p = sub.add_parser("fleet", help="identify every recording of many units on a Dask cluster, into a history")
    p.add_argument(
        "inventory",
        help="a folder of unit folders (.mcap files, bag folders, CSV manifests) or a YAML/CSV list of "
        "(unit, recording)",
    )
    p.add_argument("--out", required=True, metavar="FLEET_DIR", help="fleet folder: history.sqlite lives here")
    p.add_argument("--scheduler", metavar="tcp://HOST:8786", help="an existing Dask cluster (default: a local one)")
    p.add_argument("--workers", type=int, default=0, help="local cluster worker processes (default 0: one per core)")
    p.add_argument("--diagnose", action="store_true", help="also diagnose each recording (missing physics)")
    p.add_argument(
        "--retry-failed", action="store_true", help="run again the recordings that failed with this phid version"
    )
    p.add_argument("--summary", action="store_true", help="print one row per unit with its latest set and flags")


def _add_history(sub: Subparsers) -> None:
    p = sub.add_parser("history", help="one unit's parameters over time from a fleet history, changes flagged")
    p.add_argument("unit", help="the unit's name, as in the fleet's inventory (phid fleet --summary lists them)")
    p.add_argument(
        "--fleet", default=".", metavar="FLEET_DIR", help="the fleet folder of phid fleet --out (default: here)"
    )
    p.add_argument("--report", metavar="OUT.html", help="write an HTML report with the parameters over time")
    p.add_argument(
        "--sigmas",
        type=POSITIVE,
        default=DRIFT_SIGMAS,
        help=f"flag a change between consecutive well-identified sets beyond this many σ (default {DRIFT_SIGMAS:g})",
    )


def _add_export(sub: Subparsers) -> None:
    p = sub.add_parser("export", help="an identified machine as a planning-model record (PSS/E, PSLF, ANDES)")
    p.add_argument("result", help="results JSON of phid identify --json (its identifiability flags are honoured)")
    p.add_argument("--format", choices=("psse-dyr", "pslf-dyd", "andes"), required=True, help="the record's format")
    p.add_argument(
        "--model",
        choices=("GENROU", "GENSAL"),
        type=str.upper,
        default="GENROU",
        help="round rotor (GENROU, default) or salient pole (GENSAL: X'_q and T'_q0 are dropped)",
    )
    p.add_argument(
        "--diagnosis",
        metavar="DIAG.json",
        help="phid diagnose --json of the same unit: the base parameters of its refit, and X''/T'' "
        "(subtransient_dynamics), S(1.0)/S(1.2) (magnetic_saturation), r_a (stator_resistance) where named",
    )
    p.add_argument(
        "--base",
        metavar="UNIT.dyr",
        help="the unit's existing PSS/E record: what the recordings did not determine is kept from it (its "
        "machine constants, dampers, saturation, and its control models of a kind identify named none of), "
        "what they determined replaces it; each kept field is named in the record's comment",
    )
    p.add_argument("--out", metavar="OUT", help="the record's file (default: RESULT with .dyr, .dyd or .json)")
    p.add_argument("--mva", type=POSITIVE, help="the machine's MVA base (default: the result's base_mva)")
    p.add_argument("--kv", type=POSITIVE, default=20.0, help="the terminal bus's base kV (default 20)")
    p.add_argument(
        "--bus", type=POSITIVE_INT, help="the bus number of the machine (default: the --base record's, else 1)"
    )
    p.add_argument("--id", help="the machine id at its bus (default: the --base record's, else 1)")
    p.add_argument("--f-nominal", type=POSITIVE, help="nominal frequency for ANDES's fn (default: the result's)")
    p.add_argument(
        "--allow-flagged",
        action="store_true",
        help="write parameters flagged not identified (they are named in the record's comment)",
    )


def _add_info(sub: Subparsers) -> None:
    p = sub.add_parser("info", help="topics, message counts, rates, time span and gaps of a bag")
    p.add_argument(
        "bag", help="rosbag2 folder, .mcap file (a bag cut short is read as far as it goes), or CSV manifest.json"
    )


def _add_validate(sub: Subparsers) -> None:
    p = sub.add_parser(
        "validate",
        help="MOD-026/027: a unit's .dyr (machine, exciter, governor) against a recording's steps and disturbances",
    )
    p.add_argument("dyr", help="PSS/E dynamic data: GENROU or GENSAL, and the unit's exciter and governor if any")
    p.add_argument(
        "input",
        nargs="+",
        help="rosbag2 folder, .mcap file, or CSV manifest.json; several recordings of the unit (a no-load and an "
        "on-line day) are validated together, as phid identify reads them",
    )
    p.add_argument("--bus", type=POSITIVE_INT, help="the machine's bus in the .dyr (needed where it holds several)")
    p.add_argument("--id", help="the machine's id at its bus")
    p.add_argument("--json", metavar="OUT", help="write the checks (per scenario and channel) here")
    p.add_argument("--report", metavar="OUT.html", help="write the overlays, recorded against simulated, here")
    p.add_argument(
        "--open-loop",
        action="store_true",
        help="drive the exciter by the recorded V_t, its loop open, as playback tools do (default: the loop "
        "closed through the machine behind the network's reactance the recording shows)",
    )
    add_step_thresholds(p)


def _add_characterise(sub: Subparsers) -> None:
    p = sub.add_parser(
        "characterise",
        help="IEEE 115 from a machine's open- and short-circuit curves: air-gap line, X_du, SCR, S(1.0), S(1.2)",
        description="A test sheet (YAML) names the curves' tables and the rated voltage and armature current: "
        "rated: {v: 127.0, i_a: 5.25}; occ: {file: occ.csv, i_f: IF, v: V}; scc: {file: scc.csv, i_f: IF, i_a: IA}. "
        "Guide: docs/guide/field-recordings.md.",
    )
    p.add_argument("sheet", metavar="SHEET.yaml", help="the test sheet")
    p.add_argument("--json", metavar="OUT", help="write the characteristics here")


# every command's --help ends with examples to copy and the guide that explains them
EXAMPLES: dict[str, tuple[tuple[str, ...], str]] = {
    "simulate": (
        (
            "phid simulate --out my_catalogue",
            "phid simulate --scenario S12 --effect magnetic_saturation=s10=0.08,s12=0.35 --out sat.mcap",
        ),
        "simulate.md",
    ),
    "import-csv": (("phid import-csv my_set/manifest.json --out my_set.mcap",), "simulate.md"),
    "import-comtrade": (("phid import-comtrade fault.cfg --map unit.yaml --out fault.mcap",), "field-recordings.md"),
    "import-pmu": (
        ("phid import-pmu logs/*.csv --map map_noload.yaml --map map_online.yaml --out day.mcap",),
        "field-recordings.md",
    ),
    "identify": (
        (
            "phid identify bags/catalogue --truth bags/catalogue.truth.json --report report.html",
            "phid identify day.mcap --json result.json",
        ),
        "method.md",
    ),
    "diagnose": (("phid diagnose bags/saturation --report diagnose.html",), "diagnose.md"),
    "replay": (("phid replay bags/catalogue --out replay_out.mcap --report replay.html",), "online.md"),
    "track": (("phid track long.mcap --window 300 --hop 60 --report track.html",), "online.md"),
    "fleet": (("phid fleet units/ --out fleet/ --workers 2",), "fleet.md"),
    "history": (("phid history G1 --fleet fleet/ --report G1.html",), "fleet.md"),
    "export": (("phid export result.json --format psse-dyr --model GENSAL --out unit.dyr",), "export.md"),
    "validate": (("phid validate unit.dyr day.mcap --report mod026.html",), "controls.md"),
    "characterise": (("phid characterise lab.yaml --json lab.json",), "field-recordings.md"),
    "info": (("phid info day.mcap",), "field-recordings.md"),
}


class _HelpFormatter(argparse.HelpFormatter):
    """argparse's, except that the examples keep their lines (argparse would run them together)."""

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        if text.startswith("examples:"):
            return "".join(indent + line for line in text.splitlines(keepends=True))
        return super()._fill_text(text, width, indent)


def build_parser() -> Parser:
    parser = Parser(prog="phid", description="Port-Hamiltonian generator identification.")
    parser.add_argument("-V", "--version", action="version", version=f"phid_ros {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    parser.commands = sub.choices

    for add in (
        _add_simulate,
        _add_import_csv,
        _add_field_imports,
        _add_identify,
        _add_diagnose,
        _add_replay,
        _add_track,
        _add_fleet,
        _add_history,
        _add_export,
        _add_validate,
        _add_characterise,
        _add_info,
    ):
        add(sub)
    for name, p in sub.choices.items():
        p.set_defaults(func=command(name))
        lines, guide = EXAMPLES[name]
        p.formatter_class = _HelpFormatter
        p.epilog = "examples:\n" + "".join(f"  {line}\n" for line in lines) + f"guide: docs/guide/{guide}"
        p.add_argument("--wide", action="store_true", help="print tables at full width (default: fit the terminal)")
    return parser


def effect_names() -> list[str]:
    """The plant effects' names, read from the effects package's modules without importing them
    (each effect is named after its module: ``test/sim/test_effects.py`` holds it): importing them
    imports numba, over a second that ``phid --help`` would pay."""
    import importlib.util
    import pkgutil

    spec = importlib.util.find_spec("phid_ros.sim.effects")
    assert spec is not None and spec.submodule_search_locations is not None
    return sorted(m.name for m in pkgutil.iter_modules(spec.submodule_search_locations) if m.name != "base")
