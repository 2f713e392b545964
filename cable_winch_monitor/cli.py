"""`cable-winch-monitor`: one command, a subcommand per job; each is a thin call into the package."""
from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections.abc import Sequence
from pathlib import Path

from .bagio.reader import BagError
from .effects import BUILTIN_REGISTRY, Registry
from .effects.base import EffectError
from .formatting import format_solution
from .messages.scene import LIVE_RATE, REPLAY_RATE
from .model.plantfile.plant import CABLE_NAMES, Plant, PlantConfigError, load_plant
from .model.solvers.solve import METHODS
from .monitor.sensors import READING_LAG
from .paths import config_dir
from .sim.keys import ScenarioError

DIAGNOSE_BUDGET = 180.0  # [s] default wall time of `diagnose`: a 20-minute recording in three minutes

class UsageError(Exception):
    """A command line that cannot be carried out; the message says why."""


def _check_writable(path: str | None, option: str) -> None:
    """Refuse an output path that cannot be written, before any work is done for it."""
    if not path:
        return
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if target.is_dir():
        raise UsageError(f"{option} {path}: is a directory, give a file name")
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: folder {parent} does not exist")
    if not os.access(target if target.exists() else parent, os.W_OK):
        raise UsageError(f"{option} {path}: not writable (permission denied)")


def _effect_names(text: str | None, option: str, registry: Registry) -> list[str] | None:
    """Comma-separated effect names, each one known to `registry` (the plant model's; None for none given)."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise UsageError(f"{option}: no effect name given")
    for name in names:
        registry.effect_class(name)  # EffectError naming the known ones
    return names


def _plant_with_modules(args: argparse.Namespace) -> Plant:
    """The plant file of --config with the user modules of --effect-module after its own `effect_modules`."""
    plant = load_plant(args.config)
    return plant.with_changes(effect_modules=(*plant.effect_modules, *(str(Path(m).resolve()) for m in args.effect_module)))


def _length(text: str) -> float:
    """A command-line length: any float, so that nan, inf and negatives reach the solver's checks."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"cable length must be a number, got {text!r}") from None


def _positive(text: str) -> float:
    """A command-line rate: a positive number."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0.0:
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def _budget(text: str) -> float | None:
    """diagnose's --budget: seconds, a finite number >= 0 (0: no limit, None)."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0.0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"must be a number of seconds >= 0 (0: no limit), got {text!r}")
    return value if value > 0.0 else None


def _solve(args: argparse.Namespace) -> int:
    from .effects import PlantModel

    solution = PlantModel.from_plant(load_plant(args.config), args.method).solve(args.lengths)  # bad numbers: INVALID_INPUT
    if args.json:
        print(json.dumps(solution.to_dict(), indent=2))
    else:
        print(format_solution(solution))
    return 0 if solution.status.value in ("solved", "single_cable_indeterminate") else 1


def _paper(args: argparse.Namespace) -> int:
    from .demo import run_demo

    return run_demo(load_plant(args.config))


def _simulate(args: argparse.Namespace) -> int:
    from .sim.scenario import load_scenario, scenario_path
    from .sim.simulate import simulate

    print(simulate(load_scenario(scenario_path(args.scenario), args.set, args.seed, args.effect_module), args.out).format())
    return 0


def _replay_summary(bag: str, args: argparse.Namespace) -> int:
    from .replay import replay
    from .stopping import ignore_stop_signals

    summary = replay(bag, args.out, load_plant(args.config), args.solver, args.staleness, progress=not args.quiet,
                     scene_rate=args.scene_rate, stamp_window=_stamp_window(args), lag=args.reading_lag)
    if summary.stopped:
        ignore_stop_signals()  # stopping: the summary and the exit status are what is left to give
    print(summary.format())
    if summary.refused:
        print(f"error: {summary.refused}", file=sys.stderr)
        return 2
    return 0 if summary.complete else 1


def _stamp_window(args: argparse.Namespace):
    from .monitor.inputs import StampWindow

    try:
        return StampWindow(*args.stamp_window) if args.stamp_window else StampWindow()
    except ValueError as error:
        raise UsageError(f"--stamp-window: {error}") from None


def _fleet(args: argparse.Namespace, job, **settings: object) -> int:
    """Run `job` over the bags of the folder args.bag into the new folder args.out; print the table (its JSON
    with the job's `settings`)."""
    from .fleet import find_bags, run_fleet

    if not args.out:
        print(f"error: {args.bag} is a folder of bags: give --out, a new folder for the per-bag results",
              file=sys.stderr)
        return 2
    summary = run_fleet(find_bags(args.bag), args.out, job, args.workers, args.scheduler)
    print(summary.format())
    _write_json(getattr(args, "json", None), {"bags": summary.rows, "total": summary.total(), "wall": summary.wall,
                                              "workers": summary.workers, **settings})
    return 0 if summary.ok else 1


def _replay(args: argparse.Namespace) -> int:
    from .fleet import is_fleet, replay_job

    if not is_fleet(args.bag):
        return _replay_summary(args.bag, args)
    return _fleet(args, replay_job(load_plant(args.config), args.solver, args.staleness, args.scene_rate,
                                   args.reading_lag))


def _demo(args: argparse.Namespace) -> int:
    from .paths import demo_bag

    return _replay_summary(str(demo_bag()), args)


def _record(args: argparse.Namespace) -> int:
    from .nodes.recorder import record

    return record(args.out, args.topics)


def _play(args: argparse.Namespace) -> int:
    from .nodes.player import play

    return play(args.bag, args.rate, clock=not args.no_clock, wait=args.wait, topics=args.topics or None,
                until=args.until)


def _bench(args: argparse.Namespace) -> int:
    from .analysis.diagnose import diagnose_bag
    from .bench.suite import run_suite

    return run_suite(args.samples, args.large_mb, args.fleet_bags, diagnose=diagnose_bag)


def _limits(args: argparse.Namespace) -> int:
    from .effects import PlantModel
    from .monitor.limits import format_limits, synchronisation_limits

    plant = load_plant(args.config)
    if not 0.0 < args.length <= plant.max_payout:
        raise UsageError(f"--length {args.length}: the payout must lie in (0, {plant.max_payout:g}] m "
                         "(plant.limits.max_payout)")
    limits = synchronisation_limits(PlantModel.from_plant(plant), args.length)
    if args.json:
        print(json.dumps({"length": args.length, "limits": [
            {"change": limit.label, "cables": [CABLE_NAMES[c] for c in limit.cables], "direction": limit.direction,
             "clearance_limit": limit.clearance_limit, "taut_limit": limit.taut_limit,
             "permissible": limit.permissible, "binding": limit.binding} for limit in limits]}, indent=2))
    else:
        print(format_limits(plant, args.length, limits))
    return 0


def _analysis_inputs(args: argparse.Namespace):
    """The plant model (with its effects, user modules loaded) and the bag's measurements for compare and
    fit; UsageError if the bag holds none."""
    from .analysis.data import read_bag, require_measurements
    from .effects import PlantModel

    model = PlantModel.from_plant(_plant_with_modules(args))
    data = read_bag(args.bag, model)
    require_measurements(data)
    return model, data


def _write_json(path: str | None, content: dict) -> None:
    if path:
        with open(path, "w") as file:
            json.dump(content, file, indent=2, default=float)


def _compare(args: argparse.Namespace) -> int:
    from .analysis import report
    from .analysis.bagfields import read_fields
    from .analysis.compare import compare
    from .analysis.html import write_report

    _check_writable(args.json, "--json")
    _check_writable(args.html, "--html")
    model, data = _analysis_inputs(args)
    result = compare(model, data, read_fields(args.bag))
    print(report.compare_text(result))
    _write_json(args.json, report.compare_json(result))
    if args.html:
        write_report(result, args.html)
        print(f"report: {args.html}")
    return 0


def _diagnose(args: argparse.Namespace) -> int:
    from .analysis import report
    from .analysis.diagnose import diagnose_bag
    from .fleet import diagnose_job, is_fleet

    _check_writable(args.json, "--json")
    plant = _plant_with_modules(args)
    candidates = _effect_names(args.candidates, "--candidates", BUILTIN_REGISTRY.with_modules(plant.effect_modules))
    if is_fleet(args.bag):
        return _fleet(args, diagnose_job(plant, candidates, args.budget), budget=args.budget)
    result, data = diagnose_bag(args.bag, plant, candidates, args.budget, progress=True)
    print(report.diagnose_text(result))
    _write_json(args.json, report.diagnose_json(result, data.bag, len(data)))
    return 0


def _fit(args: argparse.Namespace) -> int:
    from .analysis import report
    from .analysis.refit import fit_command
    from .effects.plantfile import write_plant

    _check_writable(args.json, "--json")
    _check_writable(args.write_config, "--write-config")
    model, data = _analysis_inputs(args)
    names = _effect_names(args.effects, "--effects", model.registry)
    assert names is not None  # the fit command requires --effects
    result = fit_command(model, data, names)
    print(report.fit_text(result))
    _write_json(args.json, report.fit_json(result, data.bag, len(data)))
    if args.write_config:
        write_plant(result.fit.model, args.write_config, "cable-winch-monitor fit")
        print(f"plant file with the effects on: {args.write_config}")
    return 0


def _add_fleet_options(parser: argparse.ArgumentParser, command: str) -> None:
    """--workers and --scheduler of a command that runs over a folder of bags."""
    parser.add_argument("--workers", type=int, default=1, help=f"fleet {command}: bags run in parallel processes")
    parser.add_argument("--scheduler", metavar="ADDRESS",
                        help=f"fleet {command} on a Dask cluster (e.g. tcp://10.0.0.5:8786); workers must see the "
                        "bags and --out at the same paths")


def _add_analysis(sub: argparse._SubParsersAction) -> None:
    """compare, diagnose and fit: the model-versus-measurement loop (cable_winch_monitor.analysis)."""
    commands = (("compare", _compare, "compare the model with a bag's measurements: per-channel errors, score, "
                 "failure regions"),
                ("diagnose", _diagnose, "find the physical effect the model lacks: fit each candidate on training "
                 "data, rank on held-out data, add forward-stepwise"),
                ("fit", _fit, "fit chosen effects, show before/after on training and held-out data, write a plant "
                 "file with them on"))
    for name, run, what in commands:
        p = sub.add_parser(name, help=what, description=what[0].upper() + what[1:] + ".")
        p.add_argument("bag", help="rosbag2 directory or .mcap file" + (
            ", or a folder of them (fleet diagnose: with --out)" if name == "diagnose" else ""))
        p.add_argument("--config", help="plant YAML with its `effects:` (default: the bundled seed-002 plant)")
        p.add_argument("--json", metavar="PATH", help="write the result as JSON (interface.md)")
        p.add_argument("--effect-module", action="append", default=[], metavar="PATH",
                       help="a Python file defining Effect subclasses to use like the built-ins (repeatable)")
        if name == "compare":
            p.add_argument("--html", metavar="PATH", help="write a standalone HTML report with plots")
        if name == "diagnose":
            p.add_argument("--candidates", help="comma-separated effects to consider (default: every known one)")
            p.add_argument("--budget", type=_budget, default=DIAGNOSE_BUDGET, metavar="SECONDS",
                           help=f"wall time to spend (default {DIAGNOSE_BUDGET:g} s; 0: no limit), per bag in a fleet; "
                           "what did not fit in it is listed as unfinished")
            p.add_argument("--out", metavar="FOLDER", help="fleet diagnose (bag is a folder of bags): a new folder "
                           "for one JSON result per bag; --json then writes the summary table")
            _add_fleet_options(p, "diagnose")
        if name == "fit":
            p.add_argument("--effects", required=True, help="comma-separated effect names, e.g. rope_weight,cog_offset")
            p.add_argument("--write-config", metavar="NEW.yaml", help="write the plant file with the fitted effects on")
        p.set_defaults(run=run)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="cable-winch-monitor", description=__doc__)
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("solve", help="platform pose and cable tensions for four cable lengths")
    p.add_argument("lengths", nargs="+", type=_length, metavar="L", help="cable lengths l_1 .. l_4 [m]")
    p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
    p.add_argument("--method", choices=METHODS, default="energy", help="solver (default: energy)")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(run=_solve)

    p = sub.add_parser("paper", help="solve seed 002's four examples and print them beside its Table 2")
    p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
    p.set_defaults(run=_paper)

    p = sub.add_parser("limits", help="permissible synchronisation-error envelope at a payout")
    p.add_argument("--length", type=float, required=True, help="payout L of all four cables [m]")
    p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
    p.add_argument("--json", action="store_true", help="print the envelope as JSON")
    p.set_defaults(run=_limits)

    p = sub.add_parser("simulate", help="simulate a plant recording from a scenario into a new bag",
                       description="Simulate the plant (payout profile, winch synchronisation errors, rigid or elastic "
                       "ropes) and its sensors into a new rosbag2 directory (MCAP); ground_truth.csv and the resolved "
                       "scenario.yaml are written into the same directory. Deterministic for a given seed.")
    bundled = ", ".join(sorted(path.stem for path in (config_dir() / "scenarios").glob("*.yaml")))
    p.add_argument("scenario", help=f"scenario YAML, or the name of a bundled one ({bundled})")
    p.add_argument("--out", required=True, help="bag directory to create (must not exist)")
    p.add_argument("--seed", type=int, help="random seed (default: the scenario's, else 0)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. --set sync.sigma=0.01 --set sync.events.0.lag=0.2 (repeatable)")
    p.add_argument("--effect-module", action="append", default=[], metavar="PATH",
                   help="a Python file defining effects the scenario's `effects:` may hide in the truth (repeatable)")
    p.set_defaults(run=_simulate)

    replay_help = ("Exit status: 0 when the whole bag was read, 1 when parts of it could not be read (a partial "
                   "replay: the summary lists what was skipped) or a signal stopped it (SIGINT, SIGTERM, SIGHUP: the "
                   "output bag holds what was replayed until then), 2 on an error (nothing written) or where no "
                   "sample could be solved (every one invalid input: the reason on standard error).")
    for name, what in (("replay", "replay a bag through the monitor into a new bag with every output"),
                       ("demo", "replay the bundled all-channels bag (bags/all_channels) and print the summary")):
        p = sub.add_parser(name, help=what, epilog=replay_help,
                           description=f"{what[0].upper()}{what[1:]}: the live node's pipeline, fed in log order; "
                           "outputs are stamped with their input's stamp. Prints a summary: messages read, used, "
                           "rejected and skipped per topic, samples solved, tension states, alarm levels, wall time.")
        if name == "replay":
            p.add_argument("bag", help="rosbag2 directory or .mcap file, or a folder of them (fleet replay: --out "
                           "is then a new folder with one output bag per input bag)")
            _add_fleet_options(p, "replay")
        p.add_argument("--out", required=True, help="output bag directory to create (must not exist)")
        p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
        p.add_argument("--solver", choices=METHODS, default="energy", help="solver (default: energy, as the node)")
        p.add_argument("--staleness", type=float, default=0.5,
                       help="[s] oldest cable length a sample may use (default: 0.5, as the node)")
        p.add_argument("--reading-lag", type=float, default=READING_LAG, metavar="SECONDS",
                       help=f"[s] a sample fuses each sensor's latest reading stamped at least this long before it "
                       f"(default: {READING_LAG:g}, as the node)")
        p.add_argument("--scene-rate", type=_positive, default=REPLAY_RATE, metavar="HZ",
                       help=f"most 3-D scenes (/platform/scene) per second of recording (default: {REPLAY_RATE:g}; "
                       f"the node draws {LIVE_RATE:g} live)")
        p.add_argument("--stamp-window", type=float, nargs=3,
                       metavar=("AHEAD", "BEHIND", "SKEW"),
                       help="[s] a winch stamp more than AHEAD after or BEHIND before its log time, or more than "
                       "SKEW after the other winches' newest reading, is refused (default: 2 10 2, as the node)")
        p.add_argument("--quiet", action="store_true", help="no progress bar")
        p.set_defaults(run=_replay if name == "replay" else _demo)

    p = sub.add_parser("record", help="record ROS topics into a new bag (for sites without rosbag2)",
                       description="Subscribe to topics with raw (serialised) subscriptions and write the bytes as "
                       "received into a rosbag2 directory (MCAP). Topics appearing later are picked up. Stop with "
                       "Ctrl-C or SIGTERM: the bag is closed and complete.")
    p.add_argument("topics", nargs="*", metavar="TOPIC",
                   help="topics to record (default: the monitor's inputs: /winch/joint_states, "
                   "/winch_<i>/joint_states, /platform/imu, /platform/position)")
    p.add_argument("--out", required=True, help="bag directory to create (must not exist)")
    p.set_defaults(run=_record)

    p = sub.add_parser("play", help="publish a bag's messages at their log times, with /clock (as ros2 bag play --clock)",
                       description="Publish every message of a bag (the monitor's inputs by default) as its stored "
                       "bytes at its log time, with /clock, so that a node run with use_sim_time lives in the "
                       "recording's time. Waits for a subscriber to the winches' topics first.")
    p.add_argument("bag", help="rosbag2 directory or .mcap file")
    p.add_argument("topics", nargs="*", metavar="TOPIC", help="topics to play (default: the monitor's inputs)")
    p.add_argument("--rate", type=float, default=1.0, help="times as fast as recorded (default: 1)")
    p.add_argument("--no-clock", action="store_true", help="publish no /clock")
    p.add_argument("--until", type=float, default=math.inf, help="[s] play the bag's first UNTIL seconds only")
    p.add_argument("--wait", type=float, default=30.0,
                   help="[s] longest wait for a subscriber to the winches' topics (default: 30)")
    p.set_defaults(run=_play)

    p = sub.add_parser("bench", help="benchmark solvers, replay, memory and fleet replay in one run, with ratios")
    p.add_argument("--samples", type=int, default=1000, help="solver samples (the same for every solver)")
    p.add_argument("--large-mb", type=float, default=64.0,
                   help="size of the large bag for peak memory [MiB] (acceptance run: 1024)")
    p.add_argument("--fleet-bags", type=int, default=4, help="bags in the fleet benchmark (1 vs 2 workers)")
    p.set_defaults(run=_bench)
    _add_analysis(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (PlantConfigError, ScenarioError, BagError, EffectError, UsageError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # an output that could not be written after all (disk full, removed folder)
        print(f"error: {error.filename or ''}: {error.strerror or error}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:  # Ctrl-C in a command that has nothing to finish (replay finishes its bag itself)
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
