"""The diagnosis on ANDES-made sets (benchmarks/andes_sets.py): named effects, gap, base errors.

    python benchmarks/andes_study.py SET_DIR [SET_DIR ...] [--imperfect-saturation]

Each SET_DIR is a CSV scenario set with ``SET_DIR.truth.json`` beside it (andes_sets.py writes
both). Prints one row per set: the effects named with their parameters, the held-out
unexplained error before and after (noise sigma), the base parameters' errors against the
truth (those the diagnosis could not determine marked n.d.) and the wall time.

``--imperfect-saturation`` restricts the saturation candidate to GENSAL's form (d axis, on
E'_q): on GENROU's saturation (both axes) that is an imperfect model of the first effect, and
the study shows whether a second, spurious effect is named to explain what it leaves.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from phid_ros.api import load_recording  # noqa: E402
from phid_ros.diagnose import candidates  # noqa: E402
from phid_ros.diagnose.options import DiagnoseOptions  # noqa: E402
from phid_ros.diagnose.results import to_json  # noqa: E402
from phid_ros.diagnose.workflow import diagnose  # noqa: E402
from phid_ros.ident.pipeline import IdentifyOptions, identify  # noqa: E402
from phid_ros.model.parameters import PARAMETER_NAMES, GeneratorParameters  # noqa: E402
from phid_ros.stream.scenarios import scenarios_from_recording  # noqa: E402


def gensal_only() -> None:
    cand = candidates.CANDIDATES["magnetic_saturation"]
    choices = cand.choices

    def restricted(cls: type) -> list[dict[str, str]]:
        return [c for c in choices() if c["form"] == "gensal"]

    cand.choices = classmethod(restricted)  # type: ignore[method-assign, assignment]


def run(folder: Path) -> dict:
    truth = json.loads(folder.with_name(folder.name + ".truth.json").read_text())["parameters"]
    manifest = folder / "manifest.json"
    t0 = time.perf_counter()
    scenarios, _ = scenarios_from_recording(load_recording(manifest), str(manifest))
    res = identify(scenarios, IdentifyOptions(baseline=False, validate=False))
    # workers=1: a spawned worker would not see --imperfect-saturation's patch
    d = diagnose(scenarios, res.parameters, DiagnoseOptions.after(res, workers=1))
    doc = to_json(d, GeneratorParameters(**truth))
    doc["seconds"] = time.perf_counter() - t0
    doc["identification_D_std"] = res.estimates["D"].std
    return doc


def _values(effect: dict) -> str:
    """An effect's parameters, those the diagnosis could not determine marked n.d."""
    flags = effect.get("identifiable", {})
    return ", ".join(
        (f"{k} {v:.3g}" if isinstance(v, float) else f"{k} {v}") + ("" if flags.get(k, True) else " n.d.")
        for k, v in effect["parameters"].items()
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("sets", nargs="+", type=Path)
    ap.add_argument("--imperfect-saturation", action="store_true")
    ap.add_argument("--json", type=Path, help="write every diagnosis here")
    args = ap.parse_args()
    if args.imperfect_saturation:
        gensal_only()
    docs = {}
    for folder in args.sets:
        doc = docs[folder.name] = run(folder)
        named = "; ".join(f"{e['name']} {_values(e)}" for e in doc["effects"]) or "none"
        err = doc["errors_pct"]["after"]
        base = ", ".join(
            f"{n} {err[n]:+.2f} %" + ("" if doc["identifiable"].get(n, True) else " n.d.") for n in PARAMETER_NAMES
        )
        print(f"{folder.name}: named {named}")
        print(f"  held-out {doc['rmse_before']:.2f} -> {doc['rmse_after']:.2f} sigma "
              f"({100 * (doc['rmse_after'] / doc['rmse_before'] - 1):+.1f} %), {doc['seconds']:.0f} s")  # fmt: skip
        print(f"  base after: {base}")
        print(f"  D identified std {doc['identification_D_std']:.3g}, refit std {doc['uncertainty']['D']:.3g}")
    if args.json:
        args.json.write_text(json.dumps(docs, indent=1))


if __name__ == "__main__":
    main()
