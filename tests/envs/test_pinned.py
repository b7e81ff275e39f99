"""Same seeds, same numbers: every id's short rollout equals the one recorded before the
architecture change (``tests/pinning.py``; re-record only for an intended, explained change)."""

from __future__ import annotations

import json

import pytest

from tests.pinning import CASES, NEES_LOOSE_REL, NEES_SINGULAR, ROLLOUTS, assert_same_numbers, rollout

PINNED = json.loads(ROLLOUTS.read_text())


@pytest.mark.parametrize(("name", "env_id", "kwargs"), CASES, ids=[c[0] for c in CASES])
def test_rollout_equals_the_recorded_one(name: str, env_id: str, kwargs: dict) -> None:
    assert_same_numbers(PINNED[name], rollout(env_id, kwargs), where=name)


def test_pins_compare_near_singular_nees_loosely_and_everything_else_to_1e9() -> None:
    big = 3 * NEES_SINGULAR
    assert_same_numbers({"runs": [{"nees_median": big}]}, {"runs": [{"nees_median": big * (1 + NEES_LOOSE_REL / 2)}]})
    with pytest.raises(AssertionError, match="nees_median"):
        assert_same_numbers({"nees_median": big}, {"nees_median": big * (1 + 2 * NEES_LOOSE_REL)})
    with pytest.raises(AssertionError, match="nees_median"):  # a finite covariance's NEES is held to 1e-9
        assert_same_numbers({"nees_median": 2.5}, {"nees_median": 2.5 * (1 + 1e-6)})
    with pytest.raises(AssertionError, match="mean_m"):  # other keys too, however large
        assert_same_numbers({"mean_m": big}, {"mean_m": big * (1 + 1e-6)})
