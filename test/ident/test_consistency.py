"""The mistakes a plant engineer makes with units and conventions are named, never identified."""

import json
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from phid_ros.ident import consistency
from phid_ros.ident.consistency import ConsistencyError
from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions, _physical_ranges, identify
from phid_ros.ident.results import Estimate
from phid_ros.model.channels import CHANNEL_INDEX, Frame


def _variant(scenarios, fn, period_factor: int = 1):
    """Each scenario with its channels changed by ``fn(columns)`` (in place on a copy)."""
    out = []
    for s in scenarios:
        values = np.array(s.frame.values, order="F")
        cols = {c: values[:, i] for c, i in CHANNEL_INDEX.items()}
        fn(cols)
        frame = Frame(s.frame.t_ns.copy(), values, s.frame.period_ns * period_factor)
        out.append(replace(s, frame=frame, notes=[]))
    return out


def _flip(*names):
    def fn(c):
        for n in names:
            c[n] *= -1.0

    return fn


def _swap(c):
    c["i_d"][:], c["i_q"][:] = c["i_q"].copy(), c["i_d"].copy()


def _degrees(c):
    for n in ("delta", "theta_t"):
        c[n] *= 180.0 / math.pi


def _scale(name, k):
    def fn(c):
        c[name] *= k

    return fn


def test_a_consistent_recording_passes_every_check(noisy_scenarios):
    f = consistency.check(noisy_scenarios, 50.0)
    assert f.errors == [] and f.suspicions == []
    assert len(f.checked) == 5  # every check had its channels and enough signal


@pytest.mark.parametrize(
    "fn, period_factor, f_hz, words",
    [
        (
            _flip("i_d", "i_q", "p_e", "q_e"),
            1,
            50.0,
            "opposite signs, so one of them is in the motor (load) convention",
        ),
        (_flip("i_d", "i_q", "p_e", "q_e", "p_m"), 1, 50.0, "the speed falls while P_m exceeds P_e"),
        (_flip("i_d", "i_q"), 1, 50.0, "if the currents' signs are flipped"),
        (_swap, 1, 50.0, "are i_d and i_q swapped?"),
        (_degrees, 1, 50.0, "angles in degrees?"),
        (lambda c: None, 1000, 50.0, "time in milliseconds?"),
        (lambda c: None, 1, 60.0, "moves as a 50 Hz machine, its nominal frequency is declared 60 Hz"),
        (_scale("p_m", 1e-3), 1, 50.0, "kW against MW?"),
    ],
    ids=["motor", "motor-all", "currents-flipped", "swapped", "degrees", "milliseconds", "60-vs-50-Hz", "kW-MW"],
)
def test_each_mistake_is_named_and_nothing_is_identified(noisy_scenarios, fn, period_factor, f_hz, words):
    scs = _variant(noisy_scenarios, fn, period_factor)
    f = consistency.check(scs, f_hz)
    assert f.errors and words in f.errors[0], f.errors
    with pytest.raises(ConsistencyError, match="\\?|convention|declared"):
        identify(scs, IdentifyOptions(f_nominal_hz=f_hz, baseline=False, validate=False))


def test_a_suspected_mistake_withholds_what_it_touches(noisy_scenarios):
    """P_m 1.6 times P_e: losses cannot explain it, no unit mistake does either: H and D withheld."""
    scs = _variant(noisy_scenarios, _scale("p_m", 1.6))
    f = consistency.check(scs, 50.0)
    assert f.errors == [] and [s.parameters for s in f.suspicions] == [("H", "D")]
    res = identify(scs, IdentifyOptions(baseline=False, validate=False))
    assert not res.estimates["H"].identifiable and "withheld: " in res.estimates["H"].note
    assert not res.estimates["D"].identifiable
    assert res.estimates["X_d"].identifiable  # stage 2 does not read P_m
    assert any(p.startswith("channels: in steady state P_m") for p in res.problems)


def test_checks_without_their_channels_do_not_run(noisy_scenarios):
    """A field recording without rotor angle or speed is judged on what it has, not refused."""

    def no_rotor(c):
        for n in ("delta", "omega", "p_m"):
            c[n][:] = np.nan

    f = consistency.check(_variant(noisy_scenarios, no_rotor), 50.0)
    assert f.errors == [] and f.suspicions == [] and f.checked == []


def test_a_value_outside_its_physical_range_is_never_identified():
    res = IdentificationResult({}, "fast", [])
    res.estimates = {
        "H": Estimate(-3.48, 0.01),
        "X_d": Estimate(2.54, 0.01),
        "X_d_prime": Estimate(2.6, 0.01),
        "X_q": Estimate(2.41, 0.01),
    }
    _physical_ranges(res)
    assert not res.estimates["H"].identifiable and "outside" in res.estimates["H"].note
    assert not res.estimates["X_d_prime"].identifiable and not res.estimates["X_d"].identifiable
    assert res.estimates["X_q"].identifiable


def test_phid_identify_names_the_file_and_the_mistake(tmp_path):
    """Through the command line: one line, the file, the likely mistake, exit 2, no result file."""
    run = [sys.executable, "-m", "phid_ros.cli.main"]
    subprocess.run(
        [*run, "simulate", "--scenario", "S04", "--duration", "8", "--out", str(tmp_path / "set" / "manifest.json")],
        check=True,
        capture_output=True,
    )
    for csv in (tmp_path / "set").glob("*.csv"):
        lines = csv.read_text().splitlines()
        head = lines[0].split(",")
        data = np.array([[float(x) for x in line.split(",")] for line in lines[1:]])
        for name in ("theta_t", "delta"):
            data[:, head.index(name)] = np.degrees(data[:, head.index(name)])
        csv.write_text("\n".join([lines[0], *(",".join(f"{v:.9g}" for v in row) for row in data)]) + "\n")
    manifest = tmp_path / "set" / "manifest.json"
    assert json.loads(manifest.read_text())["scenarios"]
    out = subprocess.run(
        [*run, "identify", str(manifest), "--json", str(tmp_path / "r.json")], capture_output=True, text=True
    )
    assert out.returncode == 2
    last = out.stderr.strip().splitlines()[-1]
    assert last.startswith(f"phid: error: {manifest}: ") and "angles in degrees?" in last
    assert not Path(tmp_path / "r.json").exists()
