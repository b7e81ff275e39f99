"""Which packages go into the wheel; everything else about the build is in pyproject.toml.

The code packages are found at build time, so a new subpackage (``envs.sensors``,
``agents.papers.x``) is in the wheel without an edit here. The data packages are the folders
``configs/`` and ``models/`` under unique names (``[tool.setuptools.package-dir]``), their
subfolders (``configs/worlds/``, ...) namespace packages of them. ``[tool.setuptools.packages.find]``
names a package after its folder and so cannot find a renamed one, and an explicit
``packages = [...]`` would miss new subpackages. tests/test_packaging.py checks this against the tree.
"""

from __future__ import annotations

from setuptools import find_namespace_packages, find_packages, setup

#: find_packages patterns of the code packages: each one and all its subpackages (with __init__.py)
CODE_PACKAGES = ("core", "core.*", "envs", "envs.*", "localizers", "localizers.*", "agents", "agents.*")
#: data package -> its folder (the same as pyproject.toml's package-dir)
DATA_PACKAGES = {"crowdloc_configs": "configs", "crowdloc_models": "models"}


def packages(root: str = ".") -> list[str]:
    """Every package of the wheel, for the project in ``root``."""
    found = sorted(find_packages(root, include=CODE_PACKAGES))
    for package, folder in DATA_PACKAGES.items():
        subfolders = find_namespace_packages(f"{root}/{folder}", exclude=("__pycache__", "*.__pycache__"))
        found += [package] + [f"{package}.{sub}" for sub in sorted(subfolders)]
    return found


if __name__ == "__main__":  # setuptools.build_meta runs this file as __main__
    setup(packages=packages())
