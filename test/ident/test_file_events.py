"""Every event of a test file: look-alikes of a commissioning day's trend logs at 208 reports/s."""

from __future__ import annotations

import math

import numpy as np
import pytest

from phid_ros.ident.file_events import FileEvent, event_note, events_of_file
from phid_ros.ident.open_circuit import OpenCircuitError, open_circuit, saturation_seen
from phid_ros.ident.scenario import DEFAULT_THRESHOLDS, make_scenario
from phid_ros.model.channels import CHANNELS, Frame

DT = 0.0048  # a trend log's 208 reports/s
T_D0 = 3.77


def no_load_file(steps: list[tuple[float, float]], seconds: float, seed: int = 0, curve: float = 0.0) -> dict:
    """An open-circuit AVR test: E_fd steps at the given (time, level), V_t follows through T'_d0
    onto the open-circuit curve E_fd = V (1 + curve (V - 0.8)^2 for V > 0.8)."""
    rng = np.random.default_rng(seed)
    n = int(seconds / DT)
    t = np.arange(n) * DT
    e = np.full(n, 1.0)
    for at, level in steps:
        e[t >= at] = level
    v = np.empty(n)
    v[0] = 1.0 if curve == 0 else _on_curve(1.0, curve)
    for k in range(1, n):  # T'_d0 dV/dt = E_fd - V (1 + S(V))
        f = v[k - 1] * (1 + curve * max(v[k - 1] - 0.8, 0) ** 2)
        v[k] = v[k - 1] + DT / T_D0 * (e[k - 1] - f)
    sig = {c: np.full(n, np.nan) for c in CHANNELS}
    sig.update(
        v_t=v + rng.normal(0, 2e-4, n),
        v_f=e + rng.normal(0, 0.01, n),  # a static exciter's ripple
        p_e=np.zeros(n),
        q_e=np.zeros(n),
        i_d=np.zeros(n),
        i_q=np.zeros(n),
        theta_t=np.zeros(n),
    )
    return sig


def _on_curve(e: float, curve: float) -> float:
    v = e
    for _ in range(50):
        v = e / (1 + curve * max(v - 0.8, 0) ** 2)
    return v


def test_a_step_and_its_return_are_two_events_with_their_own_plateaus() -> None:
    # a manual no-load test: the field steps and V_t settles through T'_d0 (about 4 T'_d0 to settle)
    sig = no_load_file([(8.0, 1.1), (60.0, 1.0)], 75.0)
    events = events_of_file(sig, DT)
    assert [e.kind for e in events] == ["field_step", "field_step"]
    assert [round(e.event * DT, 2) for e in events] == pytest.approx([8.0, 60.0], abs=0.01)
    first, second = events
    assert first.start == 0 and first.end == second.start and second.end == len(sig["v_t"])  # no plateau twice
    assert (first.event + first.end) // 2 <= first.steady_start < first.end
    # the first event's steady part is the 1.1 plateau, not a mean over both
    v_post = float(np.mean(sig["v_t"][first.steady_start : first.end]))
    assert v_post == pytest.approx(1.1, abs=0.005)
    # the mean of the file's last fifth (the paper's rule) is the return's plateau
    assert float(np.mean(sig["v_t"][int(0.8 * len(sig["v_t"])) :])) < 1.05


def test_field_ripple_without_a_terminal_move_is_no_event() -> None:
    sig = no_load_file([], 20.0)
    sig["v_f"] = sig["v_f"] + np.where(np.arange(len(sig["v_f"])) * DT > 10.0, 0.03, 0.0)  # V_t does not follow
    sig["v_t"][:] = 1.0 + np.random.default_rng(1).normal(0, 2e-4, len(sig["v_t"]))
    assert events_of_file(sig, DT) == []


def test_a_voltage_measurement_lost_at_no_load_is_named_not_taken_for_a_fault() -> None:
    sig = no_load_file([(15.0, 1.05)], 30.0)
    k = int(6.0 / DT)
    back = int(9.0 / DT)
    sig["v_t"][k:back] = 0.0  # a VT fuse: the measurement drops in one report and comes back later
    events = events_of_file(sig, DT)
    lost = [e for e in events if e.lost_measurement]
    assert lost and lost[0].event * DT == pytest.approx(6.0, abs=DT)
    assert all(e.kind != "fault" for e in events)
    # the measurement's return is no event of the machine; the field step after it is
    assert [round(e.event * DT) for e in events if not e.lost_measurement] == [15]


def _scenarios(sig: dict, events: list) -> list:
    frame = Frame.of_columns(sig, int(round(DT * 1e9)))
    out = []
    for e in events:
        s = make_scenario(
            f"f@{e.event * DT:.1f}s", frame.rows(e.start, e.end), kind="field_step", k_event=e.event - e.start
        )
        s.steady_start = e.steady_start - e.start
        out.append(s)
    return out


def test_t_d0_from_no_load_steps_on_the_air_gap_line() -> None:
    sig = no_load_file([(8.0, 1.05), (20.0, 1.0)], 32.0, seed=3)
    scs = _scenarios(sig, events_of_file(sig, DT))
    assert saturation_seen(scs) is None
    est = open_circuit(scs).T_d0_prime
    assert est.identifiable
    assert abs(est.value - T_D0) / T_D0 < 0.03


def test_t_d0_withheld_where_the_no_load_tests_saturate() -> None:
    # S(1.1) of about 0.2: the step's own time constant is T'_d0 over the curve's slope, about half
    sig = no_load_file([(8.0, 1.35), (20.0, 1.0)], 32.0, seed=4, curve=2.5)
    scs = _scenarios(sig, events_of_file(sig, DT))
    assert saturation_seen(scs) is not None
    est = open_circuit(scs).T_d0_prime
    assert not est.identifiable and "saturated part" in est.note
    # and the fitted number is indeed wrong: publishing it would have been the defect
    assert abs(est.value - T_D0) / T_D0 > 0.15


def test_no_no_load_step_is_an_error() -> None:
    sig = no_load_file([], 20.0)
    frame = Frame.of_columns(sig, int(round(DT * 1e9)))
    s = make_scenario("flat", frame, kind="field_step", k_event=100)
    with pytest.raises(OpenCircuitError):
        open_circuit([s])
    assert math.isfinite(DT)


def test_a_voltage_step_from_the_field_is_told_from_one_of_the_network() -> None:
    """The Mostar map labels the on-line AVR test voltage_step; Q rose with V_t (+0.367 pu for
    +0.043 pu), which only the machine's own field does: a network step makes Q fall as V_t rises."""
    from phid_ros.ident.scenario import scenario_from_simulation
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
    from phid_ros.sim.scenarios import paper_catalogue, with_duration

    network = [with_duration(sc, 8.0) for sc in paper_catalogue() if sc.kind == "voltage_step"]
    assert len(network) >= 3
    for run in simulate_scenarios(network, SimulationConfig()):
        s = scenario_from_simulation(run, run.measured)
        assert s.kind == "voltage_step", s.notes
    n, k = 4000, 2000
    sig = {c: np.full(n, np.nan) for c in CHANNELS}
    rng = np.random.default_rng(3)
    rise = (np.arange(n) >= k).astype(float)
    sig.update(
        v_t=0.987 + 0.043 * rise + rng.normal(0, 5e-4, n),
        q_e=0.003 + 0.36 * rise + rng.normal(0, 3e-3, n),
        p_e=np.full(n, 0.61),
        v_f=1.4 + 0.4 * rise,
        theta_t=np.zeros(n),
    )
    s = make_scenario("AVR step", Frame.of_columns(sig, int(round(DT * 1e9))), kind="voltage_step", k_event=k)
    assert s.kind == "field_step" and any("Q moved with V_t" in note for note in s.notes)


def test_a_file_whose_every_event_is_the_measurement_s_is_no_scenario() -> None:
    """A VT-loss test at no load holds two events, the loss and the return, both the measurement's:
    the file is left out whole, by name. It was taken whole as the one scenario its label said, a
    fault (the Mostar day's AVR_RR_PH_Ispad_Q141, once the noise about zero made no more events)."""
    from phid_ros.io.recording import ScenarioInfo
    from phid_ros.stream.scenarios import _file_events

    sig = no_load_file([], 30.0)
    k, back = int(10.0 / DT), int(16.0 / DT)
    sig["v_t"][k:back] = np.abs(np.random.default_rng(3).normal(0, 0.003, back - k))
    frame = Frame.of_columns(sig, int(round(DT * 1e9)))
    problems: list[str] = []
    pieces, kind, whole = _file_events(
        ScenarioInfo("Ispad", kind="fault"), frame, DEFAULT_THRESHOLDS, "day.mcap", problems
    )
    assert (pieces, kind, whole) == ([], None, None)
    assert sum("measurement lost" in p for p in problems) == 2  # the loss and the return, each named


def manual_on_line_file(
    events: list[tuple[float, float]], seconds: float = 150.0, seed: int = 4, ramp: tuple[float, float] = (20.0, 40.0)
) -> dict:
    """A manual on-line test as Mostar's RR_MR_Step10: Q ramped 0.37 -> 0.045 pu over ``ramp`` (20-40
    s there) by the field-current regulator, then the field stepped at the given (time, +1 up / -1
    back): Q +0.115, V_t +0.014 through a 0.5 s lag."""
    rng = np.random.default_rng(seed)
    n = int(seconds / DT)
    t = np.arange(n) * DT
    q = np.interp(t, [0.0, *ramp, seconds], [0.37, 0.37, 0.045, 0.045])
    up = np.zeros(n)
    for at, sign in events:
        up += sign * np.where(t >= at, 1.0 - np.exp(-(t - at) / 0.5), 0.0)
    field = np.zeros(n)
    for at, sign in events:
        field += sign * (t >= at)
    sig = {c: np.full(n, np.nan) for c in CHANNELS}
    sig.update(
        v_t=0.992 + 0.014 * up + rng.normal(0, 3e-4, n),
        q_e=q + 0.115 * up + rng.normal(0, 2e-3, n),
        p_e=0.073 + rng.normal(0, 1e-3, n),
        v_f=1.2 - 0.9 * (q - 0.045) + 0.25 * field + rng.normal(0, 0.01, n),
        i_d=np.full(n, 0.1),
        i_q=np.full(n, 0.1),
        theta_t=np.zeros(n),
    )
    return sig


@pytest.mark.parametrize("events", [[(138.0, 1.0)], [(138.0, 1.0), (143.5, -1.0)]], ids=["step", "step-and-return"])
def test_an_event_s_window_begins_on_the_plateau_before_it_not_across_a_ramp(events: list) -> None:
    """The Q ramp 100 s before a manual field step is not the step's steady state: averaged in,
    the pre-event Q read 0.12 pu for 0.045 (and the play-in began 0.38 pu away). The window begins
    where the ramp ended, whether the file holds the step alone or the step and its return."""
    sig = manual_on_line_file(events, ramp=(90.0, 110.0))
    found = events_of_file(sig, DT)
    assert [round(e.event * DT, 1) for e in found] == [at for at, _ in events]
    first = found[0]
    assert 109.0 <= first.start * DT <= 111.0, first.start * DT
    assert float(np.mean(sig["q_e"][first.start : first.event])) == pytest.approx(0.045, abs=0.002)


def test_a_plateau_longer_than_a_minute_is_taken_for_its_last_minute() -> None:
    """Mostar's manual step stood 99 s on its plateau: the window reaches back 60 s (the online
    detector's ring holds no more, and the monitor must cut the window ``phid validate`` plays)."""
    found = events_of_file(manual_on_line_file([(138.0, 1.0)]), DT)
    assert found[0].event - found[0].start == int(round(60.0 / DT))


def test_a_file_s_one_event_is_taken_from_its_plateau_and_said() -> None:
    """A test file holding one event, imported whole: its scenario begins on the plateau before the
    event, and the problems say from where."""
    from phid_ros.io.recording import ScenarioInfo
    from phid_ros.stream.scenarios import _file_events

    frame = Frame.of_columns(manual_on_line_file([(138.0, 1.0)], ramp=(90.0, 110.0)), int(round(DT * 1e9)))
    problems: list[str] = []
    pieces, kind, whole = _file_events(
        ScenarioInfo("RR_MR_Step10", kind="field_step"), frame, DEFAULT_THRESHOLDS, "day.mcap", problems
    )
    assert pieces == [] and kind == "field_step" and whole is not None and 109.0 <= whole.start * DT <= 111.0
    assert round(whole.event * DT, 2) == 138.0
    assert any("RR_MR_Step10 taken from" in p and "the plateau before its event at 138.00 s" in p for p in problems)


def test_a_step_is_placed_at_its_onset_not_half_way() -> None:
    """A regulator's output falling in three samples (Mostar's AVR return: 0.69, 0.47, -0.16, -0.36
    pu as recorded) was stepped before its first moved sample: the event is that sample, not the
    one past half the fall (a sample late, at 30 pu/s, erred 0.3 pu of E_fd against the recording)."""
    from phid_ros.ident.scenario import locate_labelled_step

    rng = np.random.default_rng(5)
    n, k0 = 3000, 1500
    x = 0.69 + rng.normal(0, 0.004, n)
    x[k0 : k0 + 3] = [0.47, -0.155, -0.364]
    x[k0 + 3 :] = -0.9 + rng.normal(0, 0.004, n - k0 - 3)
    k, _ = locate_labelled_step({"v_f": x}, DT, "field_step")
    assert k == k0
    # a clean step is where it was
    y = np.where(np.arange(n) >= k0, 1.0, 0.0) + rng.normal(0, 1e-3, n)
    assert locate_labelled_step({"v_f": y}, DT, "field_step")[0] == k0


def test_an_event_s_note_names_its_time_in_its_file() -> None:
    """The note a scenario is cut with says where in its test file the event lies (the day's
    summary reads the time from the scenario's ``file_time_s``, not from this sentence)."""
    e = FileEvent("field_step", start=10_000, event=11_199, end=12_400, steady_start=11_900)
    note = event_note(e, 0.0048, "AVR_PH_Step10")
    assert note.startswith("event field_step at 53.76 s (window 48.00-59.52 s) of AVR_PH_Step10")


def test_a_fault_s_own_transient_is_part_of_its_event_a_later_settled_one_is_not() -> None:
    """ANDES's GENROU with EXST1 at its input limit: the field's jump 2.4 s after a fault, the
    swing still decaying, was cut as a second event ("fault at 1.00 s (window 0.00-2.32 s);
    field_step at 3.48 s"), and stage 1 lost the swing (H -19 %). A detection before the first
    event has settled is its own transient; one after it has settled (a test's return) is an event."""
    rng = np.random.default_rng(3)
    dt, n = 0.001, 12000
    t = np.arange(n) * dt
    sig = {c: np.full(n, np.nan) for c in CHANNELS}
    swing = np.where(t > 1.15, 0.25 * np.exp(-0.35 * (t - 1.15)) * np.sin(2 * np.pi * 1.1 * (t - 1.15)), 0.0)
    v = np.where((t >= 1.0) & (t < 1.15), 0.1, 1.0 + 0.3 * swing)
    e_fd = np.where(t >= 1.0, 3.0, 2.0)
    e_fd[t >= 3.48] = 2.3  # the exciter leaves its limit while the rotor still swings
    sig.update(
        v_t=v + rng.normal(0, 2e-4, n),
        v_f=e_fd + rng.normal(0, 0.005, n),
        p_e=0.8 + swing + rng.normal(0, 1e-3, n),
        q_e=0.2 + 0.5 * swing + rng.normal(0, 1e-3, n),
        p_m=np.full(n, 0.8),
        omega=1.0 + 0.002 * np.gradient(swing, dt) / (2 * np.pi * 1.1) + rng.normal(0, 1e-5, n),
        i_d=np.full(n, -0.5),
        i_q=np.full(n, 0.5),
        theta_t=np.zeros(n),
        delta=np.full(n, 0.7),
    )
    [event] = events_of_file(sig, dt)
    assert event.kind == "fault" and event.event * dt == pytest.approx(1.0, abs=0.01) and event.end == n
    assert [(k, round(j * dt, 1)) for k, j in event.joined] == [("field_step", 3.5)]
    assert "field_step at 3.48 s came before the fault at 1.00 s had settled" in event.joined_note(dt)
    # the same later step once the swing has died away (a test's own return) is an event of its own
    quiet = dict(sig)
    calm = np.where(t > 1.15, 0.25 * np.exp(-3.0 * (t - 1.15)) * np.sin(2 * np.pi * 1.1 * (t - 1.15)), 0.0)
    for c, scale in (("p_e", 1.0), ("q_e", 0.5)):
        quiet[c] = sig[c] - scale * swing + scale * calm
    quiet["v_t"] = sig["v_t"] - 0.3 * swing + 0.3 * calm
    late = np.where(t >= 1.0, 3.0, 2.0)
    late[t >= 8.0] = 2.3
    quiet["v_f"] = late + rng.normal(0, 0.005, n)
    quiet["v_t"] = quiet["v_t"] + np.where(t >= 8.0, 0.02 * (1 - np.exp(-(t - 8.0).clip(0) / 0.5)), 0.0)
    assert [e.kind for e in events_of_file(quiet, dt)] == ["fault", "field_step"]
