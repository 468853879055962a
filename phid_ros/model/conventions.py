"""Conventions shared by every layer, stated once.

- Per unit on the machine base; angles in radians (degrees only in reports).
- Generator convention: stator current flowing out of the machine is positive.
- ``delta`` is the rotor angle and ``theta_t`` the terminal-voltage phasor angle,
  both in the synchronous reference frame (the infinite bus / grid reference).
  The internal angle is ``delta - theta_t``, so

      V_d = V_t sin(delta - theta_t),   V_q = V_t cos(delta - theta_t).

  The paper writes (9)-(10) with ``delta`` alone, which only holds when the
  terminal voltage itself is the angle reference; we always use the difference.
- A network-frame phasor ``z`` maps to rotor d/q components by
  ``d + j q = j z exp(-j delta)`` (Sauer & Pai), the same map for voltages and
  currents.
- Nominal frequency is a parameter (paper: 50 Hz).
- Time: every stamp is an integer of nanoseconds (``NS`` per second); a ROS ``Time``
  is its (sec, nanosec) split.
"""

from __future__ import annotations

from datetime import datetime, timedelta, timezone
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

DEFAULT_F_NOMINAL_HZ = 50.0
NS = 1_000_000_000  # nanoseconds per second


def split_stamp(ns: int) -> tuple[int, int]:
    """(sec, nanosec) of a stamp in ns, as builtin_interfaces/Time holds it (nanosec in [0, 1e9))."""
    sec, nanosec = divmod(int(ns), NS)
    return sec, nanosec


def seconds_to_ns(seconds: float) -> int:
    """A duration in s (a message's sample period) as whole ns."""
    return int(round(float(seconds) * NS))


def utc_of_stamp(ns: int) -> datetime:
    """The wall-clock moment of a stamp (ns since the Unix epoch), in UTC."""
    sec, nanosec = split_stamp(ns)
    return datetime.fromtimestamp(sec, tz=timezone.utc) + timedelta(microseconds=nanosec // 1000)


def stamp_of_utc(text: str) -> int:
    """An ISO 8601 date-time (a date alone is its midnight; no zone: UTC) as ns since the Unix epoch.
    Raises ValueError naming the text when it is none."""
    try:
        moment = datetime.fromisoformat(text.strip().replace("Z", "+00:00"))
    except ValueError:
        raise ValueError(f"{text!r} is not an ISO 8601 date-time (e.g. 2026-03-01 or 2026-03-01T08:30:00Z)") from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=timezone.utc)
    delta = moment - datetime(1970, 1, 1, tzinfo=timezone.utc)
    return (delta.days * 86_400 + delta.seconds) * NS + delta.microseconds * 1000


def stamp_ns(t: object) -> int:
    """A builtin_interfaces/Time (anything with ``sec`` and ``nanosec``) in ns."""
    return int(t.sec) * NS + int(t.nanosec)  # type: ignore[attr-defined]


def omega_s(f_nominal_hz: float = DEFAULT_F_NOMINAL_HZ) -> float:
    """Synchronous electrical speed in rad/s, ``2 pi f0``."""
    return 2.0 * np.pi * float(f_nominal_hz)


def dq_of(v: Any, internal: Any) -> tuple[Any, Any]:
    """(9)-(10) corrected: ``(V sin a, V cos a)`` for the internal angle ``a = delta - theta``.

    Plain arithmetic on floats or arrays: the compiled play-in compiles this very function."""
    return v * np.sin(internal), v * np.cos(internal)


def powers(v_d: Any, v_q: Any, i_d: Any, i_q: Any) -> tuple[Any, Any]:
    """(13) and its reactive twin: ``(V_d I_d + V_q I_q, V_q I_d - V_d I_q)``, floats or arrays
    (compiled by the play-in too)."""
    return v_d * i_d + v_q * i_q, v_q * i_d - v_d * i_q


def terminal_to_dq(
    v_t: ArrayLike, delta: ArrayLike, theta_t: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(V_d, V_q) from the terminal magnitude and the two angles, eqs. (9)-(10) corrected."""
    internal = np.asarray(delta, dtype=float) - np.asarray(theta_t, dtype=float)
    return dq_of(np.asarray(v_t, dtype=float), internal)


def dq_to_terminal(v_d: ArrayLike, v_q: ArrayLike, delta: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(V_t, theta_t) from d/q components and the rotor angle; inverse of :func:`terminal_to_dq`."""
    vd = np.asarray(v_d, dtype=float)
    vq = np.asarray(v_q, dtype=float)
    return np.hypot(vd, vq), np.asarray(delta, dtype=float) - np.arctan2(vd, vq)


def network_to_dq(phasor: ArrayLike, delta: ArrayLike) -> NDArray[np.complex128]:
    """Network-frame complex phasor -> ``d + j q`` in the rotor frame."""
    return 1j * np.asarray(phasor, dtype=complex) * np.exp(-1j * np.asarray(delta, dtype=float))


def dq_to_network(dq: ArrayLike, delta: ArrayLike) -> NDArray[np.complex128]:
    """``d + j q`` in the rotor frame -> network-frame complex phasor."""
    return -1j * np.asarray(dq, dtype=complex) * np.exp(1j * np.asarray(delta, dtype=float))


def electrical_power(
    v_d: ArrayLike, v_q: ArrayLike, i_d: ArrayLike, i_q: ArrayLike
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(P_e, Q_e) at the terminals: eq. (13) and ``Q = V_q I_d - V_d I_q``."""
    return powers(*(np.asarray(a, float) for a in (v_d, v_q, i_d, i_q)))
