"""Overrides that take the shipped worlds' systematic odometry errors out (tests of the exact model)."""

#: error-free systematic odometry (the soccer worlds and the room ship a bias)
EXACT = {"wheel_diameter_ratio": 1.0, "wheelbase_ratio": 1.0, "distance_scale": 1.0}
