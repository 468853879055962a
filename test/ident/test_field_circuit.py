"""T'_d0 from the field circuit at no load: E_fd - X_ad I_fd integrated per V_t moved.

On the project's own simulator, no-load field steps recorded as an excitation controller does
(E_fd and I_fd on bases of their own, a few hundred reports per second, sensor noise): on the
air-gap line, on a saturated machine with and without its curve, and with a plateau below the knee.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from scipy.signal import savgol_filter

from phid_ros.ident.field_circuit import field_circuit, field_current_base, machine_field, on_line
from phid_ros.ident.scenario import ScenarioData, resampled, scenario_from_simulation
from phid_ros.ident.terminal import with_channels
from phid_ros.model.parameters import TABLE1
from phid_ros.sim.effects.magnetic_saturation import MagneticSaturation
from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
from phid_ros.sim.scenarios import Scenario
from test.io.field.field_sets import NO_LOAD, field_current

E_FD_BASE, I_FD_BASE = 0.37, 0.52  # the controller's field bases: 1 pu of the machine's reads as these
CURVE = (0.1, 0.4)  # S(1.0), S(1.2)
REPORT_NS = 4_807_692  # 208 reports per second


def no_load_steps(
    steps: dict[str, float],
    saturation: tuple[float, float] | None,
    seed: int = 0,
    on_line: bool = False,
    warmer: float = 1.0,
) -> list[ScenarioData]:
    """No-load (or on-line) field steps (name -> E_fd multiplier), as a controller's trend log carries them.

    ``warmer``: the field winding's resistance over the one the machine's E_fd base was taken at
    (a winding warmed through the day): T'_d0 = L_ffd / R_fd is that much shorter, and the field
    voltage that drives a field current that much higher."""
    effects = () if saturation is None else (MagneticSaturation(s10=saturation[0], s12=saturation[1], form="gensal"),)
    params = TABLE1.replace(T_d0_prime=TABLE1.T_d0_prime / warmer)
    cfg = dataclasses.replace(SimulationConfig() if on_line else NO_LOAD, params=params, effects=effects)
    runs = simulate_scenarios([Scenario(n, "field_step", m, duration=15.0) for n, m in steps.items()], cfg)
    rng = np.random.default_rng(seed)
    out = []
    for run in runs:
        s = scenario_from_simulation(run, run.measured)
        n = s.n
        i_fd = field_current(run, params, saturation)[:n] + rng.normal(0.0, 0.002, n)
        s = with_channels(s, {"v_f": s["v_f"] * warmer * E_FD_BASE}, "E_fd on the controller's base")
        s = dataclasses.replace(s, recorded={"i_fd": i_fd * I_FD_BASE})
        out.append(resampled(s, REPORT_NS))
    return out


def test_on_the_air_gap_line() -> None:
    scs = no_load_steps({"up": 1.1, "down": 0.9}, None)
    r = field_circuit(scs, None)
    assert r.base.determined and "air-gap line" in r.base.source
    assert r.base.scale == pytest.approx(1 / I_FD_BASE, rel=0.01)
    assert [e.scenario for e in r.events] == ["up", "down"]
    assert r.T_d0_prime.identifiable
    assert r.T_d0_prime.value == pytest.approx(TABLE1.T_d0_prime, rel=0.015)
    assert abs(r.T_d0_prime.value - TABLE1.T_d0_prime) <= 2 * r.T_d0_prime.std + 0.01
    for e in r.events:  # each event alone, and the field's resistance read from its plateaus
        assert r.base.scale * e.time_per_base == pytest.approx(TABLE1.T_d0_prime, rel=0.02)
        assert e.k_e == pytest.approx(I_FD_BASE / E_FD_BASE, rel=0.01)


def test_a_saturated_machine_needs_its_curve() -> None:
    scs = no_load_steps({"up": 1.1, "down": 0.9}, CURVE)
    bare = field_circuit(scs, None)
    # every plateau above the knee: the base is not determined, and T'_d0 is bounded from below
    assert not bare.base.determined and not bare.T_d0_prime.identifiable
    assert bare.T_d0_prime.value < TABLE1.T_d0_prime and bare.T_d0_prime.bound == "at least"
    assert "at least" in bare.T_d0_prime.note and "--saturation" in bare.T_d0_prime.note
    held = field_circuit(scs, CURVE)
    assert held.base.determined and held.base.scatter < 0.005
    assert held.T_d0_prime.identifiable
    assert held.T_d0_prime.value == pytest.approx(TABLE1.T_d0_prime, rel=0.02)
    # another machine's curve does not reproduce the plateaus, and says so
    other = field_circuit(scs, (0.02, 0.08))
    assert other.base.scatter > 0.03 and not other.T_d0_prime.identifiable
    assert "misses the no-load plateaus by up to 3.9 %" in other.T_d0_prime.note


def test_a_plateau_below_the_knee_gives_the_air_gap_line() -> None:
    scs = no_load_steps({"up": 1.1, "deep": 0.6}, CURVE)
    r = field_circuit(scs, None)
    assert r.base.determined and "air-gap line through 1 no-load plateau" in r.base.source
    assert r.T_d0_prime.identifiable
    assert r.T_d0_prime.value == pytest.approx(TABLE1.T_d0_prime, rel=0.02)


def test_the_base_from_plateaus() -> None:
    # I_f = V (1 + S(V)) / c on the quadratic curve through S(1.0) 0.1, S(1.2) 0.4: c found back
    from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor

    a, b = saturation_curve("quadratic", *CURVE)
    v = np.array([1.0, 1.1])
    i = v * (1 + saturation_factor(False, a, b, v)) / 2.5
    assert field_current_base(v, i, CURVE).scale == pytest.approx(2.5, rel=1e-9)
    bound = field_current_base(v, i, None)
    assert not bound.determined and bound.scale == pytest.approx(1.0 / 1.1 * 2.5, rel=1e-9)


def test_a_field_whose_leakage_flux_does_not_saturate_shows_it() -> None:
    """A field whose flux is the air gap's and its own leakage's, which does not saturate: the
    recorded E_fd written as X_ad I_fd + T_ad dV_t/dt + T_fl d(X_ad I_fd)/dt on the simulated V_t and
    field current of three no-load steps (above the knee, where the field current moves 2-2.4 x V_t,
    and below it). Each file's T'_d0 is T_ad + T_fl dI/dV: the line through the files gives T_fl and
    the unsaturated T'_d0 back, and the note says it. The simulator's own field (GENSAL's form: no
    leakage flux of its own) shows none."""
    t_ad, t_fl = 1.2, 0.25
    plain = no_load_steps({"up": 1.1, "deep": 0.6, "down": 0.9}, CURVE)
    leaky = []
    for s in plain:
        i = np.asarray(s["i_fd"], float) / I_FD_BASE  # X_ad I_fd on the machine's base
        # the derivatives smoothed (a quarter second): the sensors' noise differentiated would be
        # the recorded E_fd's, whose plateaus give the winding's resistance
        rate = {k: savgol_filter(x, 51, 3, deriv=1, delta=s.dt) for k, x in (("v", s["v_t"]), ("i", i))}
        e_fd = i + t_ad * rate["v"] + t_fl * rate["i"]
        leaky.append(with_channels(s, {"v_f": e_fd * E_FD_BASE}, "a field with its own leakage flux"))
    r = field_circuit(leaky, CURVE)
    assert r.leakage is not None and r.leakage.shows
    assert [f for f, _, _ in r.leakage.per_volt] == ["up", "deep", "down"]
    assert r.leakage.leakage == pytest.approx(t_fl, rel=0.10)
    assert r.leakage.unsaturated == pytest.approx(t_ad + t_fl, rel=0.03)
    assert "the field's own leakage flux, which does not saturate, shows" in r.T_d0_prime.note
    # GENSAL's form: one T'_d0 whatever dI/dV, no leakage flux of its own
    g = field_circuit(plain, CURVE)
    assert g.leakage is not None and not g.leakage.shows and abs(g.leakage.leakage) < 0.02
    assert g.leakage.unsaturated == pytest.approx(TABLE1.T_d0_prime, rel=0.01)
    assert "leakage flux" not in g.T_d0_prime.note
    # two files above the knee alike: their dI/dV do not differ enough to tell
    assert field_circuit(no_load_steps({"up": 1.1, "down": 0.9}, CURVE), CURVE).leakage is None


def test_x_d_and_x_d_prime_on_line_from_the_field_circuit_of_a_saturated_machine() -> None:
    """On line, E'_q's course comes from the field channels and T'_d0, X'_d from E'_q = V_q + X'_d
    I_d, X_d from the field current with the curve (GENSAL's form): the TABLE 1 machine with S(1.0)
    0.1, S(1.2) 0.4, two no-load steps (T'_d0, the field base) and four on-line field steps, each
    a file of its own, E_fd and I_fd on the controller's bases."""
    scs = no_load_steps({"up": 1.1, "down": 0.9}, CURVE)
    scs += no_load_steps({f"line_{k}": m for k, m in enumerate((1.05, 0.95, 1.1, 0.9))}, CURVE, seed=1, on_line=True)
    field = machine_field(scs, CURVE)
    assert field is not None and field.base.determined
    assert set(field.scale) == {"up", "down", "line_0", "line_1", "line_2", "line_3"}
    # every file's E_fd back on the machine's base (the controller's 0.37 undone)
    assert all(k == pytest.approx(1 / E_FD_BASE, rel=0.01) for k in field.scale.values())
    t_d0 = field_circuit(scs, CURVE).T_d0_prime
    out = on_line(scs, field, t_d0, TABLE1.X_q, CURVE)
    assert out.X_d.identifiable and out.X_d_prime.identifiable
    assert out.X_d.value == pytest.approx(TABLE1.X_d, rel=0.02)
    assert out.X_d_prime.value == pytest.approx(TABLE1.X_d_prime, rel=0.05)
    for e in (out.X_d, out.X_d_prime):
        assert e.std < 0.05 * e.value
    # without the curve the same events give another X_d: the saturation is in the field current
    bare = on_line(scs, machine_field(scs, None), t_d0, TABLE1.X_q, None)
    assert not bare.X_d.identifiable  # the base is not determined: every no-load plateau above the knee


def test_on_line_each_file_s_t_d0_is_its_own_field_winding_s() -> None:
    """The field winding warms through a day: on line its resistance is 6 % above the no-load
    tests' (their I_f per U_f says so), and T'_d0 = L_ffd / R_fd is 6 % shorter there. Referred to
    each on-line file's own resistance, the no-load T'_d0 gives X'_d within 3 % (measured +0.3 %)
    and X_d within 2 % (-0.1 %); taken as it is in every file (as a held T'_d0 is), X'_d comes out
    22 % short and X_d 8 % long: what the on-line tests fix is T'_d0 X'_d, and E'_q's course is
    read on that file's T'_d0."""
    warmer = 1.06
    scs = no_load_steps({"up": 1.1, "down": 0.9}, CURVE)
    scs += no_load_steps(
        {f"line_{k}": m for k, m in enumerate((1.05, 0.95, 1.1, 0.9))}, CURVE, seed=1, on_line=True, warmer=warmer
    )
    field = machine_field(scs, CURVE)
    assert field is not None
    assert field.time_constant_ratio("line_0", ["up", "down"]) == pytest.approx(1 / warmer, rel=0.01)
    t_d0 = field_circuit(scs[:2], CURVE).T_d0_prime
    assert t_d0.value == pytest.approx(TABLE1.T_d0_prime, rel=0.015)
    out = on_line(scs, field, t_d0, TABLE1.X_q, CURVE, t_d0_files=["up", "down"])
    assert out.X_d_prime.value == pytest.approx(TABLE1.X_d_prime, rel=0.03)
    assert out.X_d.value == pytest.approx(TABLE1.X_d, rel=0.02)
    assert "referred to each file's field resistance" in out.X_d_prime.note
    as_it_is = on_line(scs, field, t_d0, TABLE1.X_q, CURVE)
    assert as_it_is.X_d_prime.value < 0.85 * TABLE1.X_d_prime and as_it_is.X_d.value > 1.05 * TABLE1.X_d


def test_plateaus_at_one_voltage_do_not_make_the_air_gap_line() -> None:
    """A single plateau (or several at one voltage) agrees with any curve: one at 1.0 pu was taken
    as on the air-gap line, and a saturated unit's T'_d0 was published 10 % short."""
    from phid_ros.sim.effects.magnetic_saturation import saturation_curve, saturation_factor

    a, b = saturation_curve("quadratic", *CURVE)
    v = np.array([1.0, 1.001])
    i = v * (1 + saturation_factor(False, a, b, v)) / 2.5
    base = field_current_base(v, i, None)
    assert not base.determined and "not determined" in base.source


def test_a_build_up_from_standstill_is_one_event_and_gives_t_d0_from_its_own_air_gap_line(tmp_path) -> None:
    """Sister units' black-start build-ups (Zakucac's: 0 to 16 kV in about 7 s under a set-point
    ramp, U_f at the controller's ceiling, the whole open-circuit curve traversed, S(1.0) 0.1):
    cut into a "field step" and a "voltage step" they gave T'_d0 0.36 s and 10.8 s, and a single
    saturated plateau taken for the air-gap line published 9.78 s for 11.0. As one event whose
    linear part is the air-gap line, each unit's T'_d0 comes back within 2 % and its std covers
    it; the two sisters' within their stds of each other's truth."""
    from phid_ros.api import cut_scenarios
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.field.channel_map import load_channel_map
    from phid_ros.io.field.pmu_csv import import_pmu_csv
    from test.io.field.field_sets import build_up_log

    (tmp_path / "map.yaml").write_text(
        "machine: {mva: 160, kv: 16, f_nominal_hz: 50}\ntime: t_s\nchannels:\n"
        "  v_t: {name: Ug_kV, unit: kV_ll}\n  v_f: {name: Uf_V, unit: V}\n  i_fd: {name: If_A, unit: A}\n"
    )
    cmap = load_channel_map(tmp_path / "map.yaml")
    for unit, t_d0, seed in (("A", 11.0, 0), ("B", 11.5, 1)):
        build_up_log(tmp_path / f"{unit}.csv", t_d0, seed=seed)
        write_recording(tmp_path / f"{unit}.mcap", import_pmu_csv([tmp_path / f"{unit}.csv"], cmap))
        cut = cut_scenarios(tmp_path / f"{unit}.mcap")
        [s] = cut.scenarios
        assert s.k_event * s.dt == pytest.approx(5.0, abs=0.2)  # the field's forcing, its window the whole rise
        assert any("had settled: part of it, one event" in p for p in cut.problems) or len(cut.scenarios) == 1
        r = field_circuit(cut.scenarios, None)
        assert r.base.determined and "build-up(s) from standstill traversed" in r.base.source
        assert r.T_d0_prime.identifiable
        assert r.T_d0_prime.value == pytest.approx(t_d0, rel=0.02)
        assert abs(r.T_d0_prime.value - t_d0) <= 3 * r.T_d0_prime.std, (r.T_d0_prime.value, r.T_d0_prime.std)


@pytest.mark.parametrize("rotor", [(0.4, 1.0), (0.2, 2.0), (0.4, 0.3)])
def test_a_build_up_s_line_leaves_out_the_current_the_rotor_s_other_circuits_draw_on_the_way_up(
    tmp_path, rotor
) -> None:
    """On the way up a rising flux drives currents in the rotor's other circuits (dampers, the
    poles' iron) that the field's makes up: I_f runs above the open-circuit curve by tau dV_t/dt
    and dies away onto it at the top (Zakucac's unit A: 855 A at 16 kV on the rise, 795 A three
    seconds later). Taken as it was, the rise's line put that unit's plateau at 16 kV below the
    air-gap line and T'_d0 6 % short (11.15 s published, 11.89 s with the rise's circuits taken
    out). With the circuits fitted beside the line, T'_d0 comes back within 1 % and the circuits'
    tau within 30 %."""
    from phid_ros.api import cut_scenarios
    from phid_ros.ident.field_circuit import build_up_line
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.field.channel_map import load_channel_map
    from phid_ros.io.field.pmu_csv import import_pmu_csv
    from test.io.field.field_sets import build_up_log

    (tmp_path / "map.yaml").write_text(
        "machine: {mva: 160, kv: 16, f_nominal_hz: 50}\ntime: t_s\nchannels:\n"
        "  v_t: {name: Ug_kV, unit: kV_ll}\n  v_f: {name: Uf_V, unit: V}\n  i_fd: {name: If_A, unit: A}\n"
    )
    build_up_log(tmp_path / "A.csv", 11.0, seed=0, rotor_circuit=rotor)
    write_recording(tmp_path / "A.mcap", import_pmu_csv([tmp_path / "A.csv"], load_channel_map(tmp_path / "map.yaml")))
    cut = cut_scenarios(tmp_path / "A.mcap")
    r = field_circuit(cut.scenarios, None)
    assert r.base.determined and r.T_d0_prime.identifiable
    assert r.T_d0_prime.value == pytest.approx(11.0, rel=0.01)
    assert abs(r.T_d0_prime.value - 11.0) <= 3 * r.T_d0_prime.std
    [line] = [b for s in cut.scenarios if (b := build_up_line(s)) is not None]
    assert line.tau == pytest.approx(rotor[0], rel=0.3)
    assert [round(v, 2) for v, _, _ in r.saturation_at_plateaus()] == [1.0]
    assert r.saturation_at_plateaus()[0][1] == pytest.approx(0.1, abs=0.02)  # S(1.0) of the look-alike


def test_a_plateau_below_a_build_up_s_line_leaves_the_base_undetermined() -> None:
    """A static point of the machine below the line its build-up traversed: no open-circuit curve
    allows it (saturation only raises the field current), so the line is not the air-gap line and
    T'_d0 is a bound, never a number."""
    base = field_current_base([1.0], [0.9], None, [(1.0, "build-up")])
    assert not base.determined and "lies 10.0 % below the air-gap line the build-up" in base.source
    assert field_current_base([1.0], [1.05], None, [(1.0, "build-up")]).determined
