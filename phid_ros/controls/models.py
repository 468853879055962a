"""Excitation systems and turbine-governors as PSS/E defines them: their data apart from their equations.

Each model declares its parameters once (PSS/E's name, unit, range, meaning) and its
small-signal path: the response of its output deviation to its input deviations from rest, the
blocks of PSS/E's diagram with the limits left out. A limit is a parameter the recordings
determine only where the output reached it; identification reports it as not determined
otherwise (:mod:`phid_ros.controls.identify`). A new model is one class here, registered; the
identification and the JSON take every registered model of a kind as a candidate.

Blocks (Tustin-free: each first-order lag is :func:`phid_ros.numerics.first_order_response`,
exact for inputs linear between samples):
``lag(T)`` = 1/(1 + sT); ``lead_lag(T_lead, T_lag)`` = (1 + sT_lead)/(1 + sT_lag)
= T_lead/T_lag + (1 - T_lead/T_lag) lag(T_lag). A model with a feedback loop (a rate feedback
around the regulator, the droop around a hydro governor's PI) is its closed loop's transfer
function, :func:`transfer`, discretised with the same first-order hold.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import ClassVar

import numpy as np
from numpy.typing import NDArray

from phid_ros.jit import jit_on_first_call
from phid_ros.model.bounds import Bounded
from phid_ros.numerics import first_order_coefficients, first_order_response

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ControlParameter(Bounded):
    """One constant of a control model's PSS/E record; ``low``..``high`` is the fit's search range
    (the shared range check, :class:`~phid_ros.model.bounds.Bounded`)."""

    name: str  # PSS/E's
    unit: str
    default: float
    low: float
    high: float
    meaning: str
    limit: bool = False  # an output or state limit: determined only where the data reached it
    absent: float | None = None  # the value at which its term vanishes (a turbine damping of 0)
    within: str | None = None  # the constant whose term this one belongs to: moot where that one is absent
    held: bool = False  # not fitted: the model's structure holds it at its default (a stage left out)

    def record_problem(self, value: float) -> str | None:
        """What makes a record's value one the simulation cannot take, or None. Not the fit's
        search range: a published record carries what its fit found (ESST5B T_B2 = 5.1 ms), and
        the play-in integrates any positive time constant exactly (first-order hold)."""
        if not math.isfinite(value):
            return "is not a number"
        if self.unit == "s" and value < 0:
            return "is a negative time constant"
        return None


@dataclass(frozen=True)
class ControlInputs:
    """One scenario's deviations from its pre-event steady state, on its sample grid."""

    dt: float
    v_t: Array  # terminal voltage deviation, pu
    speed: Array  # rotor speed deviation, pu
    # the unit step at the scenario's reference change (zeros if none), or the recorded set-point's
    # deviation, played with a reference of 1 (:func:`phid_ros.controls.cases.recorded_set_point`)
    reference_step: Array
    p_m0: float = float("nan")  # mechanical power before the event, pu (a hydro turbine's operating point)
    p_e: Array | None = None  # electrical power deviation, pu (a stabiliser's input), where recorded
    v_s: Array | None = None  # a stabiliser's output deviation, pu, where recorded (joins the regulator's error)


def regulator_error(x: ControlInputs, reference: float, sensed: Array) -> Array:
    """An exciter's error at its summing point, IEEE 421.5's V_REF - V_C + V_S: the reference step,
    the sensed terminal voltage and, where recorded, the stabiliser's output."""
    e = reference * x.reference_step - sensed
    return e if x.v_s is None else e + x.v_s


def lag(u: Array, tau: float, dt: float) -> Array:
    """1/(1 + s tau) from rest; a vanishing tau is a wire."""
    return u if tau <= 1e-6 else first_order_response(u, tau, dt)


def transfer(u: Array, num: Sequence[float] | np.ndarray, den: Sequence[float] | np.ndarray, dt: float) -> Array:
    """num(s)/den(s) (coefficients from the highest power) from rest, for inputs linear between
    samples (first-order hold, as :func:`lag`)."""
    from scipy.signal import lfilter

    direct, modes = _discrete_modes(tuple(map(float, num)), tuple(map(float, den)), float(dt))
    y = np.asarray(direct * u, dtype=np.complex128)
    for lam_i, g_in, g_out in modes:
        y += g_out * lfilter([0.0, g_in], [1.0, -lam_i], u)
    return np.ascontiguousarray(y.real)


@lru_cache(maxsize=256)
def _discrete_modes(
    num: tuple[float, ...], den: tuple[float, ...], dt: float
) -> tuple[float, tuple[tuple[complex, complex, complex], ...]]:
    """The first-order-hold discretisation of num/den, mode by mode: the direct gain and each
    mode's (pole, input gain, output gain). Cached: a fit's scenarios share one step."""
    from scipy.signal import cont2discrete, tf2ss

    # mode by mode: a direct-form polynomial of degree four in z with poles near 1 (time
    # constants of seconds at 1 ms) rounds its response into noise a finite-difference Jacobian
    # takes for slopes (1e-5 of the output; a hydro governor's fit stalled at its start), and so
    # did second-order sections through the discrete zeros; each mode is a first-order recursion
    ad, bd, cd, dd, _ = cont2discrete(tf2ss(np.asarray(num), np.asarray(den)), dt, method="foh")
    lam, vec = np.linalg.eig(ad)
    gain_in = np.linalg.solve(vec, bd[:, 0])
    gain_out = cd[0] @ vec
    return float(dd[0, 0]), tuple((complex(a), complex(b), complex(c)) for a, b, c in zip(lam, gain_in, gain_out))


def first_order(t: float) -> NDArray[np.float64]:
    """1 + sT as a polynomial in s."""
    return np.array([t, 1.0])


# The transfer functions' polynomials, cached on their constants: a fit plays every case with the
# same constants, and numpy's polymul (poly1d, trim_zeros) took a quarter of the exciter search
# on 30 polled steps; the same operations, so the same coefficients.
@lru_cache(maxsize=256)
def _exst1_transfer(
    ta: float, tb: float, tc: float, tf: float, ka: float, kf: float
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    # E/e = K_A (1 + sT_C)(1 + sT_F) / [(1 + sT_A)(1 + sT_B)(1 + sT_F) + K_A K_F s (1 + sT_C)]
    loop = np.polymul(np.polymul(first_order(ta), first_order(tb)), first_order(tf))
    den = np.polyadd(loop, ka * kf * np.polymul([1.0, 0.0], first_order(tc)))
    num = ka * np.polymul(first_order(tc), first_order(tf))
    return tuple(map(float, num)), tuple(map(float, den))  # a cached value, never an array to change


@lru_cache(maxsize=256)
def _ieeet1_transfer(
    ta: float, te: float, ke: float, tf: float, ka: float, kf: float
) -> tuple[tuple[float, ...], tuple[float, ...]]:
    # E/e = K_A (1 + sT_F) / [(1 + sT_A)(K_E + sT_E)(1 + sT_F) + K_A K_F s]
    loop = np.polymul(np.polymul(first_order(ta), [te, ke]), first_order(tf))
    den = np.polyadd(loop, [ka * kf, 0.0])
    num = ka * first_order(tf)
    return tuple(map(float, num)), tuple(map(float, den))


class LimitsError(ValueError):
    """A record's limits that cannot hold the recorded operating point: not simulated."""


@dataclass(frozen=True)
class OperatingLevels:
    """Where an exciter and the machine stood before the event: what its limits are measured
    against (a static exciter's ceiling is proportional to V_T and lowered by K_C I_FD)."""

    v_t: Array  # the terminal voltage (pu) on the inputs' grid
    output0: float  # E_fd before the event, machine pu
    i_fd0: float  # the field current before the event, machine pu (E_fd at rest)


def nonwindup_lag(u: Array, tau: float, dt: float, lo: Array, hi: Array, x0: float) -> Array:
    """1/(1 + s tau) from ``x0`` with its state held within [lo, hi] (IEEE 421.5's non-windup
    limit: the output leaves a limit as soon as the input turns back)."""
    if tau <= 1e-6:
        return np.clip(u, lo, hi)
    a, b0, b1 = first_order_coefficients(tau, dt)
    f64 = np.float64
    return _nonwindup_lag_loop(np.asarray(u, f64), a, b0, b1, np.asarray(lo, f64), np.asarray(hi, f64), float(x0))


def _nonwindup_lag_steps(u: Array, a: float, b0: float, b1: float, lo: Array, hi: Array, x0: float) -> Array:
    y = np.empty(len(u))
    x = x0
    prev = u[0] if len(u) else 0.0
    for k in range(len(u)):
        x = min(max(a * x + b0 * prev + b1 * u[k], lo[k]), hi[k])
        y[k] = x
        prev = u[k]
    return y


# compiled where numba is (a limited exciter's fit plays this loop at every evaluation of every case)
_nonwindup_lag_loop = jit_on_first_call(_nonwindup_lag_steps)


def nonwindup_lead_lag(u: Array, t_lead: float, t_lag: float, dt: float, lo: float, hi: float, x0: float) -> Array:
    """(1 + s t_lead)/(1 + s t_lag) from rest at ``x0`` with a non-windup limit on its output
    (IEEE 421.5): at a limit the output sits on it and the lag's state does not move further
    beyond it, so the output leaves the limit as soon as the input allows. Setting the state so
    that the output sits exactly on the limit instead drove it far the other way behind a large
    lead (T_C/T_B 0.077 under a gain of 505: a +10 % reference step sent E_fd to the floor)."""
    if t_lag <= 1e-6:
        return np.clip(u, lo, hi)
    a, b0, b1 = first_order_coefficients(t_lag, dt)
    return _nonwindup_lead_lag_loop(
        np.asarray(u, np.float64), t_lead / t_lag, a, b0, b1, float(lo), float(hi), float(x0)
    )


def _nonwindup_lead_lag_steps(
    u: Array, r: float, a: float, b0: float, b1: float, lo: float, hi: float, x0: float
) -> Array:
    y = np.empty(len(u))
    x = x0
    prev = u[0] if len(u) else 0.0
    for k in range(len(u)):
        uk = u[k]
        moved = a * x + b0 * prev + b1 * uk
        out = r * uk + (1.0 - r) * moved
        if out > hi:
            out = hi
            moved = min(moved, x) if 1.0 - r > 0 else max(moved, x)
        elif out < lo:
            out = lo
            moved = max(moved, x) if 1.0 - r > 0 else min(moved, x)
        x = moved
        y[k] = out
        prev = uk
    return y


# compiled where numba is: ST5B's fit plays this loop at every evaluation of every case (a
# commissioning day's exciter search spent 87 of its 290 s in it as Python)
_nonwindup_lead_lag_loop = jit_on_first_call(_nonwindup_lead_lag_steps)


def lead_lag(u: Array, t_lead: float, t_lag: float, dt: float) -> Array:
    """(1 + s t_lead)/(1 + s t_lag) from rest."""
    if t_lag <= 1e-6:
        return u
    r = t_lead / t_lag
    return r * u + (1.0 - r) * first_order_response(u, t_lag, dt)


class ControlModel(ABC):
    """A control system's small-signal path; subclass and :func:`register` to add one."""

    name: ClassVar[str]
    kind: ClassVar[str]  # "exciter" (output E_fd), "governor" (output P_m) or "stabiliser" (output V_S)
    description: ClassVar[str]
    parameters: ClassVar[tuple[ControlParameter, ...]]
    # integers a .dyr record carries before the constants (PSS/E's ICONs), with the values phid writes
    icons: ClassVar[tuple[tuple[str, int], ...]] = ()
    # the ICONs whose value the simulation depends on (an input's code, a filter's order): a
    # record that gives another is refused, not simulated as phid's
    icons_simulated: ClassVar[tuple[str, ...]] = ()
    # channels a model reads beyond its kind's (a dual-input stabiliser's rotor speed)
    needs: ClassVar[tuple[str, ...]] = ()
    # constants of branches the small-signal path does not pass through (said in a validation)
    outside_path: ClassVar[tuple[str, ...]] = ()
    # limits :meth:`limited` simulates (said apart from the ones the play-in leaves out)
    simulated_limits: ClassVar[tuple[str, ...]] = ()
    # (lower, upper): the limits that bound the output itself, which a recorded flat top pins
    output_limits: ClassVar[tuple[str, str] | None] = None
    # (lower, upper): the limits on the regulator's input (its error), which no flat top shows:
    # found where the fit wants them (:func:`phid_ros.controls.limits.wanted_input_limits`)
    input_limits: ClassVar[tuple[str, str] | None] = None
    # the constant that lowers the output's ceiling with the field current (a static exciter's
    # rectifier loading K_C): fitted beside a ceiling the recordings reached
    loading: ClassVar[str | None] = None
    simulated_limits_how: ClassVar[str] = ""
    # the planning tools' own forms of the model, where phid writes them: PSLF's record is PSS/E's
    # constants after ``mwcap=`` and this many zeros (None: its layout not known, not written);
    # ANDES's model of the same name (its constants under ``andes_names`` where they differ)
    pslf_trailing_zeros: ClassVar[int | None] = None
    in_andes: ClassVar[bool] = False
    andes_names: ClassVar[Mapping[str, str]] = {}

    @classmethod
    def fitted(cls) -> tuple[ControlParameter, ...]:
        return tuple(p for p in cls.parameters if not p.limit and not p.held and p.high > p.low)

    @classmethod
    def start(cls, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        """Where the fit starts, given the fits of the models registered before it (by name): a
        model that nests a simpler one starts where that one ended, so it fits at least as well
        (a rate feedback's loop has local minima a start from the defaults falls into)."""
        return cls.defaults()

    @classmethod
    def completed(cls, values: Mapping[str, float]) -> dict[str, float]:
        """The constants that follow from the fitted ones (none unless a model says so)."""
        return dict(values)

    @classmethod
    def record_problem(cls, values: Mapping[str, float]) -> str | None:
        """What makes a record's constants ones the simulation cannot take, or None: a constant
        not a number or a negative time constant (held ones too: the play-in runs a record as
        written, T_5 = -3 s included), and a limit pair whose lower bound lies above its upper (an
        IEEEST with LSMAX below LSMIN played to an E_fd error of 9e266 pu)."""
        for q in cls.parameters:
            problem = q.record_problem(values[q.name])
            if problem is not None:
                return f"{q.name} = {values[q.name]:g} {problem}"
        for pair in (cls.output_limits, cls.input_limits):
            if pair is not None and values[pair[0]] > values[pair[1]]:
                lo, hi = pair
                return f"{lo} = {values[lo]:g} lies above {hi} = {values[hi]:g}: the lower limit is above the upper"
        return None

    @classmethod
    def recorded(cls, values: Mapping[str, float]) -> dict[str, float]:
        """A record's constants as the simulation takes them: as written (a model whose record
        can carry what phid does not simulate refuses it here, naming the constants)."""
        return dict(values)

    @classmethod
    def not_simulated(cls, values: Mapping[str, float]) -> list[str]:
        """What a record of this model carries that the small-signal play-in leaves out, with the
        record's values: its limits (and the exciter saturation, the rectifier loading, which act
        only at large signals) and the branches outside its path."""
        out = []
        limits = [p for p in cls.parameters if p.limit and p.name not in cls.simulated_limits]
        if cls.simulated_limits and cls.simulated_limits_how:
            out.append(f"{cls.name}: {cls.simulated_limits_how}")
        if limits:
            named = ", ".join(f"{p.name} = {values[p.name]:g}" for p in limits)
            out.append(
                f"{cls.name} {named} (the play-in is small-signal: a recording that reaches them is not followed)"
            )
        idle = [p for p in cls.parameters if p.name in cls.outside_path]
        if idle:
            named = ", ".join(f"{p.name} = {values[p.name]:g}" for p in idle)
            out.append(f"{cls.name} {named} ({idle[0].meaning})")
        return out

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        """The output's deviation with the limits the model declares simulated, from the
        operating levels; None where the model has only its small-signal path."""
        return None

    @classmethod
    def output_clipped(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array:
        """The small-signal response held within the output limits (a stabiliser's V_S band)."""
        assert cls.output_limits is not None
        lower, upper = cls.output_limits
        out = cls.response(values, x, reference) + levels.output0
        return np.clip(out, values[lower], values[upper]) - levels.output0

    @classmethod
    def input_signal(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        """The signal at the input limiter (absolute, pu) with that limiter open; None where the
        model declares no input limit."""
        return None

    @classmethod
    def limit_at(cls, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        """The value of limit ``name`` that puts the output's bound at ``output`` at sample ``k``
        (a recorded flat top where the output sat on it): the output itself for a limit on the
        output, divided by V_T for a static exciter's ceiling (see ESST5B)."""
        return output

    @classmethod
    def defaults(cls) -> dict[str, float]:
        return {p.name: p.default for p in cls.parameters}

    @classmethod
    @abstractmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        """The output's deviation for the scenario's inputs; ``reference`` is the size of the
        reference step (V_ref for an exciter, P_ref in pu power for a governor)."""


MODELS: dict[str, type[ControlModel]] = {}
KINDS_IN_ORDER = ("exciter", "governor", "stabiliser")  # every kind a model is of, as the unit's records go


def register(cls: type[ControlModel]) -> type[ControlModel]:
    MODELS[cls.name] = cls
    return cls


def of_kind(kind: str) -> list[type[ControlModel]]:
    return [m for m in MODELS.values() if m.kind == kind]


# the terminal-voltage transducer's lag, where an exciter model has one (absent at 0)
TRANSDUCER = ControlParameter("TR", "s", 0.0, 0.0, 0.5, "voltage transducer time constant", absent=0.0)


@register
class SEXS(ControlModel):
    """Simplified excitation system: (V_ref - V_t) through (1 + sT_A)/(1 + sT_B), K/(1 + sT_E)."""

    name = "SEXS"
    kind = "exciter"
    description = "simplified excitation system (PSS/E SEXS)"
    in_andes = True
    andes_names = {"TA/TB": "TATB"}
    parameters = (
        ControlParameter("TA/TB", "", 0.1, 0.01, 1.0, "lead-lag ratio T_A/T_B"),
        ControlParameter("TB", "s", 10.0, 0.1, 30.0, "lag time constant T_B"),
        ControlParameter("K", "pu", 100.0, 5.0, 1000.0, "steady-state gain"),
        ControlParameter("TE", "s", 0.05, 0.002, 2.0, "exciter time constant T_E"),
        ControlParameter("EMIN", "pu", -5.0, -20.0, 0.0, "minimum field voltage", limit=True),
        ControlParameter("EMAX", "pu", 5.0, 1.0, 20.0, "maximum field voltage", limit=True),
    )

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        tb = values["TB"]
        e = regulator_error(x, reference, x.v_t)
        return values["K"] * lag(lead_lag(e, values["TA/TB"] * tb, tb, x.dt), values["TE"], x.dt)

    simulated_limits = ("EMIN", "EMAX")
    simulated_limits_how = "E_fd within EMIN..EMAX on a non-windup T_E lag (PSS/E SEXS)"
    output_limits = ("EMIN", "EMAX")

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        v = values
        if not v["EMIN"] <= levels.output0 <= v["EMAX"]:
            raise LimitsError(
                f"E_fd at rest {levels.output0:.3f} lies outside EMIN..EMAX {v['EMIN']:g}..{v['EMAX']:g}: the "
                "limits do not hold the recorded operating point"
            )
        tb = v["TB"]
        e = regulator_error(x, reference, x.v_t)
        u = levels.output0 + v["K"] * lead_lag(e, v["TA/TB"] * tb, tb, x.dt)
        lo, hi = np.full(len(u), v["EMIN"]), np.full(len(u), v["EMAX"])
        return nonwindup_lag(u, v["TE"], x.dt, lo, hi, levels.output0) - levels.output0


@register
class TGOV1(ControlModel):
    """Steam turbine-governor: (P_ref - dw/R) through 1/(1 + sT_1), (1 + sT_2)/(1 + sT_3), less D_t dw."""

    name = "TGOV1"
    kind = "governor"
    description = "steam turbine-governor (PSS/E TGOV1)"
    in_andes = True
    pslf_trailing_zeros = 0
    parameters = (
        ControlParameter("R", "pu", 0.05, 0.01, 0.5, "permanent droop"),
        ControlParameter("T1", "s", 0.5, 0.02, 5.0, "governor (valve) time constant"),
        ControlParameter("VMAX", "pu", 1.0, 0.5, 1.5, "maximum valve position", limit=True),
        ControlParameter("VMIN", "pu", 0.0, -0.5, 0.5, "minimum valve position", limit=True),
        ControlParameter("T2", "s", 1.0, 0.0, 20.0, "turbine lead time constant"),
        ControlParameter("T3", "s", 3.0, 0.05, 30.0, "turbine lag (reheat) time constant"),
        ControlParameter("Dt", "pu", 0.0, 0.0, 5.0, "turbine damping", absent=0.0),
    )

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        valve = lag(reference * x.reference_step - x.speed / values["R"], values["T1"], x.dt)
        return lead_lag(valve, values["T2"], values["T3"], x.dt) - values["Dt"] * x.speed


@register
class EXST1(ControlModel):
    """Static (bus-fed) excitation system, IEEE ST1A-like: V_t sensed through 1/(1 + sT_R), the error
    through (1 + sT_C)/(1 + sT_B) and K_A/(1 + sT_A), a rate feedback sK_F/(1 + sT_F) of the output."""

    name = "EXST1"
    kind = "exciter"
    description = "static excitation system, IEEE ST1A-like (PSS/E EXST1)"
    in_andes = True
    parameters = (
        TRANSDUCER,
        ControlParameter("VIMAX", "pu", 0.2, 0.0, 1.0, "maximum error signal", limit=True),
        ControlParameter("VIMIN", "pu", -0.2, -1.0, 0.0, "minimum error signal", limit=True),
        ControlParameter("TC", "s", 1.0, 0.01, 20.0, "lead time constant T_C"),
        ControlParameter("TB", "s", 10.0, 0.05, 30.0, "lag time constant T_B"),
        ControlParameter("KA", "pu", 200.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("TA", "s", 0.02, 0.002, 1.0, "regulator time constant"),
        ControlParameter("VRMAX", "pu", 5.0, 1.0, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        ControlParameter("KC", "pu", 0.0, 0.0, 1.0, "rectifier loading factor (enters the limits only)", limit=True),
        ControlParameter("KF", "pu", 0.0, 0.0, 1.0, "rate feedback gain", absent=0.0),
        ControlParameter("TF", "s", 1.0, 0.05, 20.0, "rate feedback time constant", within="KF"),
    )

    @classmethod
    def start(cls, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        sexs = earlier.get("SEXS")
        if not sexs:
            return cls.defaults()
        # SEXS is EXST1 without its transducer and rate feedback
        lead = sexs["TA/TB"] * sexs["TB"]
        return {
            **cls.defaults(),
            "TC": lead,
            "TB": sexs["TB"],
            "KA": sexs["K"],
            "TA": sexs["TE"],
            "TR": 1e-3,
            "KF": 1e-3,
        }

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        sensed = lag(x.v_t, v["TR"], x.dt)
        num, den = _exst1_transfer(v["TA"], v["TB"], v["TC"], v["TF"], v["KA"], v["KF"])
        return transfer(regulator_error(x, reference, sensed), num, den, x.dt)

    simulated_limits = ("VIMAX", "VIMIN", "VRMAX", "VRMIN", "KC")
    output_limits = ("VRMIN", "VRMAX")
    input_limits = ("VIMIN", "VIMAX")
    loading = "KC"
    simulated_limits_how = (
        "the error within VIMIN..VIMAX, E_fd within VRMIN V_T..VRMAX V_T - K_C I_FD on the regulator's "
        "output (PSS/E EXST1; the lag winds up), the rate feedback inside the input limiter; I_FD held at "
        "its pre-event value"
    )

    @classmethod
    def limit_at(cls, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        # E_fd's ceiling is V_T VRMAX - K_C I_FD (floor V_T VRMIN): with K_C not reached, V_T's share
        return output / float(levels.v_t[k]) if name in ("VRMAX", "VRMIN") else output

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return cls._played(values, x, reference, levels, limited=True)[0] - levels.output0

    @classmethod
    def input_signal(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return cls._played(values, x, reference, levels, limited=False)[1]

    @classmethod
    def _played(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels, *, limited: bool
    ) -> tuple[Array, Array]:
        """E_fd and the error at the input limiter, sample by sample (the rate feedback closes a
        loop around the limiter, so no filter chain gives it); ``limited`` False: every limit open."""
        v = values
        vi0 = levels.output0 / v["KA"]  # at rest the lead-lag passes the error at gain 1, K_A makes E_fd
        loading = v["KC"] * levels.i_fd0
        n = len(x.v_t)
        if limited:
            if not v["VIMIN"] <= vi0 <= v["VIMAX"]:
                raise LimitsError(
                    f"the error at rest {vi0:.4f} (E_fd {levels.output0:.3f} / K_A {v['KA']:g}) lies outside "
                    f"VIMIN..VIMAX {v['VIMIN']:g}..{v['VIMAX']:g}: the limits do not hold the recorded operating point"
                )
            lo, hi = v["VRMIN"] * levels.v_t, v["VRMAX"] * levels.v_t - loading
            if not lo[0] <= levels.output0 <= hi[0]:
                raise LimitsError(
                    f"E_fd at rest {levels.output0:.3f} lies outside V_T VRMIN..V_T VRMAX - K_C I_FD "
                    f"{lo[0]:.3f}..{hi[0]:.3f}: the record's limits do not hold the recorded operating point"
                )
            in_lo, in_hi = v["VIMIN"], v["VIMAX"]
        else:
            lo, hi = np.full(n, -np.inf), np.full(n, np.inf)
            in_lo, in_hi = -np.inf, np.inf
        external = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        out = _exst1_loop(
            np.ascontiguousarray(external, np.float64),
            float(vi0),
            float(in_lo),
            float(in_hi),
            *_lead_lag_steps(v["TC"], v["TB"], x.dt),
            float(v["KA"]),
            *_lead_lag_steps(0.0, v["TA"], x.dt)[1:],
            float(v["KF"] / v["TF"]) if v["TF"] > 1e-6 else 0.0,
            *_lead_lag_steps(0.0, v["TF"], x.dt)[1:],
            np.ascontiguousarray(lo, np.float64),
            np.ascontiguousarray(hi, np.float64),
        )
        return out[0], out[1]


def _lead_lag_steps(t_lead: float, t_lag: float, dt: float) -> tuple[float, float, float, float]:
    """(r, a, b0, b1): (1 + s t_lead)/(1 + s t_lag) as r u + (1 - r) x, the lag's state x stepped
    by :func:`~phid_ros.numerics.first_order_coefficients`; a vanishing lag is a wire."""
    if t_lag <= 1e-6:
        return 1.0, 0.0, 0.0, 1.0
    return (t_lead / t_lag, *first_order_coefficients(t_lag, dt))


def _exst1_steps(
    external: Array,
    vi0: float,
    in_lo: float,
    in_hi: float,
    r: float,
    a_ll: float,
    b0_ll: float,
    b1_ll: float,
    ka: float,
    a_a: float,
    b0_a: float,
    b1_a: float,
    g_f: float,
    a_f: float,
    b0_f: float,
    b1_f: float,
    lo: Array,
    hi: Array,
) -> Array:
    # each step solved with the rate feedback of the same instant (implicit: an explicit one-step
    # delay in a loop of gain K_A K_F / T_F rings): the regulator's output is p + q x the limited
    # error, the feedback g (1 - b1_f) times it less w, so the unlimited error solves one linear
    # equation and the limiter clips that solution
    n = len(external)
    out = np.empty((2, n))
    x_ll, x_a, z = vi0, vi0, ka * vi0
    vl_prev, y_prev, vr_prev = vi0, vi0, ka * vi0
    q = ka * b1_a * (r + (1.0 - r) * b1_ll)
    gain = g_f * (1.0 - b1_f)
    for k in range(n):
        x_ll_next = a_ll * x_ll + b0_ll * vl_prev
        x_a_next = a_a * x_a + b0_a * y_prev
        p = ka * (x_a_next + b1_a * (1.0 - r) * x_ll_next)
        w = g_f * (a_f * z + b0_f * vr_prev)
        base = vi0 + external[k] + w
        vi = (base - gain * p) / (1.0 + gain * q)
        vl = min(max(vi, in_lo), in_hi)
        if vl != vi:
            vi = base - gain * (p + q * vl)
        x_ll = x_ll_next + b1_ll * vl
        y = r * vl + (1.0 - r) * x_ll
        x_a = x_a_next + b1_a * y
        vr = ka * x_a
        z = a_f * z + b0_f * vr_prev + b1_f * vr
        out[0, k] = min(max(vr, lo[k]), hi[k])
        out[1, k] = vi
        vl_prev, y_prev, vr_prev = vl, y, vr
    return out


_exst1_loop = jit_on_first_call(_exst1_steps)


@register
class IEEET1(ControlModel):
    """DC commutator exciter (IEEE type 1, PSS/E IEEET1): K_A/(1 + sT_A) on the error less the rate
    feedback sK_F/(1 + sT_F) of E_fd, the exciter 1/(K_E + sT_E)."""

    name = "IEEET1"
    kind = "exciter"
    description = "DC commutator exciter, IEEE type 1 (PSS/E IEEET1)"
    in_andes = True
    andes_names = {"SWITCH": "Switch"}
    parameters = (
        TRANSDUCER,
        ControlParameter("KA", "pu", 50.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("TA", "s", 0.05, 0.002, 1.0, "regulator time constant"),
        ControlParameter("VRMAX", "pu", 5.0, 0.5, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        # the small-signal response is unchanged when K_A, K_E and T_E scale together (and the
        # saturation's slope at the operating point adds to K_E): K_E is held at 1 (a separately
        # excited exciter's, PSS/E's usual); K_A and T_E are then K_A/K_E and T_E/K_E
        ControlParameter("KE", "pu", 1.0, 1.0, 1.0, "exciter constant (held at 1: see the class)", held=True),
        ControlParameter("TE", "s", 0.5, 0.02, 5.0, "exciter time constant"),
        ControlParameter("KF", "pu", 0.05, 0.0, 0.5, "rate feedback gain", absent=0.0),
        ControlParameter("TF", "s", 1.0, 0.05, 20.0, "rate feedback time constant", within="KF"),
        ControlParameter("SWITCH", "", 0.0, 0.0, 0.0, "PSS/E's unused switch", held=True),
        ControlParameter("E1", "pu", 0.0, 0.0, 0.0, "first saturation point", limit=True),
        ControlParameter("SE1", "", 0.0, 0.0, 0.0, "saturation at E1", limit=True),
        ControlParameter("E2", "pu", 0.0, 0.0, 0.0, "second saturation point", limit=True),
        ControlParameter("SE2", "", 0.0, 0.0, 0.0, "saturation at E2", limit=True),
    )

    @classmethod
    def record_problem(cls, values: Mapping[str, float]) -> str | None:
        if values["KE"] == 0.0:
            # PSS/E computes K_E at initialisation where the record gives 0; simulated as 0 the
            # exciter would be an integrator: a wrong model, not a validation
            return "KE = 0 (PSS/E computes it at initialisation so V_R starts at 0): give the unit's K_E"
        return super().record_problem(values)

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        sensed = lag(x.v_t, v["TR"], x.dt)
        num, den = _ieeet1_transfer(v["TA"], v["TE"], v["KE"], v["TF"], v["KA"], v["KF"])
        return transfer(regulator_error(x, reference, sensed), num, den, x.dt)


@register
class ESST5B(ControlModel):
    """Static exciter with two lead-lags, IEEE ST5B's voltage regulator path: (1 + sT_C1)/(1 + sT_B1),
    (1 + sT_C2)/(1 + sT_B2), K_R/(1 + sT_1). The over- and under-excitation limiters' lead-lags
    act only while a limiter does (never in a small-signal test): held with lead = lag.

    The record's order is the one PNNL's power plant model validation tool and InterPSS read an
    ESST5B in (T_R, K_R, T_1, K_C, V_RMAX, V_RMIN, T_C1, T_B1, T_C2, T_B2, then the limiters' T_OC1,
    T_OB1, T_OC2, T_OB2, T_UC1, T_UB1, T_UC2, T_UB2)."""

    outside_path = ("TOC1", "TOB1", "TOC2", "TOB2", "TUC1", "TUB1", "TUC2", "TUB2")

    name = "ESST5B"
    kind = "exciter"
    description = "static exciter with two lead-lags, IEEE ST5B (ESST5B)"
    parameters = (
        TRANSDUCER,
        ControlParameter("KR", "pu", 200.0, 5.0, 1000.0, "regulator gain"),
        ControlParameter("T1", "s", 0.004, 0.001, 1.0, "firing circuit time constant"),
        ControlParameter("KC", "pu", 0.0, 0.0, 1.0, "rectifier loading factor (enters the limits only)", limit=True),
        ControlParameter("VRMAX", "pu", 5.0, 1.0, 20.0, "maximum regulator output", limit=True),
        ControlParameter("VRMIN", "pu", -5.0, -20.0, 0.0, "minimum regulator output", limit=True),
        ControlParameter("TC1", "s", 1.0, 0.01, 20.0, "first lead time constant"),
        ControlParameter("TB1", "s", 10.0, 0.05, 30.0, "first lag time constant"),
        ControlParameter("TC2", "s", 0.1, 0.01, 20.0, "second lead time constant"),
        ControlParameter("TB2", "s", 0.1, 0.01, 30.0, "second lag time constant"),
        *(
            ControlParameter(n, "s", 1.0, 1.0, 1.0, "limiter lead-lag (acts only with its limiter)", held=True)
            for n in ("TOC1", "TOB1", "TOC2", "TOB2", "TUC1", "TUB1", "TUC2", "TUB2")
        ),
    )

    @classmethod
    def start(cls, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        sexs = earlier.get("SEXS")
        if not sexs:
            return cls.defaults()
        # SEXS is ESST5B with its second lead-lag a wire
        lead = sexs["TA/TB"] * sexs["TB"]
        return {**cls.defaults(), "TC1": lead, "TB1": sexs["TB"], "KR": sexs["K"], "T1": sexs["TE"], "TR": 1e-3}

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        e = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        first = lead_lag(e, v["TC1"], v["TB1"], x.dt)
        return v["KR"] * lag(lead_lag(first, v["TC2"], v["TB2"], x.dt), v["T1"], x.dt)

    @classmethod
    def limit_at(cls, name: str, output: float, levels: OperatingLevels, k: int) -> float:
        # E_fd's bound is V_T VRMAX - K_C I_FD (V_T VRMIN): with K_C not reached, V_R's limit is E_fd / V_T
        return output / float(levels.v_t[k]) if name in ("VRMAX", "VRMIN") else output

    simulated_limits = ("KC", "VRMAX", "VRMIN")
    output_limits = ("VRMIN", "VRMAX")
    loading = "KC"
    simulated_limits_how = (
        "V_R within VRMIN..VRMAX after the lead-lags, E_fd within VRMIN V_T..VRMAX V_T - K_C I_FD on a "
        "non-windup T_1 lag, the first lead-lag non-windup (IEEE 421.5 ST5B); I_FD held at its pre-event value"
    )

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        v = values
        loading = v["KC"] * levels.i_fd0
        v_r0 = levels.output0 + loading  # at rest V_R = E_fd + K_C I_FD (the lead-lags' gain is 1)
        if not v["VRMIN"] <= v_r0 <= v["VRMAX"]:
            raise LimitsError(
                f"V_R at rest {v_r0:.3f} (E_fd {levels.output0:.3f} + K_C {v['KC']:g} x I_FD {levels.i_fd0:.3f}) lies "
                f"outside VRMIN..VRMAX {v['VRMIN']:g}..{v['VRMAX']:g}: the record's limits do not hold the recorded "
                "operating point"
            )
        e = regulator_error(x, reference, lag(x.v_t, v["TR"], x.dt))
        # K_R, the second lead-lag, then the first with its non-windup limit, and the limiter
        w = v_r0 + v["KR"] * lead_lag(e, v["TC2"], v["TB2"], x.dt)
        v_r = nonwindup_lead_lag(w, v["TC1"], v["TB1"], x.dt, v["VRMIN"], v["VRMAX"], v_r0)
        u = np.clip(v_r, v["VRMIN"], v["VRMAX"]) - loading
        lo, hi = v["VRMIN"] * levels.v_t, v["VRMAX"] * levels.v_t - loading
        return nonwindup_lag(u, v["T1"], x.dt, lo, hi, levels.output0) - levels.output0


@register
class IEEEG1(ControlModel):
    """IEEE type 1 steam turbine-governor (PSS/E IEEEG1): the speed deviation through
    K (1 + sT_2)/(1 + sT_1), the servo 1/(1 + sT_3) to the valve, then the steam chest 1/(1 + sT_4),
    the reheater 1/(1 + sT_5), the crossover 1/(1 + sT_6) and 1/(1 + sT_7) in series, each stage's
    share K_1, K_3, K_5, K_7 of this shaft's power. A fit has one reheat stage (K_1 + K_3 = 1, the
    stages marked "held out" at 0: short tests do not separate them); a record's are all simulated,
    and the second shaft's shares (K_2, K_4, K_6, K_8), which drive another machine, are refused."""

    name = "IEEEG1"
    kind = "governor"
    icons = (("JBUS", 0), ("M", 0))  # the low-pressure shaft's machine: none (a tandem compound)
    icons_simulated = ("JBUS", "M")
    description = "IEEE type 1 steam turbine-governor, one reheat stage (PSS/E IEEEG1)"
    in_andes = True
    pslf_trailing_zeros = 15  # its deadbands and valve table, unused
    parameters = (
        ControlParameter("K", "pu", 20.0, 2.0, 100.0, "governor gain (1/droop)"),
        ControlParameter("T1", "s", 0.0, 0.0, 0.0, "governor lag (held out of a fit)", held=True),
        ControlParameter("T2", "s", 0.0, 0.0, 0.0, "governor lead (held out of a fit)", held=True),
        ControlParameter("T3", "s", 0.1, 0.02, 2.0, "servo time constant"),
        ControlParameter("UO", "pu/s", 1.0, 0.01, 5.0, "maximum valve opening rate", limit=True),
        ControlParameter("UC", "pu/s", -1.0, -5.0, -0.01, "maximum valve closing rate", limit=True),
        ControlParameter("PMAX", "pu", 1.0, 0.5, 1.5, "maximum valve position", limit=True),
        ControlParameter("PMIN", "pu", 0.0, -0.5, 0.5, "minimum valve position", limit=True),
        ControlParameter("T4", "s", 0.3, 0.02, 2.0, "steam chest time constant"),
        ControlParameter("K1", "", 0.3, 0.02, 0.98, "high-pressure share"),
        ControlParameter("K2", "", 0.0, 0.0, 0.0, "high-pressure share on a second shaft (held out)", held=True),
        ControlParameter("T5", "s", 7.0, 0.5, 30.0, "reheater time constant"),
        ControlParameter("K3", "", 0.7, 0.02, 0.98, "low-pressure share (1 - K1)", held=True),
        ControlParameter("K4", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("T6", "s", 0.0, 0.0, 0.0, "crossover time constant (held out of a fit)", held=True),
        ControlParameter("K5", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K6", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("T7", "s", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K7", "", 0.0, 0.0, 0.0, "(held out)", held=True),
        ControlParameter("K8", "", 0.0, 0.0, 0.0, "(held out)", held=True),
    )

    @classmethod
    def start(cls, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        tgov = earlier.get("TGOV1")
        if not tgov:
            return cls.defaults()
        # TGOV1 is IEEEG1 with a steam chest of no delay: valve lag T1, reheat lead-lag T2/T3
        return {
            **cls.defaults(),
            "K": 1.0 / tgov["R"],
            "T3": 0.05,
            "T4": tgov["T1"],
            "K1": min(max(tgov["T2"] / tgov["T3"], 0.05), 0.95),
            "T5": tgov["T3"],
        }

    @classmethod
    def completed(cls, values: Mapping[str, float]) -> dict[str, float]:
        # the servo's and the steam chest's lags are in series on one signal: in small signal
        # they commute, so the data give the pair, not which is which; the servo is given the
        # shorter (IEEE's typical data: servo 0.1-0.2 s, steam chest 0.2-0.4 s)
        servo, chest = sorted((values["T3"], values["T4"]))
        return {**values, "T3": servo, "T4": chest, "K3": 1.0 - values["K1"]}

    @classmethod
    def recorded(cls, values: Mapping[str, float]) -> dict[str, float]:
        # every stage a record gives is simulated; the shares of a second (low-pressure) shaft
        # drive another machine, which a single unit's validation does not have
        second = {k: values[k] for k in ("K2", "K4", "K6", "K8") if values[k] != 0.0}
        if second:
            named = ", ".join(f"{k} = {v:g}" for k, v in second.items())
            raise ValueError(
                f"a second shaft's shares ({named}) drive another machine, which phid does not simulate: "
                "a cross-compound unit is not validated here"
            )
        negative = [k for k in ("T1", "T2", "T6", "T7") if values[k] < 0.0]
        if negative:
            raise ValueError(f"{', '.join(negative)} negative: a time constant is 0 (no lag) or positive")
        if values["T2"] > 0.0 and values["T1"] <= 0.0:
            raise ValueError(f"T2 = {values['T2']:g} s with T1 = 0: the governor's lead needs a lag")
        return dict(values)

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        # the load reference in pu power: the valve moves by it in steady state; the speed through
        # the governor's K (1 + sT_2)/(1 + sT_1), the servo, then the steam chest, the reheater, the
        # crossover and the last stage in series, each stage's share of the shaft's power
        speed = lead_lag(v["K"] * x.speed, v["T2"], v["T1"], x.dt)
        valve = lag(reference * x.reference_step - speed, v["T3"], x.dt)
        out = np.zeros_like(valve)
        stage = valve
        for t_stage, share in (("T4", "K1"), ("T5", "K3"), ("T6", "K5"), ("T7", "K7")):
            stage = lag(stage, v[t_stage], x.dt)
            out += v[share] * stage
        return out


@register
class HYGOV(ControlModel):
    """Hydro turbine-governor (PSS/E HYGOV), linearised about the scenario's operating point: the
    speed error less R times the gate command, through 1/(1 + sT_f) and the PI (1 + sT_r)/(r T_r s),
    the gate servo 1/(1 + sT_g); the water column (q = g sqrt(h), dq/dt = (1 - h)/T_w) and
    P_m = A_t h (q - q_NL) - D_turb g dw. At rated head the gate g0 = P_m0/A_t + q_NL, so a gate
    step moves P_m by A_t (1 - (q0 - q_NL) s T_w)/(1 + s g0 T_w/2): the water hammer's
    non-minimum phase."""

    name = "HYGOV"
    kind = "governor"
    description = "hydro turbine-governor (PSS/E HYGOV), linearised at the operating point"
    in_andes = True
    andes_names = {"TW": "Tw", "Dturb": "Dt"}
    parameters = (
        ControlParameter("R", "pu", 0.05, 0.01, 0.2, "permanent droop"),
        ControlParameter("r", "pu", 0.5, 0.05, 2.0, "temporary droop"),
        ControlParameter("Tr", "s", 5.0, 0.5, 30.0, "governor time constant (reset)"),
        ControlParameter("Tf", "s", 0.05, 0.005, 0.5, "filter time constant"),
        ControlParameter("Tg", "s", 0.5, 0.05, 2.0, "gate servo time constant"),
        ControlParameter("VELM", "pu/s", 0.2, 0.01, 1.0, "gate velocity limit", limit=True),
        ControlParameter("GMAX", "pu", 1.0, 0.5, 1.5, "maximum gate opening", limit=True),
        ControlParameter("GMIN", "pu", 0.0, 0.0, 0.5, "minimum gate opening", limit=True),
        ControlParameter("TW", "s", 1.0, 0.2, 5.0, "water inertia time constant"),
        # the small-signal response is unchanged when A_t, R, r and T_W scale together and q_NL
        # inversely (g0 = P_m0/A_t + q_NL): A_t is held at its typical value, 1/(g_FL - g_NL)
        ControlParameter("At", "pu", 1.2, 1.2, 1.2, "turbine gain (held: see the class)", held=True),
        ControlParameter("Dturb", "pu", 0.0, 0.0, 2.0, "turbine damping", absent=0.0),
        ControlParameter("qNL", "pu", 0.08, 0.0, 0.3, "no-load flow"),
    )

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        if not np.isfinite(x.p_m0):
            return np.full(len(x.speed), np.nan)  # no operating point: the model does not apply
        g0 = x.p_m0 / v["At"] + v["qNL"]
        q0 = g0  # at rated head
        # the reference in pu power: the gate command moves by R/A_t of it per pu
        u = reference * v["R"] / v["At"] * x.reference_step - x.speed
        gate_num = first_order(v["Tr"])
        gate_den = np.polyadd(np.polymul([v["r"] * v["Tr"], 0.0], first_order(v["Tf"])), v["R"] * first_order(v["Tr"]))
        num = v["At"] * np.polymul(gate_num, [-(q0 - v["qNL"]) * v["TW"], 1.0])
        den = np.polymul(np.polymul(gate_den, first_order(v["Tg"])), first_order(g0 * v["TW"] / 2))
        return transfer(u, num, den, x.dt) - v["Dturb"] * g0 * x.speed


@register
class IEEEST(ControlModel):
    """IEEE stabiliser (PSS/E IEEEST) on the electrical power (input code 3): P_e through the
    filter (1 + sA_5 + s^2 A_6)/((1 + sA_1 + s^2 A_2)(1 + sA_3 + s^2 A_4)), two lead-lags
    (1 + sT_1)/(1 + sT_2), (1 + sT_3)/(1 + sT_4), K_S and the washout sT_5/(1 + sT_6), its output
    V_S within LSMIN..LSMAX, added at the voltage regulator's summing point.

    Fitted from a recorded stabiliser output against the recorded P_e, or, where the output is not
    recorded, from its effect on E_fd through the exciter (:mod:`phid_ros.controls.stabiliser_effect`).
    The torsional filter
    (A_1..A_6, for a steam unit's shaft modes) is held out at 0, a wire; the washout's gain is
    T_5/T_6, which K_S carries, so T_5 = T_6; the output's enabling band VCU/VCL at 0 (not used)."""

    name = "IEEEST"
    kind = "stabiliser"
    icons = (("MODE", 3), ("BUSR", 0))  # the input: the machine's electrical power; its own bus
    icons_simulated = ("MODE",)
    description = "IEEE stabiliser on the electrical power (PSS/E IEEEST, input code 3)"
    outside_path = ("VCU", "VCL")
    in_andes = True
    parameters = (
        *(
            ControlParameter(
                n, "s" if n in ("A1", "A3", "A5") else "s2", 0.0, 0.0, 0.0, "torsional filter (held out)", held=True
            )
            for n in ("A1", "A2", "A3", "A4", "A5", "A6")
        ),
        ControlParameter("T1", "s", 0.2, 0.0, 5.0, "first lead time constant", absent=0.0),
        ControlParameter("T2", "s", 0.05, 0.002, 5.0, "first lag time constant"),
        ControlParameter("T3", "s", 0.2, 0.0, 5.0, "second lead time constant", absent=0.0),
        ControlParameter("T4", "s", 0.05, 0.002, 5.0, "second lag time constant"),
        ControlParameter("T5", "s", 3.0, 3.0, 3.0, "washout numerator (T_6: K_S carries the gain)", held=True),
        ControlParameter("T6", "s", 3.0, 0.3, 30.0, "washout time constant"),
        ControlParameter("KS", "pu", -1.0, -100.0, 100.0, "stabiliser gain (pu of V_S per pu of P_e)"),
        ControlParameter("LSMAX", "pu", 0.1, 0.005, 0.5, "maximum stabiliser output", limit=True),
        ControlParameter("LSMIN", "pu", -0.1, -0.5, -0.005, "minimum stabiliser output", limit=True),
        ControlParameter("VCU", "pu", 0.0, 0.0, 0.0, "output enabled below this V_T (0: not used)", held=True),
        ControlParameter("VCL", "pu", 0.0, 0.0, 0.0, "output enabled above this V_T (0: not used)", held=True),
    )
    simulated_limits = ("LSMAX", "LSMIN")
    output_limits = ("LSMIN", "LSMAX")
    simulated_limits_how = "V_S within LSMIN..LSMAX (PSS/E IEEEST)"

    @classmethod
    def completed(cls, values: Mapping[str, float]) -> dict[str, float]:
        return {**values, **lead_lags_in_order(values), "T5": values["T6"]}

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values  # a record's as written (a fit's values come completed: T_5 = T_6)
        if x.p_e is None:
            return np.full(len(x.v_t), np.nan)  # no electrical power: the model does not apply
        led = lead_lag(lead_lag(x.p_e, v["T1"], v["T2"], x.dt), v["T3"], v["T4"], x.dt)
        if any(v[a] for a in ("A1", "A2", "A3", "A4", "A5", "A6")):
            num = np.array([v["A6"], v["A5"], 1.0])
            den = np.polymul([v["A2"], v["A1"], 1.0], [v["A4"], v["A3"], 1.0])
            led = transfer(led, np.trim_zeros(num, "f"), np.trim_zeros(den, "f"), x.dt)
        # K_S sT_5/(1 + sT_6) = K_S (T_5/T_6) (1 - 1/(1 + sT_6))
        return v["KS"] * v["T5"] / v["T6"] * (led - lag(led, v["T6"], x.dt))

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return cls.output_clipped(values, x, reference, levels)


def lead_lags_in_order(
    values: Mapping[str, float], pairs: Sequence[tuple[str, str]] = (("T1", "T2"), ("T3", "T4"))
) -> dict[str, float]:
    """A stabiliser's lead-lags (T_1, T_2), (T_3, T_4), ... in one order, so a fit has one answer:
    (1 + sT_1)(1 + sT_3)/((1 + sT_2)(1 + sT_4)) is the same whichever lead a lag is paired with, so
    the shorter lead goes with the shorter lag, first (a lead the fit finds absent is T_1)."""
    leads = sorted(values[lead] for lead, _ in pairs)
    lags = sorted(values[lag_] for _, lag_ in pairs)
    return {n: v for (lead, lag_), a, b in zip(pairs, leads, lags, strict=True) for n, v in ((lead, a), (lag_, b))}


def washout(u: Array, tau: float, dt: float) -> Array:
    """s tau/(1 + s tau) from rest; a vanishing tau is a wire (PSS/E bypasses a washout of T = 0)."""
    return u if tau <= 1e-6 else u - lag(u, tau, dt)


@register
class PSS2A(ControlModel):
    """IEEE dual-input stabiliser (PSS/E PSS2A, IEEE 421.5 PSS2A) on the rotor speed (input code 1)
    and the electrical power (code 3): each input through two washouts, the speed then 1/(1 + sT_6),
    the power K_S2/(1 + sT_7) (the integral of accelerating power: K_S2 = T_7/(2H)); their sum, the
    power's share K_S3, through the ramp-tracking filter [(1 + sT_8)/(1 + sT_9)^M]^N, less the power's
    path; then K_S1 and two lead-lags, V_S within VSTMIN..VSTMAX.

    Fitted from a recorded stabiliser output against the recorded speed and P_e (a recorder
    without the speed cannot fit it). As IEEE 421.5's sample data set it, the washouts and T_7 are
    one time constant (T_W1 = T_W2 = T_W3 = T_7, T_W4 = 0: a wire), T_6 = 0, K_S3 = 1, M = 5, N = 1
    and T_8 = M T_9 (the filter tracks a ramp of mechanical power with no error): the fit frees
    T_W1, K_S2, T_9, K_S1 and the lead-lags. A record's constants are all simulated as written."""

    name = "PSS2A"
    kind = "stabiliser"
    # PSS/E's ICONs: input 1 the rotor speed, input 2 the electrical power (both the machine's own
    # bus), then the ramp-tracking filter's orders
    icons = (("ICS1", 1), ("IB1", 0), ("ICS2", 3), ("IB2", 0), ("M", 5), ("N", 1))
    icons_simulated = ("ICS1", "ICS2", "M", "N")
    needs = ("omega",)
    description = "IEEE dual-input stabiliser on the speed and the electrical power (PSS/E PSS2A)"
    parameters: ClassVar[tuple[ControlParameter, ...]] = (
        ControlParameter("TW1", "s", 2.0, 0.5, 30.0, "washout time constant (the speed's first)"),
        ControlParameter("TW2", "s", 2.0, 2.0, 2.0, "the speed's second washout (T_W1 in a fit)", held=True),
        ControlParameter("T6", "s", 0.0, 0.0, 0.0, "the speed's lag (0 in a fit: a wire)", held=True),
        ControlParameter("TW3", "s", 2.0, 2.0, 2.0, "the power's first washout (T_W1 in a fit)", held=True),
        ControlParameter("TW4", "s", 0.0, 0.0, 0.0, "the power's second washout (0 in a fit: a wire)", held=True),
        ControlParameter("T7", "s", 2.0, 2.0, 2.0, "the power's integrating lag (T_W1 in a fit)", held=True),
        ControlParameter("KS2", "pu", 0.3, 0.01, 10.0, "the power's gain (T_7 / 2H)"),
        ControlParameter("KS3", "", 1.0, 1.0, 1.0, "the power's share before the filter (1 in a fit)", held=True),
        ControlParameter("T8", "s", 0.5, 0.5, 0.5, "ramp-tracking lead (M T_9 in a fit)", held=True),
        ControlParameter("T9", "s", 0.1, 0.01, 1.0, "ramp-tracking lag"),
        ControlParameter("KS1", "pu", 10.0, -200.0, 200.0, "stabiliser gain"),
        ControlParameter("T1", "s", 0.15, 0.0, 5.0, "first lead time constant", absent=0.0),
        ControlParameter("T2", "s", 0.03, 0.002, 5.0, "first lag time constant"),
        ControlParameter("T3", "s", 0.15, 0.0, 5.0, "second lead time constant", absent=0.0),
        ControlParameter("T4", "s", 0.03, 0.002, 5.0, "second lag time constant"),
        ControlParameter("VSTMAX", "pu", 0.1, 0.005, 0.5, "maximum stabiliser output", limit=True),
        ControlParameter("VSTMIN", "pu", -0.1, -0.5, -0.005, "minimum stabiliser output", limit=True),
    )
    simulated_limits = ("VSTMAX", "VSTMIN")
    output_limits = ("VSTMIN", "VSTMAX")
    simulated_limits_how = "V_S within VSTMIN..VSTMAX (PSS/E PSS2A)"
    M, N = 5, 1  # the ramp-tracking filter's orders phid simulates (icons_simulated holds a record to them)

    @classmethod
    def completed(cls, values: Mapping[str, float]) -> dict[str, float]:
        # a fit's structure (see the class); the lead-lags in one order
        tw = values["TW1"]
        return {
            **values,
            **lead_lags_in_order(values),
            "TW2": tw,
            "TW3": tw,
            "T7": tw,
            "T8": cls.M * values["T9"],
        }

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        v = values
        if x.p_e is None:
            return np.full(len(x.v_t), np.nan)  # no electrical power: the model does not apply
        speed = lag(washout(washout(x.speed, v["TW1"], x.dt), v["TW2"], x.dt), v["T6"], x.dt)
        power = v["KS2"] * lag(washout(washout(x.p_e, v["TW3"], x.dt), v["TW4"], x.dt), v["T7"], x.dt)
        tracked = speed + v["KS3"] * power
        for _ in range(cls.N):
            tracked = lead_lag(tracked, v["T8"], v["T9"], x.dt)
            for _ in range(cls.M - 1):
                tracked = lag(tracked, v["T9"], x.dt)
        u = tracked - power
        return v["KS1"] * lead_lag(lead_lag(u, v["T1"], v["T2"], x.dt), v["T3"], v["T4"], x.dt)

    @classmethod
    def limited(
        cls, values: Mapping[str, float], x: ControlInputs, reference: float, levels: OperatingLevels
    ) -> Array | None:
        return cls.output_clipped(values, x, reference, levels)


@register
class PSS2B(PSS2A):
    """IEEE 421.5-2005's PSS2B (PSS/E PSS2B): PSS2A with a third lead-lag (1 + sT_10)/(1 + sT_11)
    after the other two and limits on its two inputs (VSI1MAX/VSI1MIN on the speed,
    VSI2MAX/VSI2MIN on the electrical power), which a stabiliser's small-signal play-in never
    reaches: written, said where a record's are played, not simulated.

    Fitted as PSS2A is (the same structure held), the third lead-lag free; started where PSS2A's
    fit ended, with the third a wire, so it fits at least as well and is named only where the third
    lead-lag earns it (the simplest within 5 % is named). The CONs' order is PSS2A's with T_10,
    T_11 after T_4 and the input limits before VSTMAX, VSTMIN (23 CONs, 6 ICONs): the order of
    PowerSystems.jl's PSS2B, and the one PSS/E itself was given in ALSETLab's OpenIPSL verification
    runs (NYPAModelTransformation, ``OpenIPSLVerification/VerificationRoutines/PSSE/Scripts/
    add_models_openipsl.py``: ``psspy.add_plant_model(..., "PSS2B", ..., 6, [1, 0, 3, 0, 0, 0], ...,
    23, [...])``), whose values read in this order are a coherent unit: the washouts and T_7 2 s,
    K_S2 0.1564, K_S3 1, K_S1 10, the lead-lags 0.25/0.03 and 0.15/0.015 s, T_10 = T_11 = 0, the
    input limits +-999 and V_S within +-0.1 (PSS/E's manual itself is not at hand here)."""

    name = "PSS2B"
    description = "IEEE dual-input stabiliser with a third lead-lag (PSS/E PSS2B, IEEE 421.5-2005)"
    parameters: ClassVar[tuple[ControlParameter, ...]] = (
        *(p for p in PSS2A.parameters if not p.limit),
        ControlParameter("T10", "s", 0.1, 0.0, 5.0, "third lead time constant", absent=0.0),
        ControlParameter("T11", "s", 0.1, 0.002, 5.0, "third lag time constant"),
        ControlParameter("VSI1MAX", "pu", 2.0, 0.01, 10.0, "maximum of the speed input", limit=True),
        ControlParameter("VSI1MIN", "pu", -2.0, -10.0, -0.01, "minimum of the speed input", limit=True),
        ControlParameter("VSI2MAX", "pu", 2.0, 0.01, 10.0, "maximum of the electrical power input", limit=True),
        ControlParameter("VSI2MIN", "pu", -0.66, -10.0, -0.01, "minimum of the electrical power input", limit=True),
        *(p for p in PSS2A.parameters if p.limit),
    )
    simulated_limits_how = "V_S within VSTMIN..VSTMAX (PSS/E PSS2B)"
    LEAD_LAGS: ClassVar[tuple[tuple[str, str], ...]] = (("T1", "T2"), ("T3", "T4"), ("T10", "T11"))

    @classmethod
    def start(cls, earlier: Mapping[str, Mapping[str, float]]) -> dict[str, float]:
        pss2a = earlier.get("PSS2A")
        if not pss2a:
            return cls.defaults()
        # PSS2A is PSS2B with its third lead-lag a wire
        return {**cls.defaults(), **{k: v for k, v in pss2a.items() if k in cls.defaults()}, "T10": 0.1, "T11": 0.1}

    @classmethod
    def completed(cls, values: Mapping[str, float]) -> dict[str, float]:
        return {**super().completed(values), **lead_lags_in_order(values, cls.LEAD_LAGS)}

    @classmethod
    def response(cls, values: Mapping[str, float], x: ControlInputs, reference: float) -> Array:
        return lead_lag(super().response(values, x, reference), values["T10"], values["T11"], x.dt)
