"""phid as a library: a recording read and identified, the way ``phid identify`` does it.

The command line, the fleet's tasks, the studies in ``benchmarks/`` and scripts of users call
these; none of them needs the command line's parser or its terminal output.

>>> from phid_ros.api import load_recording, identify_recording
>>> from phid_ros.ident.pipeline import IdentifyOptions
>>> rec = load_recording("bags/catalogue")
>>> scenarios, result = identify_recording(rec, "bags/catalogue", IdentifyOptions(f_nominal_hz=rec.f_nominal_hz))
>>> round(result.parameters["H"], 2)  # the catalogue's machine has H = 3.48 s
3.48
>>> result.estimates["H"].std < 0.01
True
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from phid_ros.errors import PhidError

if TYPE_CHECKING:  # imported where used: reading a recording does not need the identification
    from phid_ros.ident.pipeline import IdentificationResult, IdentifyOptions
    from phid_ros.ident.route_figures import FieldResistanceFigures
    from phid_ros.ident.scenario import ScenarioData, StepThresholds
    from phid_ros.io.recording import Recording
    from phid_ros.model.parameters import GeneratorParameters

__all__ = [
    "Cut",
    "cut_scenarios",
    "cut_unit",
    "identify_unit",
    "UnitCut",
    "UnitIdentification",
    "identify_cut",
    "identify_recording",
    "identify_recordings",
    "identify_scenarios",
    "load_recording",
    "result_provenance",
    "validate_record",
    "RecordValidation",
    "export_record",
    "ExportedRecord",
    "replay_to_bag",
    "ReplayRun",
    "ReplayProgress",
    "track_file",
    "TrackRun",
    "simulate_to_file",
    "simulate_ambient_to_file",
    "Simulated",
    "write_output",
]


def result_provenance(*paths: str | Path) -> dict[str, str]:
    """Which recording a result came from: its path and its content's SHA-256 (``phid export``
    compares the identification's and the diagnosis's before merging them); several recordings
    are named joined by " + ", their digest the SHA-256 of theirs."""
    import hashlib

    from phid_ros.io.files.digest import content_hash
    from phid_ros.provenance import method_version

    digests = [content_hash(Path(p)) for p in paths]
    digest = digests[0] if len(digests) == 1 else hashlib.sha256("".join(digests).encode()).hexdigest()
    return {"input": " + ".join(map(str, paths)), "input_sha256": digest, "method_version": method_version()}


def load_recording(path: str | Path) -> Recording:
    """A rosbag2 folder, a single .mcap, or a CSV manifest.json; the reader's warnings in ``warnings``.

    A stream whose clock is so far off that its stamps meet no other stream's is an error
    (:mod:`phid_ros.io.field.clock_check`).
    """
    from phid_ros.io.bags.recordings import read_recording
    from phid_ros.io.csvset.csv_import import import_csv_set
    from phid_ros.io.field.clock_check import clock_problems

    p = Path(path)
    if p.suffix == ".json":
        rec = import_csv_set(p)
    else:
        rec = read_recording(p)
    problems = clock_problems(rec)
    if problems:
        raise PhidError(f"{path}: {problems[0]}")
    return rec


IMPORT_KINDS = ("csv", "comtrade", "pmu")  # a CSV scenario set's manifest, COMTRADE records, PMU and trend-log CSVs


def import_recordings(
    paths: Sequence[str | Path], maps: Sequence[str | Path] = (), *, kind: str, strict: bool = False
) -> Recording:
    """Field recordings -> one scenario set, the one face of every importer (``phid import-csv``,
    ``import-comtrade``, ``import-pmu``): the recording, what the reading noticed and did (a
    resampled clock, a field base calibrated, ignored columns) in its ``warnings``. ``kind``: one
    of IMPORT_KINDS; ``csv`` reads one manifest (``paths[0]``, no map; ``strict`` refuses extra
    columns), the others the files through the channel ``maps``."""
    if kind not in IMPORT_KINDS:
        raise PhidError(f"import kind {kind!r}: one of {', '.join(IMPORT_KINDS)}")
    if kind == "csv":
        from phid_ros.io.csvset.csv_import import import_csv_set

        if len(paths) != 1 or maps:
            raise PhidError("a CSV scenario set is one manifest.json, read without a channel map")
        return import_csv_set(paths[0], strict=strict)
    from phid_ros.io.field.channel_map import load_channel_map

    dup = sorted({str(m) for m in maps if [str(x) for x in maps].count(str(m)) > 1})
    if dup:
        raise PhidError(f"--map {dup[0]} given twice")
    loaded = [load_channel_map(m) for m in maps]
    if kind == "comtrade":
        from phid_ros.io.field.comtrade_import import import_comtrade

        return import_comtrade(list(paths), loaded)
    from phid_ros.io.field.pmu_csv import import_pmu_csv

    return import_pmu_csv(list(paths), loaded)


def identify_recording(
    rec: Recording,
    source: str,
    options: IdentifyOptions,
    truth: GeneratorParameters | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[ScenarioData], IdentificationResult]:
    """A recording's scenarios and their identification; PhidError when nothing could be identified."""
    return identify_recordings([(rec, source)], options, truth, progress)


def identify_recordings(
    recordings: Sequence[tuple[Recording, str]],
    options: IdentifyOptions,
    truth: GeneratorParameters | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[ScenarioData], IdentificationResult]:
    """Several recordings of one unit (a no-load test from one day, a relay's COMTRADE and a
    controller's trend log from another) as one scenario set: each recording's scenarios, named
    ``recording/scenario``, on the coarsest sample period among them
    (:func:`phid_ros.ident.scenario.resampled`); PhidError when nothing could be identified."""
    from phid_ros.stream.scenarios import scenarios_from_recording

    cut = []
    for rec, source in recordings:
        if progress:
            progress(f"cutting the scenarios of {source}")
        cut.append((*scenarios_from_recording(rec, source, options.step_thresholds), source))
    return identify_cut(cut, options, truth, progress)


@dataclass
class Cut:
    """A recording's scenarios as every command cuts them, and what the commands need of the rest:
    its metadata and reader's warnings (``recording``, which holds no samples), and its span."""

    scenarios: list[ScenarioData]
    problems: list[str]  # scenarios skipped and why, what the aligner dropped
    recording: Recording  # metadata and warnings only: the samples are let go once cut
    span_ns: tuple[int, int]  # the first and the last sample's stamp

    @property
    def f_nominal_hz(self) -> float:
        return self.recording.f_nominal_hz


def cut_scenarios(path: str | Path, thresholds: StepThresholds | None = None) -> Cut:
    """A recording's scenarios, the one way ``identify``, ``validate``, ``diagnose`` and the fleet
    cut them.

    A bag or .mcap with a summary is read part by part and only the scenarios' windows are
    kept, so the memory follows the events, not the hours (:func:`phid_ros.stream.scenarios.scenarios_from_parts`);
    anything else is read whole (:func:`load_recording`) and let go once cut.
    """
    from phid_ros.ident.scenario import DEFAULT_THRESHOLDS
    from phid_ros.io.parts import recording_parts
    from phid_ros.io.recording import Recording
    from phid_ros.stream.scenarios import scenarios_from_parts, scenarios_from_recording

    p, th = Path(path), thresholds or DEFAULT_THRESHOLDS
    if p.suffix != ".json":
        parts = recording_parts(p)
        got = scenarios_from_parts(parts, str(path), th)
        if got is not None:
            return Cut(got[0], got[1], Recording({}, [], dict(parts.metadata), list(parts.warnings)), parts.span_ns)
    rec = load_recording(p)
    scenarios, problems = scenarios_from_recording(rec, str(path), th)
    return Cut(scenarios, problems, Recording({}, [], dict(rec.metadata), list(rec.warnings)), rec.span_ns())


@dataclass
class UnitCut:
    """The recordings of one unit, cut: what :func:`identify_unit` identifies."""

    paths: list[str]  # each recording once (the same bytes given twice are left out)
    cuts: list[Cut]
    notes: list[str]  # what was left out and why, for the user

    @property
    def recording(self) -> Recording:
        """The first recording's metadata (all share the nominal frequency and the base)."""
        return self.cuts[0].recording

    @property
    def source(self) -> str:
        return " + ".join(self.paths)


def cut_unit(
    paths: Sequence[str | Path],
    thresholds: StepThresholds | None = None,
    progress: Callable[[str], None] | None = None,
) -> UnitCut:
    """Several recordings of one unit cut as :func:`cut_scenarios` cuts one: the same recording
    given twice counted once, and refused when the recordings are not of one unit's per unit
    (another nominal frequency, another MVA base)."""
    from phid_ros.io.files.digest import distinct_recordings

    kept, notes = distinct_recordings([str(p) for p in paths])
    cuts = []
    for path in kept:
        if progress:
            progress(f"reading {path} and cutting its scenarios")
        cuts.append(cut_scenarios(path, thresholds))
    unit = UnitCut(kept, cuts, notes)
    if any(c.f_nominal_hz != unit.recording.f_nominal_hz for c in cuts):
        raise PhidError(f"{unit.source}: the recordings' nominal frequencies differ: not one unit")
    bases = {
        p: float(c.recording.metadata["base_mva"]) for p, c in zip(kept, cuts) if "base_mva" in c.recording.metadata
    }
    if len({round(b, 9) for b in bases.values()}) > 1:
        # the same per-unit figure is another current or power on another base: nothing from both is true
        named = ", ".join(f"{p} {b:g} MVA" for p, b in bases.items())
        raise PhidError(f"the recordings are per unit on different bases ({named}); import them on one base_mva")
    return unit


@dataclass
class UnitIdentification:
    """What ``phid identify`` finds: the machine's parameters, its exciter and governor, and the
    results document ``--json`` writes (the contract in docs/contracts.md)."""

    scenarios: list[ScenarioData]
    result: IdentificationResult
    controls: dict[str, Any]  # by kind: a ControlFit, or why none (str)
    document: dict[str, Any]
    # the no-load tests played with the identified machine on open circuit (controls.no_load_playback)
    no_load: Any = None  # controls.unit_validation.UnitValidation


def identify_unit(
    unit: UnitCut,
    options: IdentifyOptions,
    truth: GeneratorParameters | None = None,
    *,
    candidates: Mapping[str, Sequence[str]] | None = None,
    control_starts: Mapping[str, Mapping[str, float]] | None = None,
    progress: Callable[[str], None] | None = None,
) -> UnitIdentification:
    """The three stages on a unit's scenarios, then its exciter and governor (``candidates`` by
    kind, default every model; ``control_starts`` an existing record's constants), as ``phid
    identify`` and ``phid fleet`` both do. ``options.f_nominal_hz`` is taken from the recordings."""
    from dataclasses import replace

    from phid_ros.controls.identify import controls_json, identify_machine_controls

    options = replace(options, f_nominal_hz=unit.recording.f_nominal_hz)
    cut = [(c.scenarios, c.problems, p) for p, c in zip(unit.paths, unit.cuts)]
    scenarios, res = identify_cut(cut, options, truth, progress)
    if progress:
        progress("identifying the exciter, the governor and the stabiliser")
    t0 = time.perf_counter()
    on_base, controls, notes = identify_machine_controls(
        scenarios, res.route_details, options.constraints.saturation, candidates, control_starts
    )
    res.problems.extend(notes)
    res.timing["controls"] = round(time.perf_counter() - t0, 6)
    no_load = None
    if res.determined_by:  # a recorder's channel set: its no-load tests played on open circuit
        from phid_ros.controls.no_load_playback import no_load_playback

        t0 = time.perf_counter()
        no_load, _why = no_load_playback(on_base, res.estimates, options.constraints, controls, options.f_nominal_hz)
        res.timing["no_load_playback"] = round(time.perf_counter() - t0, 6)
    resistance = field_resistance_of(unit)
    if resistance is not None:
        res.route_details["field_resistance"] = resistance
    doc = res.to_json(truth)
    doc["controls"] = controls_json(controls)
    if no_load is not None:
        doc["no_load_playback"] = no_load.as_json()
    doc.update(result_provenance(*unit.paths))
    doc["f_nominal_hz"] = options.f_nominal_hz  # what phid export needs to write a planning model
    if unit.recording.metadata.get("base_mva") is not None:
        doc["base_mva"] = float(unit.recording.metadata["base_mva"])
    return UnitIdentification(scenarios, res, controls, doc, no_load)


def field_resistance_of(unit: UnitCut) -> FieldResistanceFigures | None:
    """The field winding's resistance at each test file's plateaus (``ident.field_circuit.field_resistance``),
    in ohms where every recording that gives one states its field bases in V and A, else in the
    recorder's per unit (then from recordings without bases only: two recordings' per units are
    not one unit unless their bases say so); None where no plateau has U_f and I_f."""
    from phid_ros.ident.field_circuit import FieldResistance, field_resistance
    from phid_ros.ident.route_figures import FieldResistanceFigures
    from phid_ros.io.recording import field_bases

    parts = []
    for c in unit.cuts:
        bases = field_bases(c.recording.metadata)
        got = field_resistance(c.scenarios, bases.ohms_per_unit if bases else None)
        if got is not None:
            parts.append(got)
    in_ohms = [p for p in parts if p.ohms_per_unit is not None]
    use = in_ohms or parts
    if not use:
        return None
    merged = FieldResistance({f: r for p in use for f, r in p.values.items()}, 1.0 if in_ohms else None)
    left_out = sorted(f for p in parts if p.ohms_per_unit is None for f in p.per_file) if len(use) < len(parts) else []
    return FieldResistanceFigures(merged, left_out)


@dataclass
class RecordValidation:
    """What ``phid validate`` finds: every check of the record against the recording's events,
    the machine as the record gives it at the recording's operating point, and the document
    ``--json`` writes."""

    result: Any  # controls.unit_validation.UnitValidation
    parameters: GeneratorParameters
    p_m0: float
    document: dict[str, Any]
    warnings: list[str]  # the reader's


class RecordOnFile:
    """A unit's record as the transmission operator simulates it (machine, exciter, governor,
    stabiliser: a PSS/E ``.dyr``), played in against events: the one way ``phid validate`` and the
    monitor (``record:=``, ``phid replay --record``) check it, so their verdicts agree."""

    def __init__(self, dyr: str | Path, bus: int | None = None, machine_id: str | None = None) -> None:
        from phid_ros.controls.unit_validation import control_of
        from phid_ros.export.dyr_read import read_unit

        self.unit = unit = read_unit(dyr, bus, machine_id)
        self.controls = {k: control_of(c.model, c.values) for k, c in unit.controls.items()}
        models = [c.model for c in unit.controls.values()]
        self.describe = " + ".join([f"{unit.machine} at bus {unit.bus} id '{unit.machine_id}'", *models])
        c = unit.constants
        self.curve = f"S(1.0) = {c['S10']:g}, S(1.2) = {c['S12']:g}" if c["S10"] or c["S12"] else "unsaturated"
        self.saturation = (c["S10"], c["S12"]) if c["S12"] > c["S10"] > 0 else None

    def parameters(self, p_m0: float) -> GeneratorParameters:
        """The record's machine in phid's form at the operating point ``p_m0`` (PSS/E's D is
        phid's less P_m0: its swing equation divides P_m by the speed)."""
        return self.unit.parameters(p_m0)

    def fourth_order(self, p_m0: float) -> GeneratorParameters:
        """The fourth-order machine that plays the record's slow part at ``p_m0``: what phid's
        identification of the machine the record writes finds, so the two compare."""
        return self.unit.fourth_order(p_m0)

    def on_machine_base(self, scenarios: list[ScenarioData]) -> tuple[list[ScenarioData], list[str]]:
        """The recorded E_fd on the record's machine base where the no-load tests show another."""
        from phid_ros.controls.unit_validation import field_on_machine_base

        return field_on_machine_base(scenarios, self.unit.open_circuit_field, self.curve, self.saturation)

    def play(self, scenarios: Sequence[ScenarioData], f_nominal_hz: float, *, open_loop: bool = False) -> Any:
        """Every scenario (E_fd already on the machine's base) played in with the record: the
        MOD-026/027 checks (:class:`phid_ros.controls.unit_validation.UnitValidation`). Each event
        is played alone at its own operating point (D in phid's form is PSS/E's plus that event's
        P_m0), so an event's verdict is the same whichever events are played beside it."""
        from phid_ros.controls.unit_validation import UnitValidation, validate_unit

        parts = []
        for s in scenarios:
            params = self.parameters(operating_p_m0([s]))
            parts.append(
                validate_unit(
                    [s],
                    params,
                    self.controls,
                    f_nominal_hz,
                    f"{self.describe} ({self.unit.source})",
                    self.unit.effects(),
                    close_loops=not open_loop,
                )
            )
        notes = list(dict.fromkeys(n for part in parts for n in part.notes))
        return UnitValidation(f"{self.describe} ({self.unit.source})", [c for p in parts for c in p.scenarios], notes)

    def not_simulated(self) -> list[str]:
        return [f"not simulated: {n}" for n in self.unit.not_simulated()]


def record_check(dyr: str | Path, bus: int | None = None, machine_id: str | None = None, settings: Any = None) -> Any:
    """The monitor's check of the record on file (:class:`phid_ros.stream.record_check.RecordCheck`):
    each window cut as ``phid validate`` cuts a recording's events and played by the same
    :meth:`RecordOnFile.play`."""
    from phid_ros.stream.recalibration import scenario_from_window
    from phid_ros.stream.record_check import RecordCheck, RecordCheckSettings

    record = RecordOnFile(dyr, bus, machine_id)
    chosen = settings or RecordCheckSettings()

    def play(scenarios: Sequence[ScenarioData], f_nominal_hz: float) -> Any:
        return record.play(scenarios, f_nominal_hz, open_loop=chosen.open_loop)

    describe = f"{record.describe} ({record.unit.source})"
    return RecordCheck(describe, play, scenario_from_window, record.fourth_order, chosen, record.on_machine_base)


def operating_p_m0(scenarios: Sequence[ScenarioData]) -> float:
    """P_m before the events (the recorded P at rest, its median over the events)."""
    import numpy as np

    return float(np.median([np.mean(s["p_e"][s.pre_slice()]) for s in scenarios]))


def validate_record(
    dyr: str | Path,
    path: str | Path | Sequence[str | Path],
    *,
    bus: int | None = None,
    machine_id: str | None = None,
    thresholds: StepThresholds | None = None,
    progress: Callable[[str], None] | None = None,
    open_loop: bool = False,
) -> RecordValidation:
    """A unit's PSS/E record (machine, exciter, governor) played in against each event of the
    recording at ``path`` (or of several recordings of the unit, cut as ``phid identify`` cuts
    them: each event named by its file, the same recording given twice counted once), as
    MOD-026/027 ask; the record's constants on the recording's base. ``open_loop``: the exciter
    driven by the recorded V_t, never closed through the machine (:mod:`phid_ros.controls.closed_loop`)."""
    record = RecordOnFile(dyr, bus, machine_id)
    paths = [path] if isinstance(path, (str, Path)) else list(path)
    unit = cut_unit(paths, thresholds, progress)  # part by part: the windows, not the hours
    return validate_cut(record, unit, progress=progress, open_loop=open_loop)


def validate_cut(
    record: RecordOnFile,
    unit: UnitCut,
    *,
    progress: Callable[[str], None] | None = None,
    open_loop: bool = False,
) -> RecordValidation:
    """The record played in against the events of a unit's recordings already cut (``phid
    validate``, and ``phid fleet`` with a unit's record on file, which has cut them to identify)."""
    source = unit.source
    cut = unit.cuts[0]
    scenarios = []
    for one, got in zip(unit.paths, unit.cuts, strict=True):
        if len(unit.paths) > 1:
            for sc in got.scenarios:
                sc.name = f"{Path(one).stem}/{sc.name}"
        scenarios += got.scenarios
    if not scenarios:
        raise PhidError(f"{source}: no step or disturbance to validate against")
    missing = [c for c in ("v_t", "p_e", "q_e") if any(c in s.absent for s in scenarios)]
    if missing:
        raise PhidError(f"{source}: not recorded: {', '.join(missing)}; the play-in needs V_t and checks P and Q")
    scenarios, base_notes = record.on_machine_base(scenarios)
    p_m0 = operating_p_m0(scenarios)
    params = record.parameters(p_m0)
    if progress:
        progress("playing the unit in")
    result = record.play(scenarios, cut.f_nominal_hz, open_loop=open_loop)
    base = cut.recording.metadata.get("base_mva")
    on_base = f"{float(base):g} MVA" if base is not None else "not stated in the recording"
    result.notes[:0] = (
        unit.notes
        + [p for c in unit.cuts for p in c.problems]
        + base_notes
        + [
            f"the record's constants taken on the recording's machine base ({on_base}): PSS/E keeps MBASE in the .raw",
            *record.not_simulated(),
        ]
    )
    doc = {"validation": result.as_json(), "parameters": params.as_dict(), "p_m0": p_m0}
    doc.update(result_provenance(*unit.paths))
    warnings = [w for c in unit.cuts for w in c.recording.warnings]
    return RecordValidation(result, params, p_m0, doc, warnings)


def identify_cut(
    cut: Sequence[tuple[list[ScenarioData], list[str], str]],
    options: IdentifyOptions,
    truth: GeneratorParameters | None = None,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[ScenarioData], IdentificationResult]:
    """The identification of scenarios already cut, (scenarios, notes, source) per recording."""
    from phid_ros.ident.scenario import on_one_grid
    from phid_ros.stream.scenarios import seen_before

    scenarios: list[ScenarioData] = []
    problems: list[str] = []
    seen: dict[bytes, list[tuple[str, Any]]] = {}
    for got, skipped, source in cut:
        if len(cut) > 1:
            for sc in got:
                sc.name = f"{Path(source).stem}/{sc.name}"
        # the same window from two recordings (a copy, a bag folder and its own .mcap) is one
        # measurement: counted twice it turned a withheld D into an identified one
        scenarios += [sc for sc in got if not seen_before(sc.name, sc.frame.values, seen, source, problems)]
        problems += skipped
    source = " + ".join(src for _, _, src in cut)
    if not any(sc.role == "identify" for sc in scenarios):
        why = "; ".join(problems[-3:]) or f"{len(scenarios)} scenario(s), all for validation"
        raise PhidError(f"{source}: nothing to identify from: no usable identification scenario ({why})")
    scenarios, notes = on_one_grid(scenarios)
    res = identify_scenarios(scenarios, source, options, truth, progress)
    res.problems[:0] = problems + notes
    if not any(e is not None and math.isfinite(e.value) for e in res.estimates.values()):
        raise PhidError(f"{source}: nothing identified: " + ("; ".join(res.problems) or "every stage failed"))
    return scenarios, res


def identify_scenarios(
    scenarios: list[ScenarioData],
    source: str,
    options: IdentifyOptions,
    truth: GeneratorParameters | None = None,
    progress: Callable[[str], None] | None = None,
) -> IdentificationResult:
    """The identification of scenarios cut from ``source``; a unit or convention mistake the
    channels show (:mod:`phid_ros.ident.consistency`) is an error naming ``source``."""
    from phid_ros.ident.consistency import ConsistencyError
    from phid_ros.ident.pipeline import identify

    try:
        return identify(scenarios, options, truth, progress)
    except ConsistencyError as exc:
        raise ConsistencyError(f"{source}: {exc}") from None


def characterise_sheet(path: str | Path) -> tuple[Any, Any]:
    """(the test sheet, its IEEE 115 characteristics): ``phid characterise``'s work."""
    from phid_ros.ident.characteristics import characterise
    from phid_ros.io.field.test_sheet import load_test_sheet

    sheet = load_test_sheet(path)
    return sheet, characterise(sheet.occ.i_f, sheet.occ.x, sheet.scc.i_f, sheet.scc.x)


@dataclass
class ExportedRecord:
    """A planning record as ``phid export`` writes it: the record, its text in the format asked,
    each field's value as written and its source (PSS/E's D in its torque form), and what the
    front end should warn of (flagged or kept fields, the model's own notes, what the format
    leaves out)."""

    record: Any  # export.record.MachineRecord
    text: str
    written: dict[str, float]
    sources: dict[str, str]
    warnings: list[str]
    left_out: list[str]  # control records the format cannot carry (a .dyd's)


def export_record(
    result_path: str | Path,
    fmt: str,
    *,
    model: str = "GENROU",
    mva: float | None = None,
    kv: float = 20.0,
    bus: int | None = None,
    machine_id: str | None = None,
    diagnosis_path: str | Path | None = None,
    base: str | Path | None = None,
    allow_flagged: bool = False,
    f_nominal_hz: float | None = None,
) -> ExportedRecord:
    """An identification result (and its diagnosis) as a planning-model record in ``fmt``
    (``psse-dyr``, ``pslf-dyd``, ``andes``), onto the unit's existing record ``base`` where given
    (its bus and id, and what the recordings did not determine): ``phid export`` without its
    terminal. Raises ``ExportError`` where a parameter is not identified (unless ``allow_flagged``)."""
    from phid_ros.export.formats import PSLF_CONTROLS, WRITERS, pslf_left_out
    from phid_ros.export.record import ExportError, build_record
    from phid_ros.io.files.results import read_json

    result = read_json(result_path)
    diagnosis = read_json(diagnosis_path) if diagnosis_path else None
    mva = mva if mva is not None else result.get("base_mva")
    if mva is None:
        raise ExportError(f"{result_path}: the result does not say the machine's MVA base; give it with --mva")
    existing = None
    at_bus, at_id = bus or 1, machine_id or "1"
    if base:
        from phid_ros.export.dyr_read import read_unit

        existing = read_unit(base, bus, machine_id)
        # the record goes where the unit's record is: a base at bus 5 was written at bus 1, unsaid
        at_bus, at_id = bus or existing.bus, machine_id or existing.machine_id
    rec = build_record(
        result,
        source=str(result_path),
        model=model,
        mva=float(mva),
        kv=kv,
        bus=at_bus,
        machine_id=at_id,
        diagnosis=diagnosis,
        diagnosis_source=str(diagnosis_path or ""),
        allow_flagged=allow_flagged,
        existing=existing,
    )
    if f_nominal_hz is not None:
        rec.f_nominal_hz = f_nominal_hz
    warnings = []
    if rec.flagged:
        warnings.append(f"writing parameters that are NOT identified (--allow-flagged): {', '.join(rec.flagged)}")
    if rec.kept:
        warnings.append(f"kept from {rec.kept_from} (the recordings did not determine them): {', '.join(rec.kept)}")
    warnings += rec.warnings
    if existing is not None and existing.carried and fmt != "psse-dyr":
        warnings.append(
            f"{base}: {', '.join(r.model for r in existing.carried)} (records phid does not model) not written "
            f"to a {fmt} file, which has no layout for them here; the .dyr carries them as written"
        )
    written = dict(rec.values)
    sources: dict[str, str] = dict(rec.sources)
    if fmt == "psse-dyr":
        written["D"] = rec.torque_form_damping()
        if rec.p_m0 is None:
            warnings.append(
                f"{result_path}: no operating point (identified before phid 0.3): D is written as identified, "
                "but PSS/E divides P_m by the speed and needs D - P_m0; identify again to have it converted"
            )
        else:
            sources["D"] += f", minus P_m0 = {rec.p_m0:.3g} (PSS/E's torque form)"
    left_out = pslf_left_out(rec) if fmt == "pslf-dyd" else []
    if left_out:
        warnings.append(
            f"{result_path}: the {', '.join(left_out)} record(s) are not written to a .dyd (PSLF's layout for "
            f"them is not checked here; it is for {', '.join(PSLF_CONTROLS)}); the .dyr and ANDES formats carry them"
        )
    return ExportedRecord(rec, WRITERS[fmt](rec), written, sources, warnings, left_out)


@dataclass
class ReplayProgress:
    """Where a replay is: stream time played, the share of the file read, events found, and what
    the recalibration is busy with ("" when idle): what ``phid replay``'s progress line says."""

    played_s: float
    read_share: float
    events: int
    busy: str


@dataclass
class ReplayRun:
    """A recording played through the online pipeline into an output bag, as ``phid replay``
    does it: the pipeline (closed; its health, detector, record check and parameters kept), the
    outputs (without their arrays), the messages written (``collector.counts``, its health log),
    the recording's overview (for a report), its first stamp, the reading's warnings, the wall
    time, and how many events a kept store held before."""

    pipeline: Any  # stream.pipeline.MonitorPipeline
    outputs: Any  # stream.pipeline.Outputs
    collector: Any  # stream.output_bag.OutputCollector
    overview: Any  # io.overview.Overview
    start_ns: int
    warnings: list[str]
    wall_s: float
    stored_before: int


def replay_to_bag(
    bag: str | Path,
    out: str | Path,
    *,
    record: str | Path | None = None,
    store: str | Path | None = None,
    unit: str = "",
    constraints: Any = None,
    rate: float | None = None,
    progress: Callable[[ReplayProgress], None] | None = None,
    started: Callable[[Any], None] | None = None,
) -> ReplayRun:
    """``bag`` replayed through the nodes' pipeline, read part by part (memory holds one part),
    its outputs written to ``out`` (a rosbag2 folder or an .mcap) as they are made: ``out``'s
    ``.partial`` until the end, so an interruption leaves what was published so far (and the
    events in ``store``). ``record``: the unit's record on file, checked at every event (read
    first: a record it cannot read is refused before the replay). ``constraints``: held
    parameters (``ident.constraints.parse_constraints``). ``started`` gets the pipeline before the
    first sample (to say what a kept store holds); ``progress`` gets a ``ReplayProgress`` as the
    stream time advances. ``rate``: paced at this multiple of real time (None: as fast as it goes)."""
    import itertools

    from phid_ros.io.bags.recordings import open_message_writer
    from phid_ros.io.files.outputs import atomic_output
    from phid_ros.io.overview import Overview
    from phid_ros.io.parts import recording_parts
    from phid_ros.stream.output_bag import OutputCollector
    from phid_ros.stream.replay import replay

    parts = recording_parts(bag)
    part_iter = iter(parts)
    first = next(part_iter)
    pipeline = _replay_pipeline(first, parts.metadata, store=store, unit=unit, constraints=constraints)
    if record:  # read before the replay: a record it cannot read is said now, not at the first event
        pipeline.record_check = record_check(record)
    stored_before = len(pipeline.store)
    if started is not None:
        started(pipeline)
    overview = Overview()
    start_ns = min((int(s.t_ns[0]) for s in first.streams.values() if len(s)), default=0)

    def read_on() -> Any:
        for part in itertools.chain([first], part_iter):
            overview.add(part)
            yield part

    events = 0
    t0 = time.perf_counter()
    with atomic_output(Path(out), keep_partial=True) as tmp:
        writer = open_message_writer(tmp, {"source": f"phid replay {bag}"}, background=True)
        collector = OutputCollector(pipeline, sink=writer.write)

        def collect(o: Any) -> None:
            nonlocal events
            collector(o)
            events += len(o.events)

        def played(seconds: float) -> None:
            if progress is not None:
                progress(ReplayProgress(seconds, parts.fraction, events, pipeline.recalibrator.activity))

        try:
            outputs = replay(read_on(), pipeline, rate=rate, on_outputs=collect, keep_arrays=False, progress=played)
        except BaseException:
            writer.close()
            pipeline.close()
            raise
        writer.close()
    wall = time.perf_counter() - t0
    pipeline.close()
    return ReplayRun(pipeline, outputs, collector, overview, start_ns, list(parts.warnings), wall, stored_before)


def _replay_pipeline(
    first: Any, metadata: Mapping[str, Any], *, store: str | Path | None, unit: str, constraints: Any
) -> Any:
    """The nodes' pipeline for a replay whose first part is ``first``: the grid at the PT/CT rate,
    as phid identify aligns the recording (a node: its sample_rate_hz)."""
    from phid_ros.ident.pipeline import IdentifyOptions
    from phid_ros.io.recording import not_recorded
    from phid_ros.stream.pipeline import MonitorPipeline, PipelineSettings

    settings = PipelineSettings(
        period_ns=first.streams["pt_ct"].period_ns if "pt_ct" in first.streams else PipelineSettings.period_ns,
        store_path=str(store) if store else ":memory:",
        unit=unit or metadata.get("unit", ""),
        not_recorded=not_recorded(metadata),
        identify=IdentifyOptions(baseline=False, **({"constraints": constraints} if constraints is not None else {})),
    )
    return MonitorPipeline(settings)


@dataclass
class TrackRun:
    """A recording tracked hop by hop, as ``phid track`` does it: the hops, the recording's
    overview (for a report), its first stamp, the reading's warnings and the wall time."""

    points: list[Any]  # stream.tracker.TrackPoint
    overview: Any  # io.overview.Overview
    start_ns: int
    warnings: list[str]
    wall_s: float


def track_file(
    bag: str | Path,
    base: GeneratorParameters,
    window_s: float,
    hop_s: float,
    *,
    out: str | Path | None = None,
    on_point: Callable[[Any, float], None] | None = None,
    on_part: Callable[[Recording], None] | None = None,
) -> TrackRun:
    """The sliding-window tracker over ``bag``, read part by part (memory holds one part and the
    window), X_d and X_q held at ``base``: ``phid track`` without its terminal. ``on_point`` gets
    each hop as it is estimated, with the share of the file read; ``on_part`` each part as it is
    read (a health tally). ``out``: the hops as ``tracked_parameters`` messages, written whole
    at the end (never a half-written file)."""
    import itertools

    from phid_ros.io.overview import Overview
    from phid_ros.io.parts import recording_parts
    from phid_ros.stream.output_bag import write_tracked
    from phid_ros.stream.replay import track_recording
    from phid_ros.stream.tracker import TrackerSettings

    parts = recording_parts(bag)
    part_iter = iter(parts)
    first = next(part_iter)
    start = min(int(s.t_ns[0]) for s in first.streams.values() if len(s))
    overview = Overview()

    def read_on() -> Any:
        for part in itertools.chain([first], part_iter):
            overview.add(part)
            if on_part is not None:
                on_part(part)
            yield part

    def hop(p: Any) -> None:
        if on_point is not None:
            on_point(p, parts.fraction)

    t0 = time.perf_counter()
    points = track_recording(read_on(), base, TrackerSettings(window_s=window_s, hop_s=hop_s), hop)
    wall = time.perf_counter() - t0
    if out is not None and points:
        write_tracked(points, out)
    return TrackRun(points, overview, start, list(parts.warnings), wall)


def write_output(out: str | Path, rec: Recording, block_size: int) -> None:
    """A recording to a bag folder, a single .mcap, or a CSV set (``DIR/manifest.json``), whole or
    not at all: what ``phid simulate`` and the imports write."""
    from phid_ros.io.bags.recordings import write_recording
    from phid_ros.io.files.outputs import atomic_output

    out = Path(out)
    if out.name == "manifest.json":
        from phid_ros.io.csvset.csv_export import write_csv_set

        write_csv_set(out.parent, rec)  # the manifest last: a killed run leaves no set that looks complete
    else:
        with atomic_output(out) as tmp:  # a kill leaves no half-written bag that looks complete
            write_recording(tmp, rec, block_size=block_size)


@dataclass(frozen=True)
class Simulated:
    """A simulated recording on file and its truth beside it (``phid simulate``'s two outputs)."""

    out: Path
    truth: Path
    span_s: float  # the recording's length in log time


def simulate_to_file(
    scenarios: Sequence[Any],
    config: Any,
    out: str | Path,
    *,
    start_ns: int | None = None,
    block_size: int = 100,
    progress: Callable[[str], None] | None = None,
) -> Simulated:
    """The scenarios (:mod:`phid_ros.sim.scenarios`) simulated with ``config`` (a
    :class:`~phid_ros.sim.runner.SimulationConfig`) and written to ``out`` with their truth."""
    from phid_ros.io.files.results import truth_path_for, write_json
    from phid_ros.model.conventions import NS
    from phid_ros.sim.recording import DEFAULT_START_NS, recording_from_runs, truth_document
    from phid_ros.sim.runner import simulate_scenarios

    say = progress or (lambda _: None)
    out = Path(out)
    runs = simulate_scenarios(scenarios, config)
    say(f"writing {out}")
    rec = recording_from_runs(runs, config, start_ns=DEFAULT_START_NS if start_ns is None else start_ns)
    write_output(out, rec, block_size)
    truth = write_json(truth_path_for(out), truth_document(config, scenarios))
    start, end = rec.span_ns()
    return Simulated(out, Path(truth), (end - start) / NS)


def simulate_ambient_to_file(
    settings: Any,
    config: Any,
    out: str | Path,
    *,
    start_ns: int | None = None,
    block_size: int = 100,
    progress: Callable[[str], None] | None = None,
) -> Simulated:
    """A long ambient run (:class:`~phid_ros.sim.ambient.AmbientSettings`, its drifts) simulated and
    written a chunk at a time (ten minutes of samples in memory, not the day), its truth beside it
    with the drifting parameters once a second."""
    import numpy as np

    from phid_ros.io.bags.recordings import open_message_writer
    from phid_ros.io.files.outputs import atomic_output
    from phid_ros.io.files.results import truth_path_for, write_json
    from phid_ros.io.recording import Recording, StreamSamples, iter_recording_messages
    from phid_ros.io.topics import STREAMS
    from phid_ros.model.conventions import NS
    from phid_ros.sim.ambient import ambient_chunks
    from phid_ros.sim.recording import DEFAULT_START_NS, recording_metadata, truth_document

    say = progress or (lambda _: None)
    out, start = Path(out), DEFAULT_START_NS if start_ns is None else start_ns
    dt_ns = int(round(config.dt * NS))
    every = int(round(1 / config.dt))
    drifting: dict[str, list[float]] = {d.parameter: [] for d in settings.drifts}
    # a chunk is a whole number of messages, so its messages follow the last chunk's in log time
    with atomic_output(out) as tmp:
        writer = open_message_writer(tmp, recording_metadata(config))
        try:
            for chunk in ambient_chunks(settings, config):
                first = int(round(chunk.t[0] / config.dt))
                t_ns = start + (first + np.arange(len(chunk.t), dtype=np.int64)) * dt_ns
                streams = {
                    s.name: StreamSamples(t_ns.copy(), dt_ns, {c: chunk.measured[c] for c in s.channels})
                    for s in STREAMS
                }
                for item in iter_recording_messages(Recording(streams, []), block_size=block_size):
                    writer.write(*item)
                for name, v in chunk.parameters.items():  # once a second, from the run's start
                    drifting[name] += v[(-first) % every :: every].tolist()
                say(f"simulated and written {chunk.t[-1]:.0f} of {settings.duration_s:g} s")
        except BaseException:
            writer.abort()
            raise
        writer.close()
    truth = truth_document(config, [])
    truth["ambient"] = {
        "duration_s": settings.duration_s,
        "seed": settings.seed,
        "drifts": [d.__dict__ for d in settings.drifts],
    }
    truth["drifting_parameters_every_s"] = drifting
    path = write_json(truth_path_for(out), truth)
    return Simulated(out, Path(path), float(settings.duration_s))
