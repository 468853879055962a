"""The recorded E_fd put on the machine's base, for the exciter's fit and play-in."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from phid_ros.ident.determinable import FIELD_GAIN_BAND
from phid_ros.ident.field_circuit import machine_field
from phid_ros.ident.open_circuit import field_base
from phid_ros.ident.scenario import ScenarioData
from phid_ros.ident.terminal import with_channels


def on_machine_field_base(
    scenarios: Sequence[ScenarioData], saturation: tuple[float, float] | None = None
) -> tuple[list[ScenarioData], str | None]:
    """The scenarios with the recorded E_fd put on the machine's base where the no-load tests show
    it recorded on another (an excitation controller's own per unit: V_t settles at 2.68 x E_fd,
    outside what saturation explains), and the note saying so; as they are otherwise. Where the
    field current is recorded, file by file from it (:func:`phid_ros.ident.field_circuit.machine_field`:
    a test's field resistance moves with its temperature); else from E_fd's own no-load plateaus.
    The curve is ``saturation`` (the datasheet's S(1.0), S(1.2), held, which ``phid export``
    writes into the record) or the air-gap line, as ``phid validate`` takes it from a record
    without saturation: an exciter's gain fitted on it plays back on the same base."""

    by_current = machine_field(scenarios, saturation)
    if by_current is not None:
        if by_current.on_base():
            return list(scenarios), None
        note = f"the exciter fitted with {by_current.note}"
        return by_current.applied(scenarios, note), note
    base = field_base(scenarios)
    if base is None or FIELD_GAIN_BAND[0] <= base.scale <= FIELD_GAIN_BAND[1]:
        return list(scenarios), None
    k = base.scale
    note = (
        f"the exciter fitted with E_fd on the machine's base: 1 pu = {1 / k:.4g} as recorded, from "
        f"{len(base.v_t)} no-load plateau(s) at V_t {base.v_t.min():.3f}-{base.v_t.max():.3f} pu on the air-gap "
        f"line (within {100 * base.scatter:.1f} %; the saturation not known here): every E_fd multiplied by {k:.4g}"
    )
    out = [with_channels(s, {"v_f": k * np.asarray(s["v_f"], float)}, note) if s.has("v_f") else s for s in scenarios]
    return out, note
