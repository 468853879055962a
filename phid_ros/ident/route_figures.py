"""What the routes of a recorder's channels found beside their estimates, as typed records.

Each route of :mod:`phid_ros.ident.determinable` that has figures of its own (the no-load tests'
field gain, the field circuit's events and plateaus, the on-line events, the steady points, the
q axis the d axis chose) returns them as one of these; the identification keeps them under the
route's key (``IdentificationResult.route_details``), the day's table and the controls read
their fields, and :meth:`as_dict` writes them where the JSON has them (``stages``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Protocol

from phid_ros.ident.field_circuit import FieldCircuitResult, FieldResistance
from phid_ros.ident.open_circuit import OpenCircuitResult
from phid_ros.ident.open_circuit_curve import OpenCircuitCurve
from phid_ros.ident.terminal import QAxisSearch, SteadyReactances


class RouteFigures(Protocol):
    def as_dict(self) -> dict[str, Any]: ...


@dataclass(frozen=True)
class OpenCircuitFigures:
    """No-load field steps: V_t following E_fd through T'_d0."""

    result: OpenCircuitResult

    @property
    def field_gain(self) -> float:
        """V_t per unit E_fd at no load: 1 on the air-gap line."""
        return self.result.field_gain

    def as_dict(self) -> dict[str, Any]:
        o = self.result
        return {
            "T_d0_prime": o.T_d0_prime.value,
            "T_d0_prime_std": o.T_d0_prime.std,
            "field_gain": o.field_gain,
            "scenarios": o.scenarios,
            "rms_pu": o.rms_pu,
        }


@dataclass(frozen=True)
class FieldCircuitFigures:
    """No-load events through the field circuit, with the open-circuit curve where the plateaus give one."""

    result: FieldCircuitResult
    curve: OpenCircuitCurve | None = None

    def t_d0_by_scenario(self) -> dict[str, float]:
        """Each event's T'_d0 on the field current's base, by its scenario's name."""
        f = self.result
        return {e.scenario: f.base.scale * e.time_per_base for e in f.events}

    @property
    def T_d0_prime(self) -> float:
        return self.result.T_d0_prime.value

    def as_dict(self) -> dict[str, Any]:
        f = self.result
        out: dict[str, Any] = {
            "T_d0_prime": f.T_d0_prime.value,
            "T_d0_prime_std": f.T_d0_prime.std,
            "field_current_base": f.base.scale,  # X_ad I_fd per unit of the recorded I_f (a bound if not determined)
            "field_current_base_determined": f.base.determined,
            "field_current_base_source": f.base.source,
            "events": [
                {
                    "scenario": e.scenario,
                    "delta_v": e.delta_v,
                    "k_e": e.k_e,
                    "T_d0_prime": f.base.scale * e.time_per_base,
                }
                for e in f.events
            ],
            "plateaus": [{"v_t": v, "i_fd": i, "scenario": n} for v, i, n in f.plateaus],
            # the open-circuit curve's measured points on that base (empty where it is not determined)
            "saturation_at_plateaus": [{"v_t": v, "S": s, "scenario": n} for v, s, n in f.saturation_at_plateaus()],
            "build_ups": [
                {
                    "scenario": b.scenario,
                    "air_gap_line": b.c,  # V_t per unit of the recorded I_f
                    "air_gap_line_rel_std": b.rel_std,
                    "rotor_circuits_tau_s": b.tau,
                    "rotor_circuits_t_s": b.t_k,
                }
                for b in f.build_ups
            ],
        }
        if f.leakage is not None:  # the field's leakage flux: the test files' T'_d0 against their dI/dV
            lk = f.leakage
            out["leakage"] = {
                "files": [{"file": n, "field_current_per_volt": r, "T_d0_prime": t} for n, r, t in lk.per_volt],
                "T_leakage": lk.leakage,
                "T_leakage_std": lk.leakage_std,
                "T_d0_prime_unsaturated": lk.unsaturated,
                "T_d0_prime_unsaturated_std": lk.unsaturated_std,
                "shows": lk.shows,
            }
        if self.curve is not None:
            out["open_circuit_curve"] = self.curve.as_dict()
        return out


@dataclass(frozen=True)
class FieldCircuitOnlineFigures:
    """The field circuit on line: each event's X_d and X'_d, and how the field current's base was found."""

    events: list[dict[str, float | str]]
    field_base_note: str

    def by_scenario(self) -> dict[str, dict[str, float | str]]:
        return {str(e["scenario"]): e for e in self.events}

    def as_dict(self) -> dict[str, Any]:
        return {"events": self.events, "field_base_note": self.field_base_note}


@dataclass(frozen=True)
class SteadyTerminalFigures:
    """X_d from the steady states of V_t, P, Q, E_fd: the X_q they put the rotor angle at."""

    result: SteadyReactances

    def as_dict(self) -> dict[str, Any]:
        st = self.result
        return {"X_q_used": st.X_q.value, "rms_pu": st.rms_pu, "steady_points": [pt.__dict__ for pt in st.points]}


@dataclass(frozen=True)
class QAxisSearchFigures:
    """The q axis (X'_q, T'_q0; None: at rest) the d axis's residual chose for the rotor angle's reconstruction."""

    search: QAxisSearch

    @property
    def q_transient(self) -> tuple[float, float] | None:
        return self.search.q_transient

    def as_dict(self) -> dict[str, Any]:
        q, s = self.search.q_transient, self.search
        return {
            "X_q_prime": None if q is None else q[0],
            "T_q0_prime": None if q is None else q[1],
            "sse": s.sse,
            "sse_at_rest": s.sse_at_rest,
            "evaluations": s.evaluations,
        }


@dataclass(frozen=True)
class FieldResistanceFigures:
    """The field winding's resistance, merged over the recordings that give it (see ``api.field_resistance_of``)."""

    resistance: FieldResistance
    left_out: list[str] = field(default_factory=list)  # files in the recorder's per unit beside files in ohms

    def as_dict(self) -> dict[str, Any]:
        out = self.resistance.as_dict()
        if self.left_out:
            out["left_out"] = self.left_out
        return out
