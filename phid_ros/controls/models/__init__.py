"""Excitation systems, turbine-governors and stabilisers as PSS/E defines them: their data apart from their equations.

Laid out as the plant's effects are (:mod:`phid_ros.sim.effects`): the blocks in
:mod:`~phid_ros.controls.models.blocks`, a model's data and registry in
:mod:`~phid_ros.controls.models.base`, and one module per kind (exciters, governors, stabilisers),
imported below in the order the unit's records go. Each model declares its parameters once
(PSS/E's name, unit, range, meaning), its small-signal path (the response of its output deviation
to its input deviations from rest, the blocks of PSS/E's diagram with the limits left out), its
limits, and its planning tools' forms (PSLF's layout, ANDES's names). A limit is a parameter the
recordings determine only where the output reached it; identification reports it as not
determined otherwise (:mod:`phid_ros.controls.identify`). A new model is one class in its kind's
module, registered; the identification and the JSON take every registered model of a kind as a
candidate.
"""

from __future__ import annotations

from phid_ros.controls.models.base import (
    KINDS_IN_ORDER,
    MODEL_DATA,
    MODELS,
    TRANSDUCER,
    ControlModel,
    ControlParameter,
    LimitsError,
    OperatingLevels,
    of_kind,
    register,
)
from phid_ros.controls.models.blocks import (
    Array,
    ControlInputs,
    lag,
    lead_lag,
    lead_lags_in_order,
    nonwindup_lag,
    nonwindup_lead_lag,
    regulator_error,
    transfer,
    washout,
)
from phid_ros.controls.models.exciters import ESST5B, EXST1, IEEET1, SEXS
from phid_ros.controls.models.governors import HYGOV, IEEEG1, TGOV1
from phid_ros.controls.models.stabilisers import IEEEST, PSS2A, PSS2B

__all__ = [
    "ESST5B",
    "EXST1",
    "HYGOV",
    "IEEEG1",
    "IEEEST",
    "IEEET1",
    "KINDS_IN_ORDER",
    "MODEL_DATA",
    "MODELS",
    "PSS2A",
    "PSS2B",
    "SEXS",
    "TGOV1",
    "TRANSDUCER",
    "Array",
    "ControlInputs",
    "ControlModel",
    "ControlParameter",
    "LimitsError",
    "OperatingLevels",
    "lag",
    "lead_lag",
    "lead_lags_in_order",
    "nonwindup_lag",
    "nonwindup_lead_lag",
    "of_kind",
    "register",
    "regulator_error",
    "transfer",
    "washout",
]
