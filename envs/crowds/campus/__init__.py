"""A university campus: pedestrians on a walkway network, groups by the doors, cars on the road.

One crowd holds every moving obstacle of an outdoor campus, so that ``crowd_size`` (this
crowd's ``count``) is the number of pedestrians and cars together; ``car_share`` of it are
cars (rounded half up), ``group_share`` of the pedestrians stand in conversation groups near
the buildings' doors and the rest walk. Parked cars (``parked``) come on top of ``count``, at
every count but 0: ``crowd_size=0`` is the empty campus, as it means no crowd in every world.

**Members**, in body order: walkers, standing people (group by group), moving cars, parked cars.

**Walkers** follow a network of walkways (:class:`WalkwayConfig`: polylines with a width;
walkways whose end points lie within ``join_m`` of each other meet there). Each walks along
its walkway at its own desired speed (drawn per walker from N(``walk_speed_mps``), clipped to
``walk_speed_range_mps``), keeping to the right of the centre line by its own share of the
free half width (``keep_right``), heading for a point ``lookahead_m`` ahead on its lane. At a
walkway's end it goes on along another walkway meeting there (one drawn at random) or, at a
dead end, turns back. A social force (Helbing and Molnar 1995, with the bodies' surfaces'
distance and a cutoff at ``cutoff_ranges`` times the range, beyond which exp(-d/B) is below
5e-5 of its contact value) keeps walkers off each other, the robot (stronger:
``robot_repulsion_gain``) and the cars' boxes (``car_repulsion_gain``); walls and buildings
are not in it (walkers stay on their walkways; a collision is the physics' job). They give way
to the robot (:func:`envs.crowds.steering.give_way`, as the crowded room's queue heads do) and
do not step into a moving car's path (the car's box stretched over ``yield_s`` of its travel):
one about to wait at the kerb; one already in the road walks on, clearing it.

**Standing people** stand in rings (2-4 people, ``group_sizes`` in turn) facing their group's
centre, ``door_distance_m`` out from a door of a building (the world's ``buildings`` features,
:meth:`~envs.features.scenery.BuildingConfig.door_points`) and ``door_side_m`` to one side of
it, so that the door stays free; they fidget around their spots and walk back when pushed
(as the corridor crowd's groups). Without doors, groups stand beside the walkways.

**Cars** drive along directed lanes (:class:`LaneConfig`, polylines) at ``car_speed_mps``,
steering toward the lane point ``car_lookahead_m`` ahead, accelerating at ``car_accel_mps2``
and braking along the curve ``v = sqrt(2 car_brake_mps2 room)`` (at most
``car_max_brake_mps2``) so as to stop ``car_gap_m`` behind the car ahead and
``car_stop_gap_m`` before a pedestrian or the robot in the corridor ahead of them (the car's
width plus ``car_watch_margin_m`` either side; a pedestrian or robot that will be in it within
``car_watch_s`` at its present velocity counts too). A car within 1 m of its lane's end leaves
the campus (through a gate in the fence) and comes back in at the start of a lane drawn at
random among those whose way in is free, where it could stop ``car_gap_m`` short of anything
at its speed: a teleport (``Commands.teleports``) that turns it along the new lane
(``Commands.headings``) and keeps its speed, so the number of cars stays ``count``'s share and
traffic flows through. While no way in is free it brakes and waits at the end. Between
teleports the world turns cars to face their travel.

**Parked cars** (``parked``: ``(x_m, y_m, heading_rad)`` spots) never move: a parked car the
robot pushes is drawn back to its spot.

The package: :mod:`.config` (the config dataclasses), :mod:`.polylines` (walkways and lanes
packed for the kernels), :mod:`.walking` (the walkers' kernel), :mod:`.traffic` (the cars'
kernel and their boxes' geometry) and :mod:`.crowd` (the registered crowd: placement and the
step's commands).
"""

from __future__ import annotations

from envs.crowds.campus.config import CampusConfig, LaneConfig, WalkwayConfig
from envs.crowds.campus.crowd import CampusCrowd

__all__ = ["CampusConfig", "CampusCrowd", "LaneConfig", "WalkwayConfig"]
