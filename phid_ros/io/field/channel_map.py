"""The channel map of a field recording: which recorded channel is which quantity, and its scale.

One format for COMTRADE and PMU exports (YAML or JSON)::

    machine: {mva: 1000, kv: 20, f_nominal_hz: 50}   # kv: rated line-to-line terminal voltage
    time: Timestamp                                     # PMU exports: the report-time column
    date: Date                                          # trend logs: a date column beside time of day
    ratios: {pt: "20000/110", ct: "30000/1"}            # primary/secondary, or a number
    values: secondary                                   # the recorded values' side (default primary)
    rotation: abc                                       # the phases' sequence: abc (default) or acb
    channels:
      v_a: VA                                           # a channel's name, or {name, unit, side}
      i_a: {name: IA, unit: A}
      load_angle: {name: ROTOR, unit: deg}
      omega: {name: SPEED, unit: Hz}
      v_f: EFD                                          # per unit, or {name, unit: V, base: volts per pu}
      # (or the terminal phasor as v_re, v_im: its real and imaginary parts, instead of v_t, theta_t)
      i_fd: {name: IFD, unit: A}                        # field current (stands in for E_fd in steady state)
      p_m: {name: PMECH, unit: MW}
      v_r: UREG                                         # the regulator's output, the controller's units
      v_s: VPSS                                         # the stabiliser's output, as recorded
      v_ref: UREF                                       # the regulator's set-point, pu of the rated V_t
    scenarios:                                          # optional, by recording file stem
      trip_0412: {kind: fault, role: identify, event_time_s: 0.1}

Everything becomes per unit on the machine base: V_base = kv/sqrt(3) per phase, I_base =
mva/(sqrt(3) kv), S_base = mva. Secondary values are scaled by the PT ratio (voltages), the CT
ratio (currents) or both (powers); a secondary value without its ratio is refused. The field's
quantities (E_fd in V, I_fd in A) take their base from the map (``base``: the value that is
1 pu, IEEE 115's air-gap-line base) or, without one, from a no-load test in the same set
(:func:`phid_ros.io.field.field_channels.calibrate_field`).

A no-load test (breaker open) maps the terminal voltage and the field alone (``v_t`` with
``v_f`` and/or ``i_fd``, no stator quantity): it is imported as an open circuit, P = Q = I = 0,
and the import says so. Otherwise the terminal voltage and the stator current (or P and Q) are
required: a channel the
recorder did not carry (rotor angle, speed, P_m, E_fd) is left out of the map, and the
identification determines what the others allow (:mod:`phid_ros.ident.determinable`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from phid_ros.errors import PhidError

# quantity -> (physical kind, units accepted, default unit)
QUANTITIES: dict[str, tuple[str, tuple[str, ...], str]] = {
    **{f"v_{p}": ("voltage", ("V", "kV"), "V") for p in "abc"},  # instantaneous, phase to neutral
    **{f"i_{p}": ("current", ("A", "kA"), "A") for p in "abc"},
    "v_t": ("voltage", ("V", "kV", "V_ll", "kV_ll", "pu"), "kV_ll"),  # RMS magnitude
    "theta_t": ("angle", ("deg", "rad"), "deg"),
    # the terminal voltage phasor as its real and imaginary parts (a recorder's or a simulator's
    # export in its own synchronous frame), instead of v_t and theta_t
    "v_re": ("voltage", ("V", "kV", "V_ll", "kV_ll", "pu"), "kV_ll"),
    "v_im": ("voltage", ("V", "kV", "V_ll", "kV_ll", "pu"), "kV_ll"),
    "i_t": ("current", ("A", "kA", "pu"), "A"),
    "phi_i": ("angle", ("deg", "rad"), "deg"),
    "p_e": ("power", ("W", "kW", "MW", "pu"), "MW"),
    "q_e": ("power", ("var", "kvar", "Mvar", "pu"), "Mvar"),
    "p_m": ("power", ("W", "kW", "MW", "pu"), "MW"),
    "delta": ("angle", ("deg", "rad"), "deg"),  # rotor angle against a nominal-frequency reference
    "load_angle": ("angle", ("deg", "rad"), "deg"),  # rotor angle against the terminal voltage
    "omega": ("speed", ("pu", "Hz", "rpm"), "pu"),
    "v_f": ("field", ("pu", "V"), "pu"),  # E_fd; in V with its base, or calibrated at no load
    "i_fd": ("field", ("pu", "A"), "pu"),  # I_fd; likewise
    # an excitation controller's own signals, as it records them (:data:`phid_ros.io.topics.RECORDER_STREAMS`)
    "v_r": ("controller", ("pu",), "pu"),  # the voltage regulator's output
    "v_s": ("controller", ("pu",), "pu"),  # the power system stabiliser's output
    "v_ref": ("controller", ("pu",), "pu"),  # the voltage regulator's set-point, pu of the rated V_t
    # where the set-point itself is not recorded: its raise and lower commands (on while held,
    # 0/1), integrated at the regulator's ramp rate (the map's set_point: {rate_pu_per_s, start_pu})
    "v_ref_raise": ("command", ("binary",), "binary"),
    "v_ref_lower": ("command", ("binary",), "binary"),
}
PULSES = ("v_ref_raise", "v_ref_lower")
FIELD_QUANTITIES = ("v_f", "i_fd")
WAVEFORMS = ("v_a", "v_b", "v_c", "i_a", "i_b", "i_c")
SCALE = {"V": 1.0, "kV": 1e3, "V_ll": 1.0, "kV_ll": 1e3, "A": 1.0, "kA": 1e3, "W": 1.0, "kW": 1e3, "MW": 1e6}
SCALE.update({"var": 1.0, "kvar": 1e3, "Mvar": 1e6, "deg": math.pi / 180, "rad": 1.0})
ROTATIONS = ("abc", "acb")  # the phase sequence a recorder's A, B, C labels turn in
RATIO_OF = {"voltage": ("pt",), "current": ("ct",), "power": ("pt", "ct")}


class ChannelMapError(PhidError):
    """A channel map that is malformed or does not fit the recording."""


@dataclass(frozen=True)
class ChannelSpec:
    quantity: str
    name: str
    unit: str
    side: str  # primary | secondary
    base: float | None = None  # field quantities in V or A: the value that is 1 pu (None: calibrate)


@dataclass
class ChannelMap:
    path: str
    mva: float
    kv: float
    f_nominal_hz: float
    channels: dict[str, ChannelSpec]
    ratios: dict[str, float] = field(default_factory=dict)
    rated_rpm: float | None = None
    scenarios: dict[str, dict[str, Any]] = field(default_factory=dict)
    time_column: str = "Timestamp"  # PMU exports: the report-time column
    date_column: str | None = None  # trend logs: a date column beside a time-of-day one
    phasor_window_cycles: float = 0.0  # PMU exports: the cycles the PMU's phasor filter spans (0: unknown)
    rotation: str = "abc"  # the waveforms' phase sequence as the recorder's labels turn (abc or acb)
    # the set-point's ramp while a raise or lower command is held (pu/s), and its value where a
    # recording begins (a scenario's own ``set_point_start_pu`` first): for v_ref from its pulses
    set_point_rate: float | None = None
    set_point_start: float = 1.0

    @property
    def v_base(self) -> float:  # per phase, RMS volts
        return self.kv * 1e3 / math.sqrt(3.0)

    @property
    def i_base(self) -> float:
        return self.mva * 1e6 / (math.sqrt(3.0) * self.kv * 1e3)

    def has(self, *quantities: str) -> bool:
        return all(q in self.channels for q in quantities)

    @property
    def has_stator_current(self) -> bool:
        return self.has("i_a", "i_b", "i_c") or self.has("i_t", "phi_i") or self.has("p_e", "q_e")

    @property
    def rectangular(self) -> bool:
        """The terminal voltage phasor mapped as its real and imaginary parts."""
        return self.has("v_re", "v_im")

    @property
    def has_terminal_angle(self) -> bool:
        """The terminal voltage's angle is recorded (theta_t, or the phasor's two parts)."""
        return self.has("theta_t") or self.rectangular

    @property
    def open_circuit(self) -> bool:
        """A no-load test's map: the terminal voltage and the field, no stator quantity at all (the
        breaker is open: no recorder writes a stator current, and P = Q = I = 0)."""
        stator = ("i_a", "i_b", "i_c", "i_t", "phi_i", "p_e", "q_e")
        voltage = self.has("v_t") or self.rectangular
        return voltage and not any(self.has(q) for q in stator) and any(self.has(q) for q in FIELD_QUANTITIES)

    def ratio(self, spec: ChannelSpec) -> float:
        """What turns the recorded value into a primary one (1 for primary values)."""
        kind = QUANTITIES[spec.quantity][0]
        if spec.side == "primary" or kind not in RATIO_OF or spec.unit == "pu":
            return 1.0
        missing = [r for r in RATIO_OF[kind] if r not in self.ratios]
        if missing:
            raise ChannelMapError(
                f"{self.path}: {spec.quantity} ({spec.name}) is a secondary value but the map gives no "
                f"{' and '.join(missing).upper()} ratio (ratios: {{pt: ..., ct: ...}})"
            )
        return math.prod(self.ratios[r] for r in RATIO_OF[kind])

    def to_pu(self, spec: ChannelSpec, x: Any) -> Any:
        """A recorded channel in per unit on the machine base (angles in radians, speed as recorded,
        a field quantity without its base as recorded: :func:`field_channels.calibrate_field`)."""
        kind = QUANTITIES[spec.quantity][0]
        if kind == "field" and spec.base is not None:
            return x / spec.base
        if spec.unit == "pu" or kind in ("speed", "field", "controller", "command"):
            return x
        if kind == "angle":
            return x * SCALE[spec.unit]
        value = x * SCALE[spec.unit] * self.ratio(spec)
        if kind == "voltage":
            return value / (self.v_base * (math.sqrt(3.0) if spec.unit.endswith("_ll") else 1.0))
        if kind == "current":
            return value / self.i_base
        return value / (self.mva * 1e6)


def _positive(doc: Mapping[str, Any], key: str, where: str) -> float:
    v = doc.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise ChannelMapError(f"{where}: {key} must be a positive number, got {v!r}")
    return float(v)


def _ratio(value: Any, where: str) -> float:
    if isinstance(value, str) and "/" in value:
        a, _, b = value.partition("/")
        try:
            r = float(a) / float(b)
        except (ValueError, ZeroDivisionError):
            raise ChannelMapError(f"{where}: ratio {value!r} is not PRIMARY/SECONDARY") from None
    elif isinstance(value, (int, float)) and not isinstance(value, bool):
        r = float(value)
    else:
        raise ChannelMapError(f"{where}: ratio {value!r} is not a number or PRIMARY/SECONDARY")
    if not (math.isfinite(r) and r > 0):
        raise ChannelMapError(f"{where}: ratio {value!r} must be positive")
    return r


def _channel(quantity: str, entry: Any, side: str, where: str) -> ChannelSpec:
    _, units, default = QUANTITIES[quantity]
    if isinstance(entry, str):
        entry = {"name": entry}
    if not isinstance(entry, Mapping) or not isinstance(entry.get("name"), str) or not entry["name"]:
        raise ChannelMapError(f"{where}: {quantity} needs a channel name (NAME or {{name: NAME, unit: ...}})")
    unit = entry.get("unit", default)
    if unit not in units:
        raise ChannelMapError(f"{where}: {quantity} unit {unit!r} not one of {', '.join(units)}")
    s = entry.get("side", side)
    if s not in ("primary", "secondary"):
        raise ChannelMapError(f"{where}: {quantity} side {s!r} must be primary or secondary")
    base = None
    if "base" in entry:
        if quantity not in FIELD_QUANTITIES or unit == "pu":
            raise ChannelMapError(f"{where}: {quantity}: base is for a field quantity recorded in V or A")
        base = _positive(entry, "base", f"{where}: {quantity}")
    return ChannelSpec(quantity, entry["name"], unit, s, base)


def _once(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    """A JSON object whose keys are each given once (json keeps the last of two, silently)."""
    keys = [k for k, _ in pairs]
    dup = sorted({k for k in keys if keys.count(k) > 1})
    if dup:
        raise ChannelMapError(f"the key {dup[0]!r} is given twice in one object: one entry per key, or one is lost")
    return dict(pairs)


def _one_quantity_a_column(channels: Mapping[str, ChannelSpec], where: str) -> None:
    """Each recorded column is one quantity: a column mapped as two (V_t read as E_fd too) makes
    the identification fit one signal against itself, and nothing downstream can tell."""
    by_name: dict[str, list[str]] = {}
    for q, spec in channels.items():
        by_name.setdefault(spec.name, []).append(q)
    twice = {name: qs for name, qs in by_name.items() if len(qs) > 1}
    if twice:
        name, qs = next(iter(twice.items()))
        raise ChannelMapError(f"{where}: the column {name!r} is mapped as {' and '.join(qs)}: a column is one quantity")


def load_channel_map(path: str | Path) -> ChannelMap:
    from phid_ros.io.files.yaml_doc import YamlDocError, load_yaml

    p = Path(path)
    if not p.is_file():
        raise ChannelMapError(f"{p}: no such channel map")
    try:
        text = p.read_text(encoding="utf-8") if p.suffix == ".json" else ""
        doc = json.loads(text, object_pairs_hook=_once) if p.suffix == ".json" else load_yaml(p)
    except json.JSONDecodeError as exc:
        raise ChannelMapError(f"{p}: not valid JSON ({exc})") from None
    except ChannelMapError as exc:
        raise ChannelMapError(f"{p}: {exc}") from None
    except YamlDocError as exc:
        raise ChannelMapError(str(exc)) from None
    where = str(p)
    if not isinstance(doc, Mapping) or not isinstance(doc.get("machine"), Mapping):
        raise ChannelMapError(f"{where}: needs a 'machine' section with mva, kv and f_nominal_hz")
    m = doc["machine"]
    side = doc.get("values", "primary")
    if side not in ("primary", "secondary"):
        raise ChannelMapError(f"{where}: values {side!r} must be primary or secondary")
    raw = doc.get("channels")
    if not isinstance(raw, Mapping) or not raw:
        raise ChannelMapError(f"{where}: needs a 'channels' section naming the recorded channels")
    unknown = sorted(set(raw) - set(QUANTITIES))
    if unknown:
        raise ChannelMapError(f"{where}: unknown quantity {unknown}; known: {', '.join(QUANTITIES)}")
    ratios_doc = doc.get("ratios") or {}
    if not isinstance(ratios_doc, Mapping) or set(ratios_doc) - {"pt", "ct"}:
        raise ChannelMapError(f"{where}: ratios takes pt and ct only")
    scenarios = doc.get("scenarios") or {}
    if not isinstance(scenarios, Mapping) or not all(isinstance(v, Mapping) for v in scenarios.values()):
        raise ChannelMapError(f"{where}: scenarios must map a recording's file stem to {{kind, role, event_time_s}}")
    set_point = doc.get("set_point") or {}
    if not isinstance(set_point, Mapping) or set(set_point) - {"rate_pu_per_s", "start_pu"}:
        raise ChannelMapError(f"{where}: set_point takes rate_pu_per_s and start_pu only")
    if any(q in raw for q in PULSES) and "rate_pu_per_s" not in set_point:
        raise ChannelMapError(
            f"{where}: {' and '.join(q for q in PULSES if q in raw)} mapped without the set-point's ramp rate: "
            "give set_point: {rate_pu_per_s: ..., start_pu: ...} (the regulator's, pu of rated V_t a second)"
        )
    rotation = doc.get("rotation", "abc")
    if rotation not in ROTATIONS:
        raise ChannelMapError(f"{where}: rotation {rotation!r} must be one of {', '.join(ROTATIONS)}")
    cmap = ChannelMap(
        path=where,
        rotation=rotation,
        mva=_positive(m, "mva", f"{where}: machine"),
        kv=_positive(m, "kv", f"{where}: machine"),
        f_nominal_hz=_positive(m, "f_nominal_hz", f"{where}: machine") if "f_nominal_hz" in m else 50.0,
        channels={q: _channel(q, e, side, where) for q, e in raw.items()},
        ratios={k: _ratio(v, f"{where}: ratios.{k}") for k, v in ratios_doc.items()},
        rated_rpm=_positive(m, "rated_rpm", f"{where}: machine") if "rated_rpm" in m else None,
        scenarios={str(k): dict(v) for k, v in scenarios.items()},
        time_column=str(doc.get("time", "Timestamp")),
        date_column=str(doc["date"]) if doc.get("date") else None,
        phasor_window_cycles=_positive(m, "phasor_window_cycles", f"{where}: machine")
        if "phasor_window_cycles" in m
        else 0.0,
        set_point_rate=_positive(set_point, "rate_pu_per_s", f"{where}: set_point") if set_point else None,
        set_point_start=_positive(set_point, "start_pu", f"{where}: set_point") if "start_pu" in set_point else 1.0,
    )
    _one_quantity_a_column(cmap.channels, where)
    for spec in cmap.channels.values():
        cmap.ratio(spec)  # a secondary value without its ratio is refused now, not after reading
    if cmap.has("omega") and cmap.channels["omega"].unit == "rpm" and cmap.rated_rpm is None:
        raise ChannelMapError(f"{where}: omega in rpm needs machine.rated_rpm")
    return cmap


def check_recording(cmap: ChannelMap, source: str, available: list[str]) -> ChannelMap:
    """The map against one recording's channels: what the identification needs is mapped, and
    every mapped channel is there; the message lists the recording's channels to choose from.
    Returns the map as this recording is read through it: a controller's own signal (``v_r``,
    ``v_s``) that this file did not keep is left out (a stabiliser's output is in the tests
    it was switched on for), not a reason to refuse the file."""
    kept = {q: spec for q, spec in cmap.channels.items() if spec.name in available or QUANTITIES[q][0] != "controller"}
    fitted = replace(cmap, channels=kept) if len(kept) < len(cmap.channels) else cmap
    require_complete(fitted, source, available)
    for q, spec in fitted.channels.items():
        if spec.name not in available:
            raise ChannelMapError(
                f"{cmap.path}: channel {spec.name!r} for {q} is not in {source} (channels: {', '.join(available)})"
            )
    return fitted


def not_mapped(cmap: ChannelMap, available: Sequence[str]) -> list[str]:
    """The recording's channels that ``cmap`` names for nothing (neither a quantity nor its clock),
    in the recording's order: an import leaves them behind, and must say so (a regulator's or a
    stabiliser's output a map did not name is a test's evidence lost without a word)."""
    named = {spec.name for spec in cmap.channels.values()} | {cmap.time_column, cmap.date_column}
    return [name for name in available if name not in named]


def named_once(source: str, available: Sequence[str], cmap: ChannelMap) -> None:
    """Every channel ``cmap`` reads (and its clock) is named once in the recording: of two
    channels under one name one would be read and the other dropped, and which is which cannot
    be told."""
    used = [cmap.time_column, cmap.date_column, *(spec.name for spec in cmap.channels.values())]
    for name in dict.fromkeys(u for u in used if u):
        at = [k + 1 for k, h in enumerate(available) if h == name]
        if len(at) > 1:
            raise ChannelMapError(
                f"{source}: names the channel {name!r} {len(at)} times (columns {', '.join(map(str, at))}): "
                "which one the map means cannot be told; rename one"
            )


STATOR_QUANTITIES = ("i_a", "i_b", "i_c", "i_t", "phi_i", "p_e", "q_e")


def choose_map(cmaps: Sequence[ChannelMap], source: str, available: list[str]) -> ChannelMap:
    """The map among ``cmaps`` that fits a recording (:func:`check_recording`), the one naming the
    most channels where several do: a unit's folder has a no-load map (V_t and the field) and an
    on-line one, and an on-line test fits both. Where none fits, the fullest map's complaint.

    A no-load map is never taken for a recording that holds a column another map names as a
    stator quantity: that is an on-line test the fuller map failed on, and read as an open
    circuit its P, Q and I would be zeros."""
    ranked = sorted(cmaps, key=lambda m: -len(m.channels))
    first: ChannelMapError | None = None
    stator = {spec.name: (m, q) for m in cmaps for q, spec in m.channels.items() if q in STATOR_QUANTITIES}
    for cmap in ranked:
        try:
            fitted = check_recording(cmap, source, available)
        except ChannelMapError as exc:
            first = first or exc
            continue
        held = next((name for name in available if name in stator), None) if cmap.open_circuit else None
        if held is not None:
            other, q = stator[held]
            raise ChannelMapError(
                f"{source}: holds {held!r}, which {other.path} maps as {q}, but fits only the no-load map "
                f"{cmap.path} (it would be read as an open circuit, P = Q = I = 0): "
                + (str(first) if first is not None else "the on-line map does not fit it")
            )
        return fitted
    assert first is not None
    raise first


def one_machine(cmaps: Sequence[ChannelMap]) -> ChannelMap:
    """The first of several maps of one unit, after checking that they describe one machine and
    map each field quantity alike (the field's base is calibrated once for the whole set)."""
    if not cmaps:
        raise ChannelMapError("no channel map given")
    head = cmaps[0]
    for m in cmaps[1:]:
        if (m.mva, m.kv, m.f_nominal_hz) != (head.mva, head.kv, head.f_nominal_hz):
            raise ChannelMapError(
                f"{m.path}: machine {m.mva:g} MVA, {m.kv:g} kV, {m.f_nominal_hz:g} Hz, but {head.path} says "
                f"{head.mva:g} MVA, {head.kv:g} kV, {head.f_nominal_hz:g} Hz: the maps of one set describe one unit"
            )
        for q in FIELD_QUANTITIES:
            a, b = head.channels.get(q), m.channels.get(q)
            if a is not None and b is not None and a != b:
                raise ChannelMapError(
                    f"{m.path}: {q} is mapped as {b.name} ({b.unit}) here, {a.name} ({a.unit}) in {head.path}"
                )
    return head


def require_complete(cmap: ChannelMap, source: str, available: list[str]) -> None:
    """The terminal voltage and the stator current can be formed from what is mapped (every
    identification needs them; the rotor angle, speed, P_m and E_fd widen what it determines);
    else name what is missing and the recording's channels to choose from."""
    needs = []
    parts = [q for q in ("v_re", "v_im") if cmap.has(q)]
    if parts and (cmap.has("v_t") or cmap.has("theta_t") or len(parts) == 1):
        mapped = ", ".join(q for q in ("v_t", "theta_t", *parts) if cmap.has(q))
        raise ChannelMapError(
            f"{cmap.path}: the terminal voltage is mapped as {mapped}: "
            "map it once, as v_t (with theta_t) or as both parts of its phasor, v_re and v_im"
        )
    if not (cmap.has("v_a", "v_b", "v_c") or cmap.has("v_t") or cmap.rectangular):
        needs.append("the terminal voltage (v_a, v_b, v_c waveforms, or v_t, or v_re and v_im)")
    if not (cmap.has_stator_current or cmap.open_circuit):
        needs.append(
            "the stator current (i_a, i_b, i_c waveforms, or i_t and phi_i, or p_e and q_e; "
            "a no-load test maps v_t and the field, v_f or i_fd, alone)"
        )
    if cmap.has("i_t", "phi_i") and not cmap.has_terminal_angle:
        needs.append("theta_t (phi_i is an angle against the same reference)")
    if cmap.has("delta") and not (cmap.has_terminal_angle or cmap.has("v_a", "v_b", "v_c")):
        needs.append("theta_t (delta is an angle against the same reference; or map load_angle)")
    if needs:
        raise ChannelMapError(
            f"{cmap.path}: no channel mapped for {'; '.join(needs)}; {source} has: {', '.join(available)}"
        )
