"""The reference pages (docs/reference_pages.py) are written from the declarations: every declared
name is on its page with its unit, default and range, and a new declaration needs no edit there."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

from phid_ros.controls.models import MODELS
from phid_ros.model.parameters import PARAMETER_SPECS
from phid_ros.sim import effects
from phid_ros.stream.params import INGEST, RECALIBRATION

DOCS = Path(__file__).resolve().parents[1] / "docs"


@pytest.fixture(scope="module")
def pages():
    spec = importlib.util.spec_from_file_location("reference_pages", DOCS / "reference_pages.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _row(page: str, name: str) -> list[str]:
    line = next(x for x in page.splitlines() if x.startswith(f"| `{name}` |"))
    return [c.strip() for c in line.strip("|").split("|")]


def test_every_declaration_is_on_its_page(pages) -> None:
    text = pages.parameters_page()
    for s in PARAMETER_SPECS:
        assert _row(text, s.name)[2:5] == [s.unit, f"{s.default:g}", f"[{s.low:g}, {s.high:g}]"]
    text = pages.effects_page()
    for name, cls in effects.REGISTRY.items():
        section = text.split(f"## `{name}`")[1].split("\n## ")[0]
        for p in cls.parameters:
            assert _row(section, p.name)[1] == p.unit
    text = pages.controls_page()
    for name, cls in MODELS.items():
        assert f"## `{name}`: {cls.description}" in text
    assert _row(text.split("## `ESST5B`")[1], "TB2")[1:4] == ["s", "0.1", "[0.01, 30]"]
    # a default the effect derives from the machine (NaN in the table) is said as such
    assert _row(effects_text := pages.effects_page(), "x_l")[2] == "derived"
    assert "nan" not in effects_text
    text = pages.node_parameters_page()
    ingest, recal = text.split("## `recalibration_node`")
    assert all(f"| `{t.name}` |" in ingest for t in INGEST)
    assert all(f"| `{t.name}` |" in recal for t in RECALIBRATION)
    assert _row(recal, "store_path")[2] == "'phid_events.sqlite'"


def test_a_new_effect_is_in_the_reference_without_an_edit_there(pages, tmp_path) -> None:
    @effects.register
    class BrushDrop(effects.PlantEffect):
        """A constant voltage drop across the field brushes."""

        name = "brush_drop_for_test"
        parameters = (effects.EffectParameter("v_drop", 0.002, "pu", "drop across the brushes", 0.0, 0.01),)

    try:
        written = pages.write_pages(tmp_path)
        text = (tmp_path / "effects.md").read_text()
        assert "## `brush_drop_for_test`\n\nA constant voltage drop across the field brushes." in text
        assert _row(text, "v_drop")[1:4] == ["pu", "0.002", "[0, 0.01]"]
        assert sorted(p.name for p in written) == sorted(
            ["index.md", "parameters.md", "effects.md", "controls.md", "node-parameters.md"]
        )
        stamp = (tmp_path / "effects.md").stat().st_mtime_ns
        pages.write_pages(tmp_path)  # unchanged text: the file is left as it was
        assert (tmp_path / "effects.md").stat().st_mtime_ns == stamp
    finally:
        del effects.REGISTRY["brush_drop_for_test"]
