"""``phid simulate``: the paper's scenarios (or a long ambient run with drifts) -> a recording and its truth."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console

from phid_ros.api import simulate_ambient_to_file, simulate_to_file
from phid_ros.cli.progress import ProgressLine
from phid_ros.errors import PhidError


def _parse_effects(items: Sequence[str]) -> tuple:
    from phid_ros.sim.effects import parse_effect

    return tuple(parse_effect(item) for item in items)


def simulate_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.sim.runner import SimulationConfig
    from phid_ros.sim.scenarios import find_scenario, paper_catalogue, validation_scenarios
    from phid_ros.sim.sensors import SensorModel

    effects = _parse_effects(args.effect or [])
    if args.ambient and effects:
        raise PhidError("--effect is not available with --ambient yet (the long-run integrator has no effect hooks)")
    if args.ambient:
        return _simulate_ambient(args, console)
    if args.drift:
        raise PhidError("--drift needs --ambient (a drift happens over a long run)")
    if args.scenario:
        scenarios = [find_scenario(name) for name in args.scenario]
    elif args.catalogue == "validation":
        scenarios = validation_scenarios()
    else:
        scenarios = paper_catalogue()
    if args.duration is not None:
        from phid_ros.sim.scenarios import with_duration

        scenarios = [with_duration(s, args.duration) for s in scenarios]
    out = _simulation_output(args)
    cfg = SimulationConfig(
        f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless), effects=effects
    )
    with ProgressLine(f"simulating {len(scenarios)} scenario(s)") as progress:
        done = simulate_to_file(
            scenarios, cfg, out, start_ns=args.start, block_size=args.block_size, progress=progress.update
        )
    console.print(f"wrote {out} ({len(scenarios)} scenarios, {done.span_s:.1f} s of data) and {done.truth}")
    return 0


def _simulation_output(args: argparse.Namespace) -> Path:
    from phid_ros.io.files.outputs import refuse_inputs
    from phid_ros.io.files.results import truth_path_for

    out = Path(args.out)
    if out.name == "manifest.json":  # a CSV scenario set: its folder is the output
        out.parent.mkdir(parents=True, exist_ok=True)
    refuse_inputs([out, truth_path_for(out)], [])
    for p in (out, truth_path_for(out)):
        if p.exists() and not args.force:
            raise PhidError(f"{p}: already exists, not overwriting (--force to replace it)")
    return out


def _parse_drift(text: str) -> object:
    from phid_ros.sim.ambient import Drift

    try:
        name, rest = text.split("=", 1)
        rel, span = rest.split("@", 1)
        start, end = span.split("-", 1)
        return Drift(name.strip(), float(start), float(end), float(rel))
    except ValueError:
        raise PhidError(f"--drift {text!r}: expected NAME=REL@START-END, e.g. T_d0_prime=0.1@300-1500") from None


def _simulate_ambient(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.sim.ambient import AmbientSettings
    from phid_ros.sim.runner import SimulationConfig
    from phid_ros.sim.sensors import SensorModel

    out = _simulation_output(args)
    drifts = tuple(_parse_drift(d) for d in (args.drift or []))
    settings = AmbientSettings(duration_s=args.ambient, drifts=drifts, seed=args.seed)  # type: ignore[arg-type]
    cfg = SimulationConfig(f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless))
    with ProgressLine(f"simulating {args.ambient:g} s of ambient operation") as progress:
        done = simulate_ambient_to_file(
            settings, cfg, out, start_ns=args.start, block_size=args.block_size, progress=progress.update
        )
    console.print(f"wrote {out} ({args.ambient:g} s, {len(drifts)} drift(s)) and {done.truth}")
    return 0
