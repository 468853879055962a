"""What every command shares: reading its input and telling the user on stderr what went wrong."""

from __future__ import annotations

import math
import sys
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

from phid_ros.api import load_recording
from phid_ros.errors import PhidError
from phid_ros.ident.scenario import StepThresholds
from phid_ros.io.files.results import read_json
from phid_ros.io.recording import Recording
from phid_ros.model.parameters import GeneratorParameters


def warn(message: str) -> None:
    """A warning: on stderr, so that stdout stays the command's result. One line where stderr is
    a file or a pipe (a log, grep); on a terminal, folded between words at its width and
    indented, where the terminal itself cut words in two."""
    text = f"phid: warning: {message}"
    if sys.stderr.isatty():
        import shutil
        import textwrap

        width = shutil.get_terminal_size((80, 24)).columns
        text = textwrap.fill(text, width=max(40, width), subsequent_indent="    ", break_on_hyphens=False)
    print(text, file=sys.stderr)


def read_input(path: str | Path) -> tuple[Recording, str]:
    """:func:`load_recording`, its warnings on stderr."""
    rec = load_recording(path)
    for w in rec.warnings:
        warn(w)
    return rec, str(path)


def finish(
    console: Any,
    problems: Iterable[str],
    summary: str,
    json_out: Path | None,
    report: Path | None,
    write_report: Callable[[Path], None],
) -> int:
    """A command's last words: its problems as warnings, the summary line, then the HTML report if asked."""
    from phid_ros.cli.progress import ProgressLine

    for p in problems:
        warn(p)
    console.print(summary + (f"; wrote {json_out}" if json_out else ""), highlight=False)
    if report:
        with ProgressLine(f"writing {report}"):
            write_report(report)
        console.print(f"wrote {report}", highlight=False)
    return 0


def figure_backend() -> None:
    """Matplotlib as the reports draw with it: off-screen (Agg), and every text as written. The
    figures carry the user's names (scenarios, units, files); with mathtext on, ``$_$`` in a
    scenario's name stopped the report with a parse error. phid's own labels use Unicode, not TeX."""
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.rcParams["text.parse_math"] = False


SUPERSCRIPTS = str.maketrans("-0123456789", "⁻⁰¹²³⁴⁵⁶⁷⁸⁹")


def power_of_ten(value: float, _position: object = None) -> str:
    """A log axis's tick as Unicode (10⁵, 10⁻²): matplotlib's own writes TeX (``mathdefault{10^{5}}``),
    shown raw with mathtext off (:func:`figure_backend`); a tick between the decades is left blank."""
    if not value > 0:
        return ""
    exponent = math.log10(value)
    if abs(exponent - round(exponent)) > 1e-9:
        return ""
    return "1" if round(exponent) == 0 else "10" + str(round(exponent)).translate(SUPERSCRIPTS)


def log_ticks(ax: Any) -> None:
    """Both axes of a log-log plot ticked as :func:`power_of_ten` writes them."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    for axis in (ax.xaxis, ax.yaxis):
        axis.set_major_formatter(FuncFormatter(power_of_ten))
        axis.set_minor_formatter(NullFormatter())


WITHHELD_LABEL = "withheld (not identifiable): no value drawn"


def mark_withheld(ax: Any, t: Sequence[Any]) -> None:
    """Where a parameter was withheld, a tick on the time axis and no value: a number drawn where
    the report's table says "withheld" reads as identified (track drew D from -0.95 to +0.53)."""
    if len(t):
        ax.plot(
            list(t),
            [0.0] * len(t),
            "|",
            color="0.4",
            ms=12,
            mew=1.5,
            transform=ax.get_xaxis_transform(),  # x in data, y at the axis
            clip_on=False,
            label=WITHHELD_LABEL,
        )


# -- what the commands that read a recording share ------------------------------------
def step_thresholds(args: Any) -> StepThresholds:
    return StepThresholds(args.min_torque_step, args.min_voltage_step, args.min_field_step)


def load_parameters(path: str | Path) -> GeneratorParameters:
    """The eight parameters of a results or truth file; other keys ignored with a note on stderr."""
    params, notes = GeneratorParameters.from_document(read_json(path), source=str(path))
    for n in notes:
        warn(n)
    return params


def load_truth(path: str | Path, rec: Recording) -> GeneratorParameters:
    doc = read_json(path)
    truth = load_parameters(path)
    f_truth = doc.get("f_nominal_hz")
    if f_truth is not None and "f_nominal_hz" in rec.metadata and abs(float(f_truth) - rec.f_nominal_hz) > 1e-9:
        raise PhidError(f"{path}: nominal frequency {f_truth} Hz differs from the recording's {rec.f_nominal_hz} Hz")
    base_truth = doc.get("base_mva")
    base_rec = rec.metadata.get("base_mva")
    if base_truth is not None and base_rec is not None and abs(float(base_truth) - float(base_rec)) > 1e-9:
        raise PhidError(
            f"{path}: base {base_truth} MVA differs from the recording's {base_rec} MVA; "
            "per-unit parameters on different bases do not compare"
        )
    return truth
