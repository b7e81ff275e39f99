"""Shared fixtures of the localizer tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from localizers.mcl_lidar import CACHE_ENV


@pytest.fixture(scope="session")
def cache_root(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One table cache for the whole test run: each table is built once."""
    return tmp_path_factory.mktemp("crowdloc_cache")


@pytest.fixture(autouse=True)
def _cache_env(monkeypatch: pytest.MonkeyPatch, cache_root: Path) -> None:
    monkeypatch.setenv(CACHE_ENV, str(cache_root))
