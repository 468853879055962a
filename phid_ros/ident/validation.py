"""Validation (paper section 4.2): simulate a parameter set on the validation scenarios.

The model (5)-(13) is driven by the measured boundary signals V_t, theta_t, P_m
and V_f (a "play-in" simulation: the grid is whatever the terminal voltage
says, so no network model is assumed) and its rotor angle, speed, fluxes and
P, Q are compared with the reference model's (when the truth is known) or
with the measurement. Metrics: RMS and max delta error (deg) and RMS omega
error (%) as in Table 8; RMSE/MAE/STD of the combined state-trajectory error
as in Table 9; a MOD-026-style check that simulated P and Q stay within
0.05 pu (5 %) of the measurement. V_t is an input of the play-in, so it is not
checked.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from phid_ros.ident.played_inputs import played_input
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.conventions import DEFAULT_F_NOMINAL_HZ, electrical_power, terminal_to_dq
from phid_ros.model.equations import Coefficients, currents, derivatives
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.numerics import rk4
from phid_ros.sim import kernel

Array = NDArray[np.float64]
STEP_SECONDS = 0.004  # RK4 step of the play-in (an even number of samples at 1 kHz)


def play_in_samples(scenario: ScenarioData, step: float = STEP_SECONDS) -> np.ndarray:
    """The sample indices at which play_in reports (every play-in step)."""
    return np.arange(0, scenario.n, play_in_stride(scenario.dt, step))


def play_in_stride(dt: float, step: float = STEP_SECONDS) -> int:
    """Samples per play-in step; even, so the mid-step input is a sample too."""
    return max(2, 2 * int(round(step / dt / 2)))


def play_in_grid(
    scenarios: Sequence[ScenarioData], step: float = STEP_SECONDS
) -> tuple[int, float, list[np.ndarray], int, int]:
    """The play-in's time grid over scenarios run side by side: samples per step, the step in s, each
    scenario's reported sample indices, the steps of the longest, and samples per half step."""
    stride = play_in_stride(scenarios[0].dt, step)
    idx = [np.arange(0, s.n, stride) for s in scenarios]
    return stride, stride * scenarios[0].dt, idx, max(len(i) for i in idx), stride // 2


MOD026_TOLERANCE_PU = 0.05


def staged_samples(
    scenarios: Sequence[ScenarioData],
    name: str,
    m: int,
    steps: int,
    half: int,
    advance: Array | None = None,
    smooth: bool = False,
) -> Array:
    """A channel at every half play-in step (2 * steps - 1 rows), one column per (scenario, model) pair.

    Each scenario holds its last sample after its end. ``advance`` (seconds, one per
    column) reads the channel that much later, undoing a sensor's latency; it is
    linear between samples, so a fitted latency need not be whole samples. ``smooth``
    reads V_t and theta_t with their noise taken out (:mod:`phid_ros.ident.played_inputs`).
    """
    rows = 2 * steps - 1
    out = np.empty((rows, len(scenarios) * m))
    for j, s in enumerate(scenarios):
        pos = np.minimum(np.arange(rows) * half, s.n - 1)
        x = played_input(s, name) if smooth else s[name]
        if advance is None:
            out[:, j * m : (j + 1) * m] = x[pos][:, None]
            continue
        for i in range(m):
            shift = float(advance[j * m + i]) / s.dt
            out[:, j * m + i] = np.interp(pos + shift, np.arange(s.n), x) if shift else x[pos]
    return out


def prepare() -> None:
    """Compile (or load from numba's cache) the compiled play-in now, not in the first run
    (:func:`phid_ros.ident.pipeline.prepare`, which the recalibration node calls, says why)."""
    one = np.ones((3, 1))
    kernel.paper_rk4(np.zeros((4, 1)), (one, one, one, one), Coefficients.of([GeneratorParameters()]), 1, 1e-3)


@dataclass
class Trajectories:
    t: Array
    delta: Array  # (steps + 1, models)
    omega: Array
    e_q: Array
    e_d: Array
    p_e: Array
    q_e: Array
    i_d: Array
    i_q: Array


def play_in(
    scenarios: Sequence[ScenarioData],
    params: Sequence[GeneratorParameters],
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
    step: float = STEP_SECONDS,
) -> list[Trajectories]:
    """Simulate every parameter set on every scenario in one vectorised run.

    Columns are (scenario, parameter set) pairs; scenarios shorter than the
    longest simply hold their last input, and their tail is cut off again.
    """
    m = len(params)
    dt = scenarios[0].dt
    stride, h, idx, steps, half = play_in_grid(scenarios, step)

    v_t, theta, p_m, v_f = (staged_samples(scenarios, n, m, steps, half) for n in ("v_t", "theta_t", "p_m", "v_f"))
    damping_on = np.repeat([1.0 if s.generator_damping else 0.0 for s in scenarios], m)
    coef = Coefficients.of(params, f_nominal_hz, repeat=len(scenarios), damping=damping_on)
    xdp, xqp = coef.x_d_prime, coef.x_q_prime

    def rhs(x: Array, vt: Array, th: Array, pm: Array, vf: Array) -> Array:
        v_d, v_q = terminal_to_dq(vt, x[0], th)
        i_d, i_q = currents(x[2], x[3], v_d, v_q, coef)
        return derivatives(x, pm, v_d * i_d + v_q * i_q, vf, i_d, i_q, coef)  # P_e by (13)

    # initial state: the pre-event steady state as each model sees it
    x0 = np.empty((4, len(scenarios) * m))
    for j, s in enumerate(scenarios):
        pre = s.pre_slice()
        c = slice(j * m, (j + 1) * m)
        x0[0, c] = np.mean(s["delta"][pre])
        x0[1, c] = np.mean(s["omega"][pre])
        x0[2, c] = np.mean(s.v_q[pre]) + xdp[c] * np.mean(s["i_d"][pre])
        x0[3, c] = np.mean(s.v_d[pre]) - xqp[c] * np.mean(s["i_q"][pre])
    # inputs at t_k, t_k + h/2, t_k + h come straight from the 1 kHz samples; compiled where numba
    # is (the same steps on the same functions), else numpy
    states = kernel.paper_rk4(x0, (v_t, theta, p_m, v_f), coef, steps - 1, h)
    if states is None:
        states = rk4(
            rhs,
            x0,
            steps - 1,
            h,
            lambda k: (),
            staged=lambda k, j: (v_t[2 * k + j], theta[2 * k + j], p_m[2 * k + j], v_f[2 * k + j]),
        )
    delta, omega, e_q, e_d = (states[:, i] for i in range(4))
    v_t, theta = v_t[::2], theta[::2]
    v_d, v_q = terminal_to_dq(v_t, delta, theta)
    i_d, i_q = currents(e_q, e_d, v_d, v_q, coef)
    p_e, q_e = electrical_power(v_d, v_q, i_d, i_q)
    out = []
    for j, ii in enumerate(idx):
        c, n = slice(j * m, (j + 1) * m), len(ii)
        out.append(
            Trajectories(
                ii * dt,
                delta[:n, c],
                omega[:n, c],
                e_q[:n, c],
                e_d[:n, c],
                p_e[:n, c],
                q_e[:n, c],
                i_d[:n, c],
                i_q[:n, c],
            )
        )
    return out


@dataclass
class ScenarioMetrics:
    scenario: str
    against: str  # "reference" or "measurement"
    rms_delta_deg: float
    max_delta_deg: float
    rms_omega_pct: float
    rmse: float
    mae: float
    std: float
    max_dp: float
    max_dq: float
    mod026_pass: bool

    def as_dict(self) -> dict:
        return dict(self.__dict__)


@dataclass
class ValidationResult:
    scenarios: list[ScenarioMetrics]
    against: str
    problems: list[str] = field(default_factory=list)

    def worst(self, name: str) -> float:
        vals = [getattr(s, name) for s in self.scenarios]
        return max(vals) if vals else math.nan

    def as_dict(self) -> dict:
        return {
            "against": self.against,
            "scenarios": [s.as_dict() for s in self.scenarios],
            "max_rms_delta_deg": self.worst("rms_delta_deg"),
            "max_rms_omega_pct": self.worst("rms_omega_pct"),
            "mod026_pass": all(s.mod026_pass for s in self.scenarios),
            "problems": self.problems,
        }


def _metrics(name: str, against: str, t: Trajectories, col: int, ref: dict[str, Array]) -> ScenarioMetrics:
    dd = t.delta[:, col] - ref["delta"]
    dw = t.omega[:, col] - ref["omega"]
    parts = [dd, dw] + [getattr(t, k)[:, col] - ref[k] for k in ("e_q", "e_d") if k in ref]
    err = np.concatenate(parts)
    dp = np.max(np.abs(t.p_e[:, col] - ref["p_e"]))
    dq = np.max(np.abs(t.q_e[:, col] - ref["q_e"]))
    return ScenarioMetrics(
        scenario=name,
        against=against,
        rms_delta_deg=float(np.degrees(np.sqrt(np.mean(dd**2)))),
        max_delta_deg=float(np.degrees(np.max(np.abs(dd)))),
        rms_omega_pct=float(100 * np.sqrt(np.mean(dw**2))),
        rmse=float(np.sqrt(np.mean(err**2))),
        mae=float(np.mean(np.abs(err))),
        std=float(np.std(err)),
        max_dp=float(dp),
        max_dq=float(dq),
        mod026_pass=bool(dp <= MOD026_TOLERANCE_PU and dq <= MOD026_TOLERANCE_PU),
    )


PLAY_IN_CHANNELS = frozenset(("v_t", "theta_t", "p_m", "v_f", "delta", "omega", "p_e", "q_e"))


def validate(
    scenarios: Sequence[ScenarioData],
    params: GeneratorParameters,
    reference: GeneratorParameters | None = None,
    f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ,
) -> tuple[ValidationResult, ValidationResult | None]:
    """Metrics of ``params`` on the validation scenarios (role ``validate``; else all scenarios).

    Returns (primary, against measurement): with a reference set the primary
    metrics compare against the reference model's trajectories and the second
    against the measurement; without one the primary is against the measurement.
    One play-in run serves both.
    """
    chosen = [s for s in scenarios if s.role == "validate"]
    problems = []
    if not chosen:
        chosen = list(scenarios)
        problems.append("no validation scenarios in the input: validated on the identification scenarios")
    # the play-in is driven by V_t, theta_t, P_m, E_fd and scored on delta, omega, P, Q: a scenario
    # without one of them is not validated (on NaN channels it counted as a MOD-026 failure, and a
    # model held from a datasheet beside a trend log was withdrawn for it)
    lacking = {s.name: sorted(PLAY_IN_CHANNELS & s.absent) for s in chosen}
    if any(lacking.values()):
        chosen = [s for s in chosen if not lacking[s.name]]
        absent = sorted({c for cs in lacking.values() for c in cs})
        problems.append(
            f"validation: {sum(map(bool, lacking.values()))} scenario(s) not played in: not recorded: "
            f"{', '.join(absent)} (the play-in needs {', '.join(sorted(PLAY_IN_CHANNELS))})"
        )
    sets = [params] + ([reference] if reference is not None else [])
    vs_ref, vs_meas = [], []
    for s, traj in zip(chosen, play_in(chosen, sets, f_nominal_hz) if chosen else []):
        idx = np.arange(0, s.n, play_in_stride(s.dt))
        meas = {"delta": s["delta"][idx], "omega": s["omega"][idx], "p_e": s["p_e"][idx], "q_e": s["q_e"][idx]}
        vs_meas.append(_metrics(s.name, "measurement", traj, 0, meas))
        if reference is not None:
            ref = {k: getattr(traj, k)[:, 1] for k in ("delta", "omega", "e_q", "e_d", "p_e", "q_e")}
            vs_ref.append(_metrics(s.name, "reference", traj, 0, ref))
    measured = ValidationResult(vs_meas, "measurement", list(problems))
    if reference is None:
        return measured, None
    return ValidationResult(vs_ref, "reference", problems), measured
