"""What a car can do: the physical limits the motion model and the offset tracker share.

Both ask the same question of a step, "could a car have moved like that?",
and must answer it with the same numbers: the motion model to cap its turn
rate and to decide which fixes it may re-acquire on, the offset tracker to
explain a braking car's missed step and to tell a wrong predicted velocity
from a fault. Spelled once, here.
"""

from __future__ import annotations

__all__ = ["CAR_MAX_ACCEL", "CAR_MAX_SPEED"]

#: m/s²: the most a car accelerates, sideways or along (about 0.6 g).
CAR_MAX_ACCEL = 6.0

#: m/s: the fastest a car drives. A run of fixes that moves faster is no track.
CAR_MAX_SPEED = 70.0
