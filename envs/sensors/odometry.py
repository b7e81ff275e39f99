"""Wheel odometry: the *commanded* motion since the last step, as the robot's own dead
reckoning measures it (optional systematic errors), with alpha-model noise on top.

Displacement by contacts never enters it: a push is a real, unobserved pose jump.

Systematic errors (Borenstein & Feng 1996, "Measurement and correction of systematic
odometry errors in mobile robots", IEEE Trans. Robotics and Automation 12(6), 869-880).
The body moves exactly as commanded (physics aside); the reading is what a differential
drive computes from its wheel encoders with its *nominal* kinematics (wheelbase ``b``, both
wheels of the nominal diameter ``D_n``) when the real robot differs from them. With

    E_d = D_R / D_L          (``wheel_diameter_ratio``, the mean (D_R + D_L) / 2 = D_a kept)
    E_b = b_actual / b       (``wheelbase_ratio``)
    k   = D_n / D_a          (``distance_scale``: metres reported per metre driven straight)

a commanded increment of signed length ``s`` (negative backward) and turn ``dtheta`` makes
the wheels roll ``s_R = s + dtheta E_b b / 2`` and ``s_L = s - dtheta E_b b / 2``. An encoder
counts ``s_i / (pi D_i)`` turns of a wheel of diameter ``D_R = 2 E_d / (E_d + 1) D_a`` or
``D_L = 2 / (E_d + 1) D_a``, and the robot converts the counts with ``pi D_n``:

    s_R' = s_R D_n / D_R = g_R s_R,    g_R = k (E_d + 1) / (2 E_d)
    s_L' = s_L D_n / D_L = g_L s_L,    g_L = k (E_d + 1) / 2
    s'   = (s_R' + s_L') / 2,          dtheta' = (s_R' - s_L') / b

reported, like the command, as the chord ``(s' cos(dtheta'/2), s' sin(dtheta'/2), dtheta')``.
In closed form, with ``g_R + g_L = k (E_d + 1)^2 / (2 E_d)`` and ``g_R - g_L = k (1 - E_d^2) / (2 E_d)``:

    s'      = [(g_R + g_L) s + (g_R - g_L) E_b b dtheta / 2] / 2
    dtheta' = [(g_R - g_L) s + (g_R + g_L) E_b b dtheta / 2] / b

so a straight drive of ``S`` reads ``k S (E_d + 1)^2 / (4 E_d)`` long (the second factor is
1 + O((E_d - 1)^2)) and turns by ``k S (1 - E_d^2) / (2 b E_d)`` (to the right when the right
wheel is the larger, E_d > 1); a turn in place of ``dtheta`` reads
``k E_b (E_d + 1)^2 / (4 E_d) dtheta``. ``b`` only enters through E_d. The errors are unknown to
the robot: :meth:`Odometry.metadata` gives localizers the alphas only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from core.motion import odometry_noise_std, sample_odometry
from core.schema import check, check_ranges
from envs.sensors.base import SensorBase, SensorConfig, register_sensor
from envs.state import WorldState

if TYPE_CHECKING:
    from envs.config import WorldConfig


#: the range each systematic ratio may take: at most a quarter off (real robots: a fraction of a percent)
RATIO_RANGE = (0.8, 1.25)
#: the range of the nominal wheelbase, metres
WHEELBASE_RANGE_M = (0.05, 5.0)


@dataclass(frozen=True)
class OdometryConfig(SensorConfig):
    """Probabilistic Robotics odometry noise (variances per squared unit) and Borenstein's
    systematic errors (see the module docstring; the defaults are error-free)."""

    key: str = "odometry"
    alpha1: float = 0.01  # rad^2 / rad^2   rotation noise from rotation
    alpha2: float = 0.01  # rad^2 / m^2     rotation noise from translation
    alpha3: float = 0.01  # m^2 / m^2       translation noise from translation
    alpha4: float = 0.01  # m^2 / rad^2     translation noise from rotation
    wheelbase_m: float = 0.4  # the nominal wheelbase b the robot's kinematics assume
    wheel_diameter_ratio: float = 1.0  # E_d = D_R / D_L, the actual right over left wheel diameter
    wheelbase_ratio: float = 1.0  # E_b, the actual over the nominal wheelbase
    distance_scale: float = 1.0  # metres reported per metre driven (nominal over actual mean diameter)

    def __post_init__(self) -> None:
        check_ranges(self, "odometry", non_negative=("alpha1", "alpha2", "alpha3", "alpha4"))
        lo, hi = WHEELBASE_RANGE_M
        check(
            math.isfinite(self.wheelbase_m) and lo <= self.wheelbase_m <= hi,
            f"odometry.wheelbase_m must be in [{lo}, {hi}] m, got {self.wheelbase_m}",
        )
        lo, hi = RATIO_RANGE
        for name in ("wheel_diameter_ratio", "wheelbase_ratio", "distance_scale"):
            value = getattr(self, name)
            check(
                math.isfinite(value) and lo <= value <= hi,
                f"odometry.{name} must be in [{lo}, {hi}] (1 is error-free), got {value}",
            )

    @property
    def alphas(self) -> tuple[float, float, float, float]:
        return (self.alpha1, self.alpha2, self.alpha3, self.alpha4)

    @property
    def systematic(self) -> bool:
        """Whether any systematic error is set (otherwise the reading is the command plus noise)."""
        return (self.wheel_diameter_ratio, self.wheelbase_ratio, self.distance_scale) != (1.0, 1.0, 1.0)

    @property
    def wheel_gains(self) -> tuple[float, float]:
        """``(g_R, g_L)``: the distance each wheel's encoder reports per metre that wheel rolls."""
        e_d, k = self.wheel_diameter_ratio, self.distance_scale
        return k * (e_d + 1.0) / (2.0 * e_d), k * (e_d + 1.0) / 2.0


@register_sensor("odometry", OdometryConfig)
class Odometry(SensorBase):
    """Noisy increment ``(dx, dy, dtheta)`` of the commanded motion since the last step, in the previous frame.

    ``command(delta)`` is called by the env with the exact commanded increment before the
    physics step. With systematic errors set it is first turned into what the wheel encoders
    and the nominal kinematics make of it (module docstring); the noise follows the alpha
    model (:mod:`core.motion`). Without them the reading is the command plus noise,
    from the alpha model alone (the systematic errors' code is skipped).
    """

    def __init__(self, name: str, config: OdometryConfig, world: WorldConfig, state: WorldState) -> None:
        self.name = name
        self.key = config.key
        self.config = config
        self.alphas = np.asarray(config.alphas)
        # bounds: the largest commanded step (as the systematic errors read it), widened for
        # noise; clipping at 8 noise sds of the largest step is never reached in practice and
        # keeps the space finite
        trans = world.robot.max_speed_mps * world.dt_s
        rot = world.robot.max_turn_rate_rps * world.dt_s
        self._gains = config.wheel_gains
        self._half_track = 0.5 * config.wheelbase_ratio * config.wheelbase_m
        self._systematic = config.systematic  # (a property of the config: read once, not every step)
        if self._systematic:
            # the readings are linear in (s, dtheta): the largest is at a corner of the command box
            g_sum, g_diff = self._gains[0] + self._gains[1], abs(self._gains[0] - self._gains[1])
            trans, rot = (
                0.5 * (g_sum * trans + g_diff * self._half_track * rot),
                (g_diff * trans + g_sum * self._half_track * rot) / config.wheelbase_m,
            )
        std = odometry_noise_std([trans * math.cos(rot / 2), trans * math.sin(rot / 2), rot], self.alphas)
        self.bound = np.array([trans + 8 * std[1] + 1e-3, trans + 8 * std[1] + 1e-3, rot + 16 * std[0] + 1e-3], dtype=np.float32)
        self._low = -self.bound
        self._delta = np.zeros(3)

    def space(self) -> spaces.Box:
        return spaces.Box(-self.bound, self.bound, dtype=np.float32)

    def reset(self) -> None:
        self._delta = np.zeros(3)

    def command(self, delta: NDArray[np.float64], rng: np.random.Generator) -> None:
        """Record the commanded increment ``(3,)`` of this step, as dead reckoning measures it
        (systematic errors, when set) and corrupted by the alpha model."""
        if self._systematic:
            delta = self.measured(delta)
        self._delta = sample_odometry(rng, delta, self.alphas)

    def measured(self, delta: NDArray[np.float64]) -> NDArray[np.float64]:
        """The noise-free reading of a commanded chord increment ``(3,)`` under the systematic errors.

        The signed length ``s`` is the increment's component along its chord direction
        ``dtheta / 2`` (the env's commands have no other).
        """
        dx, dy, dth = float(delta[0]), float(delta[1]), float(delta[2])
        s = dx * math.cos(0.5 * dth) + dy * math.sin(0.5 * dth)
        s_right = self._gains[0] * (s + dth * self._half_track)
        s_left = self._gains[1] * (s - dth * self._half_track)
        s_read = 0.5 * (s_right + s_left)
        dth_read = (s_right - s_left) / self.config.wheelbase_m
        return np.array([s_read * math.cos(0.5 * dth_read), s_read * math.sin(0.5 * dth_read), dth_read])

    def observe(self, state: WorldState, rng: np.random.Generator) -> tuple[NDArray[np.float32], dict[str, Any]]:
        reading = self._delta.astype(np.float32)  # a fresh array each step, clipped in place (np.clip costs 2x)
        np.maximum(reading, self._low, out=reading)
        np.minimum(reading, self.bound, out=reading)
        return reading, {}

    def metadata(self) -> dict[str, Any]:
        """The alphas only: the systematic errors are the robot's unknown bias, not a model it has."""
        return {"alphas": self.config.alphas}
