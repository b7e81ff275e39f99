"""``crowdloc eval`` from parsed options (the parser lives in :mod:`agents.cli`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from agents.common.output_folder import open_output_folder
from agents.evaluate.journal import JOURNAL_NAME, EpisodeJournal
from agents.evaluate.kidnap import Kidnap
from agents.evaluate.outputs import EVAL_OUTPUTS, summary_markdown, write_outputs
from agents.evaluate.paired import paired_verdict, verdict_markdown, verdict_policy, write_verdict
from agents.evaluate.spec import Cell, EvalSpec, check_first_seed, task_conditions
from agents.evaluate.stats import EvalResult, evaluate
from core.schema import ConfigError, check


def parse_gif_cell(text: str, spec: EvalSpec) -> Cell:
    """``"policy,localizer,crowd_size"`` -> that cell on the first evaluation seed (must be in the grid)."""
    parts = text.rsplit(",", 2)
    if len(parts) != 3 or not parts[2].strip().lstrip("-").isdigit():
        raise ConfigError(f"--gif-cell must be POLICY,LOCALIZER,CROWD_SIZE, got {text!r}")
    cell = Cell(parts[0].strip(), parts[1].strip(), int(parts[2]), spec.eval_seeds[0])
    check(cell in spec.cells(), f"--gif-cell {text!r} is not in the evaluated grid")
    return cell


def spec_from_args(args: Any) -> EvalSpec:
    """The :class:`EvalSpec` of the parsed options (``--conditions`` first, ``--env-set`` on top).

    ``--conditions`` gives the training config's env, ``env_kwargs``, reward, route, observation
    (what its trained policies observe), action (what their actions mean) and localizer
    (:func:`~agents.evaluate.spec.task_conditions`); the episode length stays ``--episode-steps``
    (the config's ``ppo.n_steps`` is its training episode's).

    Raises:
        ConfigError: for a bad option value.
    """
    from agents.common.util import nest
    from agents.rl.config import load_train_config, parse_overrides
    from core.schema import merge_nested

    check_first_seed(args.first_seed, "--first-seed")
    given = {"policies": args.policies, "localizers": args.localizers, "crowd_sizes": args.crowd_sizes}
    conditions: dict[str, Any] = {"env_id": args.env_id}
    if args.conditions:
        trained = load_train_config(args.conditions)
        check(args.env_id in (None, trained.env_id),
              f"--env-id {args.env_id} differs from the env of --conditions {args.conditions} ({trained.env_id})")  # fmt: skip
        # the config's conditions include its localizer, unless --localizers names others
        conditions = task_conditions(trained)
        split = getattr(args, "layout_split", None)
        if trained.layouts is not None:
            conditions["layouts"] = getattr(trained.layouts, split or "test")
        check(split is None or trained.layouts is not None,
              f"--layout-split {split}: the --conditions config {args.conditions} has no layouts")  # fmt: skip
    else:
        check(getattr(args, "layout_split", None) is None, "--layout-split needs --conditions (a config with layouts)")
    conditions["env_kwargs"] = merge_nested(conditions.get("env_kwargs", {}), nest(parse_overrides(args.env_set)))
    chosen = {k: v for k, v in given.items() if v is not None}
    given_params = nest(parse_overrides(getattr(args, "localizer_set", []), "--localizer-set"))
    localizer_params = merge_nested(conditions.pop("localizer_params", {}), given_params)  # --localizer-set on top
    localizers = chosen.get("localizers") or conditions.get("localizers") or ()
    localizer_params = {k: v for k, v in localizer_params.items() if k in localizers or k in given_params}
    return EvalSpec(**{k: v for k, v in {**conditions, **chosen}.items() if v is not None}, seeds=args.seeds,
                    first_seed=args.first_seed, episode_steps=args.episode_steps, kidnap=kidnap_from_args(args),
                    localizer_params=localizer_params)  # fmt: skip


#: the kidnap's flags besides --kidnap-at-s, and the Kidnap fields they set
_KIDNAP_FLAGS = {
    "kidnap_m": "min_distance_m",
    "kidnap_max_m": "max_distance_m",
    "kidnap_keep_heading": "keep_heading",
    "recover_m": "recover_m",
    "recover_window_s": "window_s",
}


def kidnap_from_args(args: Any) -> Kidnap | None:
    """The :class:`Kidnap` of ``--kidnap-at-s`` and its companion flags, None without it.

    Raises:
        ConfigError: a companion flag without ``--kidnap-at-s``, or a bad value.
    """
    at_s = getattr(args, "kidnap_at_s", None)
    given = {field: getattr(args, flag) for flag, field in _KIDNAP_FLAGS.items() if getattr(args, flag, None) is not None}
    if at_s is None:
        check(not given, f"--{', --'.join(f.replace('_', '-') for f in _KIDNAP_FLAGS if getattr(args, f, None) is not None)} "
                         "only applies with --kidnap-at-s")  # fmt: skip
        return None
    return Kidnap(at_s=at_s, **given)


def run_cli(args: Any) -> EvalResult:
    """``crowdloc eval``: build the spec from parsed options, check the output folder, run (each
    episode into the journal as it finishes; with ``--resume`` only those the journal lacks),
    write, print the summary and, with ``--verdict POLICY``, the paired verdict on that policy
    against the best fixed policy (:mod:`agents.evaluate.paired`; ``verdict.md``, ``verdict.csv``).

    Raises:
        ConfigError: for a bad option value (a ``--verdict`` policy that is not among the
            policies, or without a fixed policy to judge it against), an output folder that is not
            empty (without ``--overwrite`` or ``--resume``) or cannot be written, or a journal of
            another run, before any episode runs.
    """
    spec = spec_from_args(args)
    gif_cell = parse_gif_cell(args.gif_cell, spec) if args.gif_cell else None
    judged = verdict_policy(args.verdict, spec) if getattr(args, "verdict", None) else None
    resume, overwrite = bool(getattr(args, "resume", False)), bool(getattr(args, "overwrite", False))
    check(not (resume and overwrite), "--resume continues a run and --overwrite starts it again: give one")
    out = Path(args.out)
    with open_output_folder(out, EVAL_OUTPUTS, command="crowdloc eval", overwrite=overwrite, resume=resume) as folder:
        journal_path = out / JOURNAL_NAME
        journal = EpisodeJournal.resume(journal_path, spec) if resume else EpisodeJournal.start(journal_path, spec)
        folder.record(journal_path)
        result = evaluate(spec, workers=args.workers, ray_address=args.ray_address, progress=not args.no_progress,
                          journal=journal)  # fmt: skip
        written = write_outputs(result, out, gif_cell=gif_cell, gif=not args.no_gif)
        print(summary_markdown(result))
        if judged is not None:
            rows = paired_verdict(result, judged)
            written.update(write_verdict(rows, spec, out))
            print("\n" + verdict_markdown(rows, spec))
    names = ", ".join(p.name for p in written.values())
    print(f"\n{len(result.episodes)} episodes in {result.wall_s:.0f} s; wrote {args.out}/ ({names})")
    return result
