"""``corridor_follower``: the ceiling-target paper's navigation (Fukaya et al., section 4).

The paper's robot starts under a target that fixes its pose; between targets it keeps to the
corridor centre with its ultrasonic side ranges; it stops under each target and corrects its
pose; when the measured rotation is beyond a threshold (image distortion makes such fixes
poor) it moves under the target centre and measures again; after the last target it stops.
:class:`CorridorFollower` does that from the observation alone (the localizer's estimate
behind :class:`~envs.wrappers.LocalizationObservation` and the ``sonar`` ring), and also
slows down, waits and steers around when people block the way.

**Frame.** The corridor world's: x across the corridor (centre line x = 0, walls at
``+-wall_distance_m``), y along it; the robot drives toward +y, heading pi/2. Its left is
-x: the sonar sensor nearest +90 deg from the heading (index 4 of 16) looks at the wall at
x = -``wall_distance_m``, the one nearest -90 deg (index 12) at the other.

**State machine** (:attr:`CorridorFollower.phase`):

- ``drive``: toward the next target along +y at ``cruise`` (action units), slower within
  ``slow_down_m`` of it (never below ``creep`` while moving, but the last step sized to land
  on it), until ``|dy| <= arrive_tolerance_m`` by the estimate; a target behind (a fix moved
  the estimate past it) is backed up to. The heading is held at pi/2 from the estimate's
  heading, bent by up to ``max_steer_rad`` toward the lateral goal (the centre line, or the
  side offset while passing someone). The lateral position comes from the side sonars
  (:meth:`CorridorFollower.lateral_position`): both sides are trusted when they add up to
  the corridor's width (within ``side_tolerance_m``); else one side is when its reading is
  within ``side_tolerance_m`` of what the wall should read (a shorter reading is a person or
  a group, a longer one a door recess or an alcove); with no side trusted the last sonar x,
  moved on by the estimate's change of x since, is used.
- ``settle``: stand still for ``settle_s`` (the image is then sharp and the localizer fixes on
  every frame with a target in view), then read the estimate. Off the centre line by more
  than ``lateral_tolerance_m`` (still passing someone; x from a fix, else from the side
  sonars), the robot first moves under the centre (a side-step: ``turn`` to face across,
  ``sidestep``, ``turn`` back, ``drive``).
  The localizer has fixed on the target when its position spread is at most
  ``fix_spread_m`` (a fix sets it to the fix's own spread; dead reckoning grows it with
  travel). With a fix: a heading more than ``rotation_threshold_rad`` from pi/2 is
  re-measured after a turn in place back to pi/2 and a creep under the target centre
  (``turn``, ``drive``), a ``|dy|`` beyond ``stop_tolerance_m`` after a creep (``drive``);
  at most ``max_remeasures`` re-measurements per target, then the stop is done as it is.
  Without a fix for ``fix_timeout_s`` since the robot first stopped there, the target is
  missed and the robot drives on.
- ``turn``: turn in place until the estimate's heading is within ``heading_tolerance_rad`` of
  the heading wanted; ``sidestep``: drive across the corridor to the target's x by the
  estimate (a fix's x, else the distance measured at the stop by the estimate's change of
  x), waiting, then giving up after ``patience_s``, when someone stands there.
- ``done``: after the last target, stand still (the corridor world then terminates).

Targets more than ``behind_m`` behind the first estimate are skipped. Without a valid
estimate before a first fix the robot stands still.

**Lost** (ours): when the localizer stops claiming a pose after it had one (it
noticed that it was carried away, :attr:`localizers.ceiling_target.CeilingTargetLocalizer.lost`),
the robot searches with the sonar alone (``search``): it drives on at ``cruise``, slowed as
before a person, steering toward the middle between the side sonars when both see a wall, and
turns in place toward the freer side while the straight-ahead sonar reads under
``clearance_m``, until it reads ``slow_range_m`` (a wall across its way, the corridor's end,
or people). Along the corridor it passes under a target, whose colours fix the pose again; the
state machine then starts over from that pose, with the targets ahead of it.

**People.** The front sonars are those within ``front_halfwidth_rad`` of the heading (15, 0
and 1 of 16). When the one straight ahead reads closer than ``slow_range_m`` the robot slows
down (a constant deceleration down to ``creep`` at ``clearance_m``). The way is blocked when
that one reads closer than ``clearance_m`` or a diagonal one (15, 1) closer than
``diagonal_clearance_m``: a diagonal cone spans 11 to 34 deg off the heading, so a person in it
at that range may be in the robot's path, while one standing by the wall beside the drive line
reads farther. Blocked, the robot stops and waits (until the reading is ``hysteresis_m``
beyond the clearance again). After ``patience_s`` of waiting it steers around toward the freer
side (the side whose forward-diagonal sonars, 1-3 or 13-15 of 16, read farther; within
``hysteresis_m`` of each other: the side whose wall sonar reads farther, then the right): the
lateral goal moves ``avoid_offset_m`` off the centre line to that side and the heading may
bend by up to ``avoid_steer_rad``; it turns in place toward that heading and drives on at
``avoid_speed`` once the way ahead is clear (turned toward a wall, every front sonar is then
held to ``diagonal_clearance_m``), back to the centre line once it is ``pass_m`` beyond where
the front sonar read the obstacle. Blocked again while passing, it waits and then tries the
other side.

What it did is in attributes the reproduction reads: :attr:`~CorridorFollower.remeasures`,
:attr:`~CorridorFollower.missed` and :attr:`~CorridorFollower.stops` (one
:class:`TargetStop` per target, from the estimate only).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from agents.policies.base import FixedPolicy, Observation, check_command, read_estimate, sonar_cones
from core.geometry import ring_directions, wrap_angle
from core.schema import is_int, is_real

#: the heading along the corridor (+y)
ALONG_RAD = math.pi / 2
#: the states of :attr:`CorridorFollower.phase`
PHASES = ("drive", "settle", "turn", "sidestep", "search", "done")


@dataclass(frozen=True)
class CorridorTarget:
    """A ceiling target on the map: its name and centre (world frame, metres)."""

    name: str
    x_m: float
    y_m: float


@dataclass(frozen=True)
class TargetStop:
    """How the stop at one target ended (what the policy knew: the estimate, never the truth).

    Attributes:
        target: the target's name.
        measurements: times the robot stood still there and read an estimate with a fix.
        remeasures: times it moved again to measure again (a side-step under the centre, a
            turn back to pi/2, a creep under the target).
        fixed: False when the target was missed (no fix within ``fix_timeout_s``).
        estimate: the estimated pose ``(x, y, theta)`` when the stop ended.
        step: the policy step (calls since reset) at which it ended.
    """

    target: str
    measurements: int
    remeasures: int
    fixed: bool
    estimate: tuple[float, float, float]
    step: int


@dataclass(frozen=True)
class CorridorParams:
    """The settings of :class:`CorridorFollower` (module docstring), each with its default.

    Speeds are in action units (fractions of the env's limits), distances in metres, times in
    seconds, angles in radians.

    Attributes:
        dt_s: the env's time step (timers count calls).
        max_speed_mps, max_turn_rate_rps: the env's limits (the last step before a target is
            sized to land on it; turn commands are computed in rad/s).
        cruise: forward speed between targets (0.8: 0.4 m/s on a Nomad 200).
        creep: the slowest forward speed while moving (under a target, behind a person).
        slow_down_m: the speed falls linearly to ``creep`` over this distance before a target.
        stop_tolerance_m: ``|dy|`` under which a measurement finds the robot under a target (1 cm).
        arrive_tolerance_m: ``|dy|`` at which driving to a target ends and the robot stops (2 mm;
            the last step is shortened to land on the target, so it does not step over it).
        settle_s: standing time before the estimate is read (0.5 s).
        fix_spread_m: a position spread at most this means the localizer has fixed (4 cm:
            above one fix's sqrt(2) x 2 cm of the shipped ``ceiling_target``, below the 5-6 cm
            its dead reckoning grows to over one 7 m spacing).
        fix_timeout_s: without a fix for this long after stopping, the target is missed (3 s).
        rotation_threshold_rad: a heading farther than this from pi/2 is re-measured (3 deg).
        heading_tolerance_rad: a turn in place ends this close to its heading (1 deg: wider
            than the steps a fix's heading takes while the view turns, so a turn cannot dither).
        lateral_tolerance_m: a measured ``|dx|`` beyond this is re-measured after a side-step
            (5 cm: a robot that reached the target still passing someone, or not yet back).
        max_remeasures: re-measurements per target at most (3; then the stop ends as it is).
        behind_m: targets more than this behind the first estimate are skipped (0.5 m).
        wall_distance_m: the corridor walls' distance from the centre line (1.0 m).
        side_tolerance_m: a side sonar is trusted within this of the expected wall range (6 cm;
            a door recess is 25 cm deep).
        lateral_gain_rad_per_m: heading bend per metre of lateral error (1.5).
        max_steer_rad: the largest bend of the heading away from pi/2 while driving (0.25).
        heading_gain: turn rate per radian of heading error (2 per s).
        sonar_cone_rad: the width of a sonar's cone (22.5 deg; ``make_policy`` reads the world's).
        front_halfwidth_rad: sonar sensors within this of the heading watch the way ahead (0.4:
            15, 0 and 1 of 16).
        clearance_m: the straight-ahead sonar reading closer than this blocks the way (1 m from
            the robot's centre: room to turn and pass a person standing there).
        diagonal_clearance_m: a diagonal front sonar reading closer than this blocks the way
            (0.45 m).
        slow_range_m: the straight-ahead reading under which the robot slows down (2 m).
        hysteresis_m: a blocked way is clear again this far beyond the clearances (10 cm).
        patience_s: waiting time before steering around (3 s).
        avoid_offset_m: the lateral goal's distance from the centre line while passing (0.6 m).
        avoid_steer_rad: the largest bend of the heading while passing (35 deg).
        avoid_gain_rad_per_m: the heading bend per metre of lateral error while passing (4: the
            bend stays at ``avoid_steer_rad`` until the robot is within 15 cm of the side goal).
        avoid_speed: the forward speed while passing (0.4; no slowing for the wall that the
            straight-ahead sonar then sees).
        turn_first_rad: with the heading farther than this from the one wanted, the robot turns
            in place before it drives (0.2: the start and the end of a pass).
        pass_m: the centre line is taken up again this far beyond the obstacle's reading (1 m).

    Raises:
        ValueError: for a bad value, naming it.
    """

    dt_s: float = 0.05
    max_speed_mps: float = 0.5
    max_turn_rate_rps: float = 0.8
    cruise: float = 0.8
    creep: float = 0.05
    slow_down_m: float = 1.0
    stop_tolerance_m: float = 0.01
    arrive_tolerance_m: float = 0.002
    settle_s: float = 0.5
    fix_spread_m: float = 0.04
    fix_timeout_s: float = 3.0
    rotation_threshold_rad: float = math.radians(3.0)
    heading_tolerance_rad: float = math.radians(1.0)
    lateral_tolerance_m: float = 0.05
    max_remeasures: int = 3
    behind_m: float = 0.5
    wall_distance_m: float = 1.0
    side_tolerance_m: float = 0.06
    lateral_gain_rad_per_m: float = 1.5
    max_steer_rad: float = 0.25
    heading_gain: float = 2.0
    sonar_cone_rad: float = 2 * math.pi / 16
    front_halfwidth_rad: float = 0.4
    clearance_m: float = 1.0
    diagonal_clearance_m: float = 0.45
    slow_range_m: float = 2.0
    hysteresis_m: float = 0.1
    patience_s: float = 3.0
    avoid_offset_m: float = 0.6
    avoid_steer_rad: float = math.radians(35.0)
    avoid_gain_rad_per_m: float = 4.0
    avoid_speed: float = 0.4
    turn_first_rad: float = 0.2
    pass_m: float = 1.0

    #: the settings that may be 0
    _MAY_BE_ZERO: ClassVar[tuple[str, ...]] = ("settle_s", "patience_s", "behind_m")

    def __post_init__(self) -> None:
        where = "CorridorFollower"
        for f in fields(self):
            value = getattr(self, f.name)
            number = is_real(value, finite=True)
            if f.name == "max_remeasures":
                if not (is_int(value) and value >= 0):
                    raise ValueError(f"{where} max_remeasures must be a whole number >= 0, got {value!r}")
            elif f.name in self._MAY_BE_ZERO:
                if not (number and value >= 0):
                    raise ValueError(f"{where} {f.name} must be a number >= 0, got {value!r}")
            elif not (number and value > 0):
                raise ValueError(f"{where} {f.name} must be a number > 0, got {value!r}")
        for name in ("cruise", "creep", "avoid_speed"):
            check_command(f"{where} {name}", getattr(self, name))
        order = [  # (smaller, larger, whether they may be equal, what would happen else)
            ("creep", "cruise", True, "the robot would creep faster than it cruises"),
            ("arrive_tolerance_m", "stop_tolerance_m", True, "an arrival could measure as not under the target"),
            ("heading_tolerance_rad", "rotation_threshold_rad", False, "a turn could end outside the threshold"),
            ("clearance_m", "slow_range_m", False, "there is no room to slow down"),
            ("avoid_offset_m", "wall_distance_m", False, "the side goal is in the wall"),
        ]
        for small, large, equal_ok, why in order:
            a, b = getattr(self, small), getattr(self, large)
            if a > b or (a == b and not equal_ok):
                relation = "at most" if equal_ok else "below"
                raise ValueError(f"{where} needs {small} ({a}) {relation} {large} ({b}): else {why}")


class CorridorFollower(FixedPolicy):
    """The paper's stop-and-correct corridor navigation (module docstring).

    Args:
        action_space: the env's ``Box(-1, 1, (2,))``.
        targets: the ceiling targets (:class:`CorridorTarget` or mappings with ``name``,
            ``x_m``, ``y_m``), visited in order of ``y``.
        bounds_m: the field ``(xmin, ymin, xmax, ymax)`` the estimate is normalized to.
        seed: unused (the policy is deterministic); kept for the common signature.
        **params: the settings, by name (:class:`CorridorParams`; each has a default).

    Attributes:
        params: the :class:`CorridorParams` in use.

    Raises:
        ValueError: for an unknown setting, a bad value or a bad target list, naming it.
    """

    needs_sensor = "sonar"  # its side ranges keep it centred; its front ranges watch for people
    needs_feature = "ceiling"  # it drives from target to target of the ceiling's map

    #: the observation key of the sonar ring it reads (besides the estimate)
    sonar_key: ClassVar[str] = "sonar"

    def __init__(
        self,
        action_space: spaces.Box,
        targets: Sequence[CorridorTarget | Mapping[str, Any]],
        bounds_m: tuple[float, float, float, float],
        seed: int | None = None,
        **params: Any,
    ) -> None:
        super().__init__(action_space, seed)
        known = {f.name for f in fields(CorridorParams)}
        unknown = sorted(set(params) - known)
        if unknown:
            raise ValueError(
                f"CorridorFollower has no setting {', '.join(map(repr, unknown))} (settings: {', '.join(sorted(known))})"
            )
        self.params = CorridorParams(**params)
        self.targets = self._checked_targets(targets)
        if len(bounds_m) != 4:
            raise ValueError(f"CorridorFollower bounds_m must be (xmin, ymin, xmax, ymax), got {bounds_m!r}")
        xmin, ymin, xmax, ymax = (float(b) for b in bounds_m)
        self.bounds_m = (xmin, ymin, xmax, ymax)
        self._diag = math.hypot(xmax - xmin, ymax - ymin)
        self._ring: dict[str, Any] | None = None
        self.reset()

    @staticmethod
    def _checked_targets(targets: Sequence[CorridorTarget | Mapping[str, Any]]) -> tuple[CorridorTarget, ...]:
        out = []
        for i, t in enumerate(targets):
            if isinstance(t, CorridorTarget):
                out.append(t)
                continue
            try:
                out.append(CorridorTarget(str(t["name"]), float(t["x_m"]), float(t["y_m"])))
            except (KeyError, TypeError, ValueError):
                raise ValueError(f"CorridorFollower target {i} needs a name, x_m and y_m, got {t!r}") from None
        if not out:
            raise ValueError("CorridorFollower needs at least one ceiling target")
        if not all(math.isfinite(t.x_m) and math.isfinite(t.y_m) for t in out):
            raise ValueError(f"CorridorFollower targets must have finite positions, got {out!r}")
        return tuple(sorted(out, key=lambda t: t.y_m))

    # ------------------------------------------------------------------ episode state
    def reset(self, seed: int | None = None) -> None:
        """Restart the state machine (a new episode)."""
        super().reset(seed)
        #: one of :data:`PHASES`
        self.phase = "drive"
        #: index into :attr:`targets` of the target being driven to (None before the first estimate)
        self.target_index: int | None = None
        #: re-measurements over the episode, and targets missed
        self.remeasures = 0
        self.missed = 0
        #: one record per target whose stop has ended, in order
        self.stops: list[TargetStop] = []
        #: calls since reset
        self.steps = 0
        self._phase_s = 0.0  # time in the current settle
        self._stopped_s: float | None = None  # time since the robot first stopped at this target
        self._measures = 0  # at this target
        self._remeasured_here = 0
        self._blocked_s = 0.0
        self._blocked = False
        self._avoid_side = 0  # +1: passing on the left (-x), -1: on the right (+x), 0: on the centre line
        self._pass_y = math.inf
        self._turn_to, self._after_turn = ALONG_RAD, "drive"  # the turn in place: to which heading, then what
        self._sidestep_to = 0.0  # the side-step's goal x in the estimate's frame
        self._sonar_x: tuple[float, float] | None = None  # the last sonar x and the estimate's x then
        self._search_turn = 0  # searching: +1 turning left, -1 right, 0 driving

    @property
    def target(self) -> CorridorTarget | None:
        """The target being driven to or measured at (None before the first estimate or when done)."""
        if self.target_index is None or self.target_index >= len(self.targets):
            return None
        return self.targets[self.target_index]

    # ------------------------------------------------------------------ sensing
    def _sonar(self, observation: Observation) -> NDArray[np.float64]:
        if self.sonar_key not in observation:
            raise KeyError(
                f"{type(self).__name__} keeps to the corridor centre with a sonar ring: this env's observation has no "
                f"{self.sonar_key!r} (keys: {sorted(observation)}); give the robot one (env kwarg sonar={{}})"
            )
        ranges = np.asarray(observation[self.sonar_key], dtype=np.float64).reshape(-1)
        if self._ring is None or self._ring["count"] != ranges.size:
            directions = ring_directions(ranges.size)
            front = np.flatnonzero(sonar_cones(ranges.size, 0.0, self.params.front_halfwidth_rad))
            ahead = int(np.argmin(np.abs(wrap_angle(directions))))
            left = int(np.argmin(np.abs(wrap_angle(directions - math.pi / 2))))
            right = int(np.argmin(np.abs(wrap_angle(directions + math.pi / 2))))
            if ranges.size < 4 or front.size == 0:
                raise ValueError(
                    f"{type(self).__name__} needs a sonar ring with sensors ahead and to both sides, got {ranges.size} "
                    f"sensor(s) with none within front_halfwidth_rad {self.params.front_halfwidth_rad} of the heading"
                )
            diagonal_left = np.flatnonzero(sonar_cones(ranges.size, math.pi / 4, math.pi / 4 - 1e-9))
            diagonal_right = np.flatnonzero(sonar_cones(ranges.size, -math.pi / 4, math.pi / 4 - 1e-9))
            self._ring = {
                "count": ranges.size,
                "front": front,
                "ahead": ahead,
                "diagonal": front[front != ahead],
                "left": left,
                "right": right,
                "diagonal_left": diagonal_left,
                "diagonal_right": diagonal_right,
            }
        return ranges

    def lateral_position(self, ranges: NDArray[np.float64], pose: NDArray[np.float64]) -> float:
        """The robot's x from the side sonars (the module docstring's trust rule).

        A side sonar reads a wall at distance ``d`` as ``d / cos(max(0, |delta| - cone / 2))``
        with the heading ``delta`` off the corridor (its nearest ray is the most nearly
        perpendicular one). A single side is checked against the last sonar x moved on by the
        estimate's change of x since (the estimate's own x drifts with dead reckoning; its
        change over a few metres hardly does), and only while the heading is within half a cone
        of the corridor (turned farther, a recess's edge reads like a nearer wall); with no side
        trusted that reference is the answer.
        """
        assert self._ring is not None
        w = self.params.wall_distance_m
        x_estimate = float(pose[0])
        slant = math.cos(max(0.0, abs(float(wrap_angle(pose[2] - ALONG_RAD))) - 0.5 * self.params.sonar_cone_rad))
        left, right = slant * float(ranges[self._ring["left"]]), slant * float(ranges[self._ring["right"]])
        reference = x_estimate if self._sonar_x is None else self._sonar_x[0] + x_estimate - self._sonar_x[1]
        if abs(left + right - 2 * w) <= self.params.side_tolerance_m:
            x = 0.5 * (left - right)  # both walls: x = left - w = w - right
        elif slant < 1.0:  # turned farther than half a cone (passing): one side alone is not trusted
            return reference
        else:
            off_left = abs(left - (w + reference))
            off_right = abs(right - (w - reference))
            if min(off_left, off_right) > self.params.side_tolerance_m:
                return reference
            x = left - w if off_left <= off_right else w - right
        self._sonar_x = (x, x_estimate)
        return x

    def _fixed(self, observation: Observation) -> bool:
        return float(observation["estimate_spread"][0]) * self._diag <= self.params.fix_spread_m

    # ------------------------------------------------------------------ acting
    def _act(self, observation: Observation) -> NDArray[np.float64]:
        pose = read_estimate(observation, self.bounds_m, type(self).__name__)
        ranges = self._sonar(observation)
        self.steps += 1
        if pose is None and self.target_index is not None and self.phase != "done":
            self.phase = "search"  # the localizer had a pose and gave it up: it knows it is lost
            return self._search(ranges)
        if pose is None or self.phase == "done":
            return np.zeros(2)
        if self.phase == "search":  # found again: start over from the new pose
            self._start_over()
        if self.target_index is None:
            ahead = [i for i, t in enumerate(self.targets) if t.y_m >= pose[1] - self.params.behind_m]
            if not ahead:
                self.phase = "done"
                return np.zeros(2)
            self.target_index = ahead[0]
        target = self.targets[self.target_index]
        if self.phase == "turn":
            error = float(wrap_angle(self._turn_to - pose[2]))
            if abs(error) > self.params.heading_tolerance_rad:
                return np.array([0.0, self._turn_command(error, minimum=True)])
            self.phase = self._after_turn
            self._blocked_s = 0.0
        if self.phase == "sidestep":
            # to the target's x by a fix, else by the estimate's change of x since the stop
            goal = target.x_m if self._fixed(observation) else self._sidestep_to
            action = self._sidestep(pose, ranges, goal - pose[0])
            if action is not None:
                return action
            self._turn(ALONG_RAD, then="drive")
            return np.zeros(2)
        dy = target.y_m - pose[1]
        if self.phase == "drive":
            if abs(dy) > self.params.arrive_tolerance_m:
                return self._drive(pose, ranges, dy)
            self.phase, self._phase_s = "settle", 0.0
            self._stopped_s = 0.0 if self._stopped_s is None else self._stopped_s
            self._blocked_s = 0.0
            return np.zeros(2)
        # settle: stand, then read the estimate
        assert self._stopped_s is not None
        self._phase_s += self.params.dt_s
        self._stopped_s += self.params.dt_s
        if self._phase_s < self.params.settle_s - 1e-9:
            return np.zeros(2)
        fixed = self._fixed(observation)
        # x: a fix's, else the side sonars' (a dead-reckoned x drifts with the heading error)
        dx = target.x_m - (pose[0] if fixed else self.lateral_position(ranges, pose))
        if abs(dx) > self.params.lateral_tolerance_m and self._remeasured_here < self.params.max_remeasures:
            # off the centre line (still passing someone): move under the centre first, fix or not
            self._remeasure()
            self._sidestep_to = pose[0] + dx  # in the estimate's frame
            self._turn(0.0 if dx > 0 else math.pi, then="sidestep")
            return np.zeros(2)
        if not fixed:
            if self._stopped_s >= self.params.fix_timeout_s - 1e-9:
                self.missed += 1
                self._end_stop(pose, fixed=False)
            return np.zeros(2)
        self._measures += 1
        if self._remeasured_here < self.params.max_remeasures:
            if abs(float(wrap_angle(pose[2] - ALONG_RAD))) > self.params.rotation_threshold_rad:
                self._remeasure()
                self._turn(ALONG_RAD, then="drive")
                return np.zeros(2)
            if abs(dy) > self.params.stop_tolerance_m:
                self._remeasure()
                self.phase = "drive"
                return np.zeros(2)
        self._end_stop(pose, fixed=True)
        return np.zeros(2)

    def _start_over(self) -> None:
        """After a search: forget the stop in progress; the targets ahead of the next estimate follow."""
        self.target_index, self.phase = None, "drive"
        self._stopped_s, self._measures, self._remeasured_here = None, 0, 0
        self._avoid_side, self._pass_y, self._blocked_s, self._blocked = 0, math.inf, 0.0, False
        self._sonar_x, self._search_turn = None, 0

    def _search(self, ranges: NDArray[np.float64]) -> NDArray[np.float64]:
        """One step of the search without a pose (module docstring, **Lost**): the sonar alone."""
        assert self._ring is not None
        r, p = self._ring, self.params
        ahead = float(ranges[r["ahead"]])
        if self._search_turn or ahead < p.clearance_m:
            if ahead >= p.slow_range_m:
                self._search_turn = 0
            else:
                self._search_turn = self._search_turn or self._freer_side(ranges)
                return np.array([0.0, self._search_turn * p.cruise])
        left, right = float(ranges[r["left"]]), float(ranges[r["right"]])
        bend = 0.0
        if left + right <= 2 * p.wall_distance_m + p.slow_range_m / 4:  # both sides see a wall: keep to the middle
            bend = float(np.clip(p.lateral_gain_rad_per_m * 0.5 * (left - right), -p.max_steer_rad, p.max_steer_rad))
        return np.array([self._yield_speed(ahead), self._turn_command(bend)])

    def _turn(self, heading_rad: float, then: str) -> None:
        self.phase, self._turn_to, self._after_turn = "turn", heading_rad, then

    def _sidestep(self, pose: NDArray[np.float64], ranges: NDArray[np.float64], dx: float) -> NDArray[np.float64] | None:
        """One step of driving across the corridor toward ``dx`` (the heading turned to +-x); None when done."""
        assert self._ring is not None
        if abs(dx) <= self.params.arrive_tolerance_m:
            return None
        turn = self._turn_command(float(wrap_angle(self._turn_to - pose[2])))
        if float(np.min(ranges[self._ring["front"]])) < self.params.diagonal_clearance_m:
            self._blocked_s += self.params.dt_s
            # someone stands there: after patience_s measure from where the robot is
            return None if self._blocked_s >= self.params.patience_s - 1e-9 else np.array([0.0, turn])
        return np.array([self._approach_speed(abs(dx)), turn])

    def _approach_speed(self, distance_m: float) -> float:
        """Forward speed (action units) ``distance_m`` before a stop: ``cruise``, slower within
        ``slow_down_m`` (not below ``creep``), the last step sized to land on the spot."""
        speed = max(self.params.creep, self.params.cruise * min(1.0, distance_m / self.params.slow_down_m))
        return min(speed, distance_m / (self.params.max_speed_mps * self.params.dt_s))

    def _yield_speed(self, ahead_m: float) -> float:
        """Forward speed (action units) with the straight-ahead sonar reading ``ahead_m``: ``cruise``
        beyond ``slow_range_m``, then a constant deceleration toward ``clearance_m`` (v ~ sqrt of the
        distance left), not below ``creep``."""
        p = self.params
        if ahead_m >= p.slow_range_m:
            return float(p.cruise)
        left = max(0.0, ahead_m - p.clearance_m) / (p.slow_range_m - p.clearance_m)
        return float(max(p.creep, p.cruise * math.sqrt(left)))

    def _remeasure(self) -> None:
        self.remeasures += 1
        self._remeasured_here += 1

    def _end_stop(self, pose: NDArray[np.float64], fixed: bool) -> None:
        assert self.target_index is not None
        self.stops.append(
            TargetStop(
                self.targets[self.target_index].name,
                self._measures,
                self._remeasured_here,
                fixed,
                (float(pose[0]), float(pose[1]), float(pose[2])),
                self.steps,
            )
        )
        self.target_index += 1
        self._stopped_s, self._measures, self._remeasured_here = None, 0, 0
        self._avoid_side, self._pass_y = 0, math.inf
        self.phase = "done" if self.target_index >= len(self.targets) else "drive"

    def _turn_command(self, error_rad: float, minimum: bool = False) -> float:
        """Action units turning toward ``error_rad``; with ``minimum`` at least the rate that
        closes the heading tolerance within a step or two (a turn in place never stalls)."""
        rate = self.params.heading_gain * error_rad
        if minimum:
            floor = min(abs(error_rad), self.params.heading_tolerance_rad) / self.params.dt_s
            rate = math.copysign(max(abs(rate), floor), error_rad)
        return float(np.clip(rate / self.params.max_turn_rate_rps, -1.0, 1.0))

    def _drive(self, pose: NDArray[np.float64], ranges: NDArray[np.float64], dy: float) -> NDArray[np.float64]:
        """One step toward the target ``dy`` ahead (negative: behind), keeping to the lateral goal."""
        assert self._ring is not None
        speed = self._approach_speed(abs(dy))
        if dy < 0:  # overshot (a fix moved the estimate past the target): back up, heading held
            return np.array([-speed, self._turn_command(float(wrap_angle(ALONG_RAD - pose[2])))])
        if self._avoid_side and pose[1] > self._pass_y:
            self._avoid_side, self._pass_y = 0, math.inf  # past the obstacle: back to the centre line
        x_goal = -self._avoid_side * self.params.avoid_offset_m
        steer, gain = (
            (self.params.avoid_steer_rad, self.params.avoid_gain_rad_per_m)
            if self._avoid_side
            else (self.params.max_steer_rad, self.params.lateral_gain_rad_per_m)
        )
        bend = float(np.clip(gain * (x_goal - self.lateral_position(ranges, pose)), -steer, steer))
        heading_error = float(wrap_angle(ALONG_RAD - bend - pose[2]))
        turn = self._turn_command(heading_error)
        ahead = float(ranges[self._ring["ahead"]])
        if abs(heading_error) > self.params.turn_first_rad:
            self._blocked = False
            return np.array([0.0, turn])  # turn toward the heading first (the start and the end of a pass)
        if self.blocked(ranges):
            self._blocked_s += self.params.dt_s
            if self._blocked_s >= self.params.patience_s - 1e-9:
                self._blocked_s = 0.0
                self._avoid_side = -self._avoid_side if self._avoid_side else self._freer_side(ranges)
                self._pass_y = pose[1] + ahead + self.params.pass_m
            return np.array([0.0, turn if self._avoid_side else 0.0])  # waiting; turned toward the side when passing
        self._blocked_s = 0.0
        if self._avoid_side:
            speed = min(speed, self.params.avoid_speed)
        elif ahead < self.params.slow_range_m:
            speed = min(speed, self._yield_speed(ahead))
        return np.array([speed, turn])

    def blocked(self, ranges: NDArray[np.float64]) -> bool:
        """Whether the front sonars find the way blocked (module docstring), with hysteresis."""
        assert self._ring is not None
        margin = self.params.hysteresis_m if self._blocked else 0.0
        diagonal = ranges[self._ring["diagonal"]]
        # while passing the robot is turned toward the wall it passes along: every front sonar
        # is held to the diagonal clearance (the wall ahead would block the straight-ahead one)
        ahead_clearance = self.params.diagonal_clearance_m if self._avoid_side else self.params.clearance_m
        self._blocked = bool(
            ranges[self._ring["ahead"]] < ahead_clearance + margin
            or (diagonal.size and float(np.min(diagonal)) < self.params.diagonal_clearance_m + margin)
        )
        return self._blocked

    def _freer_side(self, ranges: NDArray[np.float64]) -> int:
        """+1 (left) or -1 (right): the side whose forward-diagonal sonars read farther; within
        ``hysteresis_m`` of each other, the side whose wall sonar reads farther; then the right."""
        assert self._ring is not None
        r = self._ring
        left, right = float(np.min(ranges[r["diagonal_left"]])), float(np.min(ranges[r["diagonal_right"]]))
        if abs(left - right) <= self.params.hysteresis_m:
            left, right = float(ranges[r["left"]]), float(ranges[r["right"]])
            if abs(left - right) <= self.params.hysteresis_m:
                return -1
        return 1 if left > right else -1
