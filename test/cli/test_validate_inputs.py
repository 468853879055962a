"""``phid validate`` reads what ``phid identify`` reads: several recordings of one unit."""

from __future__ import annotations

import json

from phid_ros.cli.main import main
from phid_ros.model.parameters import TABLE1
from test.stream.test_record_check import CATALOGUE, record_of

VALIDATION = CATALOGUE.parent / "validation.mcap"


def test_validate_reads_several_recordings_as_identify_does(tmp_path, capsys) -> None:
    """``phid validate unit.dyr nl.mcap ol.mcap`` was refused (unrecognized arguments); a user who
    identified two recordings had to import them again as one file to validate."""
    dyr = record_of(tmp_path, "own", TABLE1)
    out = tmp_path / "v.json"
    assert main(["validate", str(dyr), str(VALIDATION), "--json", str(out)]) in (0, 1)
    alone = json.loads(out.read_text())["validation"]["scenarios"]
    assert main(["validate", str(dyr), str(CATALOGUE), str(VALIDATION), str(VALIDATION), "--json", str(out)]) in (0, 1)
    doc = json.loads(out.read_text())
    names = [s["scenario"] for s in doc["validation"]["scenarios"]]
    assert sum(n.startswith("catalogue/") for n in names) == 18
    both = [s for s in doc["validation"]["scenarios"] if s["scenario"].startswith("validation/")]
    assert len(both) == len(alone)  # given twice, counted once (said in the notes)
    for a, b in zip(alone, both, strict=True):  # each event played alone: the same checks beside others
        assert b["scenario"] == f"validation/{a['scenario']}" and b["checks"] == a["checks"]
    assert any("validation.mcap" in n and "once" in n for n in doc["validation"]["notes"]), doc["validation"]["notes"]
    assert doc["input"] == f"{CATALOGUE} + {VALIDATION}"


def test_a_verdict_says_how_many_checks_failed_and_a_standard_never_played_is_not_tested() -> None:
    import numpy as np

    from phid_ros.cli.validate import verdict_text
    from phid_ros.controls.unit_validation import ChannelCheck, ScenarioCheck, UnitValidation

    def check(channel: str, standard: str, passed: bool) -> ChannelCheck:
        return ChannelCheck(channel, standard, 0.02 if passed else 0.09, 0.05, passed, "SEXS")

    t = np.zeros(1)
    events = [
        ScenarioCheck(
            f"S{i}",
            "voltage_step",
            t,
            {},
            {},
            [check("q_e", "MOD-026", ok), check("p_e", "MOD-027", True)],
            made_by={"v_f": "SEXS", "p_m": "recorded"},
        )
        for i, ok in enumerate([True, False, False])
    ]
    unit = UnitValidation("GENSAL + SEXS", events, [])
    assert verdict_text(unit, "MOD-026") == "FAIL (2 of 3 checks failed)"
    assert verdict_text(unit, "MOD-027").startswith("not tested (no governor played")
