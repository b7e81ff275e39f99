"""``core.schema``: strict mapping -> frozen dataclass conversion."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import pytest

from core.schema import (
    ConfigError,
    check,
    check_ranges,
    from_mapping,
    is_int,
    is_real,
    load_yaml,
    merge_nested,
    replace_checked,
)


@dataclass(frozen=True)
class Inner:
    gain: float = 1.0
    steps: int = 3

    def __post_init__(self) -> None:
        check(self.gain >= 0, f"gain must be >= 0, got {self.gain}")


@dataclass(frozen=True)
class Outer:
    name: str
    mode: Literal["fast", "exact"] = "fast"
    enabled: bool = True
    point: tuple[float, float] = (0.0, 0.0)
    points: tuple[tuple[float, float], ...] = ()
    limit: float | None = None
    inner: Inner = field(default_factory=Inner)
    inners: tuple[Inner, ...] = ()
    extras: Mapping[str, Any] = field(default_factory=dict)


def build(data: dict, where: str = "test.yaml") -> Outer:
    return from_mapping(Outer, data, where=where)


def test_minimal_mapping_uses_defaults() -> None:
    assert build({"name": "a"}) == Outer(name="a")


def test_full_mapping_with_nested_dataclasses_tuples_and_optional() -> None:
    out = build(
        {
            "name": "b",
            "mode": "exact",
            "enabled": False,
            "point": [1, 2.5],
            "points": [[0, 1], [2, 3]],
            "limit": 4,
            "inner": {"gain": 0.5},
            "inners": [{"steps": 1}, {"gain": 2, "steps": 7}],
        }
    )
    assert out == Outer(
        name="b",
        mode="exact",
        enabled=False,
        point=(1.0, 2.5),
        points=((0.0, 1.0), (2.0, 3.0)),
        limit=4.0,
        inner=Inner(gain=0.5, steps=3),
        inners=(Inner(steps=1), Inner(gain=2.0, steps=7)),
    )
    # lists become tuples (hashable, frozen), ints declared as float become floats
    assert isinstance(out.point, tuple) and isinstance(out.points[0], tuple)
    assert type(out.point[0]) is float and type(out.limit) is float and type(out.inners[1].gain) is float


def test_optional_accepts_none() -> None:
    assert build({"name": "c", "limit": None}).limit is None


def test_dataclass_instance_passes_through() -> None:
    inner = Inner(gain=3.0)
    assert build({"name": "d", "inner": inner}).inner is inner


@pytest.mark.parametrize(
    ("data", "fragments"),
    [
        ({"name": "x", "bogus": 1}, ["'bogus'", "Outer", "test.yaml"]),
        ({"name": "x", "inner": {"gian": 1.0}}, ["'gian'", "Inner", "test.yaml.inner"]),
        ({"name": "x", "inners": [{}, {"step": 1}]}, ["'step'", "test.yaml.inners[1]"]),
        ({}, ["missing required key 'name'", "Outer", "test.yaml"]),
        ({"name": 3}, ["expected a string", "3", "test.yaml.name"]),
        ({"name": "x", "mode": "slow"}, ["'slow'", "'fast'", "'exact'", "test.yaml.mode"]),
        ({"name": "x", "enabled": 1}, ["expected true or false", "1", "test.yaml.enabled"]),  # no int -> bool
        ({"name": "x", "enabled": "yes"}, ["expected true or false", "'yes'"]),
        ({"name": "x", "inner": {"steps": True}}, ["expected an integer", "True", "test.yaml.inner.steps"]),  # bool is not int
        ({"name": "x", "inner": {"steps": 2.0}}, ["expected an integer", "2.0"]),  # no float -> int
        ({"name": "x", "inner": {"gain": True}}, ["expected a number", "True", "test.yaml.inner.gain"]),  # bool is not float
        ({"name": "x", "inner": {"gain": "1.0"}}, ["expected a number", "'1.0'"]),
        ({"name": "x", "point": [1.0]}, ["expected 2 values", "[1.0]", "test.yaml.point"]),
        ({"name": "x", "point": [1.0, 2.0, 3.0]}, ["expected 2 values", "[1.0, 2.0, 3.0]"]),
        ({"name": "x", "point": 1.0}, ["expected a list", "1.0"]),
        ({"name": "x", "points": [[0, 1], [2, "z"]]}, ["'z'", "test.yaml.points[1][1]"]),
        ({"name": "x", "limit": "high"}, ["'high'", "test.yaml.limit"]),
        ({"name": "x", "inner": 5}, ["expected a mapping for Inner", "5"]),
        ({"name": "x", "inner": {"gain": -1.0}}, ["gain must be >= 0, got -1.0", "test.yaml.inner"]),  # __post_init__
    ],
)
def test_bad_mappings_raise_config_error_naming_the_problem(data: dict, fragments: list[str]) -> None:
    with pytest.raises(ConfigError) as exc:
        build(data)
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_config_error_is_a_value_error() -> None:
    assert issubclass(ConfigError, ValueError)


def test_replace_checked_merges_nested_overrides() -> None:
    base = Outer(name="a", inner=Inner(gain=2.0, steps=5))
    out = replace_checked(base, {"mode": "exact", "inner": {"steps": 9}}, where="kwargs")
    assert out == Outer(name="a", mode="exact", inner=Inner(gain=2.0, steps=9))
    assert base.inner.steps == 5  # the original is untouched


def test_replace_checked_merges_a_mapping_field_key_by_key() -> None:
    base = Outer(name="a", extras={"camera": {"fov_rad": 1.5, "noise": 0.1}, "prior": "none"})
    out = replace_checked(base, {"extras": {"camera": {"fov_rad": 1.0}, "belief": True}}, where="kwargs")
    assert out.extras == {"camera": {"fov_rad": 1.0, "noise": 0.1}, "prior": "none", "belief": True}
    assert base.extras["camera"]["fov_rad"] == 1.5


def test_merge_nested_merges_mappings_and_replaces_everything_else() -> None:
    base = {"a": {"b": 1, "c": [1, 2]}, "d": 2}
    assert merge_nested(base, {"a": {"c": [3]}, "d": {"e": 1}}) == {"a": {"b": 1, "c": [3]}, "d": {"e": 1}}
    assert base == {"a": {"b": 1, "c": [1, 2]}, "d": 2}


@pytest.mark.parametrize(
    ("overrides", "fragments"),
    [
        ({"nmae": "b"}, ["'nmae'", "Outer", "kwargs"]),
        ({"inner": {"gian": 1.0}}, ["'gian'", "Inner", "kwargs.inner"]),
        ({"inner": {"steps": "many"}}, ["expected an integer", "'many'", "kwargs.inner.steps"]),
        ({"inner": {"gain": -2.0}}, ["gain must be >= 0, got -2.0"]),
        ({"enabled": 0}, ["expected true or false", "0"]),
    ],
)
def test_replace_checked_rejects_bad_overrides(overrides: dict, fragments: list[str]) -> None:
    with pytest.raises(ConfigError) as exc:
        replace_checked(Outer(name="a"), overrides, where="kwargs")
    for fragment in fragments:
        assert fragment in str(exc.value), (fragment, str(exc.value))


def test_replace_checked_needs_a_mapping_and_an_instance() -> None:
    with pytest.raises(ConfigError, match=r"overrides must be a mapping, got list \[1\]"):
        replace_checked(Outer(name="a"), [1], where="kwargs")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match="dataclass instance"):
        replace_checked(Outer, {}, where="kwargs")  # type: ignore[arg-type]


def test_unsupported_annotation_is_a_type_error() -> None:
    @dataclass(frozen=True)
    class Odd:
        value: set[int]

    with pytest.raises(TypeError, match="unsupported annotation"):
        from_mapping(Odd, {"value": [1]}, where="odd")


def test_frozen_results() -> None:
    out = build({"name": "a"})
    with pytest.raises(dataclasses.FrozenInstanceError):
        out.name = "b"  # type: ignore[misc]


def test_load_yaml_errors(tmp_path: Path) -> None:
    missing = tmp_path / "missing.yaml"
    with pytest.raises(ConfigError, match="missing.yaml"):
        load_yaml(missing)
    broken = tmp_path / "broken.yaml"
    broken.write_text("a: [1, 2\n")
    with pytest.raises(ConfigError, match="broken.yaml.*not valid YAML"):
        load_yaml(broken)
    listed = tmp_path / "listed.yaml"
    listed.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="listed.yaml.*top level must be a mapping, got list"):
        load_yaml(listed)
    good = tmp_path / "good.yaml"
    good.write_text("name: a\ninner: {gain: 2}\n")
    assert from_mapping(Outer, load_yaml(good), where=str(good)) == Outer(name="a", inner=Inner(gain=2.0))


@dataclass(frozen=True)
class _Ranged:
    gain: Any = 1.0
    margin: Any = 0.0


@pytest.mark.parametrize(
    ("gain", "margin", "message"),
    [
        (0.0, 0.0, "box.gain must be finite and > 0, got 0.0"),
        (float("inf"), 0.0, "box.gain must be finite and > 0, got inf"),
        (float("nan"), 0.0, "box.gain must be finite and > 0, got nan"),
        (True, 0.0, "box.gain must be finite and > 0, got True"),
        ("1", 0.0, "box.gain must be finite and > 0, got '1'"),
        (1.0, -0.5, "box.margin must be finite and >= 0, got -0.5"),
        (1.0, float("inf"), "box.margin must be finite and >= 0, got inf"),
    ],
)
def test_check_ranges_names_the_field_and_the_value(gain: Any, margin: Any, message: str) -> None:
    with pytest.raises(ConfigError, match=f"^{re.escape(message)}$"):
        check_ranges(_Ranged(gain, margin), "box", positive=("gain",), non_negative=("margin",))


def test_check_ranges_accepts_the_bounds_and_integers() -> None:
    check_ranges(_Ranged(1, 0), "box", positive=("gain",), non_negative=("margin",))
    check_ranges(_Ranged(1e-300, 0.0), "box", positive=("gain",), non_negative=("margin",))


def test_check_ranges_accepts_numpy_numbers_and_refuses_numpy_bools() -> None:
    check_ranges(_Ranged(np.int64(2), np.float32(0.5)), "box", positive=("gain",), non_negative=("margin",))
    with pytest.raises(ConfigError, match="box.gain must be finite and > 0"):
        check_ranges(_Ranged(np.bool_(True), 0.0), "box", positive=("gain",))


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, -math.inf, "1", True, None])
def test_check_ranges_positive_or_inf_refuses_all_but_numbers_above_zero(bad: Any) -> None:
    with pytest.raises(ConfigError, match=rf"^box.gain must be > 0 \(inf: no limit\), got {re.escape(repr(bad))}$"):
        check_ranges(_Ranged(bad, 0.0), "box", positive_or_inf=("gain",))


def test_check_ranges_positive_or_inf_takes_inf_as_no_limit() -> None:
    check_ranges(_Ranged(math.inf, 0.0), "box", positive_or_inf=("gain",))
    check_ranges(_Ranged(np.float64(0.5), 0.0), "box", positive_or_inf=("gain",))


@pytest.mark.parametrize(
    ("value", "real", "finite"),
    [
        (1, True, True),
        (-2.5, True, True),
        (np.float32(0.5), True, True),
        (np.int64(3), True, True),
        (math.inf, True, False),
        (math.nan, True, False),
        (np.float64("nan"), True, False),
        (True, False, False),  # Python counts a bool as 1; a config's true is no number
        (np.bool_(False), False, False),
        ("1.0", False, False),
        (None, False, False),
        (1 + 0j, False, False),
        ([1.0], False, False),
    ],
)
def test_is_real_is_a_number_and_never_a_bool(value: Any, real: bool, finite: bool) -> None:
    assert is_real(value) is real
    assert is_real(value, finite=True) is finite


@pytest.mark.parametrize(
    ("value", "integer"),
    [
        (3, True),
        (np.int64(3), True),
        (-1, True),
        (True, False),
        (np.bool_(True), False),
        (3.0, False),
        (np.float32(3), False),
        ("3", False),
    ],
)
def test_is_int_is_an_integer_and_never_a_bool(value: Any, integer: bool) -> None:
    assert is_int(value) is integer
