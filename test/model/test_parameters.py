import math

import pytest

from phid_ros.errors import ParameterError
from phid_ros.model.parameters import PARAMETER_NAMES, PARAMETER_SPECS, TABLE1, GeneratorParameters


def test_defaults_are_table_1_of_the_paper():
    assert TABLE1.as_dict() == {
        "H": 3.480,
        "D": 0.400,
        "X_d": 2.540,
        "X_q": 2.410,
        "X_d_prime": 0.500,
        "X_q_prime": 0.814,
        "T_d0_prime": 1.437,
        "T_q0_prime": 0.1351,
    }
    assert PARAMETER_NAMES == ("H", "D", "X_d", "X_q", "X_d_prime", "X_q_prime", "T_d0_prime", "T_q0_prime")
    assert all(spec.default == getattr(TABLE1, spec.name) for spec in PARAMETER_SPECS)


@pytest.mark.parametrize(
    "change, phrase",
    [
        ({"X_d_prime": 2.6}, "X_d_prime=2.6 must be below X_d"),
        ({"X_q_prime": 2.41}, "X_q_prime=2.41 must be below X_q"),
        ({"T_d0_prime": -1.0}, "T_d0_prime=-1"),
        ({"H": math.nan}, "H=nan is not finite"),
        ({"D": -0.1}, "D=-0.1 pu outside"),
    ],
)
def test_invalid_sets_are_rejected_with_the_reason(change, phrase):
    with pytest.raises(ParameterError, match=phrase.replace("(", r"\(").replace(".", r"\.")):
        TABLE1.replace(**change)


def test_from_mapping_names_unknown_and_missing_keys():
    with pytest.raises(ParameterError, match=r"unknown parameter\(s\) \['Xd'\]"):
        GeneratorParameters.from_mapping({**TABLE1.as_dict(), "Xd": 1.0})
    values = TABLE1.as_dict()
    del values["H"]
    with pytest.raises(ParameterError, match=r"missing parameter\(s\) \['H'\]"):
        GeneratorParameters.from_mapping(values)
    with pytest.raises(ParameterError, match="must be a number"):
        GeneratorParameters.from_mapping({**TABLE1.as_dict(), "H": "3.5"})
    assert GeneratorParameters.from_mapping(TABLE1.as_dict()) == TABLE1
