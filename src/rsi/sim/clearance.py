"""How close the arm comes to the mock-up: MuJoCo's exact geom distances, searched branch and bound.

The mission's transits trace it at every sample of the 44 Hz loop (seed §3.1: the proximity law keeps the
arm off the structure; this is the simulator's truth to check it against). :func:`is_arm_geom` also tells
a ray cast which hits are the arm itself.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.render import import_mujoco

if TYPE_CHECKING:
    from rsi.sim.world import World

CLEARANCE_CAP_M = 2.0
"""Clearances beyond this are reported as this (the search stops there)."""


def is_arm_geom(model: Any, geom: int, prefix: str) -> bool:
    """Whether geom `geom` of `model` belongs to the arm whose names start with `prefix`."""
    mujoco = import_mujoco()
    v.instance_of(model, "model", mujoco.MjModel, none_allowed=False)
    geom = v.positive_int(geom, "geom", minimum=0, maximum=model.ngeom - 1)
    if not isinstance(prefix, str):
        raise InputError(f"prefix must be a str (the arm's name prefix); got {type(prefix).__name__}.")
    body = str(model.body(int(model.geom_bodyid[geom])).name)
    return body.startswith(prefix) or str(model.geom(geom).name).startswith(prefix)


class ArmClearance:
    """Smallest distance between the arm's geoms and everything else (MuJoCo's ``mj_geomDistance``).

    Branch and bound on bounding spheres: pairs are measured nearest bound first until the next bound is
    farther than the best distance found, so a step costs a few exact distances, not all ~2000. Call it
    for the world as it stands; it reads the state and changes nothing.

    Parameters
    ----------
    world : World
        From ``rsi.sim.load(..., arm=True)`` (InputError otherwise, from ``world.arm``).
    """

    def __init__(self, world: World) -> None:
        v.record_named(world, "world", "World")  # by name: rsi.sim.world imports this module
        model = world.model
        prefix = world.arm.prefix
        arm = [g for g in range(model.ngeom) if is_arm_geom(model, g, prefix)]
        self._world = world
        self._mujoco = import_mujoco()
        self._arm = np.array(arm)
        self._other = np.array([g for g in range(model.ngeom) if g not in set(arm)])
        self._radius = np.asarray(model.geom_rbound, dtype=np.float64)

    def __call__(self) -> float:
        """The clearance now, metres, capped at :data:`CLEARANCE_CAP_M`."""
        world = self._world
        centres = np.asarray(world.data.geom_xpos)
        gap = np.linalg.norm(centres[self._arm][:, None, :] - centres[self._other][None, :, :], axis=-1)
        bound = gap - self._radius[self._arm][:, None] - self._radius[self._other][None, :]
        best = CLEARANCE_CAP_M
        for flat in np.argsort(bound, axis=None):
            if bound.flat[flat] >= best:
                break
            i, j = divmod(int(flat), self._other.size)
            distance = self._mujoco.mj_geomDistance(
                world.model, world.data, int(self._arm[i]), int(self._other[j]), best, None
            )
            best = min(best, float(distance))
        return best


__all__ = ["CLEARANCE_CAP_M", "ArmClearance", "is_arm_geom"]
