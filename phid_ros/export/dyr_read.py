"""A PSS/E dynamic data file (.dyr) read back: the unit's machine, exciter and governor.

A record is ``BUS 'MODEL' ID CON(J) ... /`` over one or more lines; text after the ``/`` and
lines that begin with ``@!`` are comments (PSS/E's Program Operation Manual, "Dynamics Data
File Contents"). The constants are in PSS/E's order, the order :mod:`phid_ros.export.formats`
writes (GENROU, GENSAL) and the control models declare (:mod:`phid_ros.controls.models`).

The machine becomes phid's eight parameters for the fourth-order play-in: GENROU's transient
constants as they are; GENSAL's q axis, which has no transient circuit, by its damper (X'_q =
X'', T'_q0 = T''_q0: the inverse of what ``phid export`` does to a salient pole). PSS/E's swing
equation divides P_m by the speed, so the record's D is phid's D less P_m0
(:meth:`phid_ros.export.record.MachineRecord.torque_form_damping`): :meth:`Unit.parameters` adds
the recording's P_m0 back. The dampers and the saturation are played as the simulator's effects
(:meth:`Unit.effects`); :meth:`Unit.fourth_order` is the fourth-order machine that plays the
record's slow part, the one an identification of it finds.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from phid_ros.controls.models import MODELS as CONTROL_MODELS
from phid_ros.errors import ParameterError, PhidError
from phid_ros.export.psse import PSSE_ORDER
from phid_ros.model.damper_equivalent import DamperedAxis
from phid_ros.model.parameters import GeneratorParameters
from phid_ros.sim.effects import PlantEffect
from phid_ros.sim.effects.magnetic_saturation import MagneticSaturation, no_load_field
from phid_ros.sim.effects.subtransient_dynamics import SubtransientDynamics


class DyrError(PhidError):
    """A .dyr the validation cannot read, or a unit it does not hold."""


Array = NDArray[np.float64]


@dataclass(frozen=True)
class DyrRecord:
    bus: int
    model: str
    machine_id: str
    constants: tuple[float, ...]
    line: int  # where the record starts, for messages
    text: str = ""  # the record as written (up to its '/'), so one phid does not model is carried as it is


@dataclass
class ControlSettings:
    model: str
    kind: str
    values: dict[str, float]
    icons: dict[str, int] = field(default_factory=dict)  # PSS/E's integers as the record gives them


@dataclass
class Unit:
    """One machine of a .dyr with the exciter and governor on the same bus and id."""

    source: str
    bus: int
    machine_id: str
    machine: str  # GENROU or GENSAL
    constants: dict[str, float]  # the machine's, by PSS/E's names
    controls: dict[str, ControlSettings] = field(default_factory=dict)  # by kind
    ignored: list[str] = field(default_factory=list)  # records on the unit phid does not model
    carried: list[DyrRecord] = field(default_factory=list)  # those records, to be written back as they are

    def parameters(self, p_m0: float) -> GeneratorParameters:
        """The fourth-order model's parameters, D in phid's form at the operating point ``p_m0``."""
        c = self.constants
        if self.machine == "GENSAL":
            x_q_prime, t_q0_prime = c["Xd2"], c["Tq20"]  # the salient pole's q axis is its damper
        else:
            x_q_prime, t_q0_prime = c["Xq1"], c["Tq10"]
        try:
            return GeneratorParameters(
                H=c["H"],
                D=c["D"] + p_m0,
                X_d=c["Xd"],
                X_q=c["Xq"],
                X_d_prime=c["Xd1"],
                X_q_prime=x_q_prime,
                T_d0_prime=c["Td10"],
                T_q0_prime=t_q0_prime,
            )
        except ParameterError as exc:  # the file and the record, not only the values
            raise DyrError(f"{self.source}: {self.machine} at bus {self.bus} id '{self.machine_id}': {exc}") from None

    def fourth_order(self, p_m0: float) -> GeneratorParameters:
        """The fourth-order model that plays the record's slow part (its X', T'_0 seen through the
        dampers, :mod:`phid_ros.model.damper_equivalent`): what an identification of the machine the
        record writes would find, so the two compare (``parameters`` gives the constants as written,
        which the play-in takes with :meth:`effects`)."""
        written = self.parameters(p_m0)
        if not self._dampers():
            return written
        c, out = self.constants, {}
        axes = [("d", "X_d", "X_d_prime", "T_d0_prime", "Td20")]
        if self.machine == "GENROU":  # GENSAL's q axis is its damper already
            axes.append(("q", "X_q", "X_q_prime", "T_q0_prime", "Tq20"))
        for _, x, x_t, t_0, t_0pp in axes:
            one = DamperedAxis(
                getattr(written, x), getattr(written, x_t), c["Xd2"], c["Xl"], getattr(written, t_0), c[t_0pp]
            )
            out[x_t], out[t_0] = one.fourth_order()
        return replace(written, **out)

    def effects(self) -> list[tuple[type[PlantEffect], dict[str, Any]]]:
        """The record's machine beyond the fourth-order model, as the simulator's effects, so a
        validation plays the machine the record writes: the dampers (GENSAL's d axis, GENROU's
        both; X'' = X''_d = X''_q, X_l as written) and the saturation (S(1.0), S(1.2), the
        quadratic curve of both models, on E'_q for GENSAL and on the air-gap flux for GENROU)."""
        c = self.constants
        out: list[tuple[type[PlantEffect], dict[str, Any]]] = []
        if self._dampers():
            # X''_q = X''_d in both models; GENSAL's q damper is its q transient circuit already
            # (X'_q = X'', :meth:`parameters`), which x_qpp = X'' leaves inert here
            damper = {"x_dpp": c["Xd2"], "x_qpp": c["Xd2"], "t_d0pp": c["Td20"], "t_q0pp": c["Tq20"], "x_l": c["Xl"]}
            out.append((SubtransientDynamics, damper))
        if self._saturated():
            form = "gensal" if self.machine == "GENSAL" else "genrou"
            out.append((MagneticSaturation, {"s10": c["S10"], "s12": c["S12"], "form": form, "curve": "quadratic"}))
        return out

    def open_circuit_field(self, v_t: Array) -> Array:
        """E_fd that holds the open-circuit machine at ``v_t`` (pu): V_t (1 + S(V_t)) on the
        record's saturation curve (at no load both models saturate on V_t: E'_q, the air-gap flux)."""
        c = self.constants
        return np.asarray(no_load_field(v_t, c["S10"], c["S12"]), dtype=float)

    def _dampers(self) -> bool:
        c = self.constants
        # a damper acts in an axis whose transient reactance lies above X'' (GENSAL's q axis is
        # its damper, simulated as the q transient circuit)
        acts = c["Xd2"] < c["Xd1"] - 1e-9 or (self.machine == "GENROU" and c["Xd2"] < c["Xq1"] - 1e-9)
        return bool(acts and c["Td20"] > 0 and c["Tq20"] > 0 and 0 < c["Xl"] < c["Xd2"])

    def _saturated(self) -> bool:
        c = self.constants
        return bool(c["S12"] > c["S10"] > 0)

    def not_simulated(self) -> list[str]:
        """What the record carries that the play-in (the fourth-order model with :meth:`effects`)
        leaves out."""
        out = []
        c = self.constants
        damped = c["Xd2"] < c["Xd1"] - 1e-9 or (self.machine == "GENROU" and c["Xd2"] < c["Xq1"] - 1e-9)
        if damped and not self._dampers():
            out.append(
                f"the dampers (X'' = {c['Xd2']:g}, T''_d0 = {c['Td20']:g} s, T''_q0 = {c['Tq20']:g} s, "
                f"X_l = {c['Xl']:g}: a time constant not positive or X_l not below X'')"
            )
        if (c["S10"] or c["S12"]) and not self._saturated():
            out.append(f"saturation (S(1.0) = {c['S10']:g}, S(1.2) = {c['S12']:g}: needs S(1.2) > S(1.0) > 0)")
        for settings in self.controls.values():
            out += CONTROL_MODELS[settings.model].not_simulated(settings.values)
        return out + [f"{r}: not a model phid validates" for r in self.ignored]


_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eEdD][-+]?\d+)?$")


def read_records(path: str | Path) -> list[DyrRecord]:
    """Every record of the file, constants as numbers; a malformed one is a one-line error."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8", errors="replace")
    except OSError as e:
        raise DyrError(f"{p}: cannot read: {e.strerror or e}") from e
    records: list[DyrRecord] = []
    tokens: list[str] = []
    bodies: list[str] = []
    start = 0
    for number, raw in enumerate(text.splitlines(), 1):
        line = raw.split("@!", 1)[0] if raw.lstrip().startswith("@!") else raw
        body, slash, _comment = line.partition("/")
        try:
            words = shlex.split(body.replace(",", " "), posix=True)
        except ValueError as e:
            raise DyrError(f"{p}:{number}: {e}") from e
        if words and not tokens:
            start = number
        tokens += words
        if words:
            bodies.append(body.rstrip())
        if slash and tokens:
            records.append(_record(p, start, tokens, "\n".join(bodies) + " /"))
            tokens, bodies = [], []
    if tokens:
        raise DyrError(f"{p}:{start}: record '{' '.join(tokens[:3])} ...' does not end with '/'")
    return records


def _record(p: Path, line: int, tokens: list[str], text: str) -> DyrRecord:
    if len(tokens) < 3 or not tokens[0].lstrip("-").isdigit():
        raise DyrError(f"{p}:{line}: a record begins BUS 'MODEL' ID; found '{' '.join(tokens[:3])}'")
    numbers = []
    for t in tokens[3:]:
        if not _NUMBER.match(t):
            raise DyrError(f"{p}:{line}: {tokens[1]} constant '{t}' is not a number")
        numbers.append(float(t.replace("d", "e").replace("D", "e")))
    return DyrRecord(int(tokens[0]), tokens[1].upper(), tokens[2].strip(), tuple(numbers), line, text)


def _no_control_without_its_machine(p: Path, records: list[DyrRecord], machines: list[DyrRecord], m: DyrRecord) -> None:
    """A control model's record belongs to the machine at its bus and id: one at a bus and id
    where the file holds no machine is a record written at the wrong place (an exciter at bus 2
    beside a machine at bus 1 was dropped, and the unit validated on the recorded E_fd)."""
    at = {(r.bus, r.machine_id) for r in machines}
    for r in records:
        if r.model in CONTROL_MODELS and (r.bus, r.machine_id) not in at:
            raise DyrError(
                f"{p}:{r.line}: {r.model} at bus {r.bus} id '{r.machine_id}', where the file holds no machine "
                f"(its {m.model} is at bus {m.bus} id '{m.machine_id}'): a control belongs to the machine at its "
                "bus and id"
            )


def read_unit(path: str | Path, bus: int | None = None, machine_id: str | None = None) -> Unit:
    """The unit (GENROU or GENSAL with its exciter and governor) at ``bus``/``machine_id``; the
    only machine of the file when neither is given."""
    p = Path(path)
    records = read_records(p)
    every = [r for r in records if r.model in PSSE_ORDER]
    machines = [r for r in every if bus in (None, r.bus) and machine_id in (None, r.machine_id)]
    if not machines:
        found = ", ".join(f"bus {r.bus} id '{r.machine_id}'" for r in every)
        where = f" at the unit asked; the file has {found}" if found else ""
        raise DyrError(f"{p}: no GENROU or GENSAL record{where}")
    if len(machines) > 1:
        which = ", ".join(f"bus {r.bus} id '{r.machine_id}'" for r in machines)
        raise DyrError(f"{p}: {len(machines)} machines ({which}): name one with --bus and --id")
    m = machines[0]
    order = PSSE_ORDER[m.model]
    if len(m.constants) != len(order):
        raise DyrError(f"{p}:{m.line}: {m.model} has {len(m.constants)} constants; PSS/E's has {len(order)}")
    unit = Unit(str(p), m.bus, m.machine_id, m.model, dict(zip(order, m.constants)))
    _no_control_without_its_machine(p, records, every, m)
    for r in records:
        if (r.bus, r.machine_id) != (m.bus, m.machine_id) or r is m:
            continue
        model = CONTROL_MODELS.get(r.model)
        if model is None:
            unit.ignored.append(f"{r.model} (line {r.line})")
            unit.carried.append(r)
            continue
        names = [q.name for q in model.parameters]
        skip = len(model.icons)  # PSS/E's integers before the constants (IEEEG1's second shaft)
        if len(r.constants) != skip + len(names):
            raise DyrError(
                f"{p}:{r.line}: {r.model} has {len(r.constants)} numbers; phid reads {skip} + {len(names)} constants"
            )
        icons = dict(zip((n for n, _v in model.icons), r.constants[:skip]))
        for name, simulated in model.icons:
            if name in model.icons_simulated and icons[name] != simulated:
                raise DyrError(
                    f"{p}:{r.line}: {r.model} {name} = {icons[name]:g}: phid simulates {r.model} with {name} = "
                    f"{simulated} only"
                )
        if model.kind in unit.controls:
            raise DyrError(f"{p}:{r.line}: a second {model.kind} ({r.model}) on bus {m.bus} id '{m.machine_id}'")
        values = dict(zip(names, r.constants[skip:]))
        problem = model.record_problem(values)
        if problem is not None:
            raise DyrError(f"{p}:{r.line}: {r.model} {problem}")
        try:
            model.recorded(values)  # what the simulation cannot take of the record, refused by name
        except ValueError as exc:
            raise DyrError(f"{p}:{r.line}: {r.model}: {exc}") from None
        unit.controls[model.kind] = ControlSettings(r.model, model.kind, values, {n: int(v) for n, v in icons.items()})
    return unit
