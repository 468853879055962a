"""What each test of a recorded day gave: the table a plant engineer hands over beside the numbers.

One row per event (a test file's step, its return, a de-excitation): the test, where in the file,
the machine's state (no load or on line), who held the field (the AVR, a manual field-current
regulator, nobody in a de-excitation), and what phid took from it: T'_d0 from the field circuit
at no load, X'_d and X_d from it on line, the exciter's reference step, the stabiliser's output,
and the event's own validation against the identified model.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from phid_ros.controls.cases import recorded_set_point, regulator_out_of_loop, switched_on
from phid_ros.controls.fit import ControlFit
from phid_ros.ident.pipeline import IdentificationResult
from phid_ros.ident.route_figures import FieldCircuitFigures, FieldCircuitOnlineFigures
from phid_ros.ident.scenario import ScenarioData, file_of
from phid_ros.ident.terminal import at_no_load

HEADERS = ["test", "event (s)", "kind", "state", "field held by", "what it gave"]


@dataclass
class TestRow:
    test: str
    event_s: float
    kind: str
    state: str
    held_by: str
    gave: list[str]

    def cells(self) -> list[str]:
        return [self.test, f"{self.event_s:.1f}", self.kind, self.state, self.held_by, "; ".join(self.gave) or "—"]


def _held_by(s: ScenarioData) -> str:
    why = regulator_out_of_loop(s)
    if why is None:
        return "AVR"
    return "manual (I_f regulator)" if s.regulator == "manual" else "nobody (de-excitation)"


def _event_time(s: ScenarioData) -> float:
    """The event's time in its test file, or in its window where it was not cut from a file."""
    return s.k_event * s.dt if s.file_time_s is None else s.file_time_s


def day_summary(res: IdentificationResult, controls: Mapping[str, ControlFit | str] | None = None) -> list[TestRow]:
    """A row for each scenario identify was given, in their order."""
    no_load, online = res.route_details.get("field_circuit"), res.route_details.get("field_circuit_online")
    t_d0 = no_load.t_d0_by_scenario() if isinstance(no_load, FieldCircuitFigures) else {}
    on_line = online.by_scenario() if isinstance(online, FieldCircuitOnlineFigures) else {}
    exciter = (controls or {}).get("exciter")
    references = exciter.references if isinstance(exciter, ControlFit) else {}
    checked = {m.scenario: m for m in res.validation.scenarios} if res.validation else {}
    rows = []
    for s in res.scenarios:
        gave = []
        if s.name in t_d0:
            gave.append(f"T'_d0 {t_d0[s.name]:.3g} s (field circuit)")
        if s.name in on_line:
            e = on_line[s.name]
            gave.append(f"X'_d {float(e['X_d_prime']):.3g}, X_d {float(e['X_d']):.3g} (field circuit on line)")
        if s.name in references and recorded_set_point(s) is not None:
            gave.append("exciter: the recorded set-point")
        elif s.name in references:
            gave.append(f"exciter: reference step {references[s.name]:+.3g}")
        if s.has("v_s") and switched_on(s) is not None:
            gave.append("stabiliser output (on)")
        if s.role == "validate":
            gave.append("held out for validation")
        if s.name in checked:
            m = checked[s.name]
            gave.append(f"validation max |ΔQ| {m.max_dq:.3f} pu ({'pass' if m.mod026_pass else 'FAIL'})")
        state = "no load" if at_no_load(s) else "on line"
        rows.append(TestRow(file_of(s), _event_time(s), s.kind, state, _held_by(s), gave))
    return rows
