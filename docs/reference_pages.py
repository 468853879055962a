"""The reference pages written from the declarations, never by hand: parameters, effects, control
models and node parameters (ANDES generates its model reference the same way).

``docs/conf.py`` calls :func:`write_pages` before Sphinx reads the sources, so a parameter, an
effect or a control model added to its table is in the next build's reference with its unit,
default and range, and a page cannot disagree with the code. The pages go to
``docs/reference/`` (not committed; see ``.gitignore``).
"""

from __future__ import annotations

import inspect
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

HEADER = "<!-- written by docs/reference_pages.py from the declarations: edit those, not this page -->\n\n"


def _cell(value: Any) -> str:
    if isinstance(value, float) and value != value:
        return "derived"  # a NaN default: the effect derives it from the machine (its meaning says how)
    text = "" if value is None else (f"{value:g}" if isinstance(value, float) else str(value))
    return text.replace("|", "\\|").replace("\n", " ")


def _table(head: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(_cell(v) for v in row) + " |" for row in rows]
    return "\n".join(lines) + "\n"


def _range(low: float | None, high: float | None) -> str:
    if low is None and high is None:
        return ""
    return f"[{'-inf' if low is None else f'{low:g}'}, {'inf' if high is None else f'{high:g}'}]"


def _summary(cls: type) -> str:
    """A class's docstring, its first paragraph."""
    return (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")


def parameters_page() -> str:
    from phid_ros.model.parameters import PARAMETER_SPECS

    rows = [(f"`{s.name}`", s.symbol, s.unit, s.default, _range(s.low, s.high), s.description) for s in PARAMETER_SPECS]
    return (
        "# Machine parameters\n\n"
        "The eight parameters the three stages identify (`phid_ros/model/parameters.py`). Defaults are the "
        "machine of the paper's Table 1; the ranges bound what a real synchronous machine can have: a value "
        "outside is refused as input, they are not search bounds.\n\n"
        + _table(("name", "symbol", "unit", "default", "range", "meaning"), rows)
    )


def effects_page() -> str:
    from phid_ros.sim.effects import REGISTRY

    parts = [
        "# Plant effects\n\n"
        "The physical effects the simulator can add to the fourth-order model and the diagnosis can name "
        "(`phid_ros/sim/effects/`, one module each, registered by name). `phid simulate --effect "
        "NAME:key=value,...` adds one; the ranges are the realistic ones a value is checked against.\n"
    ]
    for name, cls in sorted(REGISTRY.items()):
        parts.append(f"\n## `{name}`\n\n{_summary(cls)}\n")
        if cls.state_names:
            parts.append(f"\nStates it adds after the base four: {', '.join(f'`{s}`' for s in cls.state_names)}.\n")
        rows = [
            (
                f"`{p.name}`",
                p.unit,
                p.default,
                " / ".join(p.choices) if p.choices else _range(p.low, p.high),
                "" if p.absent is None else p.absent,
                p.description,
            )
            for p in cls.parameters
        ]
        if rows:
            parts.append(
                "\n" + _table(("parameter", "unit", "default", "range or choices", "absent at", "meaning"), rows)
            )
    return "".join(parts)


def controls_page() -> str:
    from phid_ros.controls.models import KINDS_IN_ORDER, MODELS

    parts = [
        "# Control models\n\n"
        "The exciter, turbine-governor and stabiliser models `phid identify --exciter/--governor/--stabiliser` "
        "fits and `phid export` writes (`phid_ros/controls/models.py`, registered by name), with PSS/E's names "
        "for their constants. A limit is determined only where the data reached it.\n"
    ]
    for kind in KINDS_IN_ORDER:
        for name, cls in sorted((n, c) for n, c in MODELS.items() if c.kind == kind):
            parts.append(f"\n## `{name}`: {cls.description}\n\n{_summary(cls)}\n")
            rows = [
                (
                    f"`{p.name}`",
                    p.unit,
                    p.default,
                    _range(p.low, p.high),
                    ", ".join(
                        w for w, on in (("limit", p.limit), ("held", p.held), (f"within {p.within}", p.within)) if on
                    ),
                    p.meaning,
                )
                for p in cls.parameters
            ]
            parts.append("\n" + _table(("constant", "unit", "default", "range", "kind", "meaning"), rows))
    return "".join(parts)


def node_parameters_page() -> str:
    from phid_ros.stream.params import INGEST, RECALIBRATION

    parts = [
        "# Node parameters\n\n"
        "The ROS parameters of the two nodes (`phid_ros/stream/params.py`; `config/phid.yaml` carries the same "
        "defaults). A value outside its range is refused by `ros2 param set` with the reason, and the old value "
        'kept. "while unconfigured" parameters are read on configure: set them while the (lifecycle) node is '
        "unconfigured; the others change while it runs.\n"
    ]
    for node, table in (("ingest_node", INGEST), ("recalibration_node", RECALIBRATION)):
        rows = [
            (
                f"`{t.name}`",
                t.type.__name__,
                repr(t.default) if isinstance(t.default, str) else t.default,
                _range(t.low, t.high),
                "while running" if t.runtime else "while unconfigured",
                t.description,
            )
            for t in table
        ]
        parts.append(f"\n## `{node}`\n\n" + _table(("parameter", "type", "default", "range", "set", "meaning"), rows))
    return "".join(parts)


PAGES = {
    "parameters": parameters_page,
    "effects": effects_page,
    "controls": controls_page,
    "node-parameters": node_parameters_page,
}

INDEX = """# Declarations

Written from the code's own tables at every build of this site.

```{toctree}
:maxdepth: 1

parameters
effects
controls
node-parameters
```
"""


def write_pages(folder: Path) -> list[Path]:
    """Every page into ``folder``; a file is rewritten only when its text changed (Sphinx then
    rereads only what changed)."""
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, text in {"index": INDEX, **{n: f() for n, f in PAGES.items()}}.items():
        path = folder / f"{name}.md"
        body = text if name == "index" else HEADER + text
        if not path.exists() or path.read_text(encoding="utf-8") != body:
            path.write_text(body, encoding="utf-8")
        written.append(path)
    return written
