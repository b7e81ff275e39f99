"""What the reproductions' reports say about a world, read from its configs (one wording for every paper)."""

from __future__ import annotations

from envs.config import RobotConfig
from envs.sensors import OdometryConfig


def odometry_text(odometry: OdometryConfig, robot: RobotConfig) -> str:
    """A world's odometry errors: the alpha noise, the systematic errors and the wheel slip."""
    alphas = ", ".join(f"{a:g}" for a in odometry.alphas)
    if odometry.systematic:
        systematic = (f"systematic errors set (wheel diameter ratio {odometry.wheel_diameter_ratio:g}, wheelbase ratio "
                      f"{odometry.wheelbase_ratio:g}, distance scale {odometry.distance_scale:g})")  # fmt: skip
    else:
        systematic = "no systematic error (wheel diameters, wheelbase and distance scale nominal)"
    if robot.slips:
        slip = (f"wheel slip ({100 * robot.slip_per_accel_s2:g} % of the motion lost per m/s^2 of commanded acceleration, "
                f"{100 * robot.slip_per_angular_accel_s2:g} % per rad/s^2 of turn-rate change, {100 * robot.slip_in_contact:g} % "
                f"in contact, random slips with probability {robot.slip_probability:g})")  # fmt: skip
    else:
        slip = "no wheel slip"
    return f"the alpha model's zero-mean noise (alphas {alphas}), {systematic} and {slip}"
