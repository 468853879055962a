"""The HTML reports' building blocks: the style sheet, a table, a figure inlined as PNG. Every
report (identify's, diagnose's, validate's, replay's, the fleet's history) builds on these, so no
report imports another for them."""

from __future__ import annotations

import base64
import html
import io
import re
from collections.abc import Sequence

STYLE = (
    "body{font-family:sans-serif;max-width:1100px;margin:2em auto;color:#222}"
    "table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right;"
    "white-space:nowrap}td.text{white-space:normal;text-align:left;max-width:40em}td.name,th.name{text-align:left}"
    "td:first-child,th:first-child{text-align:left}th{background:#f2f2f2}img{max-width:100%;display:block}"
    "h2,h3{margin:1.2em 0 0.3em}"
)


NUMERIC = re.compile(r"^[-+]?[0-9][0-9.,]*(e[-+]?[0-9]+)?(\([0-9]+\))?\s?(%|\*|\s\(bound\))?$")


def html_table(headers: Sequence[str], rows: Sequence[Sequence[str]], text_columns: Sequence[int] = ()) -> str:
    """A table with every header filled; cells escaped; numbers right-aligned and never wrapped.

    ``text_columns`` (and any long prose cell) may wrap over lines.
    """
    numeric = [bool(rows) and all(not r[i] or NUMERIC.match(r[i]) for r in rows) for i in range(len(headers))]
    head = "".join(
        f"<th>{html.escape(h)}</th>" if numeric[i] else f'<th class="name">{html.escape(h)}</th>'
        for i, h in enumerate(headers)
    )

    def cell(i: int, c: str) -> str:
        if i in text_columns or (len(c) > 30 and " " in c):
            return f'<td class="text">{html.escape(c)}</td>'
        return f'<td class="{"num" if NUMERIC.match(c) else "name"}">{html.escape(c)}</td>'

    body = "".join("<tr>" + "".join(cell(i, c) for i, c in enumerate(r)) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def png_data_uri(fig: object) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")  # type: ignore[attr-defined]
    import matplotlib.pyplot as plt

    plt.close(fig)  # type: ignore[arg-type]
    return "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode("ascii")
