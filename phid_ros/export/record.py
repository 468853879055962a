"""A planning-model machine record (GENROU or GENSAL) built from phid's results.

The record is the fields of the PSS/E GENROU/GENSAL models, on the machine's MVA base, each
with the place its value came from: identified (the eight base parameters), named by the
diagnosis (subtransient dynamics, saturation, stator resistance), or a stated default.
The writers in :mod:`phid_ros.export.formats` only lay these fields out.

The fourth-order model of the paper is GENROU with its damper windings taken out. GENROU
cannot take them out (its X''_d = X''_q must lie below X'_d and X'_q), so without a
diagnosed subtransient effect the defaults are chosen to change the fourth-order behaviour as
little as GENROU allows: X'' = min(X'_d, X'_q), which makes the damper of the axis with the
smaller transient reactance inert, and short subtransient time constants for the other. That
axis's identified X', T'_0 are written as the classical constants that play them through the
damper (:func:`_through_dampers`), for a damper's current loads the transient winding.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NoReturn

from phid_ros.controls.models import MODELS as CONTROL_MODELS
from phid_ros.errors import ParameterError, PhidError
from phid_ros.export.controls import ControlRecord, build_control_records, comment_text
from phid_ros.export.source import FLAG, Origin, Source
from phid_ros.model.damper_equivalent import DamperedAxis
from phid_ros.model.parameters import PARAMETER_NAMES, SPECS_BY_NAME
from phid_ros.sim.effects import leakage_default

if TYPE_CHECKING:
    from phid_ros.export.dyr_read import Unit

MODELS = ("GENROU", "GENSAL")

# the record's fields in the order PSS/E lists them, with what each means
FIELDS: dict[str, str] = {
    "Td10": "T'_d0, d-axis open-circuit transient time constant (s)",
    "Td20": "T''_d0, d-axis open-circuit subtransient time constant (s)",
    "Tq10": "T'_q0, q-axis open-circuit transient time constant (s; GENROU only)",
    "Tq20": "T''_q0, q-axis open-circuit subtransient time constant (s)",
    "H": "inertia constant (s, machine base)",
    "D": "speed damping (pu torque per pu speed)",
    "Xd": "X_d (pu)",
    "Xq": "X_q (pu)",
    "Xd1": "X'_d (pu)",
    "Xq1": "X'_q (pu; GENROU only)",
    "Xd2": "X''_d = X''_q (pu)",
    "Xl": "stator leakage reactance (pu)",
    "S10": "saturation factor S(1.0)",
    "S12": "saturation factor S(1.2)",
    "ra": "stator resistance (pu; in PSS/E it belongs to the .raw generator record)",
}
GENSAL_ABSENT = ("Tq10", "Xq1")

# where the eight base parameters go
BASE_FIELDS = {
    "H": "H",
    "D": "D",
    "X_d": "Xd",
    "X_q": "Xq",
    "X_d_prime": "Xd1",
    "X_q_prime": "Xq1",
    "T_d0_prime": "Td10",
    "T_q0_prime": "Tq10",
}

# Stated defaults for what phid does not identify, typical of large round-rotor units. T''_q0
# is short, within the damper effect's range (0.01-0.2 s): the q-axis damper GENROU cannot
# leave out then departs least from the identified model. With the q axis written through that
# damper, the tour's record (phid simulate's catalogue) misses the 200 ms fault's Q by 0.042 pu
# at 0.02 s, by 0.0505 (over the 0.05 band) at 0.03 s; with 0.05 s the ANDES round trip's
# fault was 0.49 deg off where 0.03 s gave 0.32 (before the q axis went through the damper).
DEFAULT_TD20_S = 0.03
DEFAULT_TQ20_S = 0.02


class ExportError(PhidError):
    """A result cannot become a planning-model record as asked."""


@dataclass
class MachineRecord:
    model: str
    values: dict[str, float]
    sources: dict[str, Source]
    mva: float
    kv: float
    bus: int
    machine_id: str
    f_nominal_hz: float
    origin: str
    flagged: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    # the mean P_m (pu, machine base) where the recordings held the machine; None when the result
    # does not say (written before phid 0.3)
    p_m0: float | None = None
    controls: list[ControlRecord] = field(default_factory=list)  # the exciter's, the governor's
    # fields taken from the unit's existing record (--base) where the recordings did not determine them
    kept: list[str] = field(default_factory=list)
    kept_from: str = ""
    # the existing record's records phid does not model (an over-excitation limiter), as written,
    # re-addressed to this record's bus and id: carried into a .dyr, never dropped
    carried: list[str] = field(default_factory=list)

    @property
    def fields(self) -> list[str]:
        return [f for f in FIELDS if not (self.model == "GENSAL" and f in GENSAL_ABSENT)]

    @property
    def defaults(self) -> list[str]:
        return [f for f in self.fields if self.sources[f].is_default]

    def torque_form_damping(self) -> float:
        """D for a swing equation that divides P_m by the speed, as PSS/E's GENROU and GENSAL do,
        ``(P_m - D dw)/(1 + dw) - T_e``: linearised, that is phid's (the paper's (5)) with
        D_phid = D + P_m0, since P_m/(1 + dw) = P_m - P_m0 dw to first order. Measured on STEPS's
        GENSAL (PSS/E's equation, D = 0.4, P_m = 0.8): phid identifies 1.22; a PSS/E record
        written with it damped the swings three times as much as the machine."""
        d = self.values["D"]
        return d if self.p_m0 is None else max(0.0, d - self.p_m0)

    def comment(self) -> str:
        """One line for the record's comment: where it came from and what is not identified."""
        parts = [f"phid_ros export of {self.origin}", f"{self.mva:g} MVA base"]
        if self.flagged:
            parts.append("NOT IDENTIFIED: " + ", ".join(self.flagged))
        if self.kept:
            parts.append(f"kept from {self.kept_from} (not determined by the recordings): " + ", ".join(self.kept))
        if self.defaults:
            parts.append("defaults: " + ", ".join(self.defaults))
        return comment_text(parts)


def _with_withheld(result: Mapping[str, Any]) -> Mapping[str, Any]:
    """The result with each withheld value (null under ``parameters``, kept under ``withheld``
    since 2026-12) in its place: a record needs a number in every field, and a withheld one is
    flagged, as every value not identified is (refused without ``--allow-flagged``)."""
    withheld = result.get("withheld")
    if not isinstance(withheld, Mapping) or not withheld:
        return result
    params = dict(result["parameters"])
    for name, w in withheld.items():
        if params.get(name) is None and isinstance(w, Mapping) and w.get("value") is not None:
            params[name] = w["value"]
    return {**result, "parameters": params}


def _number(doc: Mapping[str, Any], key: str, source: str) -> float:
    v = doc.get(key)
    if v is None and key in doc:  # a recorder's channel set did not determine it
        raise ExportError(
            f"{source}: parameter {key} was not determined from the recording's channels (null): a planning "
            f"record needs all eight; hold it at a datasheet value (phid identify --fix {key}=...) or keep "
            "the unit's existing record's (phid export --base UNIT.dyr)"
        )
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(float(v)):
        raise ExportError(f"{source}: parameter {key} is {v!r}, not a finite number")
    return float(v)


def _effects(diagnosis: Mapping[str, Any] | None, source: str) -> dict[str, dict[str, Any]]:
    if diagnosis is None:
        return {}
    effects = diagnosis.get("effects")
    if not isinstance(effects, list):
        raise ExportError(f"{source}: not a diagnosis result (no 'effects' list)")
    out: dict[str, dict[str, Any]] = {}
    for e in effects:
        named = isinstance(e, Mapping) and isinstance(e.get("name"), str)
        if not named or not isinstance(e.get("parameters"), Mapping):
            raise ExportError(f"{source}: an entry of 'effects' lacks its name or parameters")
        out[e["name"]] = dict(e["parameters"])
    return out


def _undetermined_effect_parameters(diagnosis: Mapping[str, Any] | None) -> set[tuple[str, ...]]:
    """(effect, parameter) of every effect parameter the diagnosis marks as not determined."""
    out: set[tuple[str, ...]] = set()
    for e in (diagnosis or {}).get("effects") or []:
        for p, ok in (e.get("identifiable") or {}).items():
            if ok is False:
                out.add((str(e["name"]), str(p)))
    return out


MACHINE_ID = re.compile(r"[A-Za-z0-9]{1,2}")


def build_record(
    result: Mapping[str, Any],
    *,
    source: str,
    model: str = "GENROU",
    mva: float,
    kv: float = 20.0,
    bus: int = 1,
    machine_id: str = "1",
    diagnosis: Mapping[str, Any] | None = None,
    diagnosis_source: str = "",
    allow_flagged: bool = False,
    existing: Unit | None = None,
) -> MachineRecord:
    """The record for an identification result (and the effects its diagnosis named).

    ``existing``: the unit's record as it stands (``phid export --base UNIT.dyr``): each machine
    constant the recordings did not determine is taken from it instead of being flagged or
    defaulted (said in its source and the record's comment), its dampers and saturation where
    neither a diagnosis nor a held curve gives them, and its control models of a kind identify
    named none of. What the recordings determined replaces it."""
    model = model.upper()
    params = _checked_request(result, source, model, mva, machine_id)
    result = _with_withheld(result)
    effects = _effects(diagnosis, diagnosis_source)
    _same_recording(result, source, diagnosis, diagnosis_source)
    held = (result.get("constraints") or {}).get("fixed") or {}
    p_m0 = _p_m0(result)
    kept: list[str] = []
    if existing is not None:  # a value the recordings did not give at all (null) is the record's
        before = existing.parameters(p_m0 or 0.0)
        filled = {n: v if v is not None else getattr(before, n) for n, v in params.items()}
        result = {**result, "parameters": filled}
    chosen = _base_values(result, diagnosis, source, diagnosis_source, held)
    if existing is not None:
        kept = _keep_existing(chosen, existing, p_m0)
    flagged = [n for n in PARAMETER_NAMES if not chosen[n][2]]
    _physical(chosen, source if diagnosis is None else f"{source} and {diagnosis_source}")
    f_nominal = float(result.get("f_nominal_hz", 50.0))
    values, sources = _base_fields(chosen, flagged)
    warnings: list[str] = []
    _fill_subtransient(values, sources, effects.get("subtransient_dynamics"), warnings)
    held_curve = (result.get("constraints") or {}).get("saturation")
    _fill_saturation(values, sources, effects.get("magnetic_saturation"), warnings, model, held_curve)
    if existing is not None:
        kept += _keep_existing_effects(values, sources, existing, effects, held_curve)
    values["ra"], sources["ra"] = _stator_resistance(effects)
    _through_dampers(values, sources, warnings, model, bool(effects.get("subtransient_dynamics")))
    if model == "GENSAL":
        _to_gensal(values, sources, warnings)
    flagged += _flag_undetermined_effects(sources, diagnosis)
    if flagged and not allow_flagged:
        _refuse_flagged(flagged, f"{source} and {diagnosis_source}" if diagnosis is not None else source)
    rec = MachineRecord(
        model,
        values,
        sources,
        mva,
        kv,
        bus,
        machine_id,
        f_nominal,
        source,
        flagged=flagged,
        warnings=warnings,
        p_m0=p_m0,
        kept=[f for f in (BASE_FIELDS.get(n, n) for n in kept) if f in values],
        kept_from=existing.source if existing is not None else "",
    )
    rec.controls = build_control_records(result, source, allow_flagged=allow_flagged)
    if existing is not None:
        _keep_existing_controls(rec, existing)
    _warn_damping_and_defaults(rec)
    _check(rec)
    return rec


def _p_m0(result: Mapping[str, Any]) -> float | None:
    """The operating point's P_m the result gives, or None."""
    point = result.get("operating_point") or {}
    p_m0 = point.get("p_m_pu") if isinstance(point, Mapping) else None
    return float(p_m0) if isinstance(p_m0, (int, float)) and math.isfinite(p_m0) else None


def _refuse_flagged(flagged: list[str], where: str) -> NoReturn:
    raise ExportError(
        f"{where}: {', '.join(flagged)} not identified; refusing to export a planning model with "
        f"{'it' if len(flagged) == 1 else 'them'} "
        "(--allow-flagged writes them anyway, marked in the record's comment)"
    )


def _base_fields(chosen: Mapping[str, Any], flagged: list[str]) -> tuple[dict[str, float], dict[str, Source]]:
    """The record's fields of the base parameters chosen, each with its source (flagged where
    the parameter is)."""
    values: dict[str, float] = {}
    sources: dict[str, Source] = {}
    for name, f in BASE_FIELDS.items():
        values[f], origin, _ = chosen[name]
        sources[f] = origin.flag() if name in flagged else origin
    return values, sources


def _stator_resistance(effects: Mapping[str, Any]) -> tuple[float, Source]:
    """R_a from the diagnosis's stator-resistance effect, else 0 as a stated default."""
    ra = effects.get("stator_resistance")
    if ra:
        return float(ra["r_a"]), Source.of_effect("stator_resistance", "r_a")
    return 0.0, Source("default", Origin.DEFAULT)


def _checked_request(
    result: Mapping[str, Any], source: str, model: str, mva: float, machine_id: str
) -> Mapping[str, Any]:
    """The result's parameters, once the model, the base and the machine id asked for are ones a
    record can carry and ``result`` is an identification result."""
    if model not in MODELS:
        raise ExportError(f"model must be one of {MODELS}, got {model!r}")
    if not mva > 0:
        raise ExportError(f"the machine base must be positive, got {mva} MVA")
    if not MACHINE_ID.fullmatch(machine_id):
        # written between quotes into every record: a newline or a quote would end it early or
        # inject another (PSS/E and PSLF name a machine at its bus with one or two characters)
        raise ExportError(f"--id {machine_id!r}: a machine id is one or two letters or digits (PSS/E's, PSLF's)")
    params = result.get("parameters")
    flags = result.get("identifiable")
    if not isinstance(params, Mapping) or not isinstance(flags, Mapping):
        raise ExportError(
            f"{source}: not an identification result "
            "(it needs 'parameters' and 'identifiable', as phid identify --json writes)"
        )
    return params


def _flag_undetermined_effects(sources: dict[str, Source], diagnosis: Mapping[str, Any] | None) -> list[str]:
    """The fields taken from an effect parameter the diagnosis did not determine, flagged as a base
    parameter is (on ANDES's GENROU with close q-axis time constants T''_q0 moved by 20 % between
    fits the held-out data could not tell apart); their names, for the record's flagged list."""
    undetermined = _undetermined_effect_parameters(diagnosis)
    flagged = []
    for f, src in sources.items():
        if src.effect is not None and src.effect in undetermined:
            flagged.append(f"{f} ({' '.join(src.effect)})")
            sources[f] = src.flag()
    return flagged


def _warn_damping_and_defaults(rec: MachineRecord) -> None:
    """Said in the record's warnings: a D below what PSS/E's torque form adds by itself, and the
    stated defaults it carries."""
    if rec.p_m0 is not None and rec.values["D"] < rec.p_m0:
        rec.warnings.append(
            f"D = {rec.values['D']:.3g} is below P_m0 = {rec.p_m0:.3g}, the damping PSS/E's torque form adds by "
            f"itself: a PSS/E record's D = 0 damps {rec.p_m0 - rec.values['D']:.3g} pu more than identified"
        )
    if rec.defaults:
        rec.warnings.append(
            "stated defaults (not identified) in the record: "
            + ", ".join(f"{f}={rec.values[f]:g}" for f in rec.defaults)
        )


def _keep_existing_controls(rec: MachineRecord, existing: Unit) -> None:
    """The existing record's control models of a kind identify named none of, kept; its PSS/E
    integers on a model identified anew (a stabiliser's remote bus was written as 0, its own,
    unsaid); and its records phid does not model, carried as written (an over-excitation limiter
    was dropped from the .dyr without a word)."""
    named = {c.kind: c for c in rec.controls}
    for kind, c in existing.controls.items():
        mine = named.get(kind)
        if mine is None:
            kept = {n: Source(f"kept from {existing.source}", Origin.KEPT) for n in c.values}
            rec.controls.append(ControlRecord(c.model, kind, dict(c.values), kept, [], existing.source, dict(c.icons)))
            continue
        if mine.model != c.model:
            continue
        mine.icons = dict(c.icons)
        moved = [f"{n} = {v}" for n, v in c.icons.items() if v != dict(CONTROL_MODELS[c.model].icons).get(n)]
        if moved:
            rec.warnings.append(f"{c.model}: {', '.join(moved)} kept from {existing.source} (phid's fit reads none)")
    for r in existing.carried:
        body = r.text.split(None, 3)
        rest = body[3] if len(body) > 3 else "/"
        rec.carried.append(f"{rec.bus} {body[1]} '{rec.machine_id}' {rest}")
    if existing.carried:
        rec.warnings.append(
            f"{', '.join(r.model for r in existing.carried)} from {existing.source}: not modelled by phid, "
            "carried into the .dyr as written"
        )


def _same_recording(
    result: Mapping[str, Any], source: str, diagnosis: Mapping[str, Any] | None, diagnosis_source: str
) -> None:
    """A diagnosis is merged only into the identification of the same recording: by content
    (``input_sha256``) where both results carry it, else by path."""
    if diagnosis is None:
        return
    for key in ("input_sha256", "input"):
        a, b = result.get(key), diagnosis.get(key)
        if key == "input" and a and b:
            a, b = os.path.normpath(str(a)), os.path.normpath(str(b))
        if a and b:
            if a != b:
                raise ExportError(
                    f"{diagnosis_source}: diagnoses {diagnosis.get('input', '?')}, but {source} identified "
                    f"{result.get('input', '?')} ({'different content' if key == 'input_sha256' else 'another file'}); "
                    "export each recording's own diagnosis"
                )
            return


def _physical(chosen: Mapping[str, tuple[float, str, bool]], where: str) -> None:
    """No planning model is written with a value outside the machine's physical ranges, flagged
    or not (--allow-flagged writes unidentified values, never impossible ones)."""
    problems = [p for n in PARAMETER_NAMES if (p := SPECS_BY_NAME[n].outside(chosen[n][0])) is not None]
    if problems:
        raise ExportError(f"{where}: {'; '.join(problems)}: not a physical machine, no record written")


def _base_values(
    result: Mapping[str, Any],
    diagnosis: Mapping[str, Any] | None,
    source: str,
    diagnosis_source: str,
    held: Mapping[str, Any],
) -> dict[str, tuple[float, Source, bool]]:
    """Each base parameter's (value, source, identified).

    With a diagnosis, its refit (with the named effects) is taken where it determined the value;
    where it did not (its ``identifiable`` false: held 10 % away, the rest refit as well), the
    identification's value is taken if that was identified, else the parameter is flagged. The
    output-error refit leaves D within about +-15 %, where stage 1's swing integral had it within
    a few per cent, and on ANDES's GENROU with close q-axis time constants it put X'_q anywhere
    between +15 % and +63 % at the same fit: exporting the refit whole would publish those.
    """
    params, flags = result["parameters"], result["identifiable"]
    out: dict[str, tuple[float, Source, bool]] = {}
    refit = fitted = None
    identified, refitted = Origin.IDENTIFIED, Origin.DIAGNOSIS
    if diagnosis is not None:
        refit = diagnosis.get("parameters")
        if not isinstance(refit, Mapping):
            raise ExportError(f"{diagnosis_source}: the diagnosis has no final 'parameters'")
        fitted = diagnosis.get("identifiable")  # absent in diagnoses of phid before 2026-11: all taken
    for name in PARAMETER_NAMES:
        ident_ok = flags.get(name) is True
        if name in held:
            out[name] = (
                _number(params, name, source),
                Source(f"held by the user ({name}, --fix)", Origin.HELD),
                ident_ok,
            )
        elif refit is not None and name in (diagnosis or {}).get("held", ()):
            note = Source(f"identified ({name}; held at that value in the diagnosis)", identified)
            out[name] = (_number(params, name, source), note, ident_ok)
        elif refit is not None and (fitted is None or fitted.get(name) is True):
            out[name] = (_number(refit, name, diagnosis_source), Source(f"diagnosis refit ({name})", refitted), True)
        elif refit is not None and ident_ok:
            note = Source(f"identified ({name}; the diagnosis's refit did not determine it)", identified)
            out[name] = (_number(params, name, source), note, True)
        elif refit is not None:  # determined by neither: the refit's, flagged (it has the named effects)
            out[name] = (_number(refit, name, diagnosis_source), Source(f"diagnosis refit ({name})", refitted), False)
        else:
            out[name] = (_number(params, name, source), Source(f"identified ({name})", identified), ident_ok)
    return out


def _keep_existing(chosen: dict[str, tuple[float, Source, bool]], existing: Unit, p_m0: float | None) -> list[str]:
    """The base parameters the recordings did not determine (and the user did not hold), taken from
    the existing record: the names so taken. Its D is PSS/E's torque form: phid's adds P_m0."""
    params = existing.parameters(p_m0 or 0.0)
    kept = []
    for name in PARAMETER_NAMES:
        value, origin, identified = chosen[name]
        if identified or origin.origin is Origin.HELD:
            continue
        chosen[name] = (
            float(getattr(params, name)),
            Source(f"kept from {existing.source} (not determined by the recordings)", Origin.KEPT),
            True,
        )
        kept.append(name)
    return kept


def _keep_existing_effects(
    values: dict[str, float],
    sources: dict[str, Source],
    existing: Unit,
    effects: Mapping[str, Any],
    held_curve: Any,
) -> list[str]:
    """The existing record's dampers (X'', T''_d0, T''_q0, X_l) and saturation where neither a
    diagnosis nor a held curve gives them: the fields so taken."""
    c = existing.constants
    fields = []
    if not effects.get("subtransient_dynamics"):
        fields += ["Xd2", "Td20", "Tq20", "Xl"]
    if not effects.get("magnetic_saturation") and not held_curve:
        fields += ["S10", "S12"]
    for f in fields:
        values[f], sources[f] = float(c[f]), Source(f"kept from {existing.source}", Origin.KEPT)
    return fields


def _fill_subtransient(
    values: dict[str, float], sources: dict[str, Source], effect: Mapping[str, Any] | None, warnings: list[str]
) -> None:
    if effect:
        x_dpp, x_qpp = float(effect["x_dpp"]), float(effect["x_qpp"])
        values["Xd2"], sources["Xd2"] = x_dpp, Source.of_effect("subtransient_dynamics", "x_dpp")
        values["Td20"], sources["Td20"] = float(effect["t_d0pp"]), Source.of_effect("subtransient_dynamics", "t_d0pp")
        values["Tq20"], sources["Tq20"] = float(effect["t_q0pp"]), Source.of_effect("subtransient_dynamics", "t_q0pp")
        if abs(x_qpp - x_dpp) > 0.01 * x_dpp:
            warnings.append(
                f"the diagnosis found X''_q = {x_qpp:.4g} and X''_d = {x_dpp:.4g}; the record has one X'' "
                "(GENROU/GENSAL hold X''_q = X''_d) and takes X''_d"
            )
    else:
        values["Xd2"] = min(values["Xd1"], values["Xq1"])
        sources["Xd2"] = Source("default: min(X'_d, X'_q), the damper of that axis inert", Origin.DEFAULT)
        values["Td20"], sources["Td20"] = DEFAULT_TD20_S, Source("default", Origin.DEFAULT)
        values["Tq20"], sources["Tq20"] = DEFAULT_TQ20_S, Source("default", Origin.DEFAULT)
    x_l = float((effect or {}).get("x_l", math.nan))
    if math.isfinite(x_l):
        values["Xl"], sources["Xl"] = x_l, Source.of_effect("subtransient_dynamics", "x_l")
    else:  # the rule the diagnosis's damper model used too (GENROU's flux split needs X_l < X'')
        x_pp = min(float(effect["x_dpp"]), float(effect["x_qpp"])) if effect else values["Xd2"]
        values["Xl"] = float(leakage_default(x_pp))
        sources["Xl"] = Source("default: min(0.15, 0.8 X'')", Origin.DEFAULT)


def _fill_saturation(
    values: dict[str, float],
    sources: dict[str, Source],
    effect: Mapping[str, Any] | None,
    warnings: list[str],
    model: str,
    held: Mapping[str, Any] | None = None,
) -> None:
    if held:  # the datasheet's curve the identification held (--saturation): the record's, as given
        values["S10"], sources["S10"] = float(held["S10"]), Source("held by the user (--saturation)", Origin.HELD)
        values["S12"], sources["S12"] = float(held["S12"]), Source("held by the user (--saturation)", Origin.HELD)
        if effect:
            warnings.append(
                f"the diagnosis found S(1.0) = {float(effect['s10']):.4g}, S(1.2) = {float(effect['s12']):.4g}; "
                "the record keeps the curve the identification held (--saturation)"
            )
    elif effect:
        values["S10"], sources["S10"] = float(effect["s10"]), Source.of_effect("magnetic_saturation", "s10")
        values["S12"], sources["S12"] = float(effect["s12"]), Source.of_effect("magnetic_saturation", "s12")
        # a diagnosis from before the planning forms had S(1.0) exp(b (E'_q - 1)) on E'_q
        form = str(effect.get("form", "exponential on E'_q (phid before 2026-11)"))
        curve = str(effect.get("curve", "exponential"))
        wanted = ("gensal" if model == "GENSAL" else "genrou", "quadratic")
        if (form, curve) != wanted:
            warnings.append(
                f"the diagnosis found saturation of {form} form with a {curve} curve; {model} has the "
                f"{wanted[0]} form with a quadratic curve: they agree at 1.0 and 1.2 pu, not between or beyond"
            )
    else:
        values["S10"], sources["S10"] = 0.0, Source("default: no saturation", Origin.DEFAULT)
        values["S12"], sources["S12"] = 0.0, Source("default: no saturation", Origin.DEFAULT)


# an axis's fields: X, X', T'_0, T''_0
AXES = {"d": ("Xd", "Xd1", "Td10", "Td20"), "q": ("Xq", "Xq1", "Tq10", "Tq20")}


def _through_dampers(
    values: dict[str, float], sources: dict[str, Source], warnings: list[str], model: str, damper_fitted: bool
) -> None:
    """A damped axis's X', T'_0 that came from a fourth-order fit, written as GENROU's classical
    constants that play them through the record's damper (:mod:`phid_ros.model.damper_equivalent`).

    A fourth-order fit finds the slow pole and the slow reactance drop; GENROU's damper loads its
    transient winding, so the same numbers written as its X', T'_0 build another machine (ANDES's
    GENROU, exported from its own fourth-order fit: the fault's angle 0.32 deg off). Values the
    diagnosis refit with its damper model, or that the user held or an existing record gave, are
    GENROU's constants already and stay as they are."""
    converted = Origin.IDENTIFIED, *(() if damper_fitted else (Origin.DIAGNOSIS,))
    for axis, (f_x, f_t, f_t0, f_t0pp) in AXES.items():
        if model == "GENSAL" and axis == "q":  # the salient pole's q axis is its damper (_to_gensal)
            continue
        if sources[f_t].origin not in converted or sources[f_t0].origin not in converted:
            continue
        try:
            one = DamperedAxis(values[f_x], values[f_t], values["Xd2"], values["Xl"], values[f_t0], values[f_t0pp])
            if not one.damper_acts:
                continue
            classical = one.for_fourth_order(values[f_t], values[f_t0])
        except ParameterError as exc:
            raise ExportError(f"the {axis} axis cannot be written as GENROU: {exc}") from None
        for f, new in ((f_t, classical.x_t), (f_t0, classical.t_0)):
            src = sources[f]
            text = str(src).removesuffix(FLAG)
            note = f"{text}; {new:.4g} is the classical constant that plays {values[f]:.4g} through the damper"
            sources[f] = Source(note, src.origin, effect=src.effect, flagged=src.flagged)
        warnings.append(
            f"the {axis} axis written as X'_{axis} = {classical.x_t:.4g}, T'_{axis}0 = {classical.t_0:.4g} s "
            f"({model}'s classical constants): with its damper (X'' = {values['Xd2']:.4g}, T''_{axis}0 = "
            f"{values[f_t0pp]:.4g} s) they play the identified fourth-order X'_{axis} = {values[f_t]:.4g}, "
            f"T'_{axis}0 = {values[f_t0]:.4g} s"
        )
        values[f_t], values[f_t0] = classical.x_t, classical.t_0


def _to_gensal(values: dict[str, float], sources: dict[str, Source], warnings: list[str]) -> None:
    # a salient-pole rotor has no q-axis field circuit: the fourth-order model's q-axis
    # transient circuit is its damper, so T'_q0 becomes T''_q0 unless the diagnosis named one
    if sources["Tq20"].is_default:
        values["Tq20"] = values["Tq10"]
        sources["Tq20"] = Source("identified T_q0_prime (GENSAL's q-axis damper)", Origin.IDENTIFIED)
    warnings.append(
        f"GENSAL has no X'_q or T'_q0: X'_q = {values['Xq1']:.4g} is dropped (its q axis goes from X_q "
        f"to X'' = {values['Xd2']:.4g} with T''_q0 = {values['Tq20']:.4g} s)"
    )
    for f in GENSAL_ABSENT:
        del values[f], sources[f]


def _check(rec: MachineRecord) -> None:
    """The orderings GENROU/GENSAL need to initialise (X_l < X'' <= X' < X, positive times)."""
    v = rec.values
    problems = []
    transient = [v["Xd1"]] + ([v["Xq1"]] if "Xq1" in v else [])
    if not v["Xl"] < v["Xd2"]:
        problems.append(f"Xl={v['Xl']:g} must be below X''={v['Xd2']:g}")
    if any(v["Xd2"] > x for x in transient):
        problems.append(f"X''={v['Xd2']:g} must not exceed X'_d, X'_q={transient}")
    if not v["Xd1"] < v["Xd"] or ("Xq1" in v and not v["Xq1"] < v["Xq"]):
        problems.append("transient reactances must lie below the synchronous ones")
    times = [f for f in ("Td10", "Td20", "Tq10", "Tq20") if f in v and not v[f] > 0]
    if times:
        problems.append(f"time constants {times} must be positive")
    if v["S10"] and not v["S12"] > v["S10"]:
        problems.append(f"S(1.2)={v['S12']:g} must exceed S(1.0)={v['S10']:g}")
    if problems:
        raise ExportError(f"{rec.origin}: cannot form a valid {rec.model} record: " + "; ".join(problems))
