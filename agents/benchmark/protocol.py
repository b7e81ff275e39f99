"""The benchmark protocol: ``configs/benchmark/NAME.yaml`` read strictly into frozen dataclasses.

A protocol fixes everything that decides a benchmark number: per world (a registered env id) the
crowd sizes, the fixed policies that drive, the episode length, the start condition and the
failure threshold; and the test seeds. :func:`protocol_digest` hashes the values of the protocol
file, of its worlds' YAML and of the built-in localizers' parameters, and crowdloc's version: two results with the same name and digest compare.

The test seeds lie at or above :data:`RESERVED_BELOW`: every training seed is below
``EVAL_SEED_BASE`` (2**31) and every held-out evaluation seed that eval, demo and tune draw is
``EVAL_SEED_BASE + first_seed + i`` with ``first_seed <= FIRST_SEED_MAX`` (2**30) and far fewer
than 2**29 seeds, so no other command reaches a benchmark seed.
"""

from __future__ import annotations

import hashlib
import importlib.metadata
import json
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import crowdloc_configs
from agents.evaluate.spec import FIRST_SEED_MAX, crowdloc_ids, runnable_policies, world_of
from agents.policies import FIXED_POLICIES
from agents.rl.config import EVAL_SEED_BASE
from core.schema import ConfigError, check, from_mapping, load_yaml
from localizers.registry import BUILTIN_LOCALIZERS

#: the first seed no other command uses: above every training seed and every held-out seed of eval, demo and tune
RESERVED_BELOW = EVAL_SEED_BASE + FIRST_SEED_MAX + 2**29
#: seeds are 32-bit (numpy's SeedSequence takes more, gymnasium's spaces do not)
SEED_LIMIT = 2**32
#: the shipped protocol ``crowdloc benchmark`` runs by default
DEFAULT_PROTOCOL = "v2"

Start = Literal["known", "unknown", "localizer"]


@dataclass(frozen=True)
class WorldProtocol:
    """One world's conditions.

    Attributes:
        crowd_sizes: the crowd sizes (the world's first crowd's count), rising, from 0 to its ``max_count``.
        policies: the fixed policies that drive, the world's paper policy first.
        episode_steps: steps per episode.
        start: ``known`` (every localizer gets the true start pose), ``unknown`` (none does) or
            ``localizer`` (each as its ``LocalizerSpec.needs_prior`` asks).
        failure_m: a step with a position error at least this is a failure.
        paper_localizers: the world's paper's method, then the baselines it was compared with (optional):
            the leaderboard's table "The papers' methods as the crowd grows" shows them at crowd 0, the
            world's default and its maximum.
    """

    crowd_sizes: tuple[int, ...]
    policies: tuple[str, ...]
    episode_steps: int
    start: Start
    failure_m: float
    paper_localizers: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check(len(self.crowd_sizes) >= 2, f"crowd_sizes needs at least 0 and the maximum, got {list(self.crowd_sizes)}")
        check(list(self.crowd_sizes) == sorted(set(self.crowd_sizes)), f"crowd_sizes must rise, got {list(self.crowd_sizes)}")
        check(self.crowd_sizes[0] == 0, f"crowd_sizes must start at 0 (the empty world), got {list(self.crowd_sizes)}")
        check(len(self.policies) >= 1, "policies needs at least one")
        check(len(set(self.policies)) == len(self.policies), f"policies repeat: {list(self.policies)}")
        check(self.episode_steps >= 1, f"episode_steps must be >= 1, got {self.episode_steps}")
        check(0.0 < self.failure_m < float("inf"), f"failure_m must be finite and > 0, got {self.failure_m}")
        check(len(set(self.paper_localizers)) == len(self.paper_localizers),
              f"paper_localizers repeat: {list(self.paper_localizers)}")  # fmt: skip

    @property
    def prior(self) -> str | None:
        """The ``prior`` condition of ``crowdloc eval`` this start gives (None: each localizer's own)."""
        return {"known": "start", "unknown": "none", "localizer": None}[self.start]


@dataclass(frozen=True)
class SeedRange:
    """The test seeds ``first .. first + count - 1``."""

    first: int
    count: int

    def __post_init__(self) -> None:
        check(self.count >= 1, f"count must be >= 1, got {self.count}")
        check(self.first >= RESERVED_BELOW,
              f"first must be >= {RESERVED_BELOW} (2**31 + 2**30 + 2**29: no training, tuning, evaluation or reproduction "
              f"seed reaches it), got {self.first}")  # fmt: skip
        check(self.first + self.count <= SEED_LIMIT, f"first + count must be <= 2**32, got {self.first + self.count}")

    @property
    def seeds(self) -> tuple[int, ...]:
        return tuple(range(self.first, self.first + self.count))


@dataclass(frozen=True)
class QuickMode:
    """``--quick``: fewer seeds (a prefix of the protocol's) and shorter episodes."""

    seeds: int
    episode_steps: int

    def __post_init__(self) -> None:
        check(self.seeds >= 1, f"seeds must be >= 1, got {self.seeds}")
        check(self.episode_steps >= 1, f"episode_steps must be >= 1, got {self.episode_steps}")


@dataclass(frozen=True)
class Protocol:
    """A benchmark protocol (``configs/benchmark/NAME.yaml``).

    Attributes:
        name: the protocol's name (``crowdloc-benchmark-v1``), printed with every result.
        description: one line.
        seeds: the test seeds.
        quick: what ``--quick`` keeps.
        worlds: env id -> its conditions, in the file's order.
        path: the file it was read from (set by :func:`load_protocol`).
    """

    name: str
    description: str
    seeds: SeedRange
    quick: QuickMode
    worlds: Mapping[str, WorldProtocol]
    path: str = ""

    def __post_init__(self) -> None:
        check(bool(self.name.strip()), "name must not be empty")
        check(len(self.worlds) >= 1, "worlds needs at least one")
        check(self.quick.seeds <= self.seeds.count, f"quick.seeds ({self.quick.seeds}) exceeds seeds.count ({self.seeds.count})")


def protocol_path(name_or_path: str | Path) -> Path:
    """A shipped protocol's file (``v1``) or the YAML path given."""
    text = str(name_or_path)
    if text.endswith((".yaml", ".yml")) or "/" in text:
        return Path(text)
    return crowdloc_configs.yaml_path("benchmark", text)


def load_protocol(name_or_path: str | Path = DEFAULT_PROTOCOL) -> Protocol:
    """Read and check a protocol: its keys and types, and each world against the registry.

    Raises:
        ConfigError: naming the file and the key (an unknown or missing key, an unknown env id or
            policy, a policy the world cannot run, a crowd size beyond the world's maximum, a
            seed range that others use).
    """
    path = protocol_path(name_or_path)
    if not path.is_file():
        shipped = ", ".join(crowdloc_configs.names("benchmark"))
        raise ConfigError(f"benchmark protocol {str(name_or_path)!r}: no such file ({path}); shipped: {shipped}")
    protocol = from_mapping(Protocol, {**load_yaml(path), "path": str(path)}, where=str(path))
    known = crowdloc_ids()
    for env_id, world in protocol.worlds.items():
        where = f"{path}: worlds.{env_id}"
        check(env_id in known, f"{where}: unknown env id {env_id!r}; known: {', '.join(known)}")
        config = world_of(env_id, {})
        limit = config.crowd.max_count if config.crowd is not None else 0
        check(protocol.worlds[env_id].crowd_sizes[-1] == limit,
              f"{where}.crowd_sizes must end at the world's maximum {limit}, got {list(world.crowd_sizes)}")  # fmt: skip
        for policy in world.policies:
            check(
                policy in FIXED_POLICIES,
                f"{where}.policies: unknown policy {policy!r}; fixed policies: {', '.join(FIXED_POLICIES)}",
            )
            check(policy in runnable_policies(config),
                  f"{where}.policies: {policy!r} cannot drive this world (it can: {', '.join(runnable_policies(config))})")  # fmt: skip
        for name in world.paper_localizers:
            check(name in BUILTIN_LOCALIZERS,
                  f"{where}.paper_localizers: {name!r} is not a built-in localizer; built-in: {', '.join(BUILTIN_LOCALIZERS)}")  # fmt: skip
    return protocol


def crowdloc_version() -> str:
    """crowdloc's installed version (``(not installed)`` from a checkout that is not)."""
    try:
        return importlib.metadata.version("crowdloc")
    except importlib.metadata.PackageNotFoundError:
        return "(not installed)"


def protocol_digest(protocol: Protocol) -> str:
    """sha256 (hex) of what decides a number: the protocol file, each of its worlds' YAML (in the
    protocol's order), the parameter file of every built-in localizer (``configs/localizers/``, by
    name) and crowdloc's version. A plug-in's own parameters are the plug-in's to cite.

    Each YAML file enters by its values (:func:`_yaml_values`), not its text: a comment or a
    reformatting decides no number, so it leaves the digest as it is."""
    import gymnasium as gym

    from envs.config import world_path
    from localizers.registry import params_path

    h = hashlib.sha256()
    h.update(_yaml_values(Path(protocol.path)))
    for env_id in protocol.worlds:
        world = gym.spec(env_id).kwargs["world"]
        h.update(env_id.encode() + b"\0" + _yaml_values(world_path(world)))
    for name in sorted(BUILTIN_LOCALIZERS):  # not the plug-ins a process has imported: one digest everywhere
        path = params_path(name)
        h.update(name.encode() + b"\0" + (_yaml_values(path) if path.is_file() else b""))
    h.update(crowdloc_version().encode())
    return h.hexdigest()


def _yaml_values(path: Path) -> bytes:
    """A YAML file's values as canonical JSON (keys sorted, no comments, no layout)."""
    return json.dumps(load_yaml(path), sort_keys=True, separators=(",", ":")).encode()
