"""crowdloc's shipped configurations, installed as the package ``crowdloc_configs``.

This folder is package data (``configs/`` in the checkout, ``crowdloc_configs`` once installed;
see ``package-dir`` in pyproject.toml): one YAML per name in ``worlds/``, ``localizers/``,
``experiments/``, ``tuning/`` and ``benchmark/`` (the benchmark's protocols), and in ``rl_zoo3/`` one rl-zoo3 hyperparameter file of the
task ids per algorithm (``ppo.yaml``). Code finds them through :func:`path` and :func:`names`
(``importlib.resources``), never by paths relative to its own source, so they are found in a
built wheel as in a checkout, and a user's own ``configs/`` folder cannot shadow them.
"""

from __future__ import annotations

from importlib.resources import files
from pathlib import Path

#: the kinds of shipped configs, one folder each
KINDS = ("worlds", "localizers", "experiments", "tuning", "rl_zoo3", "benchmark", "policy_tracks")


def path(*parts: str) -> Path:
    """A shipped file or folder, e.g. ``path("worlds", "robocup_static.yaml")`` (it need not exist)."""
    root = files(__name__)
    if not isinstance(root, Path):  # a zipped install; crowdloc is always installed as files
        raise RuntimeError(f"crowdloc's configs must be installed as files, found {root!r}")
    return root.joinpath(*parts)


def yaml_path(kind: str, name: str) -> Path:
    """``<kind>/<name>.yaml``, e.g. ``yaml_path("localizers", "kalman")``."""
    return path(kind, f"{name}.yaml")


def names(kind: str) -> list[str]:
    """The shipped config names of one kind, sorted: ``names("worlds")`` -> ``["crowded_room", ...]``."""
    return sorted(p.stem for p in path(kind).glob("*.yaml"))
