"""What every effect is made of: its parameters' declaration, the hooks it acts through, the
context they read, its compiled terms, and the registry that names it.

An effect is one module of :mod:`phid_ros.sim.effects` (see its text): a subclass of
:class:`PlantEffect` decorated with :func:`register`. It acts through hooks, each a no-op by default:

- ``configure(plant)``: change plant constants (stator resistance);
- ``transient_losses(states, ctx, params)``: terms subtracted in T'_d0 dE'_q/dt and
  T'_q0 dE'_d/dt (saturation; the damper currents of GENROU's rotor);
- ``on_measurements(measured, dt)``: act on the sensor outputs (a delayed stream);
- ``initial_states`` / ``derivatives``: states of its own after the base four;
- ``emf``: replace the EMF behind the stator reactances (damper windings);
- ``leakage(params)``: the stator leakage reactance X_l the rotor's equations assume;
- ``swing``: replace the rotor's d(omega)/dt (a second mass on the shaft).

Every hook that acts on the equations reads one typed :class:`RotorContext` (the base states,
the currents, the air-gap flux), and the terms themselves are module functions of plain
arithmetic that the same effect's :class:`Compiled` functions call too: an effect's equations
are written once, in its module, as the base model's are in ``model/equations``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.model.bounds import Bounded

Array = NDArray[np.float64]
Value = Any  # a float or an array with one entry per simulated column


@dataclass(frozen=True)
class Compiled:
    """An effect's equations as the compiled play-in (:mod:`phid_ros.sim.kernel`) calls them, per column.

    Plain functions that numba compiles as they are written (they call the effect's term
    functions through :func:`phid_ros.jit.maybe_jit` copies), each optional:

    - ``emf(x, coef, c, r, at) -> (psi_d, psi_q, X_d, X_q)``: the EMF behind the stator
      reactances, and those reactances, in place of E'_q, E'_d, X'_d, X'_q;
    - ``losses(x, out, coef, c, r, at, psi_d, psi_q, i_d, i_q) -> (loss_d, loss_q)``: terms
      subtracted in T'_d0 dE'_q/dt and T'_q0 dE'_d/dt;
    - ``swing(x, out, coef, c, r, at, p_m, p_airgap, damping, ws) -> d(omega)/dt``: in place
      of the rotor's.

    ``x`` is the column's state vector, ``coef[r + i, c]`` the column's value of ``rows[i]``
    (:meth:`PlantEffect.kernel_terms` names them), ``at`` the effect's
    :meth:`PlantEffect.kernel_setting`; ``losses`` and ``swing`` write the derivatives of the
    effect's own states into ``out`` from index ``at``. The kernel calls every effect's
    ``emf`` first, then the stator, then the ``losses`` in the registry's order, then the
    field equations and the ``swing``: the order of the numpy plant's hooks.
    """

    rows: tuple[str, ...] = ()
    emf: Callable[..., tuple[float, float, float, float]] | None = None
    losses: Callable[..., tuple[float, float]] | None = None
    swing: Callable[..., float] | None = None


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
    compiled: ClassVar[Compiled | None] = None  # its equations for the compiled play-in, if it has any
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
        """This effect's coefficients for the compiled play-in (:mod:`phid_ros.sim.kernel`), by the
        names of its ``compiled.rows``; None: the numpy plant runs instead.

        An effect that only configures the plant or re-times sensors returns ``{}``.
        """
        return None

    def kernel_setting(self, plant: Any, slot: slice) -> int:
        """The integer the compiled functions receive as ``at`` (0 or more): the index of this
        effect's first state where it has states (``slot``: its states' place in the plant's)."""
        return slot.start if self.state_names else 0

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


def leakage_default(x_pp: Any) -> Any:
    """X_l where none is known: min(0.15, 0.8 X''), the planning default (GENROU needs X_l < X'')."""
    return np.minimum(0.15, 0.8 * np.asarray(x_pp, float))


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
