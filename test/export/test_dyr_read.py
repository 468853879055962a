"""A .dyr read back: what phid export writes comes back as the same unit (machine, exciter,
governor), a salient pole's q axis by its damper, and a malformed file is a one-line error."""

from __future__ import annotations

from pathlib import Path

import pytest

from phid_ros.export.dyr_read import DyrError, read_records, read_unit
from phid_ros.export.formats import psse_dyr
from phid_ros.export.record import DEFAULT_TQ20_S, build_record
from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1
from test.export.test_andes_roundtrip import CONTROLS

P_M0 = 0.8


def result(controls: dict | None = None) -> dict:
    doc = {
        "parameters": TABLE1.as_dict(),
        "identifiable": {n: True for n in PARAMETER_NAMES},
        "operating_point": {"p_m_pu": P_M0},
    }
    if controls:
        doc["controls"] = controls
    return doc


def test_an_exported_unit_reads_back_as_the_same_machine_exciter_and_governor(tmp_path: Path) -> None:
    rec = build_record(result(CONTROLS), source="r.json", mva=1000.0, bus=7, machine_id="G1")
    path = tmp_path / "unit.dyr"
    path.write_text(psse_dyr(rec))
    unit = read_unit(path)
    assert (unit.bus, unit.machine_id, unit.machine) == (7, "G1", "GENROU")
    assert unit.constants["D"] == pytest.approx(0.4 - P_M0 if 0.4 > P_M0 else 0.0)
    # the record's machine seen as fourth order is the identified one (the .dyr's six digits)
    params = unit.fourth_order(p_m0=P_M0)
    for name in PARAMETER_NAMES:
        if name != "D":
            assert getattr(params, name) == pytest.approx(getattr(TABLE1, name), rel=5e-6), name
    # as written, its q axis carries GENROU's classical constants, which its damper loads
    written = unit.parameters(p_m0=P_M0)
    assert written.X_q_prime == pytest.approx(1.0747, abs=1e-4)
    assert written.T_q0_prime == pytest.approx(0.1140, abs=1e-4)
    assert (written.X_d_prime, written.T_d0_prime) == (TABLE1.X_d_prime, TABLE1.T_d0_prime)  # the d damper is inert
    assert {k: c.model for k, c in unit.controls.items()} == {"exciter": "SEXS", "governor": "TGOV1"}
    assert unit.controls["exciter"].values["K"] == 100.0 and unit.controls["governor"].values["T3"] == 6.0
    # the q-axis damper (X'' = X'_d < X'_q) is played as written, by the simulator's own effect
    [(damper, values)] = unit.effects()
    assert damper.name == "subtransient_dynamics" and values["x_qpp"] == 0.5 and values["t_q0pp"] == DEFAULT_TQ20_S
    said = unit.not_simulated()
    # every record constant the small-signal play-in leaves out is said, with its value
    # (SEXS's E_MIN, E_MAX are played, as PSS/E's SEXS limits E_fd: said as how, not left out)
    assert said[0] == "SEXS: E_fd within EMIN..EMAX on a non-windup T_E lag (PSS/E SEXS)"
    assert said[1].startswith("TGOV1 VMAX = ") and len(said) == 2


def test_the_damping_comes_back_in_phid_s_form(tmp_path: Path) -> None:
    """phid's D 1.2 at P_m0 0.8 is PSS/E's 0.4; read at the same operating point it is 1.2 again."""
    doc = result()
    doc["parameters"]["D"] = 1.2
    path = tmp_path / "unit.dyr"
    path.write_text(psse_dyr(build_record(doc, source="r.json", mva=1000.0)))
    unit = read_unit(path)
    assert unit.constants["D"] == pytest.approx(0.4)
    assert unit.parameters(p_m0=P_M0).D == pytest.approx(1.2)


def test_a_salient_pole_s_q_axis_is_its_damper(tmp_path: Path) -> None:
    path = tmp_path / "unit.dyr"
    path.write_text(psse_dyr(build_record(result(), source="r.json", mva=1000.0, model="GENSAL")))
    unit = read_unit(path)
    params = unit.parameters(p_m0=P_M0)
    assert unit.machine == "GENSAL"
    assert params.T_q0_prime == pytest.approx(TABLE1.T_q0_prime)  # exported as T''_q0, read back as the q axis
    assert params.X_q_prime == pytest.approx(unit.constants["Xd2"])


def test_comments_continuations_and_several_units(tmp_path: Path) -> None:
    path = tmp_path / "two.dyr"
    path.write_text(
        "@! two units, a record over three lines\n"
        "1 'GENROU' 1 1.437 0.03 0.1351 0.03\n"
        "  3.48 0.0 2.54 2.41 0.5 0.5\n"
        "  0.5 0.15 0.0 0.0 / machine one\n"
        "2 'GENROU' '2' 5.0 0.05 0.6 0.05 4.0 0.0 1.8 1.7 0.3 0.55 0.25 0.15 0.1 0.4 /\n"
        "2 'STAB1' '2' 1 2 3 / a stabiliser phid does not model\n"
        "2 'TGOV1' '2' 0.05 0.5 1.0 0.0 2.0 6.0 0.0 /\n"
    )
    assert [r.model for r in read_records(path)] == ["GENROU", "GENROU", "STAB1", "TGOV1"]
    with pytest.raises(DyrError, match=r"two\.dyr: 2 machines \(bus 1 id '1', bus 2 id '2'\): name one with --bus"):
        read_unit(path)
    one = read_unit(path, bus=1)
    assert one.constants["H"] == 3.48 and one.controls == {}
    two = read_unit(path, bus=2, machine_id="2")
    assert list(two.controls) == ["governor"] and two.ignored == ["STAB1 (line 6)"]
    assert ("magnetic_saturation", 0.1, 0.4, "genrou") in [
        (cls.name, v["s10"], v["s12"], v["form"]) for cls, v in two.effects() if "s10" in v
    ]
    assert not any("saturation" in n for n in two.not_simulated())
    # the governor's limits are in the record and not in the small-signal play-in: said, with values
    assert any(n.startswith(f"{two.controls['governor'].model} ") and "small-signal" in n for n in two.not_simulated())
    with pytest.raises(DyrError, match=r"no GENROU or GENSAL record at the unit asked; the file has bus 1"):
        read_unit(path, bus=3)


def test_a_dual_input_stabiliser_reads_back_as_written(tmp_path: Path) -> None:
    """A PSS2A record (its ICONs: speed, power, M = 5, N = 1, then the constants in PSS/E's
    order) reads back constant for constant, a record's washouts not forced equal as a fit's are."""
    path = tmp_path / "pss2a.dyr"
    path.write_text(
        "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
        "1 'SEXS' 1 0.2 5.0 500.0 0.05 -5 5 /\n"
        "1 'PSS2A' 1 1 0 3 0 5 1 10 10 0 10 0 10 0.29 1 0.5 0.1 10 0.2 0.04 0.1 0.02 0.1 -0.1 /\n"
    )
    pss = read_unit(path).controls["stabiliser"]
    assert pss.model == "PSS2A"
    assert list(pss.values.values()) == [10, 10, 0, 10, 0, 10, 0.29, 1, 0.5, 0.1, 10, 0.2, 0.04, 0.1, 0.02, 0.1, -0.1]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("1 'GENROU' 1 1.437 0.03\n", r"bad\.dyr:1: record '1 GENROU 1 \.\.\.' does not end with '/'"),
        ("1 'GENROU' 1 1.437 x 0.1 /\n", r"bad\.dyr:1: GENROU constant 'x' is not a number"),
        ("'GENROU' 1 1.0 /\n", r"bad\.dyr:1: a record begins BUS 'MODEL' ID"),
        ("1 'GENROU' 1 1.0 2.0 /\n", r"bad\.dyr:1: GENROU has 2 constants; PSS/E's has 14"),
        (
            "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
            "1 'SEXS' 1 0.2 5.0 500.0 -0.05 -5 5 /\n",
            r"bad\.dyr:2: SEXS TE = -0\.05 is a negative time constant",
        ),
        (
            "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
            "1 'IEEET1' 1 0.02 50 0.05 5 -5 0.0 0.5 0.05 1.0 0 0 0 0 0 /\n",
            r"bad\.dyr:2: IEEET1 KE = 0 \(PSS/E computes it at initialisation",
        ),
        (
            # an IEEEST on the rotor speed (MODE 1) is not the one phid plays on P_e (MODE 3)
            "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
            "1 'IEEEST' 1 1 0 0 0 0 0 0 0 0 0.02 0.2 0.04 2 2 -0.2 0.1 -0.1 0 0 /\n",
            r"bad\.dyr:2: IEEEST MODE = 1: phid simulates IEEEST with MODE = 3 only",
        ),
        (
            "1 'GENSAL' 1 5.0 0.05 0.05 3.0 0.0 1.1 0.7 0.3 0.22 0.15 0.0 0.0 /\n"
            "1 'PSS2A' 1 1 0 3 0 4 1 10 10 0 10 0 10 0.29 1 0.5 0.1 10 0.2 0.04 0.1 0.02 0.1 -0.1 /\n",
            r"bad\.dyr:2: PSS2A M = 4: phid simulates PSS2A with M = 5 only",
        ),
    ],
)
def test_a_malformed_file_is_a_one_line_error_naming_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "bad.dyr"
    path.write_text(text)
    with pytest.raises(DyrError, match=message):
        read_unit(path)


def test_a_start_from_record_outside_the_physical_range_names_the_dyr(tmp_path: Path, capsys) -> None:
    """``phid identify --start-from UNIT.dyr`` with an inertia of 348 s (a misplaced decimal):
    refused before anything is read, one line naming the .dyr and its record."""
    from phid_ros.cli.main import main

    path = tmp_path / "unit.dyr"
    path.write_text("1 'GENROU' 1 1.437 0.03 0.1351 0.03 348.0 0.0 2.54 2.41 0.5 0.5 0.5 0.15 0.0 0.0 /\n")
    bags = Path(__file__).resolve().parents[2] / "bags" / "catalogue"
    assert main(["identify", str(bags), "--start-from", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"phid: error: {path}: GENROU at bus 1 id '1': invalid generator parameters: H=348 s"), err
    assert "\n" not in err


def test_a_published_record_is_read_as_published(tmp_path: Path) -> None:
    """The Mostar unit's published ST5B fit (ALSETLab, RaPId) carries T_B2 = 5.11 ms, T_1 = 5.18 ms
    and K_R = 505: outside the fit's search ranges, inside what the play-in integrates exactly."""
    path = tmp_path / "pub.dyr"
    path.write_text(
        "1 'GENSAL' 1 3.77 0.0552 0.0823 2.3362 0.0 1.12 0.642 0.354 0.24 0.1 0.1 0.4 /\n"
        "1 'ESST5B' 1 0.0127 505.3 0.00518 0.982 2.237 -8.384 1.701 21.98 0.0263 0.00511 "
        "1 1 1 1 1 1 1 1 /\n"
    )
    unit = read_unit(path)
    exciter = unit.controls["exciter"]
    assert exciter.model == "ESST5B"
    assert exciter.values["TB2"] == 0.00511 and exciter.values["KR"] == 505.3
