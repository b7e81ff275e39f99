"""Same seeds, same numbers: every id's short rollout equals the one recorded before the
architecture change (``tests/pinning.py``; re-record only for an intended, explained change)."""

from __future__ import annotations

import json

import pytest

from tests.pinning import CASES, ROLLOUTS, assert_same_numbers, rollout

PINNED = json.loads(ROLLOUTS.read_text())


@pytest.mark.parametrize(("name", "env_id", "kwargs"), CASES, ids=[c[0] for c in CASES])
def test_rollout_equals_the_recorded_one(name: str, env_id: str, kwargs: dict) -> None:
    assert_same_numbers(PINNED[name], rollout(env_id, kwargs), where=name)
