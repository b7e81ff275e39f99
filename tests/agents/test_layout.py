"""agents/ by role: each subpackage imports only the parts its ``__init__`` allows (the import graph of
:mod:`tests.import_graph`, relative imports and imports inside functions included), and the old flat
module names still import (one release) as the same module objects, with a warning naming the new path."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

import agents
from tests.import_graph import import_graph

ROOT = Path(agents.__file__).parent

#: part -> the parts of agents it may import (its own aside); the top-level modules may import all
ALLOWED: dict[str, set[str]] = {
    "common": set(),
    "policies": {"common"},
    "experiments": {"common", "policies"},
    "rl": {"common", "policies"},
    "evaluate": {"common", "policies", "experiments", "rl"},
    "benchmark": {"common", "policies", "experiments", "rl", "evaluate"},
    "papers": {"common", "policies", "experiments", "rl", "evaluate"},
    "tune": {"common", "policies", "experiments", "rl", "evaluate", "papers"},
}


def _part(module: str) -> str | None:
    """``agents.X.y`` -> ``X`` for a subpackage of agents (None for the top-level modules)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and (ROOT / parts[1]).is_dir() else None


def test_each_part_imports_only_what_its_init_allows() -> None:
    bad = []
    for module, targets in sorted(import_graph().items()):
        part = _part(module)
        if not module.startswith("agents.") or part is None:
            continue  # cli, demo: on top
        for target in sorted(t for t in targets if t.startswith("agents.")):
            other = _part(target)
            if other is None and target.split(".")[1] in ("cli", "demo"):
                bad.append(f"{module} imports {target} (cli and demo are on top)")
            elif other is not None and other != part and other not in ALLOWED[part]:
                bad.append(f"{module} imports {target} ({part} may import {sorted(ALLOWED[part])})")
    assert not bad, "\n".join(bad)


def test_every_part_is_in_the_table() -> None:
    parts = {p.name for p in ROOT.iterdir() if (p / "__init__.py").is_file()}
    assert parts == set(ALLOWED)


@pytest.mark.parametrize("old", sorted(agents.MOVED))
def test_an_old_module_name_warns_and_is_the_new_module(old: str, monkeypatch: pytest.MonkeyPatch) -> None:
    new = agents.MOVED[old]
    module = importlib.import_module(new)
    monkeypatch.delitem(sys.modules, old, raising=False)  # as in a fresh process
    monkeypatch.delattr(agents, old.rpartition(".")[2], raising=False)
    with pytest.warns(DeprecationWarning, match=rf"{old} moved to {new}"):
        aliased = importlib.import_module(old)
    assert aliased is module
    assert sys.modules[old] is module and module.__name__ == new  # pickles keep naming the new path


def test_the_old_import_statements_give_the_same_objects(monkeypatch: pytest.MonkeyPatch) -> None:
    for old in ("agents.train", "agents.metrics"):
        monkeypatch.delitem(sys.modules, old, raising=False)
        monkeypatch.delattr(agents, old.rpartition(".")[2], raising=False)
    from agents.evaluate.metrics import position_errors
    from agents.rl.config import load_train_config

    with pytest.warns(DeprecationWarning, match="agents.rl.train"):
        import agents.train as old_train
    with pytest.warns(DeprecationWarning, match="agents.evaluate.metrics"):
        from agents.metrics import position_errors as old_position_errors
    assert old_train.load_train_config is load_train_config
    assert old_position_errors is position_errors


def test_agents_policies_keeps_its_names() -> None:
    from agents.policies import FIXED_POLICIES, PatrolPath, RandomWalk, make_policy
    from agents.policies.fixed import FIXED_POLICIES as fixed

    assert FIXED_POLICIES is fixed and {"random_walk", "patrol"} <= set(FIXED_POLICIES)
    assert callable(make_policy) and PatrolPath.__module__ == RandomWalk.__module__ == "agents.policies.fixed"
