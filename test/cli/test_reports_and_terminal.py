"""What an engineer reads: the HTML reports (rendered in headless Chromium) and the terminal at 80 columns."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from phid_ros.cli.main import main
from phid_ros.io.bags.recordings import topic_table
from phid_ros.stream.levels import Level
from test.browser import assert_readable, chromium, screenshot

BAGS = Path(__file__).resolve().parents[2] / "bags"
NUMBER_CUT = re.compile(r"[0-9.]…|…[0-9]")


def _run(capsys, *args: str) -> str:
    capsys.readouterr()
    assert main(list(args)) == 0
    return capsys.readouterr().out


@pytest.fixture(scope="module")
def outputs(tmp_path_factory):
    """identify, replay (twice) and track runs with their reports; their terminal text as captured (80 columns)."""
    tmp = tmp_path_factory.mktemp("reports")
    import contextlib
    import io

    text: dict[str, str] = {}

    def run(name: str, *args: str) -> None:
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            assert main(list(args)) == 0
        text[name] = buf.getvalue()

    run(
        "identify",
        "identify",
        str(BAGS / "catalogue"),
        "--truth",
        str(BAGS / "catalogue.truth.json"),
        "--report",
        str(tmp / "identify.html"),
    )
    run("replay", "replay", str(BAGS / "catalogue"), "--out", str(tmp / "a.mcap"), "--report", str(tmp / "replay.html"))
    run("replay2", "replay", str(BAGS / "catalogue"), "--out", str(tmp / "b.mcap"))
    bag = tmp / "drift.mcap"
    run("simulate", "simulate", "--ambient", "420", "--drift", "T_d0_prime=0.15@60-400", "--out", str(bag))
    run("track", "track", str(bag), "--window", "240", "--hop", "60", "--report", str(tmp / "track.html"))
    return tmp, text


REPORTS = {"identify": 4, "replay": 3, "track": 3}  # figures each report must show


@pytest.mark.parametrize("name", sorted(REPORTS))
def test_report_has_its_figures_and_every_table_its_headers(outputs, name):
    tmp, _ = outputs
    page = (tmp / f"{name}.html").read_text()
    assert page.count('src="data:image/png;base64,') == REPORTS[name]
    for head in re.findall(r"<tr>((?:<th>.*?</th>)+)</tr>", page):
        assert all(h.strip() for h in re.findall(r"<th>(.*?)</th>", head)), head
    assert "<th></th>" not in page and "X_d_prime" not in page  # the paper's symbols, as in the terminal


@pytest.mark.skipif(chromium() is None, reason="no Chromium here (Debian package 'chromium'): reports not rendered")
@pytest.mark.parametrize("name", sorted(REPORTS))
def test_report_renders_in_chromium(outputs, name):
    tmp, _ = outputs
    assert_readable(tmp / f"{name}.html", REPORTS[name])
    png = screenshot(tmp / f"{name}.html", tmp / f"{name}.png")
    assert png.stat().st_size > 50_000


def _table_lines(text: str) -> list[str]:
    return [line for line in text.splitlines() if line.startswith(" ") or set(line) <= {"─", " "}]


@pytest.mark.parametrize("name", ["identify", "replay", "track"])
def test_terminal_output_fits_80_columns_with_every_number_whole(outputs, name):
    _, text = outputs
    out = text[name]
    assert not NUMBER_CUT.search(out), NUMBER_CUT.search(out)
    lines = _table_lines(out)
    assert lines and max(len(line) for line in lines) <= 80


def test_identify_terminal_says_what_it_left_out_and_wide_shows_it(outputs, capsys):
    _, text = outputs
    out = text["identify"]
    assert "X'_d" in out and "+20.00%" in out and "0.49979" in out  # IEEE 115 err, proposed value
    assert "not shown at 80 columns:" in out and "(--wide shows them)" in out
    assert "identified from 18 scenarios in" in out
    wide = _run(capsys, "identify", str(BAGS / "catalogue"), "--truth", str(BAGS / "catalogue.truth.json"), "--wide")
    assert "not shown" not in wide and "RMSE" in wide and "MAE" in wide and "STD" in wide


def test_replay_prints_units_and_std_and_is_the_same_twice(outputs):
    tmp, text = outputs
    a, b = text["replay"].splitlines(), text["replay2"].splitlines()
    # only the measured timing line differs (and the report line the first run wrote)
    assert [x for x in a if "replay.html" not in x][:-1] == b[:-1]
    assert a[-1].startswith("wrote ") and "timing:" in a[-1]
    ha = dict((t, n) for t, _, n in topic_table(tmp / "a.mcap"))
    hb = dict((t, n) for t, _, n in topic_table(tmp / "b.mcap"))
    assert ha == hb and ha["/phid/hamiltonian"] > 1000
    out = text["replay"]
    assert "T'_d0    s       1.43646(83)" in out or re.search(r"T'_d0\s+s\s+1\.436\d*\(\d+\)", out)
    assert re.search(r"Hamiltonian at the end: [0-9.]+ pu·s", out)
    assert "V_t -82%" in out and "ΔP_m +0.100 pu" in out
    # a grid dip that recovers: settled near 0, its size at 0.2 s beside it
    assert re.search(r"621\.000\s+voltage_step\s+ΔV_t -0\.00\d pu, ΔQ -0\.00\d", out), out
    assert "settled (-0.117 at 0.2 s)" in out


def test_track_prints_each_hop_and_withholds_what_it_cannot_identify(outputs):
    _, text = outputs
    out = text["track"]
    hops = [line for line in out.splitlines() if re.match(r"^\s+\d+ ", line)]
    assert len(hops) == 4  # 420 s, 240 s window, 60 s hop
    assert "±1 ?" not in out and "n.i." in out
    assert re.search(r"\d\.\d+\(\d+\)", hops[0])  # the concise value(std) form


def test_track_without_base_warns_that_table1_is_used(tmp_path):
    r = subprocess.run(
        [sys.executable, "-m", "phid_ros", "track", str(BAGS / "validation.mcap")], capture_output=True, text=True
    )
    assert "no --base: X_d and X_q are the paper's Table 1 values (2.54, 2.41 pu)" in r.stderr


def test_version_flags_and_module_entry_point():
    for flag in ("-V", "--version"):
        r = subprocess.run([sys.executable, "-m", "phid_ros", flag], capture_output=True, text=True)
        assert r.returncode == 0 and r.stdout.startswith("phid_ros ")


def test_help_texts_name_their_arguments_and_the_effects():
    def helptext(*args: str) -> str:
        return subprocess.run(
            [sys.executable, "-m", "phid_ros", *args, "--help"], capture_output=True, text=True
        ).stdout

    from phid_ros.sim.effects import REGISTRY

    sim = " ".join(helptext("simulate").split())
    assert all(name in sim for name in REGISTRY)
    assert "manifest.json" in helptext("import-csv").split("positional arguments:")[1]
    info = " ".join(helptext("info").split("positional arguments:")[1].split())
    assert "rosbag2 folder, .mcap file" in info and "CSV manifest.json" in info


def test_track_health_over_time_marks_the_bin_with_a_gap(short_recording):
    """Stream health from the stamps: the 2 s bin that lost 0.5 s of PMU samples is ERROR, the rest OK."""
    import dataclasses

    import numpy as np

    from phid_ros.cli.track import health_over_time
    from phid_ros.io.recording import Recording
    from phid_ros.model.conventions import NS

    pmu = short_recording.streams["pmu"]
    start = int(pmu.t_ns[0])
    keep = (pmu.t_ns < start + 4 * NS) | (pmu.t_ns >= start + int(4.5 * NS))
    cut = dataclasses.replace(pmu, t_ns=pmu.t_ns[keep], channels={c: v[keep] for c, v in pmu.channels.items()})
    rec = Recording({**short_recording.streams, "pmu": cut}, short_recording.scenarios, short_recording.metadata)
    log = health_over_time(rec, 2.0)
    levels = [row[0] for row in log.streams["pmu"]]
    assert levels[2] == Level.ERROR and levels.count(Level.ERROR) == 1 and set(levels) <= {Level.OK, Level.ERROR}
    missing = np.array([row[1] for row in log.streams["pmu"]])
    assert missing[-1] == 500 and missing[1] == 0  # 0.5 s at 1 kHz, counted from the bin it fell in
    assert [row[2] for row in log.streams["pmu"]][-1] == 1  # one gap
    assert all(row[0] == Level.OK for row in log.streams["pt_ct"])  # the last, shorter bin is not a loss


def test_table_width_without_rich_s_measure_equals_rich_s():
    """print_table fits a table by arithmetic (each column its widest cell, a space either side, one
    separator between): equal to what rich measures for the same table, on 300 random tables."""
    import random

    from rich.console import Console
    from rich.measure import Measurement

    from phid_ros.cli.tables import WIDE_WIDTH, Col, _build, _unwrapped_width

    console = Console(width=80, soft_wrap=True)
    wide = console.options.update_width(WIDE_WIDTH)
    rng = random.Random(3)
    for _ in range(300):
        n = rng.randint(1, 8)
        cols = [
            Col("h" * rng.randint(0, 9) + rng.choice(["", "Δ", "σ [%]"]), justify=rng.choice(["right", "left"]))
            for _ in range(n)
        ]
        rows = [
            [f"{rng.uniform(-1e4, 1e4):.{rng.randint(0, 5)}f}" + rng.choice(["", "×", " s"]) for _ in range(n)]
            for _ in range(rng.randint(0, 6))
        ]
        shown = sorted(rng.sample(range(n), rng.randint(1, n)))
        assert (
            _unwrapped_width(cols, rows, shown) == Measurement.get(console, wide, _build("", cols, rows, shown)).maximum
        )


def test_names_in_brackets_are_printed_as_written(tmp_path, capsys):
    """Rich read ``x [/old]/u.dyr`` as a closing tag (MarkupError after the output was written) and
    ``[unit3]`` as a style (gone from the printed path). Printed as written now."""
    import json

    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    folder = tmp_path / "x [/old]" / "[unit3]"
    folder.mkdir(parents=True)
    result = folder / "u.json"
    doc = {"parameters": TABLE1.as_dict(), "identifiable": {n: True for n in PARAMETER_NAMES}, "base_mva": 1000.0}
    result.write_text(json.dumps({**doc, "f_nominal_hz": 50.0, "operating_point": {"p_m_pu": 0.8}}))
    assert main(["export", str(result), "--format", "psse-dyr", "--out", str(folder / "u.dyr")]) == 0
    out = capsys.readouterr().out
    assert "x [/old]/[unit3]/u.dyr" in out.replace("\n", "")
    bag = tmp_path / "[unit3].mcap"
    bag.write_bytes((Path(__file__).resolve().parents[2] / "bags" / "validation.mcap").read_bytes())
    assert main(["info", str(bag)]) == 0
    assert "[unit3].mcap" in capsys.readouterr().out


def test_figures_draw_names_as_written(tmp_path):
    """A ``$_$`` in a scenario's name stopped a report in matplotlib's mathtext."""
    from phid_ros.cli.common import figure_backend

    figure_backend()
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.set_title("scenario $_$ and $\\alpha$")
    fig.savefig(tmp_path / "f.png")
    plt.close(fig)
    assert (tmp_path / "f.png").stat().st_size > 1000


def test_a_withheld_value_is_not_drawn(monkeypatch):
    """The replay and track reports drew the values their own tables call withheld (D from -0.95 to
    +0.53). Now a withheld point is a tick on the time axis, labelled, and its value is drawn nowhere."""
    import matplotlib.pyplot as plt

    from phid_ros.cli import monitor_report
    from phid_ros.cli.common import WITHHELD_LABEL, figure_backend
    from phid_ros.ident.results import Estimate

    figure_backend()
    drawn = []
    monkeypatch.setattr(monitor_report, "png_data_uri", lambda fig: drawn.append(fig) or "data:")
    points = [
        monitor_report.ParameterPoint(10.0, {"H": Estimate(3.5, 0.01), "D": Estimate(-0.95, 0.5, identifiable=False)}),
        monitor_report.ParameterPoint(20.0, {"H": Estimate(3.49, 0.01), "D": Estimate(0.53, 0.4, identifiable=False)}),
    ]
    monitor_report._parameters_figure(points, ["H", "D"], "parameters")
    [fig] = drawn
    ax_h, ax_d = fig.axes[:2]
    values = [y for line in ax_d.get_lines() for y in line.get_ydata()]
    assert -0.95 not in values and 0.53 not in values
    assert [line.get_label() for line in ax_d.get_lines()] == [WITHHELD_LABEL]
    assert any(3.49 in line.get_ydata() for line in ax_h.get_lines())
    plt.close(fig)


def test_the_replay_report_shows_the_partial_set_the_terminal_publishes(outputs):
    """The catalogue's first recalibration (at 30 s, one torque step) publishes X'_d and T'_d0 on
    their own; the terminal says so, and the report said "0 adopted", marked it red and showed no
    value. Now it is counted, drawn green and tabled with its two values, the others "—"."""
    tmp, text = outputs
    assert "recalibration at 30.0 s with 1 event(s): partial set published: X'_d, T'_d0" in text["replay"]
    page = (tmp / "replay.html").read_text()
    assert "2 adopted recalibrations &middot; 1 partial set(s) published" in page
    first = re.search(r"<tr><td[^>]*>30\.0</td>(.*?)</tr>", page)
    assert first is not None
    cells = re.findall(r"<td[^>]*>(.*?)</td>", first.group(1))
    # H, D, X_d, X_q withheld; X'_d and T'_d0 with their stds
    assert cells[:4] == ["—"] * 4 and cells[4].startswith("0.49") and cells[6].startswith("1.43")
