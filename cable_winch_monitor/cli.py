"""`cable-winch-monitor`: one command, a subcommand per job; each is a thin call into the package."""
from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from .bagio.reader import BagError
from .formatting import format_solution
from .model.plant import CABLE_NAMES, PlantConfigError, load_plant
from .model.solve import METHODS, solve
from .paths import config_dir
from .sim.scenario import ScenarioError


def _length(text: str) -> float:
    """A command-line length: any float, so that nan, inf and negatives reach the solver's checks."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"cable length must be a number, got {text!r}") from None


def _solve(args: argparse.Namespace) -> int:
    plant = load_plant(args.config)
    solution = solve(plant, args.lengths, method=args.method)  # bad numbers come back as INVALID_INPUT
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

    print(simulate(load_scenario(scenario_path(args.scenario), args.set, args.seed), args.out).format())
    return 0


def _replay_summary(bag: str, args: argparse.Namespace) -> int:
    from .replay import replay

    summary = replay(bag, args.out, load_plant(args.config), args.solver, args.staleness, progress=not args.quiet)
    print(summary.format())
    return 0 if summary.complete else 1


def _replay(args: argparse.Namespace) -> int:
    return _replay_summary(args.bag, args)


def _demo(args: argparse.Namespace) -> int:
    from .paths import demo_bag

    return _replay_summary(str(demo_bag()), args)


def _record(args: argparse.Namespace) -> int:
    from .nodes.recorder import record

    return record(args.out, args.topics)


def _limits(args: argparse.Namespace) -> int:
    from .monitor.limits import format_limits, synchronisation_limits

    plant = load_plant(args.config)
    limits = synchronisation_limits(plant, args.length)
    if args.json:
        print(json.dumps({"length": args.length, "limits": [
            {"change": limit.label, "cables": [CABLE_NAMES[c] for c in limit.cables], "direction": limit.direction,
             "clearance_limit": limit.clearance_limit, "taut_limit": limit.taut_limit,
             "permissible": limit.permissible, "binding": limit.binding} for limit in limits]}, indent=2))
    else:
        print(format_limits(plant, args.length, limits))
    return 0


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
    p.set_defaults(run=_simulate)

    replay_help = ("Exit status: 0 when the whole bag was read, 1 when parts of it could not be read (a partial "
                   "replay: the summary lists what was skipped), 2 on an error (nothing written).")
    for name, what in (("replay", "replay a bag through the monitor into a new bag with every output"),
                       ("demo", "replay the bundled all-channels bag (bags/all_channels) and print the summary")):
        p = sub.add_parser(name, help=what, epilog=replay_help,
                           description=f"{what[0].upper()}{what[1:]}: the live node's pipeline, fed in log order; "
                           "outputs are stamped with their input's stamp. Prints a summary: messages read, used, "
                           "rejected and skipped per topic, samples solved, tension states, alarm levels, wall time.")
        if name == "replay":
            p.add_argument("bag", help="rosbag2 directory or .mcap file")
        p.add_argument("--out", required=True, help="output bag directory to create (must not exist)")
        p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
        p.add_argument("--solver", choices=METHODS, default="energy", help="solver (default: energy, as the node)")
        p.add_argument("--staleness", type=float, default=0.5,
                       help="[s] oldest cable length a sample may use (default: 0.5, as the node)")
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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except (PlantConfigError, ScenarioError, BagError) as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
