"""crowdloc's shipped PPO policies, installed as the package ``crowdloc_models``.

This folder is package data (``models/`` in the checkout, ``crowdloc_models`` once installed;
see ``package-dir`` in pyproject.toml): ``<config>.zip`` per training config of
``configs/experiments/`` with a shipped policy (the soccer field's ``ppo_<localizer>.zip``, one per
localizer; the world tasks' ``ppo_room_lidar.zip`` and the like), and README.md on how they were
trained and chosen. Code finds them through :func:`path` and :func:`names`
(``importlib.resources``), never by paths relative to its own source.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path


def path(*parts: str) -> Path:
    """A shipped file, e.g. ``path("ppo_candidate_sets.zip")`` (it need not exist)."""
    root = files(__name__)
    if not isinstance(root, Path):  # a zipped install; crowdloc is always installed as files
        raise RuntimeError(f"crowdloc's models must be installed as files, found {root!r}")
    return root.joinpath(*parts)


def policy_path(localizer: str) -> Path:
    """The shipped PPO policy trained with ``localizer``: ``ppo_<localizer>.zip``."""
    return path(f"ppo_{localizer}.zip")


def names() -> list[str]:
    """The training configs with a shipped policy, sorted, e.g. ``["ppo_candidate_sets", "ppo_mcl_bearing"]``."""
    return sorted(p.stem for p in path().glob("*.zip"))
