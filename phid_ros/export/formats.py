"""The machine record laid out in the planners' formats: PSS/E .dyr, PSLF .dyd, ANDES JSON.

Rules followed (each writer's test reads its output back by these rules):

- PSS/E .dyr: ``IBUS 'MODEL' ID`` then the model's constants in their documented order,
  free format, the record ended by ``/``; anything after the ``/`` is a comment. The constants
  are on the machine base (MBASE of the .raw generator record). GENROU: T'do T''do T'qo T''qo
  H D Xd Xq X'd X'q X''d Xl S(1.0) S(1.2); GENSAL: T'do T''do T''qo H D Xd Xq X'd X''d Xl
  S(1.0) S(1.2). Stator resistance is not a .dyr constant (it is ZSORCE in the .raw). PSS/E's
  swing equation divides P_m by the speed: D is written as D - P_m0 (``MachineRecord.torque_form_damping``).
- PSLF .dyd: ``genrou BUS "NAME" KV "ID" : #9 mva=MVA`` then ``"name" value`` pairs;
  a line ending in ``/`` continues on the next; lines starting with ``#`` are comments.
- ANDES: a JSON object ``{"GENROU": [record]}`` with ANDES's field names (M = 2H, xd1, Td10,
  ...), loadable with ``andes.io.json.read`` into a system that holds the bus and the
  static generator named by ``bus`` and ``gen``. ANDES has no GENSAL model (its .dyr reader
  maps GENSAL to GENROU with X'_q = X'_d): a GENSAL record goes out the same way.
"""

from __future__ import annotations

import json
from collections.abc import Callable

from phid_ros.controls.models import MODELS
from phid_ros.export.psse import PSSE_ORDER
from phid_ros.export.record import ExportError, MachineRecord

PSLF_NAMES = {
    "Td10": "tpdo",
    "Td20": "tppdo",
    "Tq10": "tpqo",
    "Tq20": "tppqo",
    "H": "h",
    "D": "d",
    "Xd": "ld",
    "Xq": "lq",
    "Xd1": "lpd",
    "Xq1": "lpq",
    "Xd2": "lppd",
    "Xl": "ll",
    "S10": "s1",
    "S12": "s12",
    "ra": "ra",
}
PSLF_FIXED = {"rcomp": 0.0, "xcomp": 0.0, "accel": 0.0}

# PSLF's governor records are positional after the turbine's capability ``mwcap=``, in PSS/E's
# constant order, as .dyd files run in PSLF write them (the validation cases of PSLTDSim,
# github.com/thadhaines/PSLTDSim: ``tgov1 ... : #1 mwcap=800.0 0.05 0.4 1.0 0.0 3.0 10.0 0.0``;
# ``ieeeg1 ... : #9 mwcap=1000.0`` K T1 T2 T3 UO UC PMAX PMIN T4 K1 K2 T5 K3 K4 T6 K5 K6 T7 K7 K8,
# then fifteen zeros: its deadbands and valve table, unused). Only the models whose PSLF layout
# such files show are written (each model says so: ``pslf_trailing_zeros``); the others are left
# out of a .dyd and said so: a PSLF keyword or position guessed is a wrong number in a planner's
# file. mwcap is written as the machine's MVA base, so the per-unit constants keep their base.
PSLF_CONTROLS = {n: m.pslf_trailing_zeros for n, m in MODELS.items() if m.pslf_trailing_zeros is not None}

ANDES_NAMES = {
    "Td10": "Td10",
    "Td20": "Td20",
    "Tq10": "Tq10",
    "Tq20": "Tq20",
    "D": "D",
    "Xd": "xd",
    "Xq": "xq",
    "Xd1": "xd1",
    "Xq1": "xq1",
    "Xl": "xl",
    "S10": "S10",
    "S12": "S12",
    "ra": "ra",
}


# the control models ANDES has (each model says so, and its constants' names where they are not PSS/E's)
ANDES_CONTROL_MODELS = tuple(n for n, m in MODELS.items() if m.in_andes)


def _num(v: float) -> str:
    return f"{v:.6g}"


def psse_dyr(rec: MachineRecord) -> str:
    fields = {**rec.values, "D": rec.torque_form_damping()}  # PSS/E divides P_m by the speed
    values = [_num(fields[f]) for f in PSSE_ORDER[rec.model]]
    lines = [f"{rec.bus} '{rec.model}' '{rec.machine_id}'"]
    for i in range(0, len(values), 6):
        lines.append("    " + " ".join(values[i : i + 6]))
    lines[-1] += f" /  {rec.comment()}"
    for c in rec.controls:  # the exciter and the governor beside the machine, their CONs in PSS/E's order
        icons = [str(v) for v in c.icon_values()]
        lines.append(f"{rec.bus} '{c.model}' '{rec.machine_id}' " + " ".join([*icons, *map(_num, c.values.values())]))
        lines[-1] += f" /  {c.comment()}"
    for text in rec.carried:  # the existing record's models phid does not model, as they were written
        lines.append(text)
    return "\n".join(lines) + "\n"


def _pslf_head(model: str, rec: MachineRecord, base: str) -> str:
    """A .dyd record's identification: model, bus, bus name, kV, id, then ``: #9`` and its base."""
    return f'{model.lower()} {rec.bus} "BUS{rec.bus}" {rec.kv:.2f} "{rec.machine_id}" : #9 {base}={rec.mva:g}'


def pslf_dyd(rec: MachineRecord) -> str:
    pairs = [f'"{PSLF_NAMES[f]}" {_num(rec.values[f])}' for f in rec.fields]
    pairs += [f'"{k}" {_num(v)}' for k, v in PSLF_FIXED.items()]
    body = [_pslf_head(rec.model, rec, "mva")] + ["    " + " ".join(pairs[i : i + 5]) for i in range(0, len(pairs), 5)]
    lines = [f"# {rec.comment()}", " /\n".join(body)]
    for c in rec.controls:
        if c.model not in PSLF_CONTROLS:
            continue
        values = [*map(_num, c.values.values()), *["0"] * PSLF_CONTROLS[c.model]]
        lines += [f"# {c.comment()}", _pslf_head(c.model, rec, "mwcap") + " " + " ".join(values)]
    return "\n".join(lines) + "\n"


def pslf_left_out(rec: MachineRecord) -> list[str]:
    """The unit's control models a .dyd does not carry (see PSLF_CONTROLS)."""
    return [c.model for c in rec.controls if c.model not in PSLF_CONTROLS]


def andes_json(rec: MachineRecord) -> str:
    v = rec.values
    row: dict[str, object] = {
        "idx": f"GENROU_{rec.bus}_{rec.machine_id}",
        "u": 1,
        "name": f"GEN_{rec.bus}_{rec.machine_id}",
        "bus": rec.bus,
        "gen": f"{rec.bus}_{rec.machine_id}",
        "Sn": rec.mva,
        "Vn": rec.kv,
        "fn": rec.f_nominal_hz,
        "M": 2.0 * v["H"],
    }
    row.update({ANDES_NAMES[f]: v[f] for f in ANDES_NAMES if f in v})
    row["xd2"] = row["xq2"] = v["Xd2"]
    if rec.model == "GENSAL":  # as ANDES's own .dyr reader maps GENSAL onto GENROU
        row["xq1"], row["Tq10"] = v["Xd1"], v["Td10"]
    if rec.flagged:  # ANDES rows have no comment field; the name carries the warning
        row["name"] = f"{row['name']} NOT IDENTIFIED: {', '.join(rec.flagged)}"
    doc: dict[str, list[dict[str, object]]] = {"GENROU": [row]}
    for c in rec.controls:  # ANDES's models take PSS/E's constants, wired to the machine by syn
        if c.model not in ANDES_CONTROL_MODELS:
            raise ExportError(
                f"controls.{c.kind}: ANDES has no {c.model} model (it has {', '.join(ANDES_CONTROL_MODELS)}); "
                "export this unit as psse-dyr"
            )
        ctl: dict[str, object] = {"idx": f"{c.model}_{rec.bus}_{rec.machine_id}", "u": 1, "syn": row["idx"]}
        if c.kind == "stabiliser":
            # ANDES wires a stabiliser to its exciter (the output joins the exciter's input), and
            # takes its ICONs as fields: MODE, and no remote bus
            exciter = next((e for e in rec.controls if e.kind == "exciter"), None)
            if exciter is None:
                raise ExportError(
                    f"controls.{c.kind}: ANDES's {c.model} acts through the unit's exciter, and none is named; "
                    "export this unit as psse-dyr"
                )
            del ctl["syn"]
            ctl["avr"] = f"{exciter.model}_{rec.bus}_{rec.machine_id}"
            ctl.update({k: v for k, v in MODELS[c.model].icons if k != "BUSR"})
        ctl["name"] = f"{c.model}_{rec.bus}_{rec.machine_id}" + (
            f" NOT IDENTIFIED: {', '.join(c.flagged)}" if c.flagged else ""
        )
        names = MODELS[c.model].andes_names
        ctl.update({names.get(k, k): v for k, v in c.values.items()})
        if c.kind == "governor":
            ctl["Tn"] = rec.mva  # R and the valve limits on the machine's base
        doc[c.model] = [ctl]
    return json.dumps(doc, indent=2) + "\n"


WRITERS: dict[str, Callable[[MachineRecord], str]] = {
    "psse-dyr": psse_dyr,
    "pslf-dyd": pslf_dyd,
    "andes": andes_json,
}
