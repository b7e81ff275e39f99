"""The ``crowdloc`` command line.

Every sub-command has ``--help``; bad arguments exit with status 2 and a one-line message.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from agents.common.util import at_least, positive_float, positive_int, seed_int

DEFAULT_RESULTS = Path("results")


def _add_demo(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    demo = sub.add_parser(
        "demo",
        help="the worlds survey, the ceiling corridor, the stereo campus, the active-localization table and the verdict; writes "
        "results/demo/report.md",
        description="Drive the papers' first worlds at several crowd densities with a random-walk policy (steps "
        "per second, landmark / wall visibility, one frame per world); drive the ceiling corridor among people with "
        "the paper's navigation (errors at the targets, a camera frame with the pipeline's findings, a top view); drive "
        "a short stretch of the stereo campus on far_landmark_pf (errors against the truth, a camera image with its edges marked "
        "by type, a top view with the particles and the selected far landmarks); then evaluate the fixed policies and the "
        "shipped PPO policies x 2 localizers x 3 crowd sizes on held-out test seeds (the active-localization "
        "table), and judge each trained policy against the table's best fixed policies on fresh test seeds "
        "(the verdict); last, each world task (room, corridor, campus) briefly: its paper policy, random_walk and its "
        "shipped PPO policy on a few test seeds.",
    )
    demo.add_argument("--steps", type=positive_int, default=3000, help="steps per (world, density) run (default 3000)")
    demo.add_argument("--seed", type=seed_int, default=0, help="seed of the env and the policy (default 0)")
    demo.add_argument("--out", type=Path, default=DEFAULT_RESULTS / "demo", help="output folder (default results/demo)")
    demo.add_argument(
        "--overwrite",
        action="store_true",
        help="run into an --out that is not empty: an earlier demo's files there are deleted first (other files stay); "
        "make demo gives it",
    )
    demo.add_argument(
        "--active-seeds",
        type=int,
        default=20,
        help="held-out seeds per cell of the active-localization part (default 20; 0 skips it)",
    )
    demo.add_argument(
        "--verdict-seeds",
        type=int,
        default=None,
        help="fresh test seeds, after the table's, on which the trained policies meet the best fixed "
        "policies of the table (default 100; 0 judges on the table's seeds)",
    )
    demo.add_argument(
        "--task-seeds",
        type=int,
        default=None,
        help="test seeds per world task (room, corridor, campus) of the last part: its paper policy, random_walk and "
        "its shipped PPO policy (default 2; 0 skips it)",
    )
    demo.add_argument(
        "--model",
        type=Path,
        default=None,
        help="one PPO model to evaluate with every localizer (default: the shipped one per localizer)",
    )
    demo.add_argument("--workers", type=positive_int, default=None, help="worker processes (default: the core count)")


def _add_worlds(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    sub.add_parser("worlds", help="list the registered env ids and their worlds")


def _add_train(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    train = sub.add_parser(
        "train",
        help="train a PPO active-localization policy from configs/experiments/NAME.yaml",
        description="Train PPO (stable-baselines3) on a crowdloc env wrapped with a localizer and the "
        "active-localization reward. Writes checkpoints, TensorBoard logs and run.json under --out.",
    )
    train.add_argument("config", help="experiment YAML path or name under configs/experiments/")
    train.add_argument(
        "--total-timesteps",
        type=positive_int,
        help="override total_timesteps (rounded up to whole rollouts: n_envs x ppo.n_steps)",
    )
    seeds = train.add_mutually_exclusive_group()
    seeds.add_argument("--seed", type=seed_int, help="override the run seed")
    seeds.add_argument(
        "--seeds",
        type=seed_int,
        nargs="+",
        metavar="SEED",
        help="train one run per seed, side by side (a local process pool, or Ray with --ray-address)",
    )
    train.add_argument("--workers", type=positive_int, help="with --seeds: runs at a time (default: the core count)")
    train.add_argument("--ray-address", help="with --seeds: run the training runs on this Ray cluster (e.g. auto)")
    train.add_argument("--n-envs", type=positive_int, help="override the number of parallel envs")
    train.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override any config field, e.g. --set ppo.learning_rate=1e-3 (repeatable); a mapping is merged "
        "key by key: --set env_kwargs={prior: start} keeps the file's other env_kwargs",
    )
    train.add_argument(
        "--replace",
        dest="replacements",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="set a config field whole, as if the file said so (applied before --set), e.g. --replace env_kwargs={} "
        "drops the file's conditions (repeatable)",
    )
    train.add_argument("--resume", metavar="CHECKPOINT", help="a checkpoint .zip to resume from, or 'latest'")
    train.add_argument(
        "--overwrite",
        action="store_true",
        help="start again where a run of this config and seed already is (its files are deleted)",
    )
    train.add_argument("--out", type=Path, default=DEFAULT_RESULTS / "train", help="output folder (default results/train)")
    train.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_eval(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    ev = sub.add_parser(
        "eval",
        help="evaluate policies x localizers x crowd sizes on held-out seeds; bootstrap CIs, plots, TUM files, a GIF",
        description="Run one episode per (policy, localizer, crowd size, held-out seed) and write episodes.csv, "
        "summary.csv, summary.md (mean [95% bootstrap CI] per metric), plots, TUM trajectories and episode.gif under --out.",
    )
    ev.add_argument(
        "--policies",
        nargs="+",
        metavar="POLICY",
        help="fixed policy names or ppo:PATH/model.zip (default: every fixed policy but patrol; landmark_seeking and "
        "greedy_info_gain need a camera)",
    )
    ev.add_argument(
        "--localizers",
        nargs="+",
        metavar="NAME",
        help="registered localizers (default: the --conditions config's localizer, else candidate_sets)",
    )
    ev.add_argument(
        "--crowd-sizes", "--densities", dest="crowd_sizes", nargs="+", type=int, metavar="N", help="crowd sizes (default: 2 6 10)"
    )
    ev.add_argument("--seeds", type=positive_int, default=10, help="held-out seeds per cell (default 10)")
    ev.add_argument(
        "--first-seed",
        type=int,
        default=0,
        metavar="K",
        help="held-out seeds start at 2**31 + K (default 0: the test seeds of make demo; pick between "
        "trained policies on another range, e.g. 1000)",
    )
    ev.add_argument("--episode-steps", type=positive_int, default=450, help="steps per episode (default 450 = 15 s at 30 Hz)")
    ev.add_argument(
        "--env-id",
        help="a registered crowdloc env id, e.g. crowdloc/CrowdedRoom-v0 with LIDAR localizers (default: RoboCupCrowded-v0, "
        "or the --conditions one); --env-set world=PATH.yaml evaluates another world under it",
    )
    ev.add_argument(
        "--conditions",
        metavar="EXPERIMENT",
        help="evaluate in a training config's conditions: its env id, env_kwargs (camera, prior, ...), reward, route, "
        "the observation its trained policies see and what their actions mean (a path or a name under configs/experiments/); the episode length stays "
        "--episode-steps (the config's ppo.n_steps is its training episode's)",
    )
    ev.add_argument(
        "--layout-split",
        choices=("validation", "test"),
        help="with a --conditions config that has layouts: the split whose layouts the episodes play on "
        "(default: test; validation to choose between trained policies)",
    )
    ev.add_argument(
        "--env-set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="a condition on top, e.g. --env-set camera.fov_rad=1.5708 or --env-set prior=none (repeatable)",
    )
    ev.add_argument(
        "--localizer-set",
        action="append",
        default=[],
        metavar="LOCALIZER.KEY=VALUE",
        help="a parameter of one evaluated localizer over its configs/localizers/ file, e.g. "
        "--localizer-set mcl_lidar.deskew=true (repeatable)",
    )
    kid = ev.add_argument_group("kidnapping", "carry the robot away mid-episode and score each localizer's recovery")
    kid.add_argument("--kidnap-at-s", type=float, metavar="S", help="teleport the robot at S s after the reset (default: never)")
    kid.add_argument("--kidnap-m", type=float, metavar="M", help="at least this far from where it stood (default 2.0)")
    kid.add_argument("--kidnap-max-m", type=float, metavar="M", help="at most this far (default: anywhere in the arena)")
    kid.add_argument(
        "--kidnap-keep-heading",
        action="store_true",
        default=None,
        help="keep the robot's heading: a pure translation (default: a random heading)",
    )
    kid.add_argument("--recover-m", type=float, metavar="M", help="a pose this close to the truth is a recovery (default 0.2)")
    kid.add_argument("--recover-window-s", type=float, metavar="S", help="look for the recovery this long (default 30)")
    ev.add_argument(
        "--verdict",
        metavar="POLICY",
        help="judge this policy of --policies (e.g. ppo:models/x.zip) against the best fixed policy of the run per "
        "localizer, crowd size and metric, with paired 95%% intervals over the seeds; writes verdict.md and verdict.csv",
    )
    ev.add_argument("--workers", type=positive_int, help="local worker processes (default: the core count)")
    ev.add_argument("--ray-address", help="run the episodes on this Ray cluster (e.g. auto)")
    ev.add_argument("--gif-cell", metavar="POLICY,LOCALIZER,CROWD", help="the episode to animate (default: the first)")
    ev.add_argument("--no-gif", action="store_true", help="write no GIF")
    ev.add_argument("--out", type=Path, default=DEFAULT_RESULTS / "eval", help="output folder (default results/eval)")
    again = ev.add_mutually_exclusive_group()
    again.add_argument(
        "--overwrite",
        action="store_true",
        help="run into an --out that is not empty: its earlier eval files are deleted first (other files stay)",
    )
    again.add_argument(
        "--resume",
        action="store_true",
        help="continue the interrupted run in --out (same options): run only the episodes its episodes.jsonl lacks",
    )
    ev.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_benchmark(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    bench = sub.add_parser(
        "benchmark",
        help="the benchmark protocol (the newest of configs/benchmark/): every localizer whose sensor a world has x its policies x "
        "crowd sizes x test seeds; results.json, results.csv, leaderboard.md",
        description="Run the versioned benchmark protocol: in each of its worlds every localizer whose sensor the world has "
        "(dead_reckoning everywhere), driven by the world's fixed policies, at each of its crowd sizes, on its test seeds "
        "(disjoint from every seed of training, tuning, evaluation and the reproductions). Writes results.json and "
        "results.csv (one row per world x localizer x policy x crowd size, with the protocol's name and digest), "
        "leaderboard.md (each localizer's crowd sensitivity, then one table per world) and plots/ under --out.",
    )
    bench.add_argument("--track", choices=("localizers", "policies"), default="localizers",
                       help="localizers (default): the protocol's league table of localizers; policies: fixed policies, "
                       "belief_greedy and the shipped models ranked on each task's unseen test layouts "
                       "(configs/policy_tracks/v1.yaml; --policies adds entrants: ppo:PATH.zip or plug-in policies)")  # fmt: skip
    bench.add_argument("--tasks", nargs="+", metavar="CONFIG",
                       help="with --track policies: the track's tasks to run (default: all of them)")  # fmt: skip
    bench.add_argument("--protocol", default=None,
                       help="a shipped protocol name or a protocol YAML path (default: the newest shipped one; "
                       "with --track policies a track file, default v1)")  # fmt: skip
    bench.add_argument("--worlds", nargs="+", metavar="ENV_ID", help="env ids of the protocol (default: all of them)")
    bench.add_argument("--localizers", nargs="+", metavar="NAME",
                       help="registered localizers (default: every one; each runs where the world has its sensor)")  # fmt: skip
    bench.add_argument("--policies", nargs="+", metavar="POLICY",
                       help="fixed policies, or ppo:PATH.zip for a trained one (default: each world's protocol ones)")  # fmt: skip
    bench.add_argument("--seeds", type=positive_int, metavar="N", help="the first N of the protocol's test seeds (default: all)")
    bench.add_argument("--quick", action="store_true",
                       help="the protocol's quick mode: a few seeds, short episodes; marked quick in every output, never "
                       "comparable with a full run")  # fmt: skip
    bench.add_argument("--plugins", nargs="+", metavar="MODULE", default=[],
                       help="import these modules first: each registers its localizers (register_localizer) or fixed "
                       "policies (register_policy), which are then named like built-ins")  # fmt: skip
    bench.add_argument("--workers", type=positive_int, help="local worker processes (default: the core count)")
    bench.add_argument("--ray-address", metavar="ADDRESS",
                       help="run the episodes on this Ray cluster ('auto', 'ray://host:10001') instead of local processes")  # fmt: skip
    bench.add_argument(
        "--out", type=Path, default=DEFAULT_RESULTS / "benchmark", help="output folder (default results/benchmark)"
    )
    bench.add_argument("--overwrite", action="store_true",
                       help="run into an --out that is not empty: its earlier benchmark files are deleted first (other files stay)")  # fmt: skip
    bench.add_argument("--resume", action="store_true",
                       help="continue an interrupted run in --out (the same options): play only the episodes its "
                       "journal (episodes.jsonl) lacks, then write the tables of the whole run")  # fmt: skip
    bench.add_argument("--no-progress", action="store_true", help="no progress bar")


def _add_tune(sub: argparse._SubParsersAction[argparse.ArgumentParser], argv: Sequence[str]) -> None:
    tune = sub.add_parser(
        "tune",
        help="tune a localizer's parameters with Optuna on recorded episodes; compare with the defaults on held-out seeds",
        description="Seeded TPE search with median pruning over configs/tuning/LOCALIZER.yaml; episodes are recorded "
        "once and replayed into every trial; the study lives in a database (SQLite by default) that several workers "
        "can share. Writes report.md, best_params.yaml and figures under --out.",
    )
    if argv[:1] == ["tune"]:  # import only when tuning (optuna, the replay machinery)
        importlib.import_module("agents.tune").add_arguments(tune)


def _add_reproduce(sub: argparse._SubParsersAction[argparse.ArgumentParser], argv: Sequence[str]) -> None:
    from agents.papers import EXPERIMENTS

    reproduce = sub.add_parser(
        "reproduce",
        help="re-run a paper's experiments and write results/NAME/report.md",
        description="Re-run the experiments of one source paper; the report puts the paper's numbers beside ours.",
    )
    experiments = reproduce.add_subparsers(dest="experiment", required=True, metavar="EXPERIMENT")
    chosen = argv[1] if len(argv) > 1 and argv[0] == "reproduce" else None
    for name, (module, summary) in EXPERIMENTS.items():
        exp = experiments.add_parser(name, help=summary, description=summary)
        exp.set_defaults(command_parser=exp)
        exp.add_argument("--out", type=Path, default=DEFAULT_RESULTS / name, help=f"output folder (default results/{name})")
        exp.add_argument("--overwrite", action="store_true", help="replace an existing report in --out")
        if name == chosen:  # import only the experiment being run (they pull in plotting and more)
            importlib.import_module(module).add_arguments(exp)


#: localizers whose parameters are learned from data by ``crowdloc fit``: name -> module with add_arguments / run_cli
FITTERS = {"ceiling_target": "agents.papers.ceiling_target.fit"}


def _add_fit(sub: argparse._SubParsersAction[argparse.ArgumentParser], argv: Sequence[str]) -> None:
    fit = sub.add_parser(
        "fit",
        help="learn a localizer's parameters from rendered, labelled data (ceiling_target: its colour thresholds)",
        description="Learn parameters that the papers learned from sample data, and write them into the localizer's "
        "YAML with a record of the data used.",
    )
    which = fit.add_subparsers(dest="localizer", required=True, metavar="LOCALIZER")
    chosen = argv[1] if len(argv) > 1 and argv[0] == "fit" else None
    for name, module in FITTERS.items():
        one = which.add_parser(name, help=f"fit {name}'s parameters", description=f"fit {name}'s parameters ({module})")
        one.set_defaults(command_parser=one)
        if name == chosen:
            importlib.import_module(module).add_arguments(one)


def _add_map(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    mapping = sub.add_parser(
        "map",
        help="drive a world's route once and write the scene map far_landmark_pf localizes with (run 1)",
        description="The far-landmark paper's first drive: route_follower drives the world's route on the LIDAR "
        "reference's estimate (mcl_lidar as ROS amcl runs it) and a scene is recorded every --period-s: the pose (the "
        "reference's estimate, or the truth with --pose truth) and the stereo camera's edges relative to it. Without "
        "--out the map becomes the world's default (what gym.make(..., localizer='far_landmark_pf') uses).",
    )
    mapping.add_argument("world", help="a shipped world name (stereo_campus) or a world YAML path")
    mapping.add_argument("--out", type=Path, default=None, help="the map file (.npz; default: the world's cached default)")
    mapping.add_argument("--seed", type=seed_int, default=0, help="the drive's env seed (default 0)")
    mapping.add_argument(
        "--crowd-size", type=at_least(0), default=None, help="the crowd during the drive (>= 0; default: the world's)"
    )
    mapping.add_argument("--pose", choices=("reference", "truth"), default="reference", help="where the scenes' poses come from")
    mapping.add_argument(
        "--period-s", type=positive_float, default=1.0, help="a scene every this many seconds (finite, > 0; default 1)"
    )
    mapping.add_argument(
        "--max-shift-px",
        type=positive_float,
        default=1.0,
        help="on free-running webcams, the most a turn may shift an image between the cameras' frames: the drive takes "
        "bends no faster and records no scene while turning faster (finite, > 0; default 1)",
    )
    mapping.add_argument("--overwrite", action="store_true", help="replace an existing map file")


def _version() -> str:
    import importlib.metadata

    try:
        return importlib.metadata.version("crowdloc")
    except importlib.metadata.PackageNotFoundError:  # running from a checkout that is not installed
        return "(not installed)"


def build_parser(argv: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The full parser; an experiment's own options are added only for the one named in ``argv``."""
    parser = argparse.ArgumentParser(
        prog="crowdloc",
        description="crowdloc: robot self-localization among crowds (worlds, localizers, agents).",
    )
    parser.add_argument("--version", action="version", version=f"crowdloc {_version()}")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    _add_demo(sub)
    _add_worlds(sub)
    _add_train(sub)
    _add_eval(sub)
    _add_benchmark(sub)
    _add_tune(sub, argv)
    _add_reproduce(sub, argv)
    _add_fit(sub, argv)
    _add_map(sub)
    for command in sub.choices.values():  # errors found after parsing print the command's own usage
        command.set_defaults(command_parser=command)
    return parser


def _run_demo(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.demo import ACTIVE_LOCALIZERS, VERDICT_SEEDS, run_demo
    from agents.demo_tasks import TASK_SEEDS

    if args.active_seeds < 0:
        parser.error(f"--active-seeds must be >= 0, got {args.active_seeds}")
    if args.verdict_seeds is not None and args.verdict_seeds < 0:
        parser.error(f"--verdict-seeds must be >= 0, got {args.verdict_seeds}")
    if args.task_seeds is not None and args.task_seeds < 0:
        parser.error(f"--task-seeds must be >= 0, got {args.task_seeds}")
    if args.model is not None and not args.model.is_file():
        parser.error(f"--model {args.model}: no such file")
    run_demo(
        args.out,
        steps=args.steps,
        seed=args.seed,
        active_seeds=args.active_seeds,
        verdict_seeds=VERDICT_SEEDS if args.verdict_seeds is None else args.verdict_seeds,
        task_seeds=TASK_SEEDS if args.task_seeds is None else args.task_seeds,
        models=None if args.model is None else dict.fromkeys(ACTIVE_LOCALIZERS, args.model),
        workers=args.workers,
        overwrite=args.overwrite,
    )
    return 0


def _run_train(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.rl.config import load_train_config, parse_overrides
    from agents.rl.train import latest_checkpoint, train
    from core.schema import ConfigError

    if args.seeds and args.resume:
        parser.error("--resume continues one run; give --seed, not --seeds")
    if args.resume and args.overwrite:
        parser.error("--resume continues a run and --overwrite starts it again: give one")
    if (args.workers or args.ray_address) and not args.seeds:
        parser.error("--workers and --ray-address spread several runs: give --seeds")
    overrides = parse_overrides(args.overrides, flag="--set")
    for key, value in (("total_timesteps", args.total_timesteps), ("seed", args.seed), ("n_envs", args.n_envs)):
        if value is not None:
            overrides[key] = value
    replacements = parse_overrides(args.replacements, flag="--replace")
    config = load_train_config(args.config, overrides, replacements)
    resume = None
    if args.resume == "latest":
        resume = latest_checkpoint(config, args.out)
        if resume is None:
            raise ConfigError(f"--resume latest: no checkpoint under {args.out / config.name}")
    elif args.resume:
        resume = Path(args.resume)
        if not resume.is_file():
            raise ConfigError(f"--resume {args.resume}: no such checkpoint file (or give 'latest')")
    if args.seeds:
        from agents.rl.train import train_seeds

        models = train_seeds(config, args.out, args.seeds, workers=args.workers, ray_address=args.ray_address,
                             progress=not args.no_progress, overwrite=args.overwrite)  # fmt: skip
        print("\n".join(f"wrote {m}" for m in models))
        return 0
    model = train(config, args.out, resume=resume, progress_bar=not args.no_progress, overwrite=args.overwrite)
    print(f"wrote {model}")
    return 0


def _run_eval(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.evaluate import run_cli as run_eval

    run_eval(args)
    return 0


def _run_benchmark(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.benchmark.cli import run_cli

    run_cli(args)
    return 0


def _run_tune(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.tune import run_cli

    result = run_cli(args)
    print(f"wrote {result.report} ({result.n_trials} trials in study {result.study_name!r})")
    return 0


def _run_reproduce(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.common.util import make_out_dir, refuse_to_overwrite
    from agents.papers import EXPERIMENTS

    refuse_to_overwrite(Path(args.out) / "report.md", args.overwrite)  # before minutes of work, not after
    make_out_dir(Path(args.out))
    report = importlib.import_module(EXPERIMENTS[args.experiment][0]).run(args)
    print(f"wrote {report}")
    return 0


def _run_fit(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    path = importlib.import_module(FITTERS[args.localizer]).run_cli(args)
    print(f"wrote {path}")
    return 0


def _run_map(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    from agents.common.util import check_output_file
    from agents.experiments.scene_maps import MappingDrive, build_scene_map, default_map_path
    from envs.localization_env import LocalizationEnv

    drive = MappingDrive(
        seed=args.seed, crowd_size=args.crowd_size, pose=args.pose, period_s=args.period_s, max_shift_px=args.max_shift_px
    )
    out = args.out
    if out is None:
        out = default_map_path(LocalizationEnv(args.world))
    elif out.suffix != ".npz":
        parser.error(f"--out {out}: a scene map is an .npz file")
    check_output_file(out, args.overwrite)  # before the drive, not after it
    scenes = build_scene_map(args.world, drive, progress=True)
    scenes.save(out)
    print(f"wrote {out} ({scenes.scene_count} scenes, {scenes.landmark_count} landmarks)")
    return 0


def _run_worlds(args: argparse.Namespace, parser: argparse.ArgumentParser) -> int:
    import envs
    from agents.rl import task_ids

    for env_id, world in envs.ENV_WORLDS.items():
        print(f"{env_id:32s} {world:18s} {envs.load_world(world).description}")
    print("\ntask ids (a world with its localizer, training conditions and reward; the ids above return reward 0):")
    for env_id, config in task_ids.TASK_CONFIGS.items():
        print(f"{env_id:32s} {config:18s} configs/experiments/{config}.yaml")
    return 0


_RUNNERS: dict[str, Callable[[argparse.Namespace, argparse.ArgumentParser], int]] = {
    "demo": _run_demo,
    "train": _run_train,
    "eval": _run_eval,
    "benchmark": _run_benchmark,
    "tune": _run_tune,
    "reproduce": _run_reproduce,
    "worlds": _run_worlds,
    "fit": _run_fit,
    "map": _run_map,
}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    from core.schema import ConfigError

    runner = _RUNNERS.get(args.command)
    if runner is None:
        parser.error(f"unknown command {args.command!r}")
        return 2
    command_parser = getattr(args, "command_parser", parser)
    try:
        return runner(args, command_parser)
    except ConfigError as exc:  # bad input found after parsing: one line under the command's usage
        command_parser.error(str(exc))
        return 2


if __name__ == "__main__":
    sys.exit(main())
