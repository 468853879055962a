"""Generator model: parameters, equations (5)-(13), Hamiltonian (1) and its PH form."""

from phid_ros.model.parameters import PARAMETER_NAMES, PARAMETER_SPECS, TABLE1, GeneratorParameters

__all__ = ["PARAMETER_NAMES", "PARAMETER_SPECS", "TABLE1", "GeneratorParameters"]
