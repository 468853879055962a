"""CSV scenario sets from an independent salient-pole plant: STEPS's GENSAL on phid's single-machine case.

    python benchmarks/steps_sets.py --machine gensal-sat --out sets/gensal_sat [--duration 12] [--seed 0]

Machines (``test/steps_plant.py``, machine base 1000 MVA on a 100 MVA system base): ``gensal``
(a hydro unit's salient-pole data, X'' 0.22, T''_d0 0.05 s, T''_q0 0.08 s), ``gensal-sat`` (the
same with S(1.0) 0.1, S(1.2) 0.4; STEPS's GENSAL saturates GENROU's way, on |psi''| in both
axes, not PSS/E's GENSAL way on E'_q: see test/steps_plant.py),
``gensal-controls`` and ``gensal-sat-controls`` (with SEXS and TGOV1 in the loop: a field step is a
voltage-reference step, a torque step a load-reference step). Scenarios: the paper's catalogue
(15 for identification, 3 validation) with the simulator's sensor noise; ``phid identify`` and
``phid diagnose`` read the set's manifest.json. STEPS is built from its source first:
``benchmarks/steps_build.sh``.
"""

from __future__ import annotations

import sys
from dataclasses import asdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import plant_set_main  # noqa: E402

from test.steps_plant import MACHINES, TRUTH, write_set  # noqa: E402

if __name__ == "__main__":
    plant_set_main(
        __doc__.splitlines()[0],
        MACHINES,
        write_set,
        lambda m: {"parameters": TRUTH[m], "steps": asdict(MACHINES[m]), "dyr": MACHINES[m].dyr()},
    )
