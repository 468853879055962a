"""``phid simulate``: the paper's scenarios (or a long ambient run with drifts) -> a recording and its truth."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console

from phid_ros.cli.common import write_output
from phid_ros.cli.progress import ProgressLine
from phid_ros.errors import PhidError
from phid_ros.io.files.outputs import atomic_output
from phid_ros.model.conventions import NS


def _parse_effects(items: Sequence[str]) -> tuple:
    from phid_ros.sim.effects import parse_effect

    return tuple(parse_effect(item) for item in items)


def _start(args: argparse.Namespace) -> int:
    from phid_ros.sim.recording import DEFAULT_START_NS

    return DEFAULT_START_NS if args.start is None else int(args.start)


def simulate_command(args: argparse.Namespace, console: Console) -> int:
    from phid_ros.io.files.results import truth_path_for, write_json
    from phid_ros.sim.recording import recording_from_runs, truth_document
    from phid_ros.sim.runner import SimulationConfig, simulate_scenarios
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
        runs = simulate_scenarios(scenarios, cfg)
        progress.update(f"writing {out}")
        rec = recording_from_runs(runs, cfg, start_ns=_start(args))
        write_output(out, rec, args.block_size)
    truth = write_json(truth_path_for(out), truth_document(cfg, scenarios))
    start, end = rec.span_ns()
    console.print(f"wrote {out} ({len(scenarios)} scenarios, {(end - start) / NS:.1f} s of data) and {truth}")
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
    import numpy as np

    from phid_ros.io.bags.recordings import open_message_writer
    from phid_ros.io.files.results import truth_path_for, write_json
    from phid_ros.io.recording import Recording, StreamSamples, iter_recording_messages
    from phid_ros.io.topics import STREAMS
    from phid_ros.model.conventions import NS
    from phid_ros.sim.ambient import AmbientSettings, ambient_chunks
    from phid_ros.sim.recording import recording_metadata, truth_document
    from phid_ros.sim.runner import SimulationConfig
    from phid_ros.sim.sensors import SensorModel

    out = _simulation_output(args)
    drifts = tuple(_parse_drift(d) for d in (args.drift or []))
    settings = AmbientSettings(duration_s=args.ambient, drifts=drifts, seed=args.seed)  # type: ignore[arg-type]
    cfg = SimulationConfig(f_nominal_hz=args.f_nominal, sensors=SensorModel(seed=args.seed, noiseless=args.noiseless))
    dt_ns = int(round(cfg.dt * NS))
    every = int(round(1 / cfg.dt))
    drifting: dict[str, list[float]] = {d.parameter: [] for d in settings.drifts}
    # simulated and written a chunk at a time (ten minutes of samples in memory, not the day); a
    # chunk is a whole number of messages, so its messages follow the last chunk's in log time
    with ProgressLine(f"simulating {args.ambient:g} s of ambient operation") as progress, atomic_output(out) as tmp:
        writer = open_message_writer(tmp, recording_metadata(cfg))
        try:
            for chunk in ambient_chunks(settings, cfg):
                first = int(round(chunk.t[0] / cfg.dt))
                t_ns = _start(args) + (first + np.arange(len(chunk.t), dtype=np.int64)) * dt_ns
                streams = {
                    s.name: StreamSamples(t_ns.copy(), dt_ns, {c: chunk.measured[c] for c in s.channels})
                    for s in STREAMS
                }
                for item in iter_recording_messages(Recording(streams, []), block_size=args.block_size):
                    writer.write(*item)
                for name, v in chunk.parameters.items():  # once a second, from the run's start
                    drifting[name] += v[(-first) % every :: every].tolist()
                progress.update(f"simulated and written {chunk.t[-1]:.0f} of {args.ambient:g} s")
        except BaseException:
            writer.abort()
            raise
        writer.close()
    truth = truth_document(cfg, [])
    truth["ambient"] = {"duration_s": args.ambient, "seed": args.seed, "drifts": [d.__dict__ for d in drifts]}
    truth["drifting_parameters_every_s"] = drifting
    path = write_json(truth_path_for(out), truth)
    console.print(f"wrote {out} ({args.ambient:g} s, {len(drifts)} drift(s)) and {path}")
    return 0
