"""The corpus's table in the docs is the committed one (``python benchmarks/corpus.py --docs``
writes it): a figure in docs/figures.md's corpus part is one the corpus command produced."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _corpus():
    spec = importlib.util.spec_from_file_location("corpus", ROOT / "benchmarks" / "corpus.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


def test_the_docs_corpus_part_is_the_committed_table() -> None:
    corpus = _corpus()
    table = json.loads(corpus.TABLE.read_text())
    assert corpus.docs_section(table) in corpus.DOCS.read_text(), "run: python benchmarks/corpus.py --docs"


def test_a_figure_is_marked_where_it_moved_past_its_tolerance_and_a_time_never_fails() -> None:
    corpus = _corpus()
    f = corpus.figure
    assert corpus.moved(f(0.0101), f(0.010)) == ""
    assert corpus.moved(f(0.0201), f(0.010)).startswith("MOVED +0.0101")
    assert corpus.moved(f("EXST1", 0.0, "verdict"), f("ESST5B", 0.0, "verdict")) == "MOVED"
    assert corpus.moved(f(14.0, 0.5, "time"), f(10.0, 0.5, "time")) == ""  # within +-50 %
    assert corpus.moved(f(16.0, 0.5, "time"), f(10.0, 0.5, "time")).startswith("MOVED")
    assert corpus.moved(f(None), f(0.01)) == "MOVED"  # a figure withheld where it was published


def _quotes():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    import corpus_quotes

    return corpus_quotes


def test_every_figure_a_page_quotes_is_the_committed_tables() -> None:
    quotes = _quotes()
    table = json.loads((ROOT / "benchmarks" / "corpus.json").read_text())
    assert quotes.count() >= 80  # README, figures.md and the guides quote the corpus
    stale = list(quotes.stale(table))
    assert not stale, "run: python benchmarks/corpus.py --docs\n" + "\n".join(stale)


def test_a_quote_is_written_from_its_row_and_a_missing_row_is_named() -> None:
    quotes = _quotes()
    table = {"s": {"figures": {"e": {"value": -0.00321}, "n": {"value": "SEXS"}, "w": {"value": None}}}}
    text = (
        "a <!--corpus:s;e;+.2%-->old<!--/corpus--> b <!--corpus:s;n;-->x<!--/corpus--> "
        "<!--corpus:s;w;.3f-->1<!--/corpus-->"
    )
    assert quotes.rewritten(text, table, "p.md") == (
        "a <!--corpus:s;e;+.2%-->\u22120.32 %<!--/corpus--> b <!--corpus:s;n;-->SEXS<!--/corpus--> "
        "<!--corpus:s;w;.3f-->withheld<!--/corpus-->"
    )
    with pytest.raises(quotes.QuoteError, match=r"p.md:2: quotes figure 'z' of corpus set 's'"):
        quotes.rewritten("\n<!--corpus:s;z;-->1<!--/corpus-->", table, "p.md")
    with pytest.raises(quotes.QuoteError, match="corpus set 'nope'"):
        quotes.rewritten("<!--corpus:nope;z;-->1<!--/corpus-->", table, "p.md")
