"""Physical effects the fourth-order model leaves out, switchable in the plant (off by default).

A small library in the shape of pysindy's candidate terms and ANDES's models: each
effect is one class with its parameter data (defaults, units, realistic ranges)
declared apart from what it does, registered by name, so a new effect is added
without touching the others. An effect acts through a few hooks, each a no-op
by default:

Every hook that acts on the equations reads one typed :class:`RotorContext` (the base states,
the currents, the air-gap flux), and the terms themselves are module functions of plain
arithmetic (:func:`saturation_factor`, :func:`damper_emf`, :func:`damper_drives`,
:func:`shaft_torque`) that the compiled play-in (:mod:`phid_ros.sim.kernel`) compiles as they are:
an effect's equations are written once, here, as the base model's are in ``model/equations``.

- ``configure(plant)``: change plant constants (stator resistance);
- ``transient_losses(states, ctx, params)``: terms subtracted in T'_d0 dE'_q/dt and
  T'_q0 dE'_d/dt (saturation; the damper currents of GENROU's rotor);
- ``on_measurements(measured, dt)``: act on the sensor outputs (a delayed stream).

- ``initial_states`` / ``derivatives``: states of its own after the base four;
- ``emf``: replace the EMF behind the stator reactances (damper windings);
- ``leakage(params)``: the stator leakage reactance X_l the rotor's equations assume.
- ``swing``: replace the rotor's d(omega)/dt (a second mass on the shaft).

Effects: ``stator_resistance``, ``magnetic_saturation``, ``sensor_delay``,
``subtransient_dynamics``, ``shaft_torsion``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.io.topics import STREAMS, STREAMS_BY_NAME
from phid_ros.model.bounds import Bounded
from phid_ros.model.conventions import omega_s
from phid_ros.model.equations import rotor_angle, swing

Array = NDArray[np.float64]
Value = Any  # a float or an array with one entry per simulated column


@dataclass(frozen=True, slots=True)
class RotorContext:
    """What the effects' hooks read at one instant: values of the base model, one per column.

    ``psi_d``, ``psi_q`` are the EMF behind the stator reactances (GENROU's air-gap flux psi'',
    E'_q and E'_d in the fourth-order model). In the steady-state search ``omega`` is 1 and the
    air-gap power is P_m; before the effects' own states exist (their ``initial_states``), the
    flux is the fourth-order one.
    """

    delta: Value
    omega: Value
    e_q: Value
    e_d: Value
    i_d: Value
    i_q: Value
    psi_d: Value
    psi_q: Value
    p_m: Value
    p_airgap: Value
    damping: Value  # D of the generator rotor, per column (0 where a run had none)
    x_l: Value  # the plant's: the stator leakage reactance GENROU's rotor equations assume
    ws: float  # the plant's synchronous speed


@dataclass(frozen=True)
class EffectParameter(Bounded):
    name: str
    default: Any
    unit: str
    description: str
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] = ()
    # the value at which the effect vanishes (a number, or the name of the base parameter it
    # then equals); the diagnosis names an effect only when its estimate is clearly away from it
    absent: float | str | None = None


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
                if (problem := p.outside(v)) is not None:
                    raise SimulationError(f"effect {self.name}: {problem} (realistic range)")
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

    def transient_losses(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Any, Any]:
        """(d, q): subtracted from the right-hand sides of T'_d0 dE'_q/dt and T'_q0 dE'_d/dt.

        Free of side effects: the steady state calls it while it searches the equilibrium.
        """
        return 0.0, 0.0

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

    def initial_states(self, ctx: RotorContext, plant: Any) -> list[float]:
        """Values of this effect's states at the operating point (dx/dt = 0)."""
        return []

    def emf(self, x: Array, states: Array, params: Any) -> tuple[Array, Array, Any, Any]:
        """(psi''_d, psi''_q, X''_d, X''_q) from all states ``x`` and this effect's ``states``."""
        raise SimulationError(f"effect {self.name} does not replace the stator EMF")

    def leakage(self, params: Any) -> Any:
        """X_l, when this effect's equations define it (the EMF owner's is the plant's)."""
        return None

    def swing(self, states: Array, ctx: RotorContext, params: Any) -> Array | None:
        """A replacement for d(omega)/dt of the generator rotor, or None."""
        return None

    def derivatives(self, states: Array, ctx: RotorContext, params: Any) -> list[Array]:
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
    parameters = (EffectParameter("r_a", 0.005, "pu", "stator resistance", 0.001, 0.02, absent=0.0),)

    def configure(self, plant: Any) -> None:
        plant.r_a = self["r_a"]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the plant's r_a, which the kernel reads


def leakage_default(x_pp: Any) -> Any:
    """X_l where none is known: min(0.15, 0.8 X''), the planning default (GENROU needs X_l < X'')."""
    return np.minimum(0.15, 0.8 * np.asarray(x_pp, float))


def saturation_curve(curve: str, s10: Any, s12: Any) -> tuple[Any, Any]:
    """The two constants of S(psi) through S(1.0) = s10 and S(1.2) = s12 (PSS/E's definitions).

    quadratic (GENROU, GENSAL): S = B (psi - A)^2 / psi above A, 0 below;
    exponential (GENROE, GENSAE): S = s10 psi^X with X = ln(s12 / s10) / ln 1.2.
    """
    s10, s12 = np.asarray(s10, float), np.asarray(s12, float)
    if curve == "exponential":
        return s10, np.log(s12 / s10) / np.log(1.2)
    r = np.sqrt(1.2 * s12 / s10)
    a = (1.2 - r) / (1.0 - r)
    return a, s10 / (1.0 - a) ** 2


def saturation_factor(exponential: bool, c1: Value, c2: Value, psi: Value) -> Value:
    """S(psi) for the constants of :func:`saturation_curve` (``exponential``: that curve, else
    the quadratic one)."""
    if exponential:
        return c1 * psi**c2
    over = np.maximum(psi - c1, 0.0)
    return c2 * over * over / psi


def flux_magnitude(psi_d: Value, psi_q: Value) -> Value:
    """|psi''|, on which GENROU saturates."""
    return np.sqrt(psi_d * psi_d + psi_q * psi_q)


def damper_emf(g: Value, e: Value, psi_k: Value) -> Value:
    """One axis of GENROU's air-gap flux: ``psi'' = g E' + (1 - g) psi_k``."""
    return g * e + (1.0 - g) * psi_k


def damper_drives(
    e_q: Value, e_d: Value, psi_kd: Value, psi_kq: Value, i_d: Value, i_q: Value, xdp_l: Value, xqp_l: Value
) -> tuple[Value, Value]:
    """What drives the dampers: ``E'_q - psi_kd - (X'_d - X_l) I_d`` and ``E'_d - psi_kq + (X'_q - X_l) I_q``."""
    return e_q - psi_kd - xdp_l * i_d, e_d - psi_kq + xqp_l * i_q


def shaft_torque(k: Value, d_shaft: Value, delta_t: Value, delta: Value, omega_t: Value, omega: Value) -> Value:
    """The elastic shaft's torque from the turbine to the generator."""
    return k * (delta_t - delta) + d_shaft * (omega_t - omega)


@register
class MagneticSaturation(PlantEffect):
    """Open-circuit saturation as the planning models define it, through S(1.0) and S(1.2).

    ``form=genrou`` (round rotor): on the air-gap flux magnitude |psi''| (the EMF behind the
    stator reactances), both axes: T'_d0 dE'_q/dt gains -S psi''_d and T'_q0 dE'_d/dt gains
    -S psi''_q (X_q - X_l)/(X_d - X_l). ``form=gensal`` (salient pole): on E'_q, d axis only,
    T'_d0 dE'_q/dt gains -S(E'_q) E'_q. ``curve``: quadratic (GENROU/GENSAL) or exponential
    (GENROE/GENSAE), see :func:`saturation_curve`.

    Before this form, phid's saturation was S(1.0) exp(b (E'_q - 1)) E'_q on the d axis: the
    GENSAL form with a curve no planning model uses. On a GENROU machine (ANDES) it explained
    only part of the gap and left X_q 20 % off, because GENROU saturates the q axis too.
    """

    name = "magnetic_saturation"
    parameters = (
        EffectParameter("s10", 0.08, "pu", "saturation factor at 1.0 pu", 0.02, 0.2, absent=0.0),
        EffectParameter("s12", 0.35, "pu", "saturation factor at 1.2 pu", 0.1, 0.8, absent=0.0),
        EffectParameter("form", "genrou", "", "where it acts (planning model)", choices=("genrou", "gensal")),
        EffectParameter(
            "curve", "quadratic", "", "S(psi) through S(1.0), S(1.2)", choices=("quadratic", "exponential")
        ),
    )

    def __init__(self, **values: Any) -> None:
        super().__init__(**values)
        if not self["s12"] > self["s10"]:
            raise SimulationError("effect magnetic_saturation: s12 must exceed s10")

    @cached_property
    def _constants(self) -> tuple[Any, Any]:
        return saturation_curve(self["curve"], self["s10"], self["s12"])

    def factor(self, psi: Any) -> Any:
        return saturation_factor(self["curve"] == "exponential", *self._constants, psi)

    def transient_losses(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Any, Any]:
        if self["form"] == "gensal":
            return self.factor(ctx.e_q) * ctx.e_q, 0.0
        s = self.factor(flux_magnitude(ctx.psi_d, ctx.psi_q))
        return s * ctx.psi_d, s * ctx.psi_q * q_share(params, ctx.x_l)

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        from phid_ros.sim.kernel import SATURATION_FORMS

        c1, c2 = self._constants
        p, x_l = plant.params, plant.x_l
        return {
            "saturation": SATURATION_FORMS[self["form"]],
            "sat_curve": 1.0 if self["curve"] == "exponential" else 0.0,
            "sat_c1": c1,
            "sat_c2": c2,
            "sat_q": q_share(p, x_l),
        }


def q_share(params: Any, x_l: Value) -> Value:
    """GENROU's share of the saturation on the q axis, ``(X_q - X_l)/(X_d - X_l)``."""
    return (params.X_q - x_l) / (params.X_d - x_l)


@register
class SensorDelay(PlantEffect):
    """A fixed latency on one sensor stream (e.g. PMU angles reported late)."""

    name = "sensor_delay"
    parameters = (
        EffectParameter("stream", "pmu", "", "the delayed stream", choices=tuple(s.name for s in STREAMS)),
        EffectParameter("delay_ms", 10.0, "ms", "latency", 1.0, 100.0),
    )

    def on_measurements(self, measured: dict[str, Array], dt: float) -> dict[str, Array]:
        k = int(round(self["delay_ms"] * 1e-3 / dt))  # the simulated latency is whole samples
        out = dict(measured)
        for c in STREAMS_BY_NAME[self["stream"]].channels:
            x = measured[c]
            out[c] = np.concatenate((np.full(k, x[0]), x[:-k])) if k else x
        return out

    def delays(self) -> dict[str, Any]:
        return {c: self["delay_ms"] * 1e-3 for c in STREAMS_BY_NAME[self["stream"]].channels}

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        return {}  # the play-in re-times the measurements; the equations are the plant's


@register
class SubtransientDynamics(PlantEffect):
    """Damper windings as GENROU writes them (PSS/E; ANDES, OpenIPSL): psi_kd, psi_kq behind X''.

    T''_d0 dpsi_kd/dt = E'_q - psi_kd - (X'_d - X_l) I_d
    T''_q0 dpsi_kq/dt = E'_d - psi_kq + (X'_q - X_l) I_q
    psi''_d = g_d E'_q + (1 - g_d) psi_kd,   g_d = (X''_d - X_l)/(X'_d - X_l)   (same for q)
    V_q = psi''_d - X''_d I_d,   V_d = psi''_q + X''_q I_q
    and the damper currents load the transient windings: T'_d0 dE'_q/dt gains
    -(X_d - X'_d)(X'_d - X''_d)/(X'_d - X_l)^2 (E'_q - psi_kd - (X'_d - X_l) I_d), and likewise q.

    Before, phid used the simplified form T''_d0 dE''_q/dt = E'_q - E''_q - (X'_d - X''_d) I_d
    (no load on the field): on ANDES's GENROU the diagnosis then explained the damper transient
    with X'' and T'' 5-20 % off and left T'_q0 24 % off. With X''_q = X'_q the q damper is inert
    (GENSAL's single q winding is then X'_q, T'_q0). X_l is the leakage reactance; unset, it is
    :func:`leakage_default` of X''.
    """

    name = "subtransient_dynamics"
    parameters = (
        EffectParameter("x_dpp", 0.25, "pu", "d-axis subtransient reactance X''_d", 0.12, 0.4, absent="X_d_prime"),
        EffectParameter("x_qpp", 0.30, "pu", "q-axis subtransient reactance X''_q", 0.12, 0.5, absent="X_q_prime"),
        EffectParameter("t_d0pp", 0.03, "s", "d-axis subtransient time constant T''_d0", 0.01, 0.1),
        EffectParameter("t_q0pp", 0.05, "s", "q-axis subtransient time constant T''_q0", 0.01, 0.2),
        EffectParameter("x_l", math.nan, "pu", "stator leakage reactance X_l (unset: min(0.15, 0.8 X''))", 0.05, 0.3),
    )
    state_names = ("psi_kd", "psi_kq")
    provides_emf = True

    def as_dict(self) -> dict[str, Any]:
        # The X_l in force, not the "unset" NaN: a truth file names the machine that was simulated.
        doc = super().as_dict()
        if self.checked:
            doc["x_l"] = float(self.leakage(None))
        return doc

    def leakage(self, params: Any) -> Any:
        x_l = np.asarray(self["x_l"], float)
        rule = leakage_default(np.minimum(self["x_dpp"], self["x_qpp"]))
        return np.where(np.isnan(x_l), rule, x_l)

    def configure(self, plant: Any) -> None:
        p = plant.params
        if self.checked:
            if not (self["x_dpp"] < p.X_d_prime and self["x_qpp"] < p.X_q_prime):
                raise SimulationError("effect subtransient_dynamics: X''_d, X''_q must lie below X'_d, X'_q")
            if not self.leakage(p) < min(self["x_dpp"], self["x_qpp"]):
                raise SimulationError("effect subtransient_dynamics: X_l must lie below X''_d and X''_q")
        self._constants = self._gains(p)

    def _gains(self, p: Any) -> tuple[Any, ...]:
        """Once per plant: X_l, g_d, g_q and the two load factors on the transient windings."""
        x_l = self.leakage(p)
        xdp_l, xqp_l = p.X_d_prime - x_l, p.X_q_prime - x_l
        g_d = (self["x_dpp"] - x_l) / xdp_l
        g_q = (self["x_qpp"] - x_l) / xqp_l
        load_d = (p.X_d - p.X_d_prime) * (p.X_d_prime - self["x_dpp"]) / (xdp_l * xdp_l)
        load_q = (p.X_q - p.X_q_prime) * (p.X_q_prime - self["x_qpp"]) / (xqp_l * xqp_l)
        return x_l, g_d, g_q, load_d, load_q

    def initial_states(self, ctx: RotorContext, plant: Any) -> list[float]:
        # at rest a damper's drive is zero: its flux is the drive that psi_k = 0 would leave
        p, x_l = plant.params, self.leakage(plant.params)
        return list(damper_drives(ctx.e_q, ctx.e_d, 0.0, 0.0, ctx.i_d, ctx.i_q, p.X_d_prime - x_l, p.X_q_prime - x_l))

    def emf(self, x: Array, states: Array, params: Any) -> tuple[Array, Array, Any, Any]:
        _, g_d, g_q, _, _ = self._constants
        return damper_emf(g_d, x[2], states[0]), damper_emf(g_q, x[3], states[1]), self["x_dpp"], self["x_qpp"]

    def _drives(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Array, Array]:
        x_l = self._constants[0]
        return damper_drives(
            ctx.e_q, ctx.e_d, states[0], states[1], ctx.i_d, ctx.i_q, params.X_d_prime - x_l, params.X_q_prime - x_l
        )

    def transient_losses(self, states: Array, ctx: RotorContext, params: Any) -> tuple[Any, Any]:
        d, q = self._drives(states, ctx, params)
        _, _, _, load_d, load_q = self._constants
        return load_d * d, load_q * q

    def derivatives(self, states: Array, ctx: RotorContext, params: Any) -> list[Array]:
        d, q = self._drives(states, ctx, params)
        return [d / self["t_d0pp"], q / self["t_q0pp"]]

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        x_l, g_d, g_q, load_d, load_q = self._constants
        p = plant.params
        terms = {k: self[k] for k in ("x_dpp", "x_qpp", "t_d0pp", "t_q0pp")}
        return {
            "subtransient": True,
            **terms,
            "xdp_l": p.X_d_prime - x_l,
            "xqp_l": p.X_q_prime - x_l,
            "g_d": g_d,
            "g_q": g_q,
            "load_d": load_d,
            "load_q": load_q,
        }


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

    def initial_states(self, ctx: RotorContext, plant: Any) -> list[float]:
        _, _, k = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))
        return [ctx.delta + ctx.p_m / k, 1.0]

    def configure(self, plant: Any) -> None:
        self._constants = self._stiffness(plant.params, omega_s(plant.f_nominal_hz))

    def _torque(self, states: Array, ctx: RotorContext) -> Array:
        k = self._constants[2]  # the plant's: its parameters do not change while it runs
        return shaft_torque(k, self["d_shaft"], states[0], ctx.delta, states[1], ctx.omega)

    def swing(self, states: Array, ctx: RotorContext, params: Any) -> Array:
        # (6) for the generator's mass alone, driven by the shaft instead of P_m
        h_g = self._constants[1]
        return swing(self._torque(states, ctx), ctx.p_airgap, ctx.omega, ctx.damping, 1.0 / (2 * h_g))

    def kernel_terms(self, plant: Any) -> dict[str, Any]:
        h_t, h_g, k = self._constants
        terms = {"inv_2h_t": 1.0 / (2 * h_t), "inv_2h_g": 1.0 / (2 * h_g), "k_shaft": k, "d_shaft": self["d_shaft"]}
        return {"torsion": True, **terms}

    def derivatives(self, states: Array, ctx: RotorContext, params: Any) -> list[Array]:
        # (5) and (6) for the turbine's mass: P_m in, the shaft's torque out, no damping of its own
        h_t = self._constants[0]
        omega_t = states[1]
        return [rotor_angle(omega_t, ctx.ws), swing(ctx.p_m, self._torque(states, ctx), omega_t, 0.0, 1.0 / (2 * h_t))]


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
