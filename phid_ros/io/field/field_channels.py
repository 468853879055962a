"""Mapped field channels -> the identification's channels (t, v_t, theta_t, i_d, i_q, ...).

Shared by the COMTRADE and PMU importers: a reader hands over a function that returns a
recorded channel by name, the sample rate and the recording's name; this turns them into the
per-unit channels of a scenario, in the recording's synchronous frame (a reference rotating
at the system frequency before the disturbance: the single-machine model's infinite bus).
With waveforms, every channel goes through the same one-cycle window as the phasors (the DFT
for the waveforms, its moving average for the channels recorded as values), so all share one
delay and one bandwidth and are stamped at the window's centre.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.errors import CsvImportError
from phid_ros.io.csvset.csv_import import (
    KINDS,
    ROLES,
    ScenarioTable,
    each_once,
    recording_from_tables,
    reference_step_of,
)
from phid_ros.io.field import phasors
from phid_ros.io.field.channel_map import (
    FIELD_QUANTITIES,
    PULSES,
    QUANTITIES,
    WAVEFORMS,
    ChannelMap,
    ChannelMapError,
    one_machine,
)
from phid_ros.io.field.phasors import (
    PhasorError,
    blocks,
    moving_average,
    phasor_piece,
    samples_per_cycle,
    sequence_problem,
    system_frequency,
)
from phid_ros.io.recording import (
    FIELD_BASES_KEY,
    MEASUREMENT_WINDOW_KEY,
    NOT_IMPORTED_KEY,
    REGULATORS,
    FieldBases,
    Recording,
)
from phid_ros.io.topics import RECORDER_CHANNELS
from phid_ros.model.channels import NO_LOAD_CURRENT, current_of
from phid_ros.model.conventions import terminal_to_dq

Array = NDArray[np.float64]
CArray = NDArray[np.complex128]
MIN_OUTPUT_RATE_HZ = 1000.0  # waveforms above twice this are decimated to at least this rate


Recorded = Callable[[str, slice], Array]  # a recorded channel's samples in a range, by the channel's name


def identification_channels(
    cmap: ChannelMap, recorded: Recorded, length: int, fs: float, source: str
) -> tuple[Array, dict[str, Array]]:
    """(t from the first sample in s, the CHANNELS in per unit) of ``length`` recorded samples.

    A channel the map does not name comes out NaN (not recorded): the identification runs what
    the others determine. Without a terminal angle (a trend log's V_t, P, Q) the terminal
    voltage is the reference, theta_t is 0 and the frequency the nominal one. A field current
    (``i_fd``), the regulator's and the stabiliser's outputs (``v_r``, ``v_s``) come out beside the
    CHANNELS: a recorder's own channels (:data:`~phid_ros.io.topics.RECORDER_STREAMS`).

    The recording is converted a block at a time (:func:`phasors.blocks`: each block's phasors
    from the samples around it, so the outcome is the whole recording's at once): only the
    outputs are held whole, not the complex phasors and their intermediates (a 2 h, 1 kHz
    recording's would be gigabytes).
    """
    f0 = cmap.f_nominal_hz
    waveforms = cmap.has(*WAVEFORMS[:3])
    try:
        n = samples_per_cycle(fs, f0) if waveforms else 1
    except PhasorError as exc:
        raise ChannelMapError(f"{source}: {exc}") from None
    if waveforms and length < 12 * n:
        raise ChannelMapError(f"{source}: {length} samples: too short for phasors (needs at least 12 cycles)")
    m = length - n + 1
    # waveforms above twice MIN_OUTPUT_RATE_HZ are decimated to at least it
    step = int(fs // MIN_OUTPUT_RATE_HZ) if waveforms and fs >= 2 * MIN_OUTPUT_RATE_HZ else 1
    t = (np.arange(0, m, step, dtype=np.float64) + (n - 1) / 2) / fs
    names = ["v_t", "theta_t", "omega", "delta", "v_f", "p_m", "p_e", "q_e", "i_d", "i_q"]
    pulses = [q for q in PULSES if cmap.has(q)] if not cmap.has("v_ref") else []
    recorder = [c for c in RECORDER_CHANNELS if cmap.has(c)]
    out = {c: np.full(len(t), np.nan) for c in names + recorder + pulses}
    currents: list[tuple[Array, Array]] = []  # (|P + jQ| / V_t, recorded I_t) where both are, for the check
    f_sys = f0
    for s, e, lo, hi in blocks(m, n) if waveforms else blocks(m, 1, 4 * phasors.BLOCK):
        k = np.arange(s, e)
        keep = (k % step) == 0
        rows = slice(-(-s // step), -(-e // step))
        t_block = (k + (n - 1) / 2).astype(np.float64) / fs
        v1, value = _block_phasor(cmap, recorded, fs, n, (s, e, lo, hi), source)
        if s == 0:
            f_sys = _frequency_before(cmap, v1, value, t_block, fs, n)
        frame = np.exp(-2j * np.pi * (f_sys - f0) * t_block)
        v = v1 * frame
        del v1
        if cmap.has("i_a", "i_b", "i_c"):
            i1, _ = _three_phase(cmap, recorded, fs, n, (s, e, lo, hi), ("i_a", "i_b", "i_c"), source)
            i = i1 * frame
            del i1
        elif cmap.has("i_t", "phi_i"):
            i = value("i_t") * np.exp(1j * value("phi_i")) * frame
        elif cmap.open_circuit:
            i = np.zeros_like(v)
        else:  # no voltage, no current (a build-up's first samples from standstill)
            i = np.conj(np.divide(value("p_e") + 1j * value("q_e"), v, out=np.zeros_like(v), where=v != 0))
        del frame
        block = _block_channels(cmap, v, i, value, t_block, f_sys, pulses)
        if cmap.has("i_t") and not cmap.has("phi_i") and cmap.has("p_e", "q_e"):
            currents.append((np.abs(i), value("i_t")))
        for c, x in block.items():
            out[c][rows] = x[keep]
    for c in ("theta_t", "delta"):  # angles are unwrapped within a block; between blocks here
        _unwrap_in_place(out[c])
    _check_terminal_voltage(cmap, out["v_t"], source)  # before the current's check: its cause is the plainer
    if currents:
        _check_current(np.concatenate([a for a, _ in currents]), np.concatenate([b for _, b in currents]), source)
    return t, out


V_T_IMPLAUSIBLE = 1.45  # pu: no machine holds its terminals there; sqrt(3) = 1.73 is a phase-for-line mistake


def _block_channels(
    cmap: ChannelMap, v: Any, i: Any, value: Callable[[str], Array], t_block: Array, f_sys: float, pulses: list[str]
) -> dict[str, Array]:
    """One block's channels from its terminal voltage and current phasors (on the system's
    frequency) and its other recorded values."""
    theta_t = np.angle(v)  # unwrapped over the whole recording by the caller
    if cmap.has("load_angle"):
        delta = theta_t + value("load_angle")
    elif cmap.has("delta"):
        delta = value("delta") - 2 * np.pi * (f_sys - cmap.f_nominal_hz) * t_block
    else:
        delta = None
    block = {"v_t": np.abs(v), "theta_t": theta_t}
    if delta is not None:
        block["delta"] = delta
    if cmap.has("omega"):
        block["omega"] = _speed(cmap, value("omega"), f_sys)
    block.update({q: value(q) for q in ("v_f", "p_m", *RECORDER_CHANNELS, *pulses) if cmap.has(q)})
    if cmap.has("p_e", "q_e"):
        block["p_e"], block["q_e"] = value("p_e"), value("q_e")
    else:
        power = v * np.conj(i)
        block["p_e"], block["q_e"] = power.real, power.imag
    if delta is not None:
        block["i_d"], block["i_q"] = terminal_to_dq(np.abs(i), delta, np.angle(i))
    return block


def _check_terminal_voltage(cmap: ChannelMap, v_t: Array, source: str) -> None:
    """A recording whose V_t stays far above any machine's rating (its 90th percentile above
    :data:`V_T_IMPLAUSIBLE`) is read on a wrong base: most often a line-to-line value mapped as
    phase to neutral (1.73 pu at 1 pu), else the map's kv or PT ratio."""
    known = v_t[np.isfinite(v_t)]
    if known.size < 10:
        return
    high = float(np.percentile(known, 90))
    if high <= V_T_IMPLAUSIBLE:
        return
    spec = next((cmap.channels[q] for q in ("v_t", "v_re", "v_a") if cmap.has(q)), None)
    unit = spec.unit if spec is not None else ""
    if unit in ("V", "kV") and abs(high / np.sqrt(3.0) - 1.0) < 0.25:
        why = (
            f"a line-to-line value mapped as phase to neutral (give unit: {unit}_ll)"
            if spec is not None and spec.quantity != "v_a"
            else "line-to-line waveforms (V_AB) mapped as phase to neutral voltages"
        )
    else:
        why = f"the map's machine kv ({cmap.kv:g}), the PT ratio or the unit ({unit or 'none'}) is wrong"
    raise ChannelMapError(
        f"{source}: V_t reads {high:.3f} pu (90th percentile), above {V_T_IMPLAUSIBLE} pu where no machine runs: {why}"
    )


def _unwrap_in_place(x: Array, block: int = 1 << 18) -> None:
    """``np.unwrap`` of the finite entries, a block at a time (no copies of hours of samples)."""
    last = np.nan
    for s in range(0, len(x), block):
        seg = x[s : s + block]
        known = np.flatnonzero(np.isfinite(seg))
        if known.size:
            y = seg[known] if np.isnan(last) else np.concatenate(([last], seg[known]))
            y = np.unwrap(y)
            seg[known] = y if np.isnan(last) else y[1:]
            last = float(seg[known[-1]])


def _values_of(cmap: ChannelMap, recorded: Recorded, rows: slice, n: int) -> Callable[[str], Array]:
    """A block's value channels (per unit; angles unwrapped) through the phasors' one-cycle window."""

    def value(q: str) -> Array:
        x = _pu(cmap, recorded, q, rows)
        return moving_average(x, n) if n > 1 else x

    return value


def _pu(cmap: ChannelMap, recorded: Recorded, q: str, rows: slice) -> Array:
    spec = cmap.channels[q]
    x = np.asarray(cmap.to_pu(spec, recorded(spec.name, rows)), dtype=float)
    return np.unwrap(x) if QUANTITIES[q][0] == "angle" else x  # recorders wrap angles to +-180 deg


def _three_phase(
    cmap: ChannelMap,
    recorded: Recorded,
    fs: float,
    n: int,
    plan: tuple[int, int, int, int],
    phases: tuple[str, str, str],
    source: str,
) -> tuple[CArray, Array]:
    s, e, lo, hi = plan
    piece = slice(lo, hi + n - 1)
    try:
        xa, xb, xc = (_pu(cmap, recorded, q, piece) for q in phases)
        if cmap.rotation == "acb":  # the recorder's phases turn A-C-B: its C is the B of an A-B-C sequence
            xb, xc = xc, xb
        if lo == 0 and (problem := sequence_problem(xa, xb, xc, n)) is not None:
            names = ", ".join(f"{q}: {cmap.channels[q].name}" for q in phases)
            raise ChannelMapError(f"{source}: {names}: {problem}")
        p, f = phasor_piece(xa, xb, xc, fs, cmap.f_nominal_hz, n, lo)
    except PhasorError as exc:
        raise ChannelMapError(f"{source}: {exc}") from None
    return p[s - lo : e - lo], f[s - lo : e - lo]


def _block_phasor(
    cmap: ChannelMap, recorded: Recorded, fs: float, n: int, plan: tuple[int, int, int, int], source: str
) -> tuple[CArray, Callable[[str], Array]]:
    """(the terminal voltage phasor at the nominal frequency's reference, the value channels) of a block."""
    s, e, _, _ = plan
    value = _values_of(cmap, recorded, slice(s, e + n - 1), n)
    if cmap.has(*WAVEFORMS[:3]):
        return _three_phase(cmap, recorded, fs, n, plan, ("v_a", "v_b", "v_c"), source)[0], value
    if cmap.rectangular:
        return value("v_re") + 1j * value("v_im"), value
    v_mag = value("v_t")
    return (v_mag * np.exp(1j * value("theta_t")) if cmap.has("theta_t") else v_mag.astype(complex)), value


def _frequency_before(
    cmap: ChannelMap, v1: CArray, value: Callable[[str], Array], t: Array, fs: float, n: int
) -> float:
    """The system frequency before the disturbance, from the first block: the reference of the
    synchronous frame (the single-machine model's infinite bus)."""
    f0 = cmap.f_nominal_hz
    if cmap.has(*WAVEFORMS[:3]):
        return system_frequency(v1, fs, f0, n)
    if not cmap.has_terminal_angle:
        return f0
    m = min(len(t), max(int(0.5 * fs), 10))
    return f0 + float(np.polyfit(t[:m], np.unwrap(np.angle(v1[:m])), 1)[0]) / (2 * np.pi)


CURRENT_TOLERANCE = 0.05  # |S|/V against a recorded I_t: beyond this a CT ratio or a base is wrong


def _check_current(from_powers: Array, i_t: Array, source: str) -> None:
    """A recorded I_t against |P + jQ| / V_t: the three disagree when a ratio or base is wrong."""
    loaded = from_powers > 0.1
    if loaded.sum() < 10:
        return
    r = float(np.median(i_t[loaded] / from_powers[loaded]))
    if abs(r - 1.0) > CURRENT_TOLERANCE:
        raise ChannelMapError(
            f"{source}: I_t is {r:.3g} times |P + jQ| / V_t: the CT ratio, a unit or the machine's base "
            "(mva, kv) in the map is wrong"
        )


def _speed(cmap: ChannelMap, x: Array, f_sys: float) -> Array:
    """Speed per unit of the synchronous frame (the grid's frequency before the disturbance)."""
    unit = cmap.channels["omega"].unit
    if unit == "Hz":
        return x / f_sys
    per_nominal = x / cmap.rated_rpm if unit == "rpm" and cmap.rated_rpm else x
    return per_nominal * cmap.f_nominal_hz / f_sys


def scenario_table(path: Path, cmap: ChannelMap, t: Array, channels: dict[str, Array]) -> ScenarioTable:
    """One recording's channels as a scenario, with what the map says of it (by the file's stem)."""
    meta = cmap.scenarios.get(path.stem, {})
    kind, role = meta.get("kind", "unknown"), meta.get("role", "identify")
    if kind not in KINDS or role not in ROLES:
        raise ChannelMapError(f"{cmap.path}: scenarios.{path.stem}: kind must be one of {KINDS}, role one of {ROLES}")
    event = meta.get("event_time_s")
    if event is not None and not (isinstance(event, (int, float)) and t[0] < float(event) < t[-1]):
        raise ChannelMapError(
            f"{cmap.path}: scenarios.{path.stem}: event_time_s {event!r} lies outside the recording's "
            f"{t[0]:.3f} .. {t[-1]:.3f} s"
        )
    damping = meta.get("generator_damping", True)
    if not isinstance(damping, bool):
        raise ChannelMapError(f"{cmap.path}: scenarios.{path.stem}: generator_damping must be true or false")
    ev = None if event is None else float(event)
    notes = []
    if any(q in channels for q in PULSES):
        channels, note = _set_point_from_pulses(cmap, meta, t, channels, f"{cmap.path}: scenarios.{path.stem}")
        notes.append(f"{path.name}: {note}")
    regulator = meta.get("regulator", "")
    if regulator not in ("", *REGULATORS):
        raise ChannelMapError(f"{cmap.path}: scenarios.{path.stem}: regulator must be one of {REGULATORS}")
    table = ScenarioTable(path.stem, kind, role, damping, t, channels, ev, str(path))
    table.notes.extend(notes)
    table.regulator = regulator
    try:
        table.reference_step = reference_step_of(meta.get("reference_step"), f"{cmap.path}: scenarios.{path.stem}")
    except CsvImportError as exc:
        raise ChannelMapError(str(exc)) from None
    if cmap.open_circuit:
        table.notes.append(
            f"{path.name}: no stator quantity mapped ({cmap.path}): imported as a no-load test, breaker open, "
            "P = Q = I = 0"
        )
    return table


def _set_point_from_pulses(
    cmap: ChannelMap, meta: Mapping[str, Any], t: Array, channels: dict[str, Array], where: str
) -> tuple[dict[str, Array], str]:
    """v_ref from the regulator's raise and lower commands: its value at the recording's start plus
    the ramp rate times the time a command was held (each report's command held to the next, as a
    polled log samples it: the trapezoid between them). On Zakucac's polled logs, which record the
    set-point too, this came within 0.002 pu of it (0.0042-0.0046 pu/s fitted file by file)."""
    start = meta.get("set_point_start_pu", cmap.set_point_start)
    if isinstance(start, bool) or not isinstance(start, (int, float)) or not math.isfinite(start) or start <= 0:
        raise ChannelMapError(f"{where}: set_point_start_pu must be a positive number, got {start!r}")
    assert cmap.set_point_rate is not None  # the map refuses pulses without it
    out = {c: x for c, x in channels.items() if c not in PULSES}
    command = np.zeros(len(t))
    for q, sign in zip(PULSES, (1.0, -1.0)):
        if q in channels:
            command += sign * np.clip(np.nan_to_num(channels[q]), 0.0, 1.0)
    held = np.concatenate([[0.0], np.cumsum(0.5 * (command[1:] + command[:-1]) * np.diff(t))])
    out["v_ref"] = float(start) + cmap.set_point_rate * held
    said = (
        f"v_ref from its raise/lower commands at {cmap.set_point_rate:g} pu/s from {float(start):g} pu "
        f"({float(np.min(out['v_ref'])):.4f}-{float(np.max(out['v_ref'])):.4f} pu)"
    )
    return out, said


def field_recording(
    tables: list[ScenarioTable], cmaps: Sequence[ChannelMap], source: str, window_s: float
) -> Recording:
    """The scenario set of several field recordings (each read through one of ``cmaps``, maps of
    one unit), with the window their phasors were measured over."""
    cmap = one_machine(cmaps)
    names = [t.name for t in tables]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise ChannelMapError(f"recordings with the same name {dup}: scenario names must differ")
    _scenarios_name_recordings(tables, cmaps)
    each_once(tables)
    field_notes, bases = calibrate_field(tables, cmaps)
    starts = [t.start_ns for t in tables if t.start_ns is not None]
    # the recording begins when its first file says it did (the import's own date before)
    kwargs = {"start_ns": min(starts)} if starts else {}
    rec = recording_from_tables(tables, cmap.f_nominal_hz, cmap.mva, source, **kwargs)
    rec.warnings.extend(n for t in tables for n in t.notes)
    rec.warnings.extend(field_notes)
    left = left_behind(tables)
    if left:
        rec.warnings.append(left)
        rec.metadata[NOT_IMPORTED_KEY] = ",".join(dict.fromkeys(c for t in tables for c in t.not_imported))
    if window_s > 0:
        rec.metadata[MEASUREMENT_WINDOW_KEY] = repr(window_s)
    if bases.text():
        rec.metadata[FIELD_BASES_KEY] = bases.text()
    return rec


def _scenarios_name_recordings(tables: Sequence[ScenarioTable], cmaps: Sequence[ChannelMap]) -> None:
    """Every map's ``scenarios`` entry names a recording: one of the files read, or a file beside
    them that this import leaves out (a folder's map read for some of its files). An entry that
    names neither (``step_O`` for ``step_0``) is a setting that would be dropped without a word."""
    read = {t.name for t in tables}
    folders = {Path(t.source).parent for t in tables if t.source}
    beside = {Path(p.name.removesuffix(".gz")).stem for d in folders if d.is_dir() for p in d.iterdir()}
    for cmap in cmaps:
        for stem in cmap.scenarios:
            if stem in read or stem in beside:
                continue
            near = difflib.get_close_matches(stem, sorted(read | beside), n=3)
            raise ChannelMapError(
                f"{cmap.path}: scenarios.{stem} names no recording: no file {stem}.* was read or lies beside them"
                + (f" (close: {', '.join(near)})" if near else "")
            )


def left_behind(tables: Sequence[ScenarioTable]) -> str:
    """One line naming the channels the files recorded and no map named, each with the files that
    hold it ("" where there are none): the import leaves them out of the set, and says so."""
    files: dict[str, list[str]] = {}
    for t in tables:
        for column in t.not_imported:
            files.setdefault(column, []).append(t.name)

    def where(names: list[str]) -> str:
        if len(names) == len(tables) > 1:
            return "every file"
        return ", ".join(names) if len(names) <= 3 else f"{len(names)} files"

    if not files:
        return ""
    return (
        "recorded but named by no channel map, so not imported: "
        + "; ".join(f"{c} ({where(n)})" for c, n in files.items())
        + " (map them to use them: v_r takes a regulator's output, v_s a stabiliser's, v_ref the regulator's "
        "set-point, v_ref_raise and v_ref_lower its raise and lower commands)"
    )


STEADY_SHARE = 0.2  # the final fifth of a recording (and the part before its event) as steady states


def _steady_slices(tab: ScenarioTable) -> list[slice]:
    """The recording's steady parts: before its event (or its first fifth) and its final fifth."""
    n = len(tab.t)
    if tab.event_time_s is not None:
        k = int(np.searchsorted(tab.t, tab.event_time_s)) - max(1, n // 100)
    else:
        k = int(n * STEADY_SHARE)
    head = slice(0, k) if k >= 10 else None
    return [sl for sl in (head, slice(int(n * (1 - STEADY_SHARE)), n)) if sl is not None]


def no_load_points(tables: list[ScenarioTable], quantity: str) -> list[tuple[float, float, str]]:
    """(the field quantity as recorded, V_t, the recording) at each steady state without stator current."""
    out = []
    for tab in tables:
        if quantity not in tab.columns:
            continue
        c = tab.columns
        current = current_of(c)
        for sl in _steady_slices(tab):
            if float(np.median(current[sl])) < NO_LOAD_CURRENT:
                out.append((float(np.median(c[quantity][sl])), float(np.median(c["v_t"][sl])), tab.name))
    return out


def calibrate_field(tables: list[ScenarioTable], cmaps: Sequence[ChannelMap]) -> tuple[list[str], FieldBases]:
    """Field quantities recorded in V or A without a stated base get it from the set's no-load tests.

    At no load in steady state the fourth-order model has V_t = E'_q = E_fd (and = I_fd, both in
    IEEE 115's air-gap-line per unit), so the slope of the recorded field quantity against V_t
    through the origin is its base. A saturated no-load point (above rated voltage) gives a base
    too high; the note says how far the points scatter about the line. Returns the notes, and what
    1 pu of each field quantity recorded in V or A is (the map's base or this calibration's).
    """
    notes = []
    bases: dict[str, float] = {}
    for q in FIELD_QUANTITIES:
        cmap = next((m for m in cmaps if q in m.channels), cmaps[0])
        spec = cmap.channels.get(q)
        if spec is None or spec.unit == "pu":
            continue
        if spec.base is not None:
            bases[q] = spec.base
            continue
        pts = no_load_points(tables, q)
        if not pts:
            raise ChannelMapError(
                f"{cmap.path}: {q} ({spec.name}) is recorded in {spec.unit} without a base, and no no-load test "
                f"in the set calibrates it: add one, or give {q}: {{name: {spec.name}, unit: {spec.unit}, "
                f"base: <{spec.unit} at 1 pu on the air-gap line>}}"
            )
        raw, v_t = np.array([p[0] for p in pts]), np.array([p[1] for p in pts])
        base = float(raw @ v_t / (v_t @ v_t))
        bases[q] = base
        scatter = float(np.max(np.abs(raw / (base * v_t) - 1.0)))
        for tab in tables:
            if q in tab.columns:
                tab.columns[q] = tab.columns[q] / base
        recordings = sorted({p[2] for p in pts})
        notes.append(
            f"{q} ({spec.name}): 1 pu = {base:.5g} {spec.unit}, calibrated on the air-gap line from "
            f"{len(pts)} no-load steady state(s) of {', '.join(recordings)} (V_t = {q} at no load; "
            f"V_t {v_t.min():.3f}-{v_t.max():.3f} pu, points within {100 * scatter:.2f} % of the line)"
        )
    return notes, FieldBases(bases.get("v_f"), bases.get("i_fd"))
