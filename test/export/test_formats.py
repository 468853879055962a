"""Each writer's output read back by its format's rules (module docstring of phid_ros.export.formats)."""

from __future__ import annotations

import json
import re

import pytest

from phid_ros.export.formats import PSLF_NAMES, andes_json, pslf_dyd, psse_dyr
from phid_ros.export.psse import PSSE_ORDER
from phid_ros.export.record import build_record
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

RESULT = {
    "parameters": TABLE1.as_dict(),
    "identifiable": {n: n != "D" for n in PARAMETER_NAMES},
    "f_nominal_hz": 60.0,
}


def record(model: str = "GENROU"):
    return build_record(RESULT, source="r.json", model=model, mva=247.5, bus=1001, machine_id="G2", allow_flagged=True)


def read_dyr(text: str) -> list[tuple[int, str, str, list[float], str]]:
    """PSS/E .dyr: free-format records ended by '/', text after the '/' ignored (a comment)."""
    records, pending = [], ""
    for line in text.splitlines():
        data, slash, comment = line.partition("/")
        pending += " " + data
        if slash:
            m = re.fullmatch(r"\s*(\d+)\s+'([A-Z0-9]+)'\s+'([^']{1,2})'\s+(.*)", pending)
            assert m, f"not a .dyr record: {pending!r}"
            records.append((int(m[1]), m[2], m[3], [float(x) for x in m[4].split()], comment.strip()))
            pending = ""
    assert not pending.strip(), "a record without its closing '/'"
    return records


def read_dyd(text: str) -> list[tuple[str, int, str, float, str, float, dict[str, float]]]:
    """PSLF .dyd: '#' comment lines; a line ending in '/' continues; model bus "name" kV "id" : #9 mva=...
    then "name" value pairs (a machine), or : #9 mwcap=... then values by position (a governor, keyed
    "1", "2", ... here)."""
    records, pending = [], ""
    for line in text.splitlines():
        if line.startswith("#") or not line.strip():
            continue
        if line.rstrip().endswith("/"):
            pending += line.rstrip()[:-1] + " "
            continue
        full = pending + line
        pending = ""
        head = r'\s*([a-z0-9]+)\s+(\d+)\s+"([^"]*)"\s+([\d.]+)\s+"([^"]*)"\s*:\s*#9\s+(mva|mwcap)=([\d.eE+-]+)'
        m = re.fullmatch(head + r"\s+(.*)", full)
        assert m, f"not a .dyd record: {full!r}"
        if m[6] == "mwcap":
            params = {str(i): float(v) for i, v in enumerate(m[8].split(), start=1)}
        else:
            pairs = re.findall(r'"([a-z0-9]+)"\s+([-\d.eE+]+)', m[8])
            assert len(pairs) * 2 == len(m[8].split()), 'parameters are not all "name" value pairs'
            params = {k: float(v) for k, v in pairs}
        records.append((m[1], int(m[2]), m[3], float(m[4]), m[5], float(m[7]), params))
    assert not pending, "the last line continues with '/'"
    return records


@pytest.mark.parametrize("model", ["GENROU", "GENSAL"])
def test_psse_dyr_parses_by_its_rules(model: str) -> None:
    rec = record(model)
    [(bus, name, ident, values, comment)] = read_dyr(psse_dyr(rec))
    assert (bus, name, ident) == (1001, model, "G2")
    # six significant digits: the record's classical X'_q (1.0747322...) is written 1.07473
    assert values == pytest.approx([rec.values[f] for f in PSSE_ORDER[model]], rel=5e-6)
    assert len(values) == (14 if model == "GENROU" else 12)
    assert values[: 4 if model == "GENROU" else 3][0] == pytest.approx(1.437)  # T'do first
    assert "NOT IDENTIFIED: D" in comment and "247.5 MVA base" in comment


@pytest.mark.parametrize("model", ["GENROU", "GENSAL"])
def test_pslf_dyd_parses_by_its_rules(model: str) -> None:
    rec = record(model)
    text = pslf_dyd(rec)
    assert text.splitlines()[0].startswith("# ") and "NOT IDENTIFIED: D" in text.splitlines()[0]
    [(name, bus, _, kv, ident, mva, params)] = read_dyd(text)
    assert (name, bus, kv, ident, mva) == (model.lower(), 1001, 20.0, "G2", 247.5)
    for f in rec.fields:
        assert params[PSLF_NAMES[f]] == pytest.approx(rec.values[f], rel=5e-6)
    assert ("lpq" in params) == (model == "GENROU") and params["accel"] == 0.0


def test_andes_json_carries_andes_names_and_machine_base() -> None:
    rec = record()
    [row] = json.loads(andes_json(rec))["GENROU"]
    assert row["M"] == pytest.approx(2 * 3.48) and row["Sn"] == 247.5 and row["fn"] == 60.0
    v = rec.values  # the q axis as GENROU's classical constants (test_record), as the .dyr has it
    assert (row["xd1"], row["xq1"], row["xd2"], row["xq2"], row["Tq10"]) == pytest.approx(
        (0.5, v["Xq1"], 0.5, 0.5, v["Tq10"]), rel=5e-6
    )
    assert row["name"].endswith("NOT IDENTIFIED: D")


def test_psse_dyr_is_read_by_andes(tmp_path) -> None:
    """ANDES's own .dyr reader (not ours) takes the record onto the generator it names."""
    andes = pytest.importorskip("andes")
    from andes.io.psse import _read_dyr_dict

    path = tmp_path / "unit.dyr"
    rec = record()
    path.write_text(psse_dyr(rec))
    frame = _read_dyr_dict(str(path))["GENROU"]
    assert frame.shape == (1, 16) and andes is not None
    assert list(frame.iloc[0, 2:]) == pytest.approx([rec.values[f] for f in PSSE_ORDER["GENROU"]], rel=5e-6)


def test_pss_e_gets_damping_in_its_torque_form_andes_and_pslf_as_identified():
    """PSS/E's swing equation is (P_m - D dw)/(1 + dw) - T_e (STEPS's GENSAL and GENROU, which
    follow PSS/E's block diagrams, compute it so): linearised, P_m0 more damping than phid's (5).
    On STEPS's GENSAL with D = 0.4 at P_m = 0.8 phid identified D = 1.22; the .dyr carries D - P_m0."""
    doc = {**RESULT, "operating_point": {"p_m_pu": 0.8, "p_e_pu": 0.8, "q_e_pu": 0.4, "v_t_pu": 1.0}}
    doc["parameters"] = {**TABLE1.as_dict(), "D": 1.22}
    rec = build_record(doc, source="r.json", mva=1000.0, allow_flagged=True)
    assert rec.p_m0 == 0.8 and rec.values["D"] == 1.22
    [(_, _, _, values, _)] = read_dyr(psse_dyr(rec))
    assert values[PSSE_ORDER["GENROU"].index("D")] == pytest.approx(0.42)
    assert json.loads(andes_json(rec))["GENROU"][0]["D"] == 1.22  # ANDES's swing equation is phid's
    # a result without its operating point (written before phid 0.3) goes out as identified
    assert build_record(RESULT, source="r.json", mva=1000.0, allow_flagged=True).torque_form_damping() == TABLE1.D
    # a machine whose damping is below what PSS/E's form adds on its own: D = 0, not negative
    doc["parameters"]["D"] = 0.5
    low = build_record(doc, source="r.json", mva=1000.0, allow_flagged=True)
    assert low.torque_form_damping() == 0.0
    assert any("D = 0.5 is below P_m0 = 0.8" in w and "damps 0.3 pu more" in w for w in low.warnings)
