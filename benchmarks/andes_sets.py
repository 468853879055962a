"""CSV scenario sets from an independent plant: ANDES's GENROU on phid's single-machine case.

    python benchmarks/andes_sets.py --machine genrou-sat --out sets/genrou_sat [--duration 30] [--seed 0]

Machines (``test/andes_plant.py``, machine base, Table 1 otherwise; the list there is whole): ``genrou-4th`` (X'_d =
X'_q = X'': exactly the fourth-order model), ``genrou-sat`` (the same with S(1.0) 0.07, S(1.2)
0.45, quadratic on the air-gap flux), ``genrou-sub`` (X'' 0.25, T''_d0 0.04 s, T''_q0 0.08 s),
``genrou-sat-sub`` (saturation and X'' 0.3, T''_d0 0.03 s, T''_q0 0.05 s). ANDES 2.0 has no
GENSAL. Scenarios: the paper's catalogue (15 for identification, 3 validation),
each simulated by ANDES with the simulator's sensor noise added; ``phid identify`` and
``phid diagnose`` read the set's manifest.json.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from common import plant_set_main  # noqa: E402

from test.andes_plant import MACHINES, TRUTH, write_set  # noqa: E402

if __name__ == "__main__":
    plant_set_main(
        __doc__.splitlines()[0], MACHINES, write_set, lambda m: {"parameters": TRUTH[m], "andes_genrou": MACHINES[m]}
    )
