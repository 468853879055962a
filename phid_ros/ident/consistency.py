"""Physical consistency of a recording before any fit: the mistakes a plant engineer makes.

A recording in the motor (load) sign convention, angles in degrees, time in milliseconds, the
currents' axes swapped, a wrong nominal frequency or P_m in kW beside P_e in MW all identify
*something*, with small standard deviations: H = -3.48 s, X_d +190 %. The stages cannot tell;
the laws that tie the channels together can, and each names the likely mistake:

- the rotor angle's rate against the speed, dδ/dt = ω_s (ω − 1): their ratio is 1; 180/π means
  angles in degrees, 1/1000 time in milliseconds, f/f_declared a wrong nominal frequency;
- the angle between rotor and terminal in steady state, |δ − θ_t| < π/2 for a machine in step;
- the terminal powers, P_e + j Q_e = (13) from V_d, V_q, I_d, I_q (generator convention): a
  match with the currents' signs flipped means the currents and the powers follow different
  conventions, a match with I_d and I_q exchanged that their axes are swapped;
- the steady-state power balance, P_m ≈ P_e (losses are a few per cent): opposite signs mean
  one is in the motor convention, a factor near 1000 a kW/MW mix.

A finding that names a mistake is an error (:class:`ConsistencyError`): nothing is identified
from such data. One that can only suspect (P_m and P_e apart by more than losses explain) is a
:class:`Suspicion`: the identification runs, and the parameters it touches are withheld.
Each check runs only where its channels are measured (finite) and the data carry enough
signal to judge, so a recording without rotor angle is not refused for lacking one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from phid_ros.errors import PhidError
from phid_ros.ident.scenario import ScenarioData
from phid_ros.model.conventions import omega_s, powers

# |P_e| below this (pu) carries no sign to judge: a machine near no load
MIN_POWER_PU = 0.1
# the terminal power balance holds to this (pu, plus 5 % of |P_e|): sensor noise and offsets
POWER_TOLERANCE_PU = 0.02
# P_m / P_e in steady state within these: mechanical and electrical losses, a governor's offset
POWER_RATIO_RANGE = (0.8, 1.25)
# dδ/dt against ω_s (ω − 1): a ratio within this of 1 is consistent
RATE_TOLERANCE = 0.05
# the two must move together this well (correlation) before their ratio is judged
MIN_CORRELATION = 0.95
# the speed against the accelerating power: damping and noise blur it more
SWING_CORRELATION = 0.8


class ConsistencyError(PhidError):
    """The channels contradict the laws that tie them together: a unit or convention mistake."""


@dataclass(frozen=True)
class Suspicion:
    message: str
    parameters: tuple[str, ...]  # withheld: their estimates cannot be trusted if it holds


@dataclass
class Findings:
    errors: list[str] = field(default_factory=list)
    suspicions: list[Suspicion] = field(default_factory=list)
    checked: list[str] = field(default_factory=list)  # which checks had the data to run


def _finite(*arrays: np.ndarray) -> np.ndarray:
    ok = np.ones(len(arrays[0]), bool)
    for a in arrays:
        ok &= np.isfinite(a)
    return ok


def _pre(s: ScenarioData, name: str) -> np.ndarray:
    return np.asarray(s[name][s.pre_slice()], dtype=float)


def _median(values: list[float]) -> float:
    return float(np.median(values)) if values else math.nan


def rate_ratio(s: ScenarioData, f_nominal_hz: float) -> float:
    """The least-squares ratio of δ's change to ∫ ω_s (ω − 1) dt over the scenario; NaN when
    the two do not move together well enough (no swing, a channel missing) to judge."""
    delta, omega = np.asarray(s["delta"], dtype=float), np.asarray(s["omega"], dtype=float)
    ok = _finite(delta, omega)
    if ok.sum() < 0.9 * s.n:
        return math.nan
    delta, omega = delta[ok], omega[ok]
    w_s = omega_s(f_nominal_hz)
    # integrated, not differentiated: the angle's noise stays where it is instead of growing with 1/dt
    x = np.concatenate(([0.0], np.cumsum(0.5 * (omega[1:] + omega[:-1]) - 1.0))) * w_s * s.dt
    y = delta - delta[0]
    x, y = x - x.mean(), y - y.mean()
    sxx, syy = float(x @ x), float(y @ y)
    if sxx <= 0 or syy <= 0:
        return math.nan
    if float(x @ y) ** 2 < MIN_CORRELATION**2 * sxx * syy:
        return math.nan
    return float(x @ y) / sxx


def _near(value: float, target: float, rel: float = RATE_TOLERANCE) -> bool:
    return abs(value - target) <= rel * abs(target)


def _check_rates(scenarios: Sequence[ScenarioData], f_hz: float, out: Findings) -> None:
    ratios = [r for s in scenarios if math.isfinite(r := s.derived(("rate_ratio", f_hz), partial(rate_ratio, s, f_hz)))]
    if not ratios:
        return
    out.checked.append("dδ/dt against ω")
    k = _median(ratios)
    if _near(k, 1.0):
        return
    where = f"the rotor angle changes {k:.4g} times as fast as the speed says (dδ/dt against ω_s (ω − 1))"
    if _near(k, 180.0 / math.pi):
        out.errors.append(f"{where}: angles in degrees? δ and θ_t must be in radians")
    elif _near(k, 1e-3):
        out.errors.append(f"{where}: time in milliseconds? t must be in seconds")
    elif _near(k, 1e3):
        out.errors.append(f"{where}: time in kiloseconds, or ω in the wrong unit? t must be in seconds, ω in pu")
    elif 0.5 < k < 2.0:
        f_data = k * f_hz
        named = next((f for f in (50.0, 60.0, 16.7, 25.0) if _near(f_data, f, 0.02)), None)
        if named is not None:
            out.errors.append(
                f"{where}: the recording moves as a {named:g} Hz machine, its nominal frequency is declared "
                f"{f_hz:g} Hz (f_nominal_hz)"
            )
        else:
            out.suspicions.append(
                Suspicion(f"{where}: check the units of δ and ω and the nominal frequency", ("H", "D"))
            )
    else:
        out.errors.append(f"{where}: check the units of t, δ and ω")


def _check_angles(scenarios: Sequence[ScenarioData], out: Findings) -> None:
    internal = []
    for s in scenarios:
        d, th = _pre(s, "delta"), _pre(s, "theta_t")
        ok = _finite(d, th)
        if ok.sum() >= 10:
            internal.append(float(np.median(d[ok] - th[ok])))
    if not internal:
        return
    out.checked.append("δ − θ_t")
    a = _median(internal)
    if abs(a) > 2 * math.pi and abs(math.radians(a)) < math.pi / 2:
        out.errors.append(f"δ − θ_t is {a:.4g} in steady state, {math.radians(a):.3f} if degrees: angles in degrees?")
    elif abs(math.remainder(a, 2 * math.pi)) > math.pi / 2:
        out.suspicions.append(
            Suspicion(
                f"δ − θ_t is {a:.3f} rad in steady state, beyond π/2: a machine in step cannot hold that; "
                "is δ the rotor angle on the PMU's reference?",
                ("X_d", "X_q", "X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime"),
            )
        )


# how the currents may have been recorded, and what that means for the user
CURRENT_HYPOTHESES = (  # (sign, swapped, the condition, what it means)
    (1.0, False, "", ""),
    (
        -1.0,
        False,
        "the currents' signs are flipped",
        "the currents and P_e, Q_e follow opposite sign conventions (one of them motor/load); "
        "phid reads the generator convention (current out of the machine, P_e > 0 generating)",
    ),
    (1.0, True, "I_d and I_q are exchanged", "are i_d and i_q swapped?"),
    (-1.0, True, "I_d and I_q are exchanged and sign-flipped", "are i_d and i_q swapped and in the motor convention?"),
)


def _terminal_power_row(s: ScenarioData) -> tuple[float, list[float]] | None:
    """One scenario's steady P_e and its mismatch to (13) under each current hypothesis, or None."""
    v_d, v_q, i_d, i_q, p_e, q_e = (_pre(s, c) for c in ("v_d", "v_q", "i_d", "i_q", "p_e", "q_e"))
    ok = _finite(v_d, v_q, i_d, i_q, p_e)
    if ok.sum() < 10:
        return None
    q_ok = ok & np.isfinite(q_e)
    measured = (float(np.median(p_e[ok])), float(np.median(q_e[q_ok])) if q_ok.sum() >= 10 else math.nan)
    if abs(measured[0]) < MIN_POWER_PU:
        return None
    mismatch = []
    for sign, swap, _, _ in CURRENT_HYPOTHESES:
        a, b = (i_q, i_d) if swap else (i_d, i_q)
        p, q = powers(v_d[ok], v_q[ok], sign * a[ok], sign * b[ok])
        dq = abs(float(np.median(q)) - measured[1]) if math.isfinite(measured[1]) else 0.0
        mismatch.append(max(abs(float(np.median(p)) - measured[0]), dq))
    return measured[0], mismatch


def _check_terminal_power(scenarios: Sequence[ScenarioData], out: Findings) -> None:
    """P_e + j Q_e against (13) from V_d, V_q and the currents as recorded, sign-flipped, swapped."""
    rows = [r for s in scenarios if (r := s.derived(("terminal_power",), partial(_terminal_power_row, s)))]
    if not rows:
        return
    out.checked.append("P_e, Q_e against V_d, V_q, I_d, I_q")
    p_steady = _median([r[0] for r in rows])
    mismatch = [_median([r[1][k] for r in rows]) for k in range(len(CURRENT_HYPOTHESES))]
    tol = POWER_TOLERANCE_PU + 0.05 * abs(p_steady)
    if mismatch[0] <= tol:
        return
    best = int(np.argmin(mismatch))
    told = f"P_e, Q_e and (13) from V_d, V_q, I_d, I_q disagree by {mismatch[0]:.3f} pu in steady state"
    if best > 0 and mismatch[best] <= tol:
        _, _, condition, meaning = CURRENT_HYPOTHESES[best]
        out.errors.append(f"{told}, and agree to {mismatch[best]:.3f} pu if {condition}: {meaning}")
    else:
        out.suspicions.append(
            Suspicion(
                f"{told} (stator resistance cannot explain that much)",
                ("X_d", "X_q", "X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime"),
            )
        )


def _check_power_balance(scenarios: Sequence[ScenarioData], out: Findings) -> None:
    ratios, both = [], []
    for s in scenarios:
        p_m, p_e = _pre(s, "p_m"), _pre(s, "p_e")
        ok = _finite(p_m, p_e)
        if ok.sum() < 10:
            continue
        pm, pe = float(np.median(p_m[ok])), float(np.median(p_e[ok]))
        if abs(pe) >= MIN_POWER_PU:
            ratios.append(pm / pe)
            both.append((pm, pe))
    if not ratios:
        return
    out.checked.append("P_m against P_e")
    r = _median(ratios)
    pm, pe = _median([b[0] for b in both]), _median([b[1] for b in both])
    told = f"in steady state P_m is {pm:.4g} pu and P_e {pe:.4g} pu"
    lo, hi = POWER_RATIO_RANGE
    if lo <= r <= hi:
        return
    if -hi <= r <= -lo:
        out.errors.append(
            f"{told}: opposite signs, so one of them is in the motor (load) convention; "
            "phid reads the generator convention (P_m and P_e > 0 generating)"
        )
    elif 300 <= abs(r) <= 3000 or 1 / 3000 <= abs(r) <= 1 / 300:
        out.errors.append(f"{told}: a factor of about {max(abs(r), 1 / abs(r)):.0f}: kW against MW? both must be pu")
    else:
        out.suspicions.append(
            Suspicion(f"{told}: P_m/P_e = {r:.3g}, more than losses explain: check P_m's scaling", ("H", "D"))
        )


def swing_slope(s: ScenarioData) -> float:
    """The least-squares slope of ω's change on ∫ (P_m − P_e) dt over the scenario, 1/(2H) by the
    swing equation (5) with D left out; NaN when the two do not move together well enough."""
    omega, p_m, p_e = (np.asarray(s[c], dtype=float) for c in ("omega", "p_m", "p_e"))
    ok = _finite(omega, p_m, p_e)
    if ok.sum() < 0.9 * s.n:
        return math.nan
    acc = (p_m - p_e)[ok]
    x = np.concatenate(([0.0], np.cumsum(0.5 * (acc[1:] + acc[:-1])))) * s.dt
    y = omega[ok] - omega[ok][0]
    x, y = x - x.mean(), y - y.mean()
    sxx, syy = float(x @ x), float(y @ y)
    if sxx <= 0 or syy <= 0 or float(x @ y) ** 2 < SWING_CORRELATION**2 * sxx * syy:
        return math.nan
    return float(x @ y) / sxx


def _check_swing(scenarios: Sequence[ScenarioData], out: Findings) -> None:
    slopes = [
        k
        for s in scenarios
        if s.kind == "torque_step" and math.isfinite(k := s.derived(("swing_slope",), partial(swing_slope, s)))
    ]
    if not slopes:
        return
    out.checked.append("dω/dt against P_m − P_e")
    k = _median(slopes)
    if k < 0:
        out.errors.append(
            f"the speed falls while P_m exceeds P_e (2H = {1 / k:.3g} s from the torque steps): "
            "P_m and P_e, or ω, are in the motor (load) convention; phid reads the generator convention"
        )


def check(scenarios: Sequence[ScenarioData], f_nominal_hz: float) -> Findings:
    """Every check the scenarios have the channels for, in the order a mistake shows first:
    time and angle units before the powers that are computed from the angles."""
    out = Findings()
    _check_rates(scenarios, f_nominal_hz, out)
    _check_angles(scenarios, out)
    if not out.errors:  # V_d, V_q come from the angles: judged only when those are right
        _check_terminal_power(scenarios, out)
    _check_power_balance(scenarios, out)
    if not out.errors:
        _check_swing(scenarios, out)
    return out


def raise_errors(findings: Findings) -> None:
    """A :class:`ConsistencyError` with the first error (and how many more there are)."""
    if findings.errors:
        more = f" (and {len(findings.errors) - 1} more)" if len(findings.errors) > 1 else ""
        raise ConsistencyError(findings.errors[0] + more)
