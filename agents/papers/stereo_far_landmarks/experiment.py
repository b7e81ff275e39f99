"""The experiment as we set it up: our choices, the localizers compared, the plan.

The paper's own numbers come from :mod:`.paper`; the world's and the localizers' shipped
settings from :mod:`.world`. What is defined here is ours (each constant says why).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from agents.experiments.scene_maps import reference_env_kwargs as reference_env_kwargs_of

from . import world

ENV_ID = "crowdloc/StereoCampus-v0"
DEFAULT_SEEDS = 10
#: crowd sizes of the sweep beyond the paper (pedestrians and cars together, the world's car share);
#: the world's own (30) is the paper's experiment
DENSITIES = (0, 30, 60, 100, 150)
#: ours: run 1 (the map) drives with env seed ``MAP_SEED_OFFSET + seed``, run 2 with ``seed``: the
#: same route at the same crowd size, another crowd (as the paper's two drives met other people)
MAP_SEED_OFFSET = 1000
#: far_landmark_pf's ``selection`` values replayed into every run: the paper's far emphasis, no
#: emphasis (every matching detection: the baseline the paper argues against), nearest first
SELECTIONS = ("farthest", "all", "nearest")
PAPER_SELECTION = "farthest"
REFERENCE_KEY = "reference"  # mcl_lidar with AMCL_LIKE: the paper's amcl on the flattened VLP-16
KEYS = (*SELECTIONS, REFERENCE_KEY)
#: ours: far_landmark_pf's generator of a run is ``[seed, crowd size, salt]``, the same for every selection
PF_RNG_SALT = 0xD1F
FAIL_M = 1.0  # ours (as the LIDAR reproduction's paper B): a failure is an estimate >= 1 m from the truth
#: ours: a localizer "fails" at a crowd size when at least this share of its steps are failures or lost
FAILING_SHARE = 0.01
BOOTSTRAP_RESAMPLES = 2000  # ours: the paired comparisons' percentile bootstrap over seeds
BOOTSTRAP_SEED = 0x5FB
#: ours: Figs 8-9's windows along the route's arc length: the paper's place 1 is passed "soon after
#: the start", place 2 "after the right turn"; each window is this long
PLACE_WINDOW_M = 15.0
#: ours: the paper's weak spot: a stretch where far emphasis uses at most ``SPARSE_USED`` landmarks a
#: frame on average over ``SPARSE_WINDOW_S`` is "few landmarks"; drift is the error's change over it
SPARSE_USED = 0.5
SPARSE_WINDOW_S = 2.0
#: ours: "corrected" when the distance to the reference falls to half its peak within this long after it
CORRECTION_S = 10.0
#: ours: the weak spot is read on the distance to the reference averaged over this long (centred):
#: the reference moves in steps at its updates (every 0.5 m), and the paper plots once a second
SMOOTH_S = 1.0
#: ours: how much of the robot's surroundings the crowd fills: LIDAR beams returning within this
#: (at crowd 0 the static scene's share: poles, trees, parked cars, the fence)
NEAR_M = 5.0
ABOUT = 1.2  # ours: "about 0.7 m" holds up to 1.2 x the paper's number

#: ``--quick``: at most this many seeds, these crowd sizes, the drives cut after this many steps
QUICK_SEEDS = 2
QUICK_DENSITIES = (30, 150)
QUICK_STEPS = 200

LABELS = {
    "farthest": "far_landmark_pf, farthest (the paper's)",
    "all": "far_landmark_pf, all (no far emphasis)",
    "nearest": "far_landmark_pf, nearest first",
    REFERENCE_KEY: "mcl_lidar AMCL-like (the reference)",
}
SHORT = {"farthest": "farthest", "all": "all", "nearest": "nearest", REFERENCE_KEY: "LIDAR reference"}


def reference_env_kwargs(crowd_size: int) -> dict[str, Any]:
    """``gym.make`` arguments of run 2: the crowd, and the LIDAR reference run online (what the robot drives on)."""
    return {"crowd_size": crowd_size, **reference_env_kwargs_of(world.campus())}


def pf_params(selection: str) -> dict[str, Any]:
    """far_landmark_pf's overrides of a selection (the rest as shipped; the scene map is handed over as an object)."""
    return {"selection": selection}


@dataclass(frozen=True)
class Plan:
    """How much to run.

    Attributes:
        seeds: seeds 0..seeds-1: each one map (run 1) and one run 2 per crowd size.
        densities: the crowd sizes of run 2, the world's own among them (the paper's experiment).
        max_steps: the drives are cut after this many steps (None: the world's episode length).
        quick: the smoke run.
    """

    seeds: int
    densities: tuple[int, ...]
    max_steps: int | None = None
    quick: bool = False

    @property
    def crowd(self) -> int:
        """The paper's experiment: run 2 at the world's crowd size."""
        return world.default_crowd()


def crowd_size(text: str) -> int:
    """argparse type of ``--crowd-sizes 0 30 60`` (each one, ``nargs``): a crowd size within the world's limits."""
    limit = int(world.crowd_config().max_count)
    try:
        size = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a crowd size, a whole number 0..{limit} (several: separated by spaces), "
                                         f"got {text!r}") from None  # fmt: skip
    if not 0 <= size <= limit:
        raise argparse.ArgumentTypeError(f"expected a crowd size 0..{limit}, got {size}")
    return size


def make_plan(args: argparse.Namespace) -> Plan:
    crowd = world.default_crowd()
    if args.quick:
        chosen: Sequence[int] = args.crowd_sizes or QUICK_DENSITIES  # sorted and distinct below
        return Plan(min(args.seeds, QUICK_SEEDS), tuple(sorted({crowd, *chosen})), QUICK_STEPS, quick=True)
    return Plan(args.seeds, tuple(sorted({crowd, *(args.crowd_sizes or DENSITIES)})))


def places() -> tuple[tuple[str, float, float], ...]:
    """Figs 8-9: ``(name, from, to)`` along the route's arc length: the start, and after the turn."""
    _, turn_end = world.turn_arc_m()
    return (("place 1 (the start)", 0.0, PLACE_WINDOW_M), ("place 2 (after the turn)", turn_end, turn_end + PLACE_WINDOW_M))
