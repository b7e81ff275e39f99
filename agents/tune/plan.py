"""What a ``crowdloc tune`` run is: its options (:class:`TuneConfig`), the checked plan they resolve
to (:class:`StudyPlan`) and what it produced (:class:`TuneResult`).

Plain data, shared by :mod:`agents.tune.study` (which checks a config into a plan and runs it) and
:mod:`agents.tune.report` (which writes the plan's numbers), so neither imports the other's module.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from agents.common.util import flatten
from agents.tune.objective import DEFAULT_FAILURE_PENALTY_M, DEFAULT_PENALTY_M, EpisodeSetup, ObjectiveTerms, WorldFacts
from agents.tune.space import SearchSpace

DEFAULT_STORAGE = "sqlite:///results/tuning.db"


@dataclass(frozen=True)
class TuneConfig:
    """One ``crowdloc tune`` run.

    Attributes:
        localizer: a registered localizer with a search space (:func:`~agents.tune.space.tunable_localizers`).
        setup: the episodes (``None``: :func:`~agents.tune.objective.default_setup` of the
            localizer, its world by measurement kind); its ``measurement`` is set to the localizer's.
        space_path: search-space YAML (default ``configs/tuning/<localizer>.yaml``).
        trials: trials to add to the study in this run (split over the workers).
        train_seeds: training episodes (env seeds ``0 .. n - 1``).
        eval_seeds: held-out episodes (env seeds ``EVAL_SEED_BASE + i``).
        workers: parallel workers, each running ``study.optimize`` on the shared storage.
        ray_address: run the workers on a Ray cluster instead of local processes.
        storage: SQLAlchemy database URL of the study.
        study_name: default ``<localizer>-<env>-crowd<N>-<scenario>``.
        out: report folder (default ``results/tuning/<study>``).
        seed: sampler seed.
        penalty_m: metres added per unit of unavailability.
        failure_penalty_m: metres added per unit of failure share (0: the objective of the
            earlier tune, error and availability only, exactly).
        fail_m: failure threshold (``None``: :func:`~agents.tune.objective.default_fail_m` of the world).
        overwrite: replace an existing ``report.md`` under ``out`` (else a ConfigError).
        verbose: log every trial and show progress bars.
    """

    localizer: str
    setup: EpisodeSetup | None = None
    space_path: Path | None = None
    trials: int = 40
    train_seeds: int = 4
    eval_seeds: int = 8
    workers: int = 1
    ray_address: str | None = None
    storage: str = DEFAULT_STORAGE
    study_name: str | None = None
    out: Path | None = None
    seed: int = 0
    penalty_m: float = DEFAULT_PENALTY_M
    failure_penalty_m: float = DEFAULT_FAILURE_PENALTY_M
    fail_m: float | None = None
    overwrite: bool = False
    verbose: bool = True


@dataclass(frozen=True)
class TuneResult:
    """What a run produced."""

    study_name: str
    report: Path
    best_params_file: Path
    best_params: dict[str, Any]
    n_trials: int
    summary: dict[str, Any]


def default_study_name(localizer: str, setup: EpisodeSetup, crowd_size: int) -> str:
    """``candidate_sets-RoboCupCrowded-v0-crowd10-soccer`` (+ ``-camera.dropout_probability=0.5`` per world override)."""
    name = f"{localizer}-{setup.env_id.split('/')[-1]}-crowd{crowd_size}-{setup.scenario}"
    for key, value in sorted(flatten(setup.env_overrides).items()):
        name += f"-{key}={value}"
    return name


@dataclass(frozen=True)
class StudyPlan:
    """A checked :class:`TuneConfig`: the study, its report folder and its episodes.

    Attributes:
        name: the study name.
        out: the report folder.
        space: the search space.
        setup: the episodes (the localizer's default world where the config gave none).
        terms: the objective's terms (the world's failure threshold where the config gave none).
        world: the effective world's crowd size and time step.
        train_seeds: env seeds of the training episodes.
        held_out_seeds: env seeds of the held-out episodes (never a training seed).
        attrs: the study's user attributes: the objective's definition (``_SETUP_ATTRS``) and the space.
        fixed: parameters every trial and held-out episode gets besides the searched ones, from the
            localizer's preparation hook (:meth:`~agents.tune.objective.EpisodeSetup.prepared_params`:
            ``far_landmark_pf``'s scene map); empty for most localizers.
    """

    name: str
    out: Path
    space: SearchSpace
    setup: EpisodeSetup
    terms: ObjectiveTerms
    world: WorldFacts
    train_seeds: tuple[int, ...]
    held_out_seeds: tuple[int, ...]
    attrs: Mapping[str, Any]
    fixed: Mapping[str, Any] = dataclasses.field(default_factory=dict)
