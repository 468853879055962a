"""Figures the README and the docs quote from the corpus's committed table, written in place.

A quoted figure is marked in the Markdown source by the row it comes from::

    runs at <!--corpus:long-replay;2 h replay, real time x;.0f-->163<!--/corpus-->× real time

(set; figure; a Python format spec, separated by semicolons, since a Markdown table's cells are
split at every ``|``, comments included; ``%`` specs print a relative error as a percentage).
``python benchmarks/corpus.py --docs`` rewrites every marked value from ``benchmarks/corpus.json``,
and ``test/test_corpus_docs.py`` fails where one differs from the table or names a row the table
does not hold: a figure in the docs is then one the corpus command produced, and it moves in the
same commit as the table.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]

QUOTE = re.compile(r"<!--corpus:(?P<set>[^;>]+);(?P<figure>[^;>]+)(?:;(?P<fmt>[^;>]*))?-->(?P<value>.*?)<!--/corpus-->")


class QuoteError(ValueError):
    """A marked figure the committed table cannot give."""


def documents() -> list[Path]:
    """Every Markdown page that may quote the corpus: the README and docs/ (the changelog and the
    measurement log apart: dated records of what was measured then)."""
    pages = [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]
    return [p for p in pages if p.name not in ("changelog.md", "measurement-log.md")]


def formatted(value: Any, fmt: str | None) -> str:
    """A figure as the docs print it: numbers by ``fmt``, a typographic minus, a space before %;
    a withheld figure as "withheld"."""
    if value is None:
        return "withheld"
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    text = format(value, fmt or ".4g")
    if text.endswith("%"):
        text = text[:-1] + " %"
    return text.replace("-", "\u2212")


def quoted(table: dict[str, Any], name: str, fig: str, fmt: str | None, where: str) -> str:
    row = table.get(name)
    if row is None:
        raise QuoteError(f"{where}: quotes corpus set {name!r}, which benchmarks/corpus.json does not hold")
    if fig not in row["figures"]:
        raise QuoteError(f"{where}: quotes figure {fig!r} of corpus set {name!r}, which its row does not hold")
    return formatted(row["figures"][fig]["value"], fmt)


def rewritten(text: str, table: dict[str, Any], where: str) -> str:
    """``text`` with every marked figure written from ``table``."""

    def one(m: re.Match[str]) -> str:
        line = text.count("\n", 0, m.start()) + 1
        value = quoted(table, m["set"], m["figure"], m["fmt"], f"{where}:{line}")
        return m.group(0).replace(f"-->{m['value']}<!--/corpus-->", f"-->{value}<!--/corpus-->")

    return QUOTE.sub(one, text)


def stale(table: dict[str, Any]) -> Iterator[str]:
    """Each marked figure that differs from the table, as "page:line: set | figure: docs say A, table B"."""
    for page in documents():
        text = page.read_text()
        where = str(page.relative_to(ROOT))
        for m in QUOTE.finditer(text):
            line = text.count("\n", 0, m.start()) + 1
            value = quoted(table, m["set"], m["figure"], m["fmt"], f"{where}:{line}")
            if value != m["value"]:
                yield f"{where}:{line}: {m['set']} | {m['figure']}: the docs say {m['value']!r}, the table {value!r}"


def write_all(table: dict[str, Any]) -> list[Path]:
    """Every page's marked figures rewritten from ``table``; the pages that changed."""
    changed = []
    for page in documents():
        text = page.read_text()
        new = rewritten(text, table, str(page.relative_to(ROOT)))
        if new != text:
            page.write_text(new)
            changed.append(page)
    return changed


def count(pages: list[Path] | None = None) -> int:
    return sum(len(QUOTE.findall(p.read_text())) for p in (pages or documents()))
