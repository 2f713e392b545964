"""`cable-winch-monitor`: one command, a subcommand per job; each is a thin call into the package."""
from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from .formatting import format_solution
from .model.plant import CABLE_NAMES, PlantConfigError, load_plant
from .model.solve import METHODS, solve


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


def _demo(args: argparse.Namespace) -> int:
    from .demo import run_demo

    return run_demo(load_plant(args.config))


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

    p = sub.add_parser("demo", help="solve seed 002's four examples and print them beside its Table 2")
    p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
    p.set_defaults(run=_demo)

    p = sub.add_parser("limits", help="permissible synchronisation-error envelope at a payout")
    p.add_argument("--length", type=float, required=True, help="payout L of all four cables [m]")
    p.add_argument("--config", help="plant YAML (default: the bundled seed-002 plant)")
    p.add_argument("--json", action="store_true", help="print the envelope as JSON")
    p.set_defaults(run=_limits)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        return args.run(args)
    except PlantConfigError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
