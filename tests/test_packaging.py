"""Packaging without a build: every package is found, every shipped name resolves through the
data packages, and the package-data patterns cover every data file (.ci/check_wheel.sh checks
a real wheel)."""

from __future__ import annotations

import glob
import importlib.util
from pathlib import Path
from types import ModuleType

import pytest

import crowdloc_configs
import crowdloc_models

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    tomllib = pytest.importorskip("tomli")

ROOT = Path(__file__).resolve().parents[1]
CODE_PACKAGES = ("core", "envs", "localizers", "agents")
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())
SETUPTOOLS = PYPROJECT["tool"]["setuptools"]


def _setup_py() -> ModuleType:
    """setup.py as a module (its ``setup()`` runs only as ``__main__``)."""
    spec = importlib.util.spec_from_file_location("crowdloc_setup", ROOT / "setup.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


SETUP = _setup_py()


def _files(folder: Path) -> list[Path]:
    """Every file under ``folder`` except bytecode caches."""
    return sorted(p for p in folder.rglob("*") if p.is_file() and "__pycache__" not in p.relative_to(folder).parts)


def test_every_code_package_is_in_the_wheel() -> None:
    packages = set(SETUP.packages(str(ROOT)))
    on_disk = {
        ".".join(init.parent.relative_to(ROOT).parts)
        for top in CODE_PACKAGES
        for init in (ROOT / top).rglob("__init__.py")
        if "__pycache__" not in init.parts
    }
    assert {
        "envs",
        "localizers",
        "agents",
        "agents.papers",
        "agents.papers.bearing_candidates",
        "agents.papers.lidar_far_point",
        "envs.sensors",
        "envs.crowds",
    } <= on_disk
    assert on_disk - packages == set(), "packages with an __init__.py that setup.py's find would leave out of the wheel"


def test_data_packages_match_pyproject() -> None:
    assert SETUP.DATA_PACKAGES == SETUPTOOLS["package-dir"]
    assert "packages" not in SETUPTOOLS, "setup.py lists the packages; a packages key in pyproject.toml would override it"
    packages = SETUP.packages(str(ROOT))
    for package, folder in SETUP.DATA_PACKAGES.items():
        assert (ROOT / folder / "__init__.py").is_file()
        assert package in packages
        for sub in (p for p in (ROOT / folder).iterdir() if p.is_dir() and p.name != "__pycache__"):
            assert f"{package}.{sub.name}" in packages, f"{folder}/{sub.name}/ is not a (namespace) package of the wheel"
    for package in CODE_PACKAGES:
        assert "py.typed" in SETUPTOOLS["package-data"][package]


@pytest.mark.parametrize("folder", [*CODE_PACKAGES, *SETUP.DATA_PACKAGES.values()])
def test_package_data_covers_every_file(folder: str) -> None:
    """Every file that is not a module matches a package-data pattern of its package (the way
    setuptools' build_py globs them), so no data file or new data folder is left out silently."""
    package = {v: k for k, v in SETUP.DATA_PACKAGES.items()}.get(folder, folder)
    patterns = SETUPTOOLS["package-data"].get(package, []) + SETUPTOOLS["package-data"].get("*", [])
    covered = {Path(p) for pattern in patterns for p in glob.glob(pattern, root_dir=ROOT / folder, recursive=True)}
    data = [p.relative_to(ROOT / folder) for p in _files(ROOT / folder) if p.suffix != ".py"]
    assert data or folder in CODE_PACKAGES
    missing = [str(p) for p in data if p not in covered]
    assert missing == [], f"{folder}/: files no package-data pattern of {package!r} in pyproject.toml covers"


def test_shipped_worlds_resolve() -> None:
    import envs
    from envs.config import available_worlds, load_world, world_path

    names = crowdloc_configs.names("worlds")
    assert names == available_worlds()
    assert sorted(envs.ENV_WORLDS.values()) == names
    for name in names:
        assert world_path(name) == crowdloc_configs.yaml_path("worlds", name)
        assert world_path(name).is_file()
        assert load_world(name).name == name


def test_shipped_localizer_params_resolve() -> None:
    from localizers.registry import LOCALIZERS, load_params, params_path

    names = crowdloc_configs.names("localizers")
    assert names and set(names) <= set(LOCALIZERS), "a localizer YAML without a registry entry"
    for name in names:
        assert params_path(name) == crowdloc_configs.yaml_path("localizers", name)
        assert params_path(name).is_file()
        load_params(name)


def test_shipped_experiments_and_search_spaces_resolve() -> None:
    from agents.rl.config import load_train_config
    from agents.tune import load_search_space, space_path

    experiments = crowdloc_configs.names("experiments")
    assert experiments
    for name in experiments:
        load_train_config(name)
    spaces = crowdloc_configs.names("tuning")
    assert spaces
    for name in spaces:
        assert space_path(name) == crowdloc_configs.yaml_path("tuning", name)
        assert space_path(name).is_file()
        load_search_space(name)


def test_shipped_models_resolve() -> None:
    from agents.demo import ACTIVE_LOCALIZERS, SHIPPED_CONFIG, SHIPPED_MODELS

    assert sorted(ACTIVE_LOCALIZERS) == sorted(SHIPPED_MODELS)
    assert {f"ppo_{localizer}" for localizer in ACTIVE_LOCALIZERS} <= set(crowdloc_models.names())
    assert set(crowdloc_models.names()) <= set(crowdloc_configs.names("experiments")), "each model is a config's"
    for localizer, path in SHIPPED_MODELS.items():
        assert path == crowdloc_models.policy_path(localizer)
        assert path.is_file()
    assert SHIPPED_CONFIG in crowdloc_configs.names("experiments")


def test_kinds_are_the_config_folders() -> None:
    folders = sorted(p.name for p in (ROOT / "configs").iterdir() if p.is_dir() and p.name != "__pycache__")
    assert sorted(crowdloc_configs.KINDS) == folders
