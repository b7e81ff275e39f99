"""The ``crowdloc`` command line.

Every sub-command has ``--help``; bad arguments exit with status 2 and a one-line message.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from pathlib import Path

DEFAULT_RESULTS = Path("results")


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"expected a positive integer, got {value}")
    return value


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="crowdloc",
        description="crowdloc: robot self-localization among crowds (worlds, localizers, agents).",
    )
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    demo = sub.add_parser(
        "demo",
        help="run every world with a scripted policy and write results/demo/report.md",
        description="Drive every registered world at several crowd densities with a random-walk policy; "
        "report steps per second and landmark / wall visibility, and save one frame per world.",
    )
    demo.add_argument("--steps", type=_positive_int, default=3000, help="steps per (world, density) run (default 3000)")
    demo.add_argument("--seed", type=int, default=0, help="seed of the env and the policy (default 0)")
    demo.add_argument("--out", type=Path, default=DEFAULT_RESULTS / "demo", help="output folder (default results/demo)")

    sub.add_parser("worlds", help="list the registered env ids and their worlds")

    from agents.reproduce import EXPERIMENTS

    reproduce = sub.add_parser(
        "reproduce",
        help="re-run a paper's experiments and write results/NAME/report.md",
        description="Re-run the experiments of one source paper; the report puts the paper's numbers beside ours.",
    )
    experiments = reproduce.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    for name, module in EXPERIMENTS.items():
        mod = importlib.import_module(module)
        exp = experiments.add_parser(name, help=(mod.__doc__ or "").strip().splitlines()[0], description=mod.__doc__)
        exp.add_argument("--out", type=Path, default=DEFAULT_RESULTS / name, help=f"output folder (default results/{name})")
        mod.add_arguments(exp)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "demo":
        from agents.demo import run_demo

        run_demo(args.out, steps=args.steps, seed=args.seed)
        return 0
    if args.command == "reproduce":
        from agents.reproduce import EXPERIMENTS

        report = importlib.import_module(EXPERIMENTS[args.experiment]).run(args)
        print(f"wrote {report}")
        return 0
    if args.command == "worlds":
        import envs

        for env_id, world in envs.ENV_WORLDS.items():
            print(f"{env_id:32s} {world:18s} {envs.load_world(world).description}")
        return 0
    parser.error(f"unknown command {args.command!r}")
    return 2


if __name__ == "__main__":
    sys.exit(main())
