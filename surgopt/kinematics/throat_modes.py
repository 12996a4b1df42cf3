"""The suture task modes of the throat-arm kernel, in a module without numba (configs import it)."""
from __future__ import annotations

from enum import IntEnum


class SutureMode(IntEnum):
    """How the gripper follows the suture (``throat.suture_target``); configs use the lower-case names.

    spin: the gripper spins about its own axis at a fixed point (a needle held off the axis traces
    the arc); orbit_parallel: the platform circles in its own x-y plane, orientation fixed;
    orbit_tangent: it circles in its y-z plane with its axis kept tangent to the path.
    """

    SPIN = 0
    ORBIT_PARALLEL = 1
    ORBIT_TANGENT = 2

    @property
    def config_name(self) -> str:
        return self.name.lower()


#: The config names, in kernel order.
MODE_NAMES = tuple(m.config_name for m in SutureMode)
