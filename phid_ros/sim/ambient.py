"""Long recordings for the sliding-window tracker: ambient fluctuations, small steps, drift.

One continuous trajectory of the plant of :mod:`plant` (same equations, same
network) with
- mechanical power and infinite-bus voltage wandering as Ornstein-Uhlenbeck
  processes (load and grid ambient noise),
- occasional small torque and voltage steps,
- any parameter drifting linearly between two times (e.g. T'_d0 +10 % as the
  field winding warms).

A single long trajectory cannot be vectorised over scenarios, and numpy on
one-element arrays costs more than the arithmetic, so this integrator runs RK4
on plain Python floats (about 10x faster here); a test checks it against
:class:`~phid_ros.sim.plant.Plant` step for step.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import SimulationError
from phid_ros.model.conventions import dq_of, electrical_power, omega_s
from phid_ros.model.equations import airgap_power, field_d, field_q, rotor_angle, stator, swing
from phid_ros.model.parameters import PARAMETER_NAMES
from phid_ros.numerics import recursive_first_order
from phid_ros.sim.network import terminal_dq
from phid_ros.sim.runner import SimulationConfig

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Drift:
    parameter: str
    start_s: float
    end_s: float
    relative_change: float


@dataclass(frozen=True)
class AmbientSettings:
    duration_s: float = 1800.0
    load_std: float = 0.01  # pu, OU standard deviation of P_m
    load_tau_s: float = 30.0
    voltage_std: float = 0.003  # relative, OU standard deviation of V_inf
    voltage_tau_s: float = 20.0
    step_every_s: float = 60.0  # a small disturbance this often, alternating torque and voltage
    torque_step: float = 0.04  # pu
    voltage_step: float = 0.03  # relative
    drifts: tuple[Drift, ...] = ()
    seed: int = 0


@dataclass
class AmbientRun:
    t: Array
    truth: dict[str, Array]
    measured: dict[str, Array]
    parameters: dict[str, Array] = field(default_factory=dict)  # true value of each drifting parameter


def _ou(n: int, dt: float, std: float, tau: float, rng: np.random.Generator, start: float = 0.0) -> Array:
    """An Ornstein-Uhlenbeck path of ``n`` steps continuing from ``start``."""
    a = math.exp(-dt / tau)
    x = recursive_first_order(std * math.sqrt(1 - a * a) * rng.standard_normal(n), a)
    if start:
        x += start * a ** np.arange(1, n + 1)
    return x


CHUNK_S = 600.0  # simulated, measured and handed on this much at a time: a day in the memory of 10 minutes


@dataclass
class AmbientChunk:
    """Consecutive samples of an ambient run (``t`` from the run's start)."""

    t: Array
    truth: dict[str, Array]
    measured: dict[str, Array]
    parameters: dict[str, Array]  # true value of each drifting parameter


def simulate_ambient(settings: AmbientSettings, cfg: SimulationConfig | None = None) -> AmbientRun:
    """The whole run at once (:func:`ambient_chunks` joined)."""
    chunks = list(ambient_chunks(settings, cfg))

    def joined(key: str) -> dict[str, Array]:
        return {c: np.concatenate([getattr(k, key)[c] for k in chunks]) for c in getattr(chunks[0], key)}

    return AmbientRun(np.concatenate([k.t for k in chunks]), joined("truth"), joined("measured"), joined("parameters"))


def ambient_chunks(
    settings: AmbientSettings, cfg: SimulationConfig | None = None, chunk_s: float = CHUNK_S
) -> Iterator[AmbientChunk]:
    """The run in chunks of ``chunk_s``: its state, the wander's state and the random streams
    carried from one to the next (a run no longer than one chunk is what it always was).
    Sensor noise is drawn per chunk, from a seed of its own."""
    cfg = cfg or SimulationConfig()
    p = cfg.params
    dt = cfg.dt
    n = int(round(settings.duration_s / dt))
    per_chunk = max(1, int(round(chunk_s / dt)))
    rng = np.random.default_rng(settings.seed)
    plant = cfg.plant()
    ss = plant.steady_state(cfg.operating_point)
    for d in settings.drifts:
        if d.parameter not in PARAMETER_NAMES:
            raise SimulationError(f"cannot drift unknown parameter {d.parameter!r}")
    ze = plant.network.z_e
    r, x_e = ze.real, ze.imag
    ws = omega_s(cfg.f_nominal_hz)
    v_f = ss.v_f
    x = [ss.delta, 1.0, ss.e_q, ss.e_d]
    load, voltage = 0.0, 0.0  # the wander's state
    a = 0
    chunk = 0
    while a <= n:
        b = min(n + 1, a + per_chunk)  # samples a .. b-1 (the run has n + 1)
        m = b - a
        t = np.arange(a, b, dtype=np.float64) * dt
        # inputs per step: ambient wander plus alternating small steps that come back after half the period
        load_path = _ou(m, dt, settings.load_std, settings.load_tau_s, rng, load)
        volt_path = _ou(m, dt, settings.voltage_std, settings.voltage_tau_s, rng, voltage)
        load, voltage = float(load_path[-1]), float(volt_path[-1])
        p_m = ss.p_m + load_path
        v_inf = ss.v_inf * (1.0 + volt_path)
        period = settings.step_every_s
        k = np.floor(t / period).astype(int)
        in_step = (t % period) < period / 2
        torque_turn = k % 2 == 0
        p_m += np.where(in_step & torque_turn & (t >= period), settings.torque_step, 0.0)
        v_inf *= np.where(in_step & ~torque_turn, 1.0 + settings.voltage_step, 1.0)
        values = {name: np.full(m, getattr(p, name)) for name in PARAMETER_NAMES}
        for d in settings.drifts:
            ramp = np.clip((t - d.start_s) / max(d.end_s - d.start_s, dt), 0.0, 1.0)
            values[d.parameter] = values[d.parameter] * (1.0 + d.relative_change * ramp)
        states = np.empty((m, 4))
        states[0] = x
        x = _integrate(states, x, p_m, v_inf, values, v_f, r, x_e, ws, dt)
        if not np.all(np.isfinite(states)) or np.max(np.abs(states[:, 1] - 1.0)) > 0.05:
            raise SimulationError("the ambient run lost synchronism; reduce the fluctuations or the steps")
        truth = _terminal(states, p_m, v_inf, v_f, values, r, x_e)
        # the first chunk's noise is the one a run in one piece always had
        measured = cfg.sensors.measure(truth, stream_seed=10_000 + settings.seed + 7919 * chunk)
        yield AmbientChunk(t, truth, measured, {d.parameter: values[d.parameter] for d in settings.drifts})
        a = b
        chunk += 1


def _integrate(
    states: Array,
    x: list[float],
    p_m: Array,
    v_inf: Array,
    values: dict[str, Array],
    v_f: float,
    r: float,
    x_e: float,
    ws: float,
    dt: float,
) -> list[float]:
    """RK4 from ``x`` (already ``states[0]``) over the chunk's steps; returns the state one step
    after its last sample (the next chunk's first)."""
    H, D, XD, XQ, XDP, XQP, TD0, TQ0 = (values[k].tolist() for k in PARAMETER_NAMES)
    pm_l, vi_l = p_m.tolist(), v_inf.tolist()
    sin, cos = math.sin, math.cos  # not conventions.dq_of: numpy's sin on a float costs 20x math's
    h2, h6 = 0.5 * dt, dt / 6.0
    m = len(pm_l)
    for j in range(m):
        pm, vi = pm_l[j], vi_l[j]
        xdp, xqp = XDP[j], XQP[j]
        dd, inv_2h, xd_diff, xq_diff = D[j], 0.5 / H[j], XD[j] - xdp, XQ[j] - xqp
        inv_td0, inv_tq0, x_d, x_q = 1.0 / TD0[j], 1.0 / TQ0[j], xdp + x_e, xqp + x_e

        def f(d0: float, w0: float, eq: float, ed: float) -> tuple[float, float, float, float]:
            # the plant's equations (model/equations) with the network's impedance, on floats
            i_d, i_q = stator(eq, ed, vi * sin(d0), vi * cos(d0), r, x_d, x_q)
            return (
                rotor_angle(w0, ws),
                swing(pm, airgap_power(eq, ed, i_d, i_q, xdp, xqp), w0, dd, inv_2h),
                field_d(v_f, eq, i_d, xd_diff, None, inv_td0),
                field_q(ed, i_q, xq_diff, None, inv_tq0),
            )

        d0, w0, eq, ed = x
        k1 = f(d0, w0, eq, ed)
        k2 = f(d0 + h2 * k1[0], w0 + h2 * k1[1], eq + h2 * k1[2], ed + h2 * k1[3])
        k3 = f(d0 + h2 * k2[0], w0 + h2 * k2[1], eq + h2 * k2[2], ed + h2 * k2[3])
        k4 = f(d0 + dt * k3[0], w0 + dt * k3[1], eq + dt * k3[2], ed + dt * k3[3])
        x = [x[i] + h6 * (k1[i] + 2.0 * (k2[i] + k3[i]) + k4[i]) for i in range(4)]
        if j + 1 < m:
            states[j + 1] = x
    return x


def _terminal(
    states: Array, p_m: Array, v_inf: Array, v_f: float, values: dict[str, Array], r: float, x_e: float
) -> dict[str, Array]:
    delta, omega, e_q, e_d = states.T
    xdp, xqp = values["X_d_prime"], values["X_q_prime"]
    vd_inf, vq_inf = dq_of(v_inf, delta)  # the infinite bus is the angle reference
    i_d, i_q = stator(e_q, e_d, vd_inf, vq_inf, r, xdp + x_e, xqp + x_e)
    v_d, v_q = terminal_dq(vd_inf, vq_inf, i_d, i_q, r, x_e)
    p_e, q_e = electrical_power(v_d, v_q, i_d, i_q)
    return {
        "v_t": np.hypot(v_d, v_q),
        "theta_t": delta - np.arctan2(v_d, v_q),
        "i_d": i_d,
        "i_q": i_q,
        "omega": omega,
        "delta": delta,
        "v_f": np.full_like(delta, v_f),
        "p_m": p_m,
        "p_e": p_e,
        "q_e": q_e,
    }
