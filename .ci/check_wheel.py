"""The installed half of the wheel check (.ci/check_wheel.sh runs it).

Run with the Python of a fresh virtual environment that holds the built wheel, from a directory
outside the checkout: ``python -I check_wheel.py CHECKOUT``. It checks that crowdloc comes from
that environment, that every module and data file of the checkout is installed, that every
registered env id makes, resets and steps with a localizer, and that the shipped models resolve.
The command line (``crowdloc worlds``, ``crowdloc eval --help``) is checked by the shell script.
"""

from __future__ import annotations

import importlib
import importlib.resources
import sys
import zipfile
from pathlib import Path

CODE_PACKAGES = ("core", "envs", "localizers", "agents")
#: data package -> its folder in the checkout
DATA_PACKAGES = {"crowdloc_configs": "configs", "crowdloc_models": "models"}
STEPS = 5


def fail(message: str) -> None:
    print(f"check_wheel: FAIL: {message}", file=sys.stderr)
    sys.exit(1)


def check_origin(checkout: Path) -> None:
    """Every package is the installed one, never the checkout's."""
    prefix = Path(sys.prefix).resolve()
    for name in (*CODE_PACKAGES, *DATA_PACKAGES):
        try:
            module = importlib.import_module(name)
        except Exception as exc:  # ImportError, or a shipped config missing at import (envs loads its worlds)
            fail(f"cannot import {name!r} from the wheel: {type(exc).__name__}: {exc}")
        origin = Path(module.__file__ or "").resolve()
        if origin.is_relative_to(checkout) or not origin.is_relative_to(prefix):
            fail(f"{name!r} was imported from {origin}, not from the fresh environment {prefix}")


def check_modules(checkout: Path) -> None:
    """Every module of the checkout's code packages imports from the wheel, and py.typed is there."""
    count = 0
    for package in CODE_PACKAGES:
        if not importlib.resources.files(package).joinpath("py.typed").is_file():
            fail(f"{package}/py.typed is missing from the wheel")
        for source in sorted((checkout / package).rglob("*.py")):
            parts = source.relative_to(checkout).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            if not all((checkout.joinpath(*parts[:i]) / "__init__.py").is_file() for i in range(1, len(parts))):
                continue  # not inside a package (a stray script): not expected in the wheel
            name = ".".join(parts)
            try:
                importlib.import_module(name)
            except ModuleNotFoundError as exc:
                fail(f"module {name!r} ({source.relative_to(checkout)}) is missing from the wheel: {exc}")
            count += 1
    print(f"check_wheel: {count} modules import from the wheel")


def check_data(checkout: Path) -> None:
    """Every data file of the checkout is in the installed data packages."""
    count = 0
    for package, folder in DATA_PACKAGES.items():
        root = importlib.resources.files(package)
        for source in sorted((checkout / folder).rglob("*")):
            if not source.is_file() or "__pycache__" in source.parts:
                continue
            relative = source.relative_to(checkout / folder)
            if not root.joinpath(*relative.parts).is_file():
                fail(f"{folder}/{relative} is missing from the wheel (package {package!r}; see package-data in pyproject.toml)")
            count += 1
    print(f"check_wheel: {count} data files in the wheel")


def check_envs() -> None:
    """Every registered id makes with every localizer its sensors can feed, resets and steps."""
    import gymnasium as gym

    import agents  # noqa: F401  (the task ids and far_landmark_pf's scene-map builder)
    import envs
    from localizers.measurements import readable_kinds
    from localizers.registry import LOCALIZERS

    if not envs.ENV_WORLDS:
        fail("no env ids registered")
    for env_id, world in envs.ENV_WORLDS.items():
        kinds = readable_kinds(gym.make(env_id).unwrapped.sensor_metadata)
        names = [name for name, spec in LOCALIZERS.items() if spec.measurement in kinds]
        if not names:
            fail(f"{env_id}: no registered localizer reads its sensors")
        for localizer in names:
            try:
                env = gym.make(env_id, localizer=localizer)
                env.reset(seed=0)
                for _ in range(STEPS):
                    _, _, terminated, truncated, info = env.step(env.action_space.sample())
                    if terminated or truncated:
                        env.reset()
                env.close()
            except Exception as exc:
                fail(f"gym.make({env_id!r}, localizer={localizer!r}) then reset and step: {type(exc).__name__}: {exc}")
            if "estimate" not in info:
                fail(f"{env_id}: no localizer estimate in info")
        print(f"check_wheel: {env_id} ({world}) with {', '.join(names)}: reset and {STEPS} steps each")


def check_models() -> None:
    """The shipped PPO policies resolve to zip files in the environment."""
    from agents.demo import SHIPPED_MODELS

    prefix = Path(sys.prefix).resolve()
    for localizer, path in SHIPPED_MODELS.items():
        path = Path(path).resolve()
        if not path.is_file():
            fail(f"shipped model for {localizer!r} does not exist: {path}")
        if not path.is_relative_to(prefix):
            fail(f"shipped model for {localizer!r} is outside the fresh environment: {path}")
        if not zipfile.is_zipfile(path):
            fail(f"shipped model for {localizer!r} is not a zip file (a Git LFS pointer?): {path}")
    print(f"check_wheel: shipped models resolve: {', '.join(sorted(SHIPPED_MODELS))}")


def main() -> None:
    if len(sys.argv) != 2:
        fail("usage: python -I check_wheel.py CHECKOUT")
    checkout = Path(sys.argv[1]).resolve()
    if Path.cwd().resolve().is_relative_to(checkout):
        fail(f"run from outside the checkout, not from {Path.cwd()}")
    check_origin(checkout)
    check_modules(checkout)
    check_data(checkout)
    check_envs()
    check_models()


if __name__ == "__main__":
    main()
