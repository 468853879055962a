"""Terminal tables and numbers: one look for every command, fitted to the console's width.

A table is declared as columns with a priority; when it does not fit the console (80
columns in a log, the terminal's width on a terminal), the least needed columns are left
out and a legend line says which, so that no number is ever cut to ``0.06…``. ``--wide``
gives the console room for everything.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rich import box
from rich.cells import cell_len
from rich.console import Console
from rich.table import Table

if TYPE_CHECKING:
    from phid_ros.ident.results import Estimate

LOG_WIDTH = 80  # a console that is not a terminal (a log, a pipe) is this wide
WIDE_WIDTH = 400  # --wide: room for every column


def make_console(*, wide: bool = False) -> Console:
    """The command's console: the terminal's width, 80 columns in a file, unlimited with --wide.

    Markup is off: what phid prints holds the user's names (paths, units, scenarios), and rich
    read ``x [/old]/u.json`` as a closing tag (MarkupError after the output was written) and
    ``[unit3]`` as a style (gone from the line). phid's own text uses styles, not markup."""
    import sys

    if wide:
        return Console(width=WIDE_WIDTH, soft_wrap=True, markup=False)
    if sys.stdout.isatty():
        return Console(markup=False)
    return Console(width=LOG_WIDTH, soft_wrap=True, markup=False)


@dataclass(frozen=True)
class Col:
    header: str
    justify: str = "right"
    keep: int = 9  # priority: columns with the lowest ``keep`` are left out first when space runs short
    text: bool = False  # free text: may wrap over lines (numbers and names never do)
    key: bool = False  # repeated in every part when a table too wide is folded into parts
    breakable: bool = False  # text that may break inside a word (names, ids: never a number)


def _build(title: str, cols: Sequence[Col], rows: Sequence[Sequence[str]], shown: list[int]) -> Table:
    table = Table(title=title, title_justify="left", box=box.SIMPLE_HEAD, padding=(0, 1), show_edge=False)
    for i in shown:
        c = cols[i]
        table.add_column(
            c.header,
            justify=c.justify,  # type: ignore[arg-type]
            no_wrap=not c.text,
            overflow="fold",
            min_width=_longest_word(cols, rows, i) if c.text and not c.breakable else None,
        )
    for r in rows:
        table.add_row(*(r[i] for i in shown))
    return table


def _needed(cols: Sequence[Col], rows: Sequence[Sequence[str]], shown: list[int]) -> int:
    """Columns needed with every number whole; a text column counts at most 16 (it wraps)."""
    fixed = [i for i in shown if not cols[i].text]
    width = _unwrapped_width(cols, rows, fixed) if fixed else 0
    for i in shown:
        if cols[i].text:
            natural = max([len(cols[i].header)] + [len(r[i]) for r in rows])
            least = 0 if cols[i].breakable else _longest_word(cols, rows, i)
            width += 3 + max(least, min(16, natural))
    return width


def _unwrapped_width(cols: Sequence[Col], rows: Sequence[Sequence[str]], shown: list[int]) -> int:
    """What rich measures for :func:`_build`'s table of columns that never wrap: each column its widest
    cell plus one space either side, one separator between columns (a test holds the two equal).
    Why not rich's own measure: fitting and folding a table measured it a dozen times, 3 ms each."""
    widths = [max([cell_len(cols[i].header)] + [cell_len(r[i]) for r in rows]) for i in shown]
    return sum(w + 2 for w in widths) + len(widths) - 1


def _longest_word(cols: Sequence[Col], rows: Sequence[Sequence[str]], i: int) -> int:
    return max([len(w) for r in rows for w in r[i].split()] + [len(cols[i].header.split()[0]) if cols[i].header else 1])


def print_table(
    console: Console, title: str, cols: Sequence[Col], rows: Sequence[Sequence[str]], legend: str = ""
) -> list[str]:
    """Print a table that fits the console; returns the headers left out (named under the table).

    Columns empty in every row are not shown at all.
    """
    shown = [i for i in range(len(cols)) if any(r[i] for r in rows)] if rows else list(range(len(cols)))
    order = sorted(shown, key=lambda i: (cols[i].keep, -i))
    dropped: list[str] = []
    while _needed(cols, rows, shown) > console.width:
        candidates = [i for i in order if i in shown and cols[i].keep < 9]
        if not candidates:
            break
        shown.remove(candidates[0])
        dropped.append(cols[candidates[0]].header)
    parts = _fold(console, cols, rows, shown)
    for k, part in enumerate(parts, start=1):
        suffix = f" (part {k} of {len(parts)})" if len(parts) > 1 else ""
        console.print(_build(title + suffix, cols, rows, part))
    notes = [legend] if legend else []
    if dropped:
        notes.append(f"not shown at {console.width} columns: {', '.join(dropped)} (--wide shows them)")
    for n in notes:
        console.print(n, highlight=False, style="dim")
    return dropped


def _fold(console: Console, cols: Sequence[Col], rows: Sequence[Sequence[str]], shown: list[int]) -> list[list[int]]:
    """The shown columns in parts that each fit, every part led by the key columns."""
    keys = [i for i in shown if cols[i].key]
    parts: list[list[int]] = [list(keys)]
    for i in shown:
        if i in keys:
            continue
        if len(parts[-1]) > len(keys) and _needed(cols, rows, parts[-1] + [i]) > console.width:
            parts.append(list(keys))
        parts[-1].append(i)
    return [sorted(p) for p in parts]


def fmt(v: float | None, digits: int = 4) -> str:
    """A number in ``digits`` significant figures; a dash for none; never exponent notation above 1e-3."""
    if v is None or not math.isfinite(v):
        return "—"
    if v != 0 and (abs(v) >= 10**digits or abs(v) < 1e-3):
        return f"{v:.{max(1, digits - 2)}e}" if abs(v) < 1e-3 else f"{v:,.0f}"
    return f"{v:.{digits}g}"


def signed_int(v: float | None) -> str:
    """A large signed count-like figure (ΔBIC): whole, with thousands separators."""
    return "—" if v is None or not math.isfinite(v) else f"{v:+,.0f}"


def pct(v: float | None, digits: int = 2) -> str:
    return "—" if v is None or not math.isfinite(v) else f"{v:+.{digits}f}%"


def concise(value: float, std: float) -> str:
    """``1.4430(55)`` for 1.4430 ± 0.0055: the metrologists' short form, two digits of the std."""
    if not math.isfinite(value):
        return "—"
    if not math.isfinite(std) or std <= 0:
        return f"{value:.4g}"
    decimals = max(0, 1 - math.floor(math.log10(std)))
    digits = round(std * 10**decimals)
    if decimals == 0:
        return f"{value:.0f}({digits})"
    return f"{value:.{decimals}f}({digits})"


# how a measured channel is named and in what unit it is compared, in tables and on figure axes
CHANNEL_LABELS = {
    "omega": ("ω", "pu"),
    "delta": ("δ", "rad"),
    "i_d": ("I_d", "pu"),
    "i_q": ("I_q", "pu"),
    "p_e": ("P_e", "pu"),
    "q_e": ("Q_e", "pu"),
    "v_t": ("V_t", "pu"),
    "p_m": ("P_m", "pu"),
}


def axis_label(channel: str) -> str:
    symbol, unit = CHANNEL_LABELS[channel]
    return f"{symbol} ({unit})"


NOT_IDENTIFIED = "n.i."
NOT_IDENTIFIED_MEANS = "not identifiable from these data (value withheld)"
CONCISE_LEGEND = f"1.4430(55) = 1.4430 ± 0.0055; {NOT_IDENTIFIED} = {NOT_IDENTIFIED_MEANS}"
BOUND_SIGNS = {"at least": "≥", "at most": "≤"}


def withheld_text(est: Estimate) -> str:
    """A withheld estimate in a table: its bound where the data give one (``≥ 4.37``, no std: a
    bound is not a value), else the one notation of a withheld value."""
    if est.bound in BOUND_SIGNS and math.isfinite(est.value):
        return f"{BOUND_SIGNS[est.bound]} {est.value:.4g}"
    return NOT_IDENTIFIED


def estimate_text(value: float, std: float, identifiable: bool) -> str:
    """An estimate for a table: concise form when identified; withheld, not printed as a number, when not."""
    if not math.isfinite(value):
        return "—"
    return concise(value, std) if identifiable else NOT_IDENTIFIED


def effect_values_text(values: dict[str, Any], effect: dict[str, Any] | None = None, nd: str = " n.d.") -> str:
    """``k=v`` pairs; with the named ``effect``'s JSON, ``nd`` after a value the data do not determine."""
    from phid_ros.diagnose.results import effect_determined as _effect_determined  # the command's, not every table's

    def one(k: str, v: Any) -> str:
        text = f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
        return text + (nd if effect is not None and not _effect_determined(effect, k) else "")

    return ", ".join(one(k, v) for k, v in values.items())


def print_determinable(
    console: Console, title: str, planned: Sequence[Any], done: dict[str, str] | None = None
) -> None:
    """The channel set's table: each parameter and the route that determines it, or what it needs
    (``planned``: :class:`phid_ros.ident.determinable.Planned` rows; ``done``: the routes taken)."""
    from phid_ros.ident.determinable import describe_plan

    cols = [Col("param", "left", key=True), Col("determined by", "left", text=True)]
    print_table(console, title, cols, [list(r) for r in describe_plan(planned, done)])
