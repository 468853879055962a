"""Stage 1: mechanical parameters H and D.

(b) ``swing_regression`` (default, works on plant data): the swing equation (22)
passed through one linear low-pass filter F,

    F[P_m - P_e] = 2H d/dt F[omega] + D F[omega - 1] + b_s + sum_j c_j F[delta_kj],

a linear least-squares problem with no numerical derivative of noisy data (the
derivative is taken of the filtered signal, exactly). The noisy power
measurements sit on the measured side; the precise speed signal forms the
regressors (errors in variables would otherwise bias H and D down). b_s absorbs
a per-scenario offset between the P_m and P_e transducers. The impulse terms c_j
at the switching instants (fault inception and clearing, torque steps) absorb
the within-sample timing of a switch: without them a sampled fault looks half a
sample early or late, and because D is tiny next to the synchronising power that
half millisecond alone biases D by 2H*tau*omega_n^2 (about 0.15 pu here).

(a) ``differential_damping``: the paper's method (section 3.3.1, Algorithm 1
lines 1-9) on dampingless/normal pairs: exponential envelope of the speed peaks
-> zeta, omega_n; D_gen = 4H(zeta_n w_n,n - zeta_dl w_n,dl) averaged over pairs;
H the median of (31) over |d omega/dt| > 0.001 with 1 < H < 10 (32).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy.optimize import OptimizeWarning, curve_fit

from phid_ros.errors import StageError
from phid_ros.ident.constraints import NONE, Constraints, at_user_bound, held
from phid_ros.ident.results import STD_CALIBRATION, Estimate, flag
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.uncertainty import block_ids, cluster_robust_cov, information_share
from phid_ros.numerics import find_peaks, lowpass2, lowpass2_derivative

DEFAULT_CUTOFF_HZ = 2.0
BLOCK_SECONDS = 1.0
WINDOW_AFTER_EVENT_S = 15.0  # the swing has died out long before; the steady tail adds only noise


class Stage1Error(StageError):
    """Stage 1 cannot run on these scenarios (no swing, no damping to see)."""


@dataclass
class Stage1Result:
    method: str
    H: Estimate
    D: Estimate
    scenarios: list[str]
    details: dict = field(default_factory=dict)
    problems: list[str] = field(default_factory=list)


def usable_for_stage1(sc: ScenarioData) -> bool:
    """Every disturbance swings the rotor; torque steps and faults do it most."""
    return sc.role == "identify"


def _impulse_response(cutoff_hz: float, dt: float) -> np.ndarray:
    """F applied to a unit impulse, cut where it has decayed to 1e-9 of its peak."""
    n = int(np.ceil(12.0 / (2 * np.pi * cutoff_hz) / dt)) + 2
    e = np.zeros(n)
    e[0] = 1.0
    h = lowpass2(e, cutoff_hz, dt)
    keep = np.flatnonzero(np.abs(h) > 1e-9 * np.abs(h).max())
    return h[: keep[-1] + 1]


def _scenario_rows(s: ScenarioData, cutoff_hz: float, h_imp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """One scenario's filtered swing equation with its nuisance terms projected out: (y, [H, D] columns)."""
    dt = s.dt
    pre = s.pre_slice()
    end = min(s.n, s.k_event + int(round(WINDOW_AFTER_EVENT_S / dt)))
    omega = s["omega"][:end]
    w0 = float(np.mean(omega[pre]))
    # without a P_m channel P_m is taken constant between steps: its constant cancels against
    # the pre-event balance below, and a torque step's unknown size is a step column of its own
    p_m = s["p_m"] if s.has("p_m") else np.zeros(s.n)
    dp = (p_m - s["p_e"])[:end]
    # filters start from rest on deviations from the pre-event steady state: exactly
    # linear, no start-up transient; the D column is then F[omega - omega_0] because the
    # pre-event balance already holds D(omega_0 - 1) and the transducer offsets
    y = lowpass2(dp - float(np.mean(dp[pre])), cutoff_hz, dt)
    main = np.column_stack(
        [
            2.0 * lowpass2_derivative(omega - w0, cutoff_hz, dt),
            lowpass2(omega - w0, cutoff_hz, dt) if s.generator_damping else np.zeros(end),
        ]
    )
    nuisance = [lowpass2(np.ones(end), cutoff_hz, dt)]
    if not s.has("p_m") and s.kind == "torque_step":
        nuisance.append(lowpass2((np.arange(end) >= s.k_event).astype(float), cutoff_hz, dt))
    for k in (k for k in s.switching if k < end):
        for lag in (0, 1):  # impulse and doublet: any sub-sample switching time
            col = np.zeros(end)
            seg = h_imp[: end - k]
            col[k : k + len(seg)] += seg
            if lag:
                seg1 = h_imp[: end - k + 1]
                col[k - 1 : k - 1 + len(seg1)] -= seg1
            nuisance.append(col)
    z = np.column_stack(nuisance)
    coef, *_ = np.linalg.lstsq(z, np.column_stack([y, main]), rcond=None)
    resid = np.column_stack([y, main]) - z @ coef
    return resid[:, 0], resid[:, 1:]


def swing_regression(
    scenarios: Sequence[ScenarioData], cutoff_hz: float = DEFAULT_CUTOFF_HZ, constraints: Constraints = NONE
) -> Stage1Result:
    scs = [s for s in scenarios if usable_for_stage1(s)]
    if not scs:
        raise Stage1Error("stage 1 needs at least one disturbance (a torque step or a fault)")
    if not any(s.generator_damping for s in scs):
        raise Stage1Error("stage 1: every scenario is dampingless, D cannot be identified")
    # Per-scenario nuisance terms (offset, switching impulses) touch only that scenario's
    # rows, so they are projected out scenario by scenario (Frisch-Waugh-Lovell) and the
    # final fit has two columns: same estimate as one big regression, far less work.
    h_imp = _impulse_response(cutoff_hz, scs[0].dt)
    rows = [
        s.derived(
            ("stage1_rows", cutoff_hz, scs[0].dt, tuple(s.switching)), partial(_scenario_rows, s, cutoff_hz, h_imp)
        )
        for s in scs
    ]
    X = np.vstack([x for _, x in rows])
    Y = np.concatenate([y for y, _ in rows])
    lengths = [len(y) for y, _ in rows]
    theta, free, clipped = _constrained_fit(X, Y, constraints)
    resid = Y - X @ theta
    blocks = block_ids(lengths, max(1, int(round(BLOCK_SECONDS / scs[0].dt))))
    # the held and clipped columns leave the regression: the free ones' covariance without them
    cov = np.zeros((2, 2))
    if free:
        cov[np.ix_(free, free)] = cluster_robust_cov(X[:, free], resid, blocks)
    names = [s.name for s in scs]
    h_share = information_share(X, lengths, 0)
    d_share = information_share(X, lengths, 1)
    sd = STD_CALIBRATION * np.sqrt(np.maximum(np.diag(cov), 0.0))
    H = flag(Estimate(float(theta[0]), float(sd[0]), drivers=_top(names, h_share)), "H")
    D = flag(Estimate(float(theta[1]), float(sd[1]), drivers=_top(names, d_share)), "D")
    ests = [H, D]
    for j, name in enumerate(SWING_PARAMETERS):
        if name in constraints.fixed:
            ests[j] = held(name, constraints.fixed[name])
        elif name in clipped:  # no error bar: the number is the bound's
            ests[j] = at_user_bound(Estimate(float(theta[j]), math.nan), name, clipped[name], float(theta[j]))
    H, D = ests
    damped = [s for s in scs if s.generator_damping]
    if len(damped) < 2 and D.identifiable:
        # D is a few percent of the plant's total damping; one swing's estimate scattered up to
        # 3 std in the coverage study (and +19 % on one torque step): it needs a second event
        D.disqualify("D rests on a single swing event; record another torque step or fault to confirm it")
    rms = float(np.sqrt(np.mean(resid**2)))
    return Stage1Result(
        "swing_regression",
        H,
        D,
        names,
        details={
            "cutoff_hz": cutoff_hz,
            "residual_rms_pu": rms,
            "samples": int(len(Y)),
            "information_share_D": dict(zip(names, d_share.round(4).tolist())),
        },
    )


SWING_PARAMETERS = ("H", "D")  # the regression's two columns


def _constrained_fit(
    x: np.ndarray, y: np.ndarray, constraints: Constraints
) -> tuple[np.ndarray, list[int], dict[str, float]]:
    """Least squares with held columns and bounds (an active set over two columns).

    Returns the coefficients, the free columns, and for each parameter held at a bound the
    value the data wanted.
    """
    theta = np.array([constraints.fixed.get(n, math.nan) for n in SWING_PARAMETERS])
    clipped: dict[str, float] = {}
    while True:
        free = [j for j in range(2) if math.isnan(theta[j])]
        if not free:
            return theta, free, clipped
        rhs = y - x[:, [j for j in range(2) if j not in free]] @ theta[[j for j in range(2) if j not in free]]
        sol, *_ = np.linalg.lstsq(x[:, free], rhs, rcond=None)
        out = [(j, v) for j, v in zip(free, sol) if constraints.outside(SWING_PARAMETERS[j], float(v))]
        if not out:
            theta[free] = sol
            return theta, free, clipped
        j, v = out[0]
        clipped[SWING_PARAMETERS[j]] = float(v)
        theta[j] = constraints.clip(SWING_PARAMETERS[j], float(v))


def _top(names: list[str], share: np.ndarray, k: int = 3) -> list[str]:
    order = np.argsort(share)[::-1][:k]
    return [names[i] for i in order if share[i] > 0.05]


# -- (a) the paper's differential damping method ---------------------------------------
def _envelope(s: ScenarioData, window_s: float = 15.0) -> tuple[float, float]:
    """(alpha, omega_d) of the speed oscillation after the event, from its peaks (23)-(24)."""
    k0 = s.k_event if s.k_clear is None else s.k_clear
    k1 = min(s.n, k0 + int(window_s / s.dt))
    w = s["omega"][k0:k1]
    w_ss = float(np.mean(s["omega"][s.steady_slice()]))
    dev = lowpass2(w - w_ss, 10.0, s.dt, steady_start=True)  # the encoder's noise makes false peaks
    peaks = find_peaks(np.abs(dev), distance=max(1, int(0.1 / s.dt)))
    peaks = peaks[np.abs(dev[peaks]) > 20 * max(float(np.std(s["omega"][s.steady_slice()])), 1e-9)]
    if len(peaks) < 3:
        raise Stage1Error(f"{s.name}: fewer than 3 speed oscillation peaks above the noise")
    t = peaks * s.dt
    amp = np.abs(dev[peaks])

    def envelope(tt: np.ndarray, a0: float, alpha: float) -> np.ndarray:
        return a0 * np.exp(-alpha * tt)

    # MINPACK's Levenberg-Marquardt: our own exact-Jacobian version of it reached the same optimum
    # (to 1e-7) 2.7x slower (benchmarks/bench_own_code.py, 2026-11-25), so the library's it is
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", OptimizeWarning)  # the covariance it could not form: not used
            (_, alpha), _ = curve_fit(envelope, t - t[0], amp, p0=(amp[0], 0.5), method="lm", maxfev=2000)
    except (RuntimeError, ValueError) as exc:  # no convergence within maxfev; non-finite data
        raise Stage1Error(f"{s.name}: the speed envelope's exponential fit failed: {exc}") from exc
    # |dev| peaks come every half period
    omega_d = math.pi / float(np.mean(np.diff(t)))
    return float(alpha), omega_d


def differential_damping(scenarios: Sequence[ScenarioData], torque_of: dict[str, float] | None = None) -> Stage1Result:
    torque = [s for s in scenarios if s.kind == "torque_step" and s.role == "identify"]
    dl = [s for s in torque if not s.generator_damping]
    normal = [s for s in torque if s.generator_damping]
    if not dl:
        raise Stage1Error("the differential damping method needs dampingless torque scenarios (simulation only)")

    def step(s: ScenarioData) -> float:
        if torque_of and s.name in torque_of:
            return torque_of[s.name]
        k = s.k_event
        span = int(0.5 / s.dt)
        return float(np.mean(s["p_m"][k : k + span]) - np.mean(s["p_m"][max(0, k - span) : k]))

    pairs = []
    for a in dl:
        match = min(normal, key=lambda b: abs(step(b) - step(a)), default=None)
        if match is not None and abs(step(match) - step(a)) < 0.02:
            pairs.append((a, match))
    if not pairs:
        raise Stage1Error("no normal torque scenario matches a dampingless one in step size")
    # H_init from (31) with D = 0, then D from the pairs, then H again with D (Algorithm 1)
    h_init = _median_h(torque, 0.0)
    d_gen, table = [], []
    for a, b in pairs:
        alpha_dl, wd_dl = _envelope(a)
        alpha_n, wd_n = _envelope(b)
        z_dl, wn_dl = alpha_dl / math.hypot(alpha_dl, wd_dl), math.hypot(alpha_dl, wd_dl)
        z_n, wn_n = alpha_n / math.hypot(alpha_n, wd_n), math.hypot(alpha_n, wd_n)
        d_grid = 4 * z_dl * h_init * wn_dl  # (27)
        d_total = 4 * z_n * h_init * wn_n  # (28)
        d_gen.append(d_total - d_grid)  # (29)
        table.append(
            {
                "dampingless": a.name,
                "normal": b.name,
                "zeta_dl": z_dl,
                "omega_n_dl": wn_dl,
                "zeta_normal": z_n,
                "omega_n_normal": wn_n,
                "D_grid": d_grid,
                "D_total": d_total,
                "D_gen": d_total - d_grid,
            }
        )
    d_id = float(np.mean(d_gen))  # (30)
    h_id = _median_h(torque, d_id)
    d_std = float(np.std(d_gen, ddof=1) / math.sqrt(len(d_gen))) if len(d_gen) > 1 else math.nan
    return Stage1Result(
        "differential_damping",
        flag(Estimate(h_id, note="median of (31)", drivers=[s.name for s in torque]), "H"),
        flag(Estimate(d_id, d_std, drivers=[p for a, b in pairs for p in (a.name, b.name)]), "D"),
        [s.name for s in torque],
        details={"H_init": h_init, "pairs": table},
    )


def _median_h(scenarios: Sequence[ScenarioData], d: float, cutoff_hz: float = 10.0) -> float:
    """Equations (31)-(32): median of H(t_k) over |d omega/dt| > 0.001 and 1 < H < 10."""
    values = []
    for s in scenarios:
        w = s["omega"]
        wdot = lowpass2_derivative(w - w[0], cutoff_hz, s.dt)
        pm = lowpass2(s["p_m"], cutoff_hz, s.dt, steady_start=True)
        pe = lowpass2(s["p_e"], cutoff_hz, s.dt, steady_start=True)
        wf = lowpass2(w, cutoff_hz, s.dt, steady_start=True)
        d_s = d if s.generator_damping else 0.0
        ok = np.abs(wdot) > 0.001
        h = (pm[ok] - pe[ok] - d_s * (wf[ok] - 1.0)) / (2.0 * wdot[ok])
        values.append(h[(h > 1.0) & (h < 10.0)])
    allv = np.concatenate(values) if values else np.zeros(0)
    if allv.size == 0:
        raise Stage1Error("equation (31): no sample with |d omega/dt| > 0.001 gives 1 < H < 10")
    return float(np.median(allv))
