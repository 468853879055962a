"""What each report's figures and tables say, read from the figures themselves (no browser): every
axis its quantity and unit, the recording never hidden under a model, no axis that misleads (a
negative count, a four-year span for one point), the MOD-026 table with error, band and verdict."""

from __future__ import annotations

import math
from datetime import timedelta

import numpy as np
import pytest

from phid_ros.cli.common import figure_backend
from phid_ros.stream.levels import Level


@pytest.fixture
def drawn(monkeypatch):
    """The figures a report module made, kept open instead of encoded."""
    figure_backend()
    import matplotlib.pyplot as plt

    figs: list = []
    yield figs, monkeypatch
    for f in figs:
        plt.close(f)


def _keep(figs, monkeypatch, module) -> None:
    monkeypatch.setattr(module, "png_data_uri", lambda fig: figs.append(fig) or "data:image/png;base64,")


def _unit_validation():
    from phid_ros.controls.unit_validation import ChannelCheck, ScenarioCheck, UnitValidation

    t = np.linspace(0.0, 10.0, 501)
    q = 0.2 + 0.1 * (t > 1)
    e = 2.0 + 0.5 * (t > 1)
    scenario = ScenarioCheck(
        "AVR_step@13.3s",
        "voltage_step",
        t,
        {"q_e": q, "v_f": e},
        {"q_e": q + 0.0123, "v_f": e + 0.31},
        [
            ChannelCheck("q_e", "MOD-026", 0.0123, 0.05, True, "GENSAL"),
            ChannelCheck("v_f", "MOD-026", 0.31, 0.10, False, "ESST5B"),
        ],
    )
    return UnitValidation("GENSAL + ESST5B", [scenario], [])


def test_the_mod026_report_gives_error_band_and_verdict_per_check_and_labels_every_axis(drawn, tmp_path):
    from phid_ros.cli import validate

    figs, monkeypatch = drawn
    _keep(figs, monkeypatch, validate)
    report = validate.write_report(tmp_path / "v.html", _unit_validation(), "day.mcap")
    html = report.read_text()
    # one header per column (two columns were both headed "check"), the terminal's figures in the rows
    for header in ("standard", "channel", "max |error| (pu)", "band (pu)", "verdict"):
        assert f">{header}<" in html
    assert ">0.0123<" in html and ">0.0500<" in html and ">pass<" in html
    assert ">0.3100<" in html and ">0.1000<" in html and ">FAIL<" in html
    [fig] = figs
    axes = [ax for ax in fig.axes if ax.get_visible()]
    assert [ax.get_ylabel() for ax in axes] == ["Q (pu)", "E_fd (pu, machine base)"]
    assert all(ax.get_xlabel().startswith("t (s)") for ax in axes)
    assert "E_fd (ESST5B): max |error| 0.31 pu, band ±0.1 pu: FAIL" in axes[1].get_title()
    for ax in axes:
        lines = {line.get_label(): line for line in ax.get_lines()}
        simulated = next(v for k, v in lines.items() if k.startswith("simulated"))
        assert lines["recorded"].get_zorder() > simulated.get_zorder()  # the recording is never hidden
    assert fig.get_size_inches()[0] >= 10  # two panels a row at a readable size


def test_the_identify_report_has_its_exciter_and_governor_and_a_note_per_parameter():
    from phid_ros.cli.report import MEASURED_STYLE, STYLES, _controls_section, _note
    from phid_ros.controls.fit import ControlFit
    from phid_ros.ident.results import Estimate

    fit = ControlFit(
        "SEXS",
        "exciter",
        {"K": 98.7, "T_E": 0.049, "E_MAX": None},
        {"K": 1.2, "T_E": 0.002, "E_MAX": None},
        {"K": True, "T_E": True, "E_MAX": False},
        0.0012,
        0.0015,
        0.21,
        True,
        "named: held-out error 0.0015 pu against 0.21 without control action",
    )
    html = _controls_section({"exciter": fit, "governor": "the recordings do not show the governor"})
    assert "exciter: SEXS" in html and ">98.7<" in html and ">0.049<" in html
    assert "not determined by these data" in html  # E_MAX, never reached
    assert "held-out RMSE 1.50e-03 pu (without any control action 2.10e-01 pu)" in html
    assert "governor: none" in html and "do not show the governor" in html
    assert _note(Estimate(1.4, 0.01)) == "identified"
    assert _note(Estimate(0.4, 0.3, identifiable=False, note="D: poorly determined")).startswith("withheld")
    assert _note(None) == "not estimated"
    # the measurement is drawn over every model, the identified one beneath the thin lines
    assert MEASURED_STYLE["zorder"] > max(float(s["zorder"]) for s in STYLES.values())  # type: ignore[arg-type]
    assert STYLES["proposed"]["zorder"] == min(float(s["zorder"]) for s in STYLES.values())  # type: ignore[arg-type]


def test_one_recording_in_a_history_spans_hours_not_years(drawn):
    from phid_ros.cli import history_report
    from phid_ros.fleet.history import Row
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    figs, monkeypatch = drawn
    _keep(figs, monkeypatch, history_report)
    row = Row("U1", "/rec/day.mcap", "h", "ok", "0.4.3", start_ns=1_780_000_000 * 10**9, end_ns=1_780_000_600 * 10**9)
    for name in PARAMETER_NAMES:
        row.values[name], row.stds[name], row.identifiable[name] = getattr(TABLE1, name), 0.001, True
    history_report._figure([row], [])
    [fig] = figs
    import matplotlib.dates as mdates

    lo, hi = (mdates.num2date(x) for x in fig.axes[0].get_xlim())
    assert timedelta(hours=1.9) <= hi - lo <= timedelta(hours=2.1)


def test_the_stream_health_counts_never_go_below_zero(drawn):
    from phid_ros.cli import monitor_report

    figs, monkeypatch = drawn
    _keep(figs, monkeypatch, monitor_report)
    log = monitor_report.HealthLog()
    for k in range(5):
        log.add(float(k), {"pt_ct": (Level.OK, 0, 0, 0), "pmu": (Level.OK, 0, 0, 0)})
    monitor_report._health_figure(log)
    [fig] = figs
    count_axis = fig.axes[1]
    assert count_axis.get_ylim()[0] == 0 and count_axis.get_ylim()[1] >= 1
    assert all(tick >= 0 and math.isclose(tick, round(tick)) for tick in count_axis.get_yticks())


def test_validate_says_why_its_errors_are_not_identify_s():
    from phid_ros.cli.validate import why_larger_than_identify

    with_controls = why_larger_than_identify(_unit_validation())
    assert "its ESST5B making E_fd and P_m" in with_controls and "recorded E_fd and P_m" in with_controls
    machine_only = _unit_validation()
    machine_only.scenarios[0].checks = machine_only.scenarios[0].checks[:1]
    assert "making" not in why_larger_than_identify(machine_only)


def test_the_history_draws_what_its_table_prints_and_says_where_nothing_is_identified(drawn):
    """X_d identified without a computed std (stage 3's, where stage 2 could not run) is printed in the
    table, so it is drawn (hollow, no band); D withheld in every recording: no value axis, a sentence."""
    from phid_ros.cli import history_report
    from phid_ros.fleet.history import Row
    from phid_ros.model.parameters import PARAMETER_NAMES, TABLE1

    figs, monkeypatch = drawn
    _keep(figs, monkeypatch, history_report)
    rows = []
    for day in (1, 2):
        row = Row("U1", f"/rec/d{day}.mcap", f"h{day}", "ok", "0.4.3", start_ns=day * 86_400 * 10**9, end_ns=1)
        for name in PARAMETER_NAMES:
            row.values[name], row.stds[name], row.identifiable[name] = getattr(TABLE1, name), 0.001, True
        row.stds["X_d"] = math.nan
        row.identifiable["D"] = False
        rows.append(row)
    history_report._figure(rows, [])
    [fig] = figs
    ax_d, ax_xd = fig.axes[1], fig.axes[2]
    hollow = [line for line in ax_xd.get_lines() if line.get_label() == "identified, std not computed"]
    assert hollow and list(hollow[0].get_ydata()) == [TABLE1.X_d, TABLE1.X_d]
    assert not ax_xd.collections  # no ±2σ band without a std
    assert not list(ax_d.get_yticks()) and "withheld in every recording" in ax_d.texts[0].get_text()
    assert all(TABLE1.D not in line.get_ydata() for line in ax_d.get_lines())


def test_log_ticks_are_unicode_powers_of_ten_not_raw_tex() -> None:
    """With mathtext off (a user's name with ``$`` in it), matplotlib's log ticks printed as raw
    TeX (``$\\mathdefault{10^{5}}$``) on the diagnosis's spectra; now 10⁵."""
    import matplotlib.pyplot as plt

    from phid_ros.cli.common import figure_backend, log_ticks, power_of_ten

    assert [power_of_ten(v) for v in (1e5, 1e-2, 1.0, 3e3, 0.0)] == ["10⁵", "10⁻²", "1", "", ""]
    figure_backend()
    fig, ax = plt.subplots()
    ax.loglog([1, 10, 100, 1e5], [1e-2, 1, 10, 1e3])
    log_ticks(ax)
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() + ax.get_xticklabels() if t.get_text()]
    assert labels and not any("$" in t or "mathdefault" in t for t in labels) and "10⁵" in labels
    plt.close(fig)


def test_a_validation_overlay_zooms_to_where_its_check_is_decided() -> None:
    """A 48 s window around a step whose failing 60 ms could not be seen: the overlay shows 3 s
    either side of the largest error, V_t with its unit, the recording on top and the legend off
    the traces (below the panels)."""
    import matplotlib.pyplot as plt
    import numpy as np

    from phid_ros.cli.common import figure_backend
    from phid_ros.cli.validate import overlay_figure
    from phid_ros.controls.unit_validation import ChannelCheck, ScenarioCheck

    figure_backend()
    t = np.arange(0.0, 48.0, 0.01)
    rec = np.where(t > 20.0, 1.05, 1.0)
    sim = rec + np.where((t > 20.0) & (t < 20.06), 0.02, 0.0)
    check = ChannelCheck("v_t", "MOD-026", 0.02, 0.01, False, "SEXS")
    fig = overlay_figure(ScenarioCheck("step", "field_step", t, {"v_t": rec}, {"v_t": sim}, [check]))
    [ax] = [a for a in fig.axes if a.get_visible()]
    lo, hi = ax.get_xlim()
    assert 16.9 < lo < 17.1 and 22.9 < hi < 23.1 and ax.get_ylabel() == "V_t (pu)"
    assert ax.get_legend() is None and len(fig.legends) == 1
    recorded = next(line for line in ax.get_lines() if line.get_label() == "recorded")
    assert recorded.get_zorder() > max(line.get_zorder() for line in ax.get_lines() if line is not recorded)
    plt.close(fig)


def test_the_replay_report_draws_p_e_where_p_m_was_never_recorded(monkeypatch) -> None:
    """On a recorder's day (no encoder stream) the events figure drew an empty P_m axis; it draws
    P_e in its place, said on the axis, and P_m where the recording has it."""
    from pathlib import Path

    from phid_ros.cli import monitor_report
    from phid_ros.cli.common import figure_backend
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.io.overview import Overview
    from phid_ros.io.recording import Recording

    figure_backend()
    drawn = []
    monkeypatch.setattr(monitor_report, "png_data_uri", lambda fig: drawn.append(fig) or "data:")
    rec = read_recording(Path(__file__).resolve().parents[2] / "bags" / "validation.mcap")
    recorder = Recording({"pt_ct": rec.streams["pt_ct"]}, [], rec.metadata)
    for recording, labels in ((rec, ["V_t (pu)", "P_m (pu)"]), (recorder, ["V_t (pu)", "P_e (pu), P_m not recorded"])):
        monitor_report._events_figure(Overview.of(recording), [], [])
        assert [ax.get_ylabel() for ax in drawn.pop().axes] == labels
