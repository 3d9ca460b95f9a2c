"""The 3D scene for the page's three.js view: the MuJoCo model's shapes, and the poses that move.

:func:`scene_geometry` lists every shape the inspection camera would see (geom groups 0 and 3: the
mock-up with its anomalies, the arm, the ISEE, the lamp) relative to its body, and every body's pose;
:func:`moving_poses` gives, many times a second, the poses of the bodies that move (the arm's links, the
door, the lamp), plus the two proximity beams and the lamp's spot.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rsi.control.proximity_law import OUT_OF_RANGE_LABEL
from rsi.errors import InputError
from rsi.sim.arm import RANGEFINDER_CUTOFF_M
from rsi.sim.solar_simulator import lamp_pose
from rsi.sim.world import World
from rsi.web.teleop import TeleopStep

# MuJoCo geom types the page draws (mjtGeom values); planes and meshes are left out (the floor is a grid),
# but for a box drawn as a grid mesh (rsi.sim.scene.MESHED_BOX_M): MuJoCo gives a mesh geom its bounding
# box's half sizes in its own frame, which for a box is the box
SHAPES = {2: "sphere", 3: "capsule", 4: "ellipsoid", 5: "cylinder", 6: "box"}
_MESH = 7
VISIBLE_GROUPS = (0, 3)  # seed §4: the mock-up as inspected (group 4 holds the pristine parts it replaced)


def _round(values: Any, digits: int = 5) -> list[float]:
    return [round(float(x), digits) for x in np.asarray(values).ravel()]


def _moving_bodies(world: World) -> list[int]:
    """Bodies with a joint or a mocap, and everything they carry."""
    model = world.model
    moves = np.zeros(model.nbody, dtype=bool)
    for body in range(1, model.nbody):
        parent = int(model.body_parentid[body])
        moves[body] = bool(model.body_jntnum[body] > 0 or model.body_mocapid[body] >= 0 or moves[parent])
    return [int(b) for b in np.flatnonzero(moves)]


def _check_world(world: object) -> None:
    if not isinstance(world, World) or world.arm is None:
        raise InputError(
            f"world must be the console's World (loaded with arm=True); got {type(world).__name__}."
        )


def _check_bodies(bodies: object, count: int) -> None:
    if not isinstance(bodies, (list, tuple)) or not all(
        isinstance(b, int) and not isinstance(b, bool) and 0 <= b < count for b in bodies
    ):
        raise InputError(f"bodies must be a list of body ids in [0, {count}) (scene_geometry's 'moving').")


def scene_geometry(world: World) -> dict[str, Any]:
    """Every drawn shape (type, size, colour, body, pose in its body) and every body's world pose."""
    _check_world(world)
    model, data = world.model, world.data
    boxes = {part.name for part in world.mockup.parts if part.shape == "box"}
    shapes = []
    for geom in range(model.ngeom):
        kind = SHAPES.get(int(model.geom_type[geom]))
        if int(model.geom_type[geom]) == _MESH and model.geom(geom).name.removesuffix("_swapped") in boxes:
            kind = "box"  # a dented box shows as the box: its crater is a millimetre flaw
        if kind is None or int(model.geom_group[geom]) not in VISIBLE_GROUPS:
            continue
        rgba = model.geom_rgba[geom]
        if model.geom_matid[geom] >= 0:
            rgba = model.mat_rgba[model.geom_matid[geom]]
        if rgba[3] <= 0:
            continue
        shapes.append(
            {
                "type": kind,
                "size": _round(model.geom_size[geom]),
                "rgba": _round(rgba, 3),
                "body": int(model.geom_bodyid[geom]),
                "pos": _round(model.geom_pos[geom]),
                "quat": _round(model.geom_quat[geom]),
            }
        )
    return {
        "shapes": shapes,
        "bodies": {
            str(b): {"pos": _round(data.xpos[b]), "quat": _round(data.xquat[b])} for b in range(model.nbody)
        },
        "moving": _moving_bodies(world),
        "cutoff_m": RANGEFINDER_CUTOFF_M,
    }


def moving_poses(world: World, step: TeleopStep | None, bodies: list[int]) -> dict[str, Any]:
    """Poses of the moving bodies, the two beams (start, axis, length, region) and the lamp and its spot."""
    _check_world(world)
    if step is not None and not isinstance(step, TeleopStep):
        raise InputError(f"step must be None or the console's last TeleopStep; got {type(step).__name__}.")
    _check_bodies(bodies, world.model.nbody)
    data = world.data
    arm = world.arm
    axis = arm.tool_pose()[1][:, 2]
    beams = []
    for index, site in enumerate(("range_left", "range_right")):
        distance = RANGEFINDER_CUTOFF_M if step is None else float(step.distances_m[index])
        region = OUT_OF_RANGE_LABEL if step is None else step.regions[index]
        beams.append(
            {
                "start": _round(arm.site_position_m(site)),
                "axis": _round(axis),
                "length_m": round(RANGEFINDER_CUTOFF_M if math.isinf(distance) else distance, 4),
                "region": region,
            }
        )
    task = world.lamp_task
    lamp_position = lamp_pose(world.lamp).position_world_m
    spot = np.asarray(task.spot_world_m)
    spot_radius_m = float(np.linalg.norm(spot - lamp_position)) * math.tan(task.beam_angle_rad)
    return {
        "bodies": {str(b): [*_round(data.xpos[b]), *_round(data.xquat[b])] for b in bodies},
        "beams": beams,
        "lamp": {
            "position": _round(lamp_position),
            "spot": _round(spot),
            "spot_radius_m": round(spot_radius_m, 4),
            "on": world.lamp_on,
        },
    }


__all__ = ["moving_poses", "scene_geometry"]
