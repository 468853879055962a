"""Physical effects the fourth-order model leaves out, switchable in the plant (off by default).

A small library in the shape of pysindy's candidate terms and ANDES's models: each
effect is one class with its parameter data (defaults, units, realistic ranges)
declared apart from what it does, registered by name, so a new effect is added
without touching the others. An effect acts through a few hooks, each a no-op
by default:

- ``configure(plant)``: change plant constants (stator resistance);
- ``flux_loss_d(e_q)``: an extra term subtracted in T'_d0 dE'_q/dt (saturation);
- ``on_measurements(measured, dt)``: act on the sensor outputs (a delayed stream).

- ``initial_states`` / ``derivatives``: states of its own after the base four;
- ``emf``: replace the EMF behind the stator reactances (damper windings);
- ``swing``: replace the rotor's d(omega)/dt (a second mass on the shaft).

Effects: ``stator_resistance``, ``magnetic_saturation``, ``sensor_delay``,
``subtransient_dynamics``, ``shaft_torsion``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.model.conventions import omega_s

Array = NDArray[np.float64]


@dataclass(frozen=True)
class EffectParameter:
    name: str
    default: Any
    unit: str
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()


class PlantEffect:
    """Base class: parameter handling and no-op hooks."""

    name: ClassVar[str] = ""
    parameters: ClassVar[tuple[EffectParameter, ...]] = ()
    state_names: ClassVar[tuple[str, ...]] = ()  # states this effect adds after the base four
    provides_emf: ClassVar[bool] = False  # replaces the EMF behind the stator reactances
    checked: bool = True  # False for a fitter's trial instance: its values are not user input

    def __init__(self, **values: Any) -> None:
        known = {p.name: p for p in self.parameters}
        unknown = sorted(set(values) - set(known))
        if unknown:
            raise SimulationError(f"effect {self.name}: unknown parameter(s) {unknown}; known: {sorted(known)}")
        self.values: dict[str, Any] = {}
        for p in self.parameters:
            v = values.get(p.name, p.default)
            if p.choices:
                if v not in p.choices:
                    raise SimulationError(f"effect {self.name}: {p.name}={v!r} not one of {p.choices}")
            else:
                v = float(v)
                if (p.low is not None and v < p.low) or (p.high is not None and v > p.high):
                    raise SimulationError(
                        f"effect {self.name}: {p.name}={v:g} {p.unit} outside [{p.low:g}, {p.high:g}] (realistic range)"
                    )
            self.values[p.name] = v

    @classmethod
    def from_arrays(cls, **values: Any) -> PlantEffect:
        """An instance whose parameters may be arrays (one value per simulated column), unchecked.

        The diagnosis fits a candidate by simulating many parameter sets side by side; the
        range checks of ``__init__`` are for user input, the fitter keeps to the bounds itself.
        """
        self = cls.__new__(cls)
        self.values = {p.name: values.get(p.name, p.default) for p in cls.parameters}
        self.checked = False
        return self

    def __getitem__(self, key: str) -> Any:
        return self.values[key]

    def as_dict(self) -> dict[str, Any]:
        return {"name": self.name, **self.values}

    # hooks ---------------------------------------------------------------------------------
    def configure(self, plant: Any) -> None:
        return None

    def flux_loss_d(self, e_q: Array) -> Array | float:
        return 0.0

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        return measured

    def delays(self) -> dict[str, Any]:
        """Channel -> latency (s) with which this effect makes that channel's sensor report."""
        return {}

    def kernel_terms(self, plant: Any) -> dict[str, Any] | None:
        """This effect's terms for the compiled play-in (phid_ros.sim.kernel), or None: numpy runs.

        An effect that only configures the plant or re-times sensors returns ``{}``; one with
        equations names its kernel flag and coefficients, and the kernel writes them out.
        """
        return None

    def initial_states(self, ctx: dict[str, Any], plant: Any) -> list[float]:
        """Values of this effect's states at the operating point (dx/dt = 0)."""
        return []

    def emf(self, states: Array, params: Any) -> tuple[Array, Array, float, float]:
        raise SimulationError(f"effect {self.name} does not replace the stator EMF")

    def swing(self, states: Array, ctx: dict[str, Any], params: Any) -> Array | None:
        """A replacement for d(omega)/dt of the generator rotor, or None."""
        return None

    def derivatives(self, states: Array, ctx: dict[str, Any], params: Any) -> list[Array]:
        """d/dt of this effect's states."""
        return []


REGISTRY: dict[str, type[PlantEffect]] = {}


def register(cls: type[PlantEffect]) -> type[PlantEffect]:
    REGISTRY[cls.name] = cls
    return cls


@register
class StatorResistance(PlantEffect):
    """Armature resistance R_a (the base model has R_a = 0)."""

    name = "stator_resistance"
    parameters = (EffectParameter("r_a", 0.005, "pu", "stator resistance", 0.001, 0.02),)

    def configure(self, plant: Any) -> None:
        plant.r_a = self["r_a"]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the plant's r_a, which the kernel reads


@register
class MagneticSaturation(PlantEffect):
    """Open-circuit saturation of the d axis: T'_d0 dE'_q/dt gains -S_E(E'_q) E'_q.

    S_E(E) = A exp(B E), fitted through the usual two points S(1.0) and S(1.2).
    """

    name = "magnetic_saturation"
    parameters = (
        EffectParameter("s10", 0.08, "pu", "saturation factor at 1.0 pu", 0.02, 0.2),
        EffectParameter("s12", 0.35, "pu", "saturation factor at 1.2 pu", 0.1, 0.8),
    )

    def __init__(self, **values: Any) -> None:
        super().__init__(**values)
        if not self["s12"] > self["s10"]:
            raise SimulationError("effect magnetic_saturation: s12 must exceed s10")

    @cached_property
    def _exponent(self) -> Any:
        return np.log(self["s12"] / self["s10"]) / 0.2

    def flux_loss_d(self, e_q: Array) -> Array:
        return self["s10"] * np.exp(self._exponent * (e_q - 1.0)) * e_q

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {"saturation": True, "s10": self["s10"], "sat_b": self._exponent}


@register
class SensorDelay(PlantEffect):
    """A fixed latency on one sensor stream (e.g. PMU angles reported late)."""

    name = "sensor_delay"
    parameters = (
        EffectParameter("stream", "pmu", "", "the delayed stream", choices=("pt_ct", "encoder", "pmu", "excitation")),
        EffectParameter("delay_ms", 10.0, "ms", "latency", 1.0, 100.0),
    )

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        from phid_ros.io.topics import STREAMS_BY_NAME

        k = int(round(self["delay_ms"] * 1e-3 / dt))  # the simulated latency is whole samples
        out = dict(measured)
        for c in STREAMS_BY_NAME[self["stream"]].channels:
            x = measured[c]
            out[c] = np.concatenate((np.full(k, x[0]), x[:-k])) if k else x
        return out

    def delays(self) -> dict[str, Any]:
        from phid_ros.io.topics import STREAMS_BY_NAME

        return {c: self["delay_ms"] * 1e-3 for c in STREAMS_BY_NAME[self["stream"]].channels}

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the play-in re-times the measurements; the equations are the plant's


@register
class SubtransientDynamics(PlantEffect):
    """Damper windings: two more flux states behind the subtransient reactances (sixth order).

    T''_d0 dE''_q/dt = E'_q - E''_q - (X'_d - X''_d) I_d
    T''_q0 dE''_d/dt = E'_d - E''_d + (X'_q - X''_q) I_q
    V_q = E''_q - X''_d I_d,   V_d = E''_d + X''_q I_q
    """

    name = "subtransient_dynamics"
    parameters = (
        EffectParameter("x_dpp", 0.25, "pu", "d-axis subtransient reactance X''_d", 0.12, 0.4),
        EffectParameter("x_qpp", 0.30, "pu", "q-axis subtransient reactance X''_q", 0.12, 0.5),
        EffectParameter("t_d0pp", 0.03, "s", "d-axis subtransient time constant T''_d0", 0.01, 0.1),
        EffectParameter("t_q0pp", 0.05, "s", "q-axis subtransient time constant T''_q0", 0.01, 0.2),
    )
    state_names = ("e_q_pp", "e_d_pp")
    provides_emf = True

    def configure(self, plant: Any) -> None:
        p = plant.params
        if self.checked and not (self["x_dpp"] < p.X_d_prime and self["x_qpp"] < p.X_q_prime):
            raise SimulationError("effect subtransient_dynamics: X''_d, X''_q must lie below X'_d, X'_q")

    def initial_states(self, ctx: dict[str, Any], plant: Any) -> list[float]:
        p = plant.params
        return [
            ctx["e_q"] - (p.X_d_prime - self["x_dpp"]) * ctx["i_d"],
            ctx["e_d"] + (p.X_q_prime - self["x_qpp"]) * ctx["i_q"],
        ]

    def emf(self, states: Array, params: Any) -> tuple[Array, Array, float, float]:
        return states[0], states[1], self["x_dpp"], self["x_qpp"]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {"subtransient": True, **{k: self[k] for k in ("x_dpp", "x_qpp", "t_d0pp", "t_q0pp")}}

    def derivatives(self, states: Array, ctx: dict[str, Any], params: Any) -> list[Array]:
        e_qpp, e_dpp = states[0], states[1]
        return [
            (ctx["e_q"] - e_qpp - (params.X_d_prime - self["x_dpp"]) * ctx["i_d"]) / self["t_d0pp"],
            (ctx["e_d"] - e_dpp + (params.X_q_prime - self["x_qpp"]) * ctx["i_q"]) / self["t_q0pp"],
        ]


@register
class ShaftTorsion(PlantEffect):
    """Turbine and generator as two masses on an elastic shaft (one torsional mode).

    H splits into H_t = f H (turbine) and H_g = (1 - f) H (generator); the stiffness K
    follows from the torsional frequency; P_m acts on the turbine; the encoder sees the
    generator rotor.
    """

    name = "shaft_torsion"
    parameters = (
        EffectParameter("turbine_fraction", 0.6, "", "share of the inertia in the turbine", 0.3, 0.85),
        EffectParameter("f_torsion_hz", 15.0, "Hz", "torsional mode frequency", 5.0, 40.0),
        EffectParameter("d_shaft", 0.5, "pu", "damping across the shaft", 0.0, 5.0),
    )
    state_names = ("delta_t", "omega_t")

    def _stiffness(self, params: Any, ws: float) -> tuple[Any, Any, Any]:
        h_t = self["turbine_fraction"] * params.H
        h_g = params.H - h_t
        k = (2 * np.pi * self["f_torsion_hz"]) ** 2 / (ws * (1 / (2 * h_t) + 1 / (2 * h_g)))
        return h_t, h_g, k

    def initial_states(self, ctx: dict[str, Any], plant: Any) -> list[float]:
        _, _, k = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))
        return [ctx["delta"] + ctx["p_m"] / k, 1.0]

    def configure(self, plant: Any) -> None:
        self._constants = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))

    def _shaft(self, states: Array, ctx: dict[str, Any], params: Any) -> tuple[Array, float, float]:
        h_t, h_g, k = self._constants  # the plant's: its parameters do not change while it runs
        torque = k * (states[0] - ctx["delta"]) + self["d_shaft"] * (states[1] - ctx["omega"])
        return torque, h_t, h_g

    def swing(self, states: Array, ctx: dict[str, Any], params: Any) -> Array:
        torque, _, h_g = self._shaft(states, ctx, params)
        return (torque - ctx["p_airgap"] - ctx["damping"] * (ctx["omega"] - 1.0)) / (2 * h_g)

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        h_t, h_g, k = self._constants
        return {"torsion": True, "h_t": h_t, "h_g": h_g, "k_shaft": k, "d_shaft": self["d_shaft"]}

    def derivatives(self, states: Array, ctx: dict[str, Any], params: Any) -> list[Array]:
        torque, h_t, _ = self._shaft(states, ctx, params)
        return [ctx["ws"] * (states[1] - 1.0), (ctx["p_m"] - torque) / (2 * h_t)]


def parse_effect(spec: str) -> PlantEffect:
    """``NAME`` or ``NAME=k=v,k=v`` (the ``phid simulate --effect`` syntax) -> an effect."""
    name, _, rest = spec.partition("=")
    cls = REGISTRY.get(name.strip())
    if cls is None:
        raise SimulationError(f"unknown effect {name.strip()!r}; available: {', '.join(sorted(REGISTRY))}")
    values: dict[str, Any] = {}
    for item in filter(None, (s.strip() for s in rest.split(","))):
        key, sep, value = item.partition("=")
        if not sep:
            raise SimulationError(f"effect {name}: {item!r} is not key=value")
        values[key.strip()] = value.strip()
    return cls(**values)


def effects_summary(effects: Mapping[str, PlantEffect] | list[PlantEffect]) -> list[dict[str, Any]]:
    items = effects.values() if isinstance(effects, Mapping) else effects
    return [e.as_dict() for e in items]
