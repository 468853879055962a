"""Positive-sequence phasors from three-phase waveforms: one-cycle DFT with frequency tracking.

Each phase goes through a sliding one-cycle DFT at the nominal frequency; its phase is the
signal's at the window's centre (there the Dirichlet kernel is real, so an off-nominal
fundamental keeps its true phase), and the phasor is stamped there. The positive-sequence
combination (X_a + a X_b + a^2 X_c)/3 cancels the
negative-frequency image an off-nominal fundamental leaves in each phase's DFT, and the
frequency tracked from the phasor's rotation corrects the remaining magnitude droop
D(f - f_0) = sin(pi N df/fs)/(N sin(pi df/fs)). A harmonic is rejected exactly at nominal
frequency and nearly so off it (a balanced 5th is negative sequence and cancels as well).

The phasors are then expressed in the recording's synchronous frame: a reference rotating at
the system frequency before the disturbance (fitted over the first cycles), which is the
infinite bus of the single-machine model.
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]

A_OP = np.exp(2j * np.pi / 3)
MIN_SAMPLES_PER_CYCLE = 16
MIN_RATE_HZ = 960.0  # 16 samples per 60 Hz cycle: the lowest rate that resolves a fault's waveform


class PhasorError(ValueError):
    """Waveforms that cannot give phasors (rate, length, cycle not a whole number of samples)."""


def samples_per_cycle(fs: float, f_nominal: float) -> int:
    if fs < MIN_RATE_HZ:
        raise PhasorError(f"sampling rate {fs:g} Hz is below the {MIN_RATE_HZ:g} Hz waveforms need")
    n = fs / f_nominal
    if abs(n - round(n)) > 1e-6 * n:
        raise PhasorError(
            f"sampling rate {fs:g} Hz is not a whole number of samples per {f_nominal:g} Hz cycle ({n:.3f})"
        )
    if round(n) < MIN_SAMPLES_PER_CYCLE:
        raise PhasorError(
            f"sampling rate {fs:g} Hz is below {MIN_SAMPLES_PER_CYCLE} samples per cycle "
            f"({MIN_SAMPLES_PER_CYCLE * f_nominal:g} Hz) needed for waveforms"
        )
    return int(round(n))


def sliding_dft(x: Array, n: int, first: int = 0) -> CArray:
    """RMS phasor of the nominal bin over each window of ``n`` samples, at the window's centre.

    Output k covers samples k .. k+n-1 (len(x) - n + 1 windows); the phase is relative to a
    nominal-frequency reference that is 0 at sample ``-first`` (``x`` a piece of a longer
    recording that starts at its sample ``first``).
    """
    k = (first + np.arange(len(x))) % n  # the reference repeats every cycle: no growing argument
    w = np.exp(-2j * np.pi * k / n)
    c = np.concatenate(([0.0], np.cumsum(x * w)))
    # the reference is absolute (sample 0), so the sum's phase is the signal's at the window centre
    return (np.sqrt(2.0) / n) * (c[n:] - c[:-n])


def positive_sequence(xa: Array, xb: Array, xc: Array, n: int, first: int = 0) -> CArray:
    return (sliding_dft(xa, n, first) + A_OP * sliding_dft(xb, n, first) + A_OP**2 * sliding_dft(xc, n, first)) / 3.0


SEQUENCE_JUDGED_PU = 0.05  # phases smaller than this (per unit) are not judged


def sequence_problem(xa: Array, xb: Array, xc: Array, n: int) -> str | None:
    """What the first cycle of three phases says of how they were mapped, or None: a negative
    sequence above the positive one is B and C swapped (the positive sequence then reads the
    voltage as a small, unbalanced remainder), and a zero sequence the size of the phases is one
    waveform on several phases. Both made X_d -3.6e4 with no word before."""
    if min(len(xa), len(xb), len(xc)) < n:
        return None
    a, b, c = (complex(sliding_dft(np.asarray(x[:n], float), n)[0]) for x in (xa, xb, xc))
    size = max(abs(a), abs(b), abs(c))
    if not np.isfinite(size) or size < SEQUENCE_JUDGED_PU:
        return None  # a current at no load is noise: its sequences say nothing of the map
    zero = abs(a + b + c) / 3.0
    positive = abs(a + A_OP * b + A_OP**2 * c) / 3.0
    negative = abs(a + A_OP**2 * b + A_OP * c) / 3.0
    if zero > 0.8 * size:
        return (
            f"the three phases carry one waveform (zero sequence {zero / size:.2f} of a phase): "
            "one channel mapped to several phases?"
        )
    if negative > positive:
        return (
            f"negative sequence {negative / size:.2f} of a phase, positive {positive / size:.2f}: "
            "phases B and C swapped in the map, or the recorder's phases turn A-C-B (then say rotation: acb in the map)"
        )
    return None


def moving_average(x: Array, n: int) -> Array:
    """The one-cycle window the phasors see, for the channels recorded as values (same delay)."""
    c = np.concatenate(([0.0], np.cumsum(np.asarray(x, float))))
    return (c[n:] - c[:-n]) / n


def tracked_frequency(phasor: CArray, fs: float, f_nominal: float, n: int) -> Array:
    """Frequency (Hz) from the phasor's rotation, averaged over one cycle."""
    ang = np.unwrap(np.angle(phasor))
    rate = np.gradient(ang) * fs / (2 * np.pi)
    return f_nominal + np.convolve(rate, np.ones(n) / n, mode="same")


def droop(df: Array, fs: float, n: int) -> Array:
    """The one-cycle DFT's gain at f_0 + df, centred (real)."""
    num = np.sin(np.pi * n * df / fs)
    den = n * np.sin(np.pi * df / fs)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(np.abs(df) < 1e-12, 1.0, num / den)


def system_frequency(phasor: CArray, fs: float, f_nominal: float, n: int, span_s: float = 0.5) -> float:
    """The frequency before the disturbance: the angle's slope over the first ``span_s`` (>= 10 cycles)."""
    m = max(int(round(span_s * fs)), 10 * n)
    m = min(m, len(phasor))
    t = np.arange(m) / fs
    slope = np.polyfit(t, np.unwrap(np.angle(phasor[:m])), 1)[0]
    return f_nominal + slope / (2 * np.pi)


BLOCK = 1 << 16  # phasors computed this many at a time: a long recording's complex intermediates stay small


def blocks(m: int, n: int, block: int | None = None) -> Iterator[tuple[int, int, int, int]]:
    """(s, e, lo, hi): phasors s..e-1 of ``m``, computed from the phasors lo..hi-1 around them, a
    margin as wide as the tracked frequency's one-cycle average and its central difference
    reach, so a block's phasors are the ones the whole recording at once gives. Phasor k needs
    samples k .. k+n-1."""
    margin = n + 2
    size = block or BLOCK
    for s in range(0, m, size):
        e = min(s + size, m)
        yield s, e, max(0, s - margin), min(m, e + margin)


def phasor_piece(
    xa: Array, xb: Array, xc: Array, fs: float, f_nominal: float, n: int, first: int
) -> tuple[CArray, Array]:
    """:func:`three_phase_phasors` of a piece of a recording that starts at its sample ``first``."""
    p = positive_sequence(xa, xb, xc, n, first)
    f = tracked_frequency(p, fs, f_nominal, n)
    return p / droop(f - f_nominal, fs, n), f


def three_phase_phasors(xa: Array, xb: Array, xc: Array, fs: float, f_nominal: float) -> tuple[CArray, Array]:
    """Positive-sequence RMS phasor (magnitude droop corrected) and tracked frequency, at window centres.

    Computed in :func:`blocks` (to rounding the whole recording at once; the running sums
    restart each block, so they round less on hours of samples).
    """
    n = samples_per_cycle(fs, f_nominal)
    if len(xa) < 12 * n:
        raise PhasorError(f"{len(xa)} samples: too short for phasors (needs at least 12 cycles)")
    xa, xb, xc = (np.asarray(x, float) for x in (xa, xb, xc))
    m = len(xa) - n + 1
    p = np.empty(m, dtype=np.complex128)
    f = np.empty(m)
    for s, e, lo, hi in blocks(m, n):
        piece = slice(lo, hi + n - 1)
        pb, fb = phasor_piece(xa[piece], xb[piece], xc[piece], fs, f_nominal, n, lo)
        p[s:e], f[s:e] = pb[s - lo : e - lo], fb[s - lo : e - lo]
    return p, f
