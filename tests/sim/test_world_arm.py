"""The arm on its rail in the truss world (issue 4 item 2): one MuJoCo model, rangefinders that see the
mock-up, frames from the ISEE camera (bad input here too)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sim.arm import HOME_Q, RANGEFINDER_RECESS_M, WORLD_ARM_PREFIX, Arm, arm_spec, attach_arm
from rsi.sim.mockup import truss_mockup
from rsi.sim.render import SceneRenderer
from rsi.sim.solar_simulator import inverse_kinematics
from rsi.sim.world import AMBIENT_RENDER_LEVEL, ARM_HOME_TOOL_TIP_M, LAB_LAMP_LUX, World, load

SEED = 3
SMALL = (120, 160)
DT_S = 1.0 / 44.0  # seed §3.1: the 44 Hz loop
ORU_A_X_M = 0.38  # between ORU A's Kapton circles: both rays land on the bare face (A_fill)


def _front_y_m(part_name: str) -> float:
    """Front (most -y) face of an axis-aligned mock-up box, from the mock-up's geometry."""
    part = next(p for p in truss_mockup().parts if p.name == part_name)
    return float(part.pos[1] - part.size[1])


@pytest.fixture(scope="module")
def arm_world() -> Iterator[World]:
    built = load("truss", seed=SEED, arm=True)
    yield built
    built.close()


def _tool_at_oru_a(world: World) -> Arm:
    arm = world.arm
    q = HOME_Q.copy()
    q[0] = ORU_A_X_M - ARM_HOME_TOOL_TIP_M[0]  # the rail carries the home pose along the truss
    arm.reset(q)
    return arm


def test_world_with_the_arm_builds_deterministically(arm_world: World) -> None:
    twin = load("truss", seed=SEED, arm=True)
    try:
        for name in ("body_pos", "body_quat", "geom_pos", "geom_size", "jnt_range", "actuator_gainprm"):
            assert np.array_equal(getattr(twin.model, name), getattr(arm_world.model, name)), name
        arm_world.arm.reset()
        first = arm_world.render_from_tool(size=SMALL, truth=False)
        second = twin.render_from_tool(size=SMALL, truth=False)
        assert np.array_equal(first.frame.raw, second.frame.raw)
    finally:
        twin.close()
    # one model: the mock-up's door and lamp, and the arm's joints, sensors and actuators
    model = arm_world.model
    assert model.joint("A_door_hinge").id >= 0 and model.body("solar_lamp").id >= 0
    assert model.nu == 10 and model.sensor(f"{WORLD_ARM_PREFIX}range_left").id >= 0
    plain = load("truss", seed=SEED)
    try:
        assert plain.model.nu == 0 and plain.model.nbody < model.nbody
    finally:
        plain.close()


def test_home_pose_faces_the_truss_at_the_vistas_standoff(arm_world: World) -> None:
    arm = arm_world.arm
    arm.reset()
    tip, rotation = arm.tool_pose()
    np.testing.assert_allclose(tip, ARM_HOME_TOOL_TIP_M, atol=1e-9)
    np.testing.assert_allclose(rotation[:, 2], [0.0, 1.0, 0.0], atol=1e-12)  # tool axis toward the truss
    np.testing.assert_allclose(rotation[:, 0], [1.0, 0.0, 0.0], atol=1e-12)  # sensor baseline along the rail
    # the B tank (capsule r = 70 mm along x, in front of its plate) is ahead: the sensors read its front
    tank = next(p for p in truss_mockup().parts if p.name == "B_tank")
    tank_front_y = tank.pos[1] - tank.size[0]
    np.testing.assert_allclose(
        arm.rangefinder_distances_m(), tank_front_y - tip[1] + RANGEFINDER_RECESS_M, atol=1e-3
    )


def test_rangefinders_read_the_oru_a_face_and_follow_a_commanded_approach(arm_world: World) -> None:
    arm = _tool_at_oru_a(arm_world)
    face_y = _front_y_m("A_fill")
    tip = arm.tool_pose()[0]
    assert tip[0] == pytest.approx(ORU_A_X_M, abs=1e-9)
    tip_to_face = face_y - tip[1]
    assert tip_to_face == pytest.approx(0.39, abs=1e-9)  # 0.5 m from the sensor faces
    before = arm.rangefinder_distances_m()
    np.testing.assert_allclose(before - RANGEFINDER_RECESS_M, tip_to_face, atol=1e-3)
    # 5 cm/s along the tool axis for one second at 44 Hz: the readings fall by 5 cm
    for _ in range(44):
        arm.step_velocity([0.0, 0.0, 0.05], DT_S, frame="tool")
    after = arm.rangefinder_distances_m()
    np.testing.assert_allclose(before - after, 0.05, atol=1e-4)
    np.testing.assert_allclose(after - RANGEFINDER_RECESS_M, face_y - arm.tool_pose()[0][1], atol=1e-3)
    # the world's own state is not touched by the arm's reset
    arm_world.set_door(0.5)
    arm.reset()
    assert arm_world.door_angle_rad == 0.5
    arm_world.set_door(0.0)


def test_frame_from_the_isee_shows_the_plate_and_no_rangefinder_ray(arm_world: World) -> None:
    arm = _tool_at_oru_a(arm_world)
    arm_world.set_lamp(inverse_kinematics((ORU_A_X_M, -0.47, 1.2), intensity_lux=LAB_LAMP_LUX, rail_m=2.0))
    size = (240, 320)
    view = arm_world.render_from_tool(size=size, stereo=True)
    assert view.vista == "tool" and view.pose_error_px == (0.0, 0.0)
    np.testing.assert_allclose(view.pose.position_m, arm.camera_pose("left")[0])
    # the plate fills the middle of the frame at the sensors' 0.5 m (within the Kapton's 0.5 mm)
    middle = (slice(size[0] // 3, 2 * size[0] // 3), slice(size[1] // 3, 2 * size[1] // 3))
    assert float(np.mean(view.frame.raw[middle])) > 40.0
    assert view.depth_m is not None
    assert abs(float(np.median(view.depth_m[middle])) - 0.5) < 0.002
    assert abs(arm_world.readouts()["standoff_m"] - 0.5) < 0.002
    assert view.stereo is not None and not np.array_equal(view.stereo[0].raw, view.stereo[1].raw)
    # with MuJoCo's default the rays would cross this very view; the world's frames leave them out
    camera = arm.camera_name("left")
    sun = tuple(int(arm_world.model.light(n).id) for n in ("solar_lamp", "room"))
    drawn = SceneRenderer(arm_world.model, *size, show_rangefinders=True)
    plain = SceneRenderer(arm_world.model, *size)
    try:
        level = AMBIENT_RENDER_LEVEL  # the level the world renders its sun at
        with_rays = drawn.luminance(arm_world.data, camera, state="inspection", lights=sun, level=level)
        without = plain.luminance(arm_world.data, camera, state="inspection", lights=sun, level=level)
    finally:
        drawn.close()
        plain.close()
    ray = with_rays != without
    assert ray.sum() > 100
    np.testing.assert_array_equal(view.basis["sun"], without)


def test_bad_input_names_the_argument() -> None:
    with pytest.raises(InputError, match="arm must be True or False"):
        load("truss", seed=SEED, arm="yes")  # type: ignore[arg-type]
    plain = load("truss", seed=SEED)
    try:
        with pytest.raises(InputError, match="this world has no arm"):
            _ = plain.arm
        with pytest.raises(InputError, match="this world has no arm"):
            plain.render_from_tool(size=SMALL)
        with pytest.raises(InputError, match="model has no arm element named 'arm_rail'"):
            Arm.bind(plain.model, plain.data)
    finally:
        plain.close()
    standalone = Arm()
    with pytest.raises(InputError, match="prefix must be a str"):
        Arm.bind(standalone.model, standalone.data, prefix=None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="mode"):
        Arm.bind(standalone.model, standalone.data, prefix="", mode="fast")
    with pytest.raises(InputError, match="camera"):
        standalone.camera_pose("middle")
    with pytest.raises(InputError, match="home_tool_tip_m must be 3 finite numbers"):
        attach_arm(arm_spec(), home_tool_tip_m=(0.0, np.nan, 1.0))


def test_an_arm_bound_to_a_standalone_model_moves_like_the_standalone_arm() -> None:
    standalone = Arm()
    bound = Arm.bind(standalone.model, standalone.data, prefix="")
    np.testing.assert_array_equal(bound.tool_pose()[0], standalone.tool_pose()[0])
    step = bound.step_velocity([0.0, 0.0, 0.05], DT_S, frame="tool")
    twin = Arm()
    np.testing.assert_array_equal(
        twin.step_velocity([0.0, 0.0, 0.05], DT_S, frame="tool").joint_velocity, step.joint_velocity
    )


def test_the_arm_in_its_own_frame_counts_as_not_inspected(arm_world: World) -> None:
    arm = _tool_at_oru_a(arm_world)
    size = (120, 160)
    view = arm_world.render_from_tool(size=size)
    renderer = SceneRenderer(arm_world.model, *size)
    try:
        _, segments = renderer.depth_and_segments(arm_world.data, arm.camera_name("left"), state="inspection")
    finally:
        renderer.close()
    model = arm_world.model
    arm_geoms = [
        g
        for g in range(model.ngeom)
        if model.body(int(model.geom_bodyid[g])).name.startswith(WORLD_ARM_PREFIX)
    ]
    on_arm = np.isin(segments, arm_geoms)
    assert view.truss_mask is not None
    assert on_arm.any()  # the gripper reaches into the ISEE's own view
    assert view.truss_mask[on_arm].all()


# ------------------------------------------------------------------ the jaws in the ISEE's own frame


def _rows_of(mask: np.ndarray) -> float:
    return float(np.nonzero(mask)[0].mean())


def test_the_jaws_footprint_moves_with_the_opening_and_not_with_the_pose(arm_world: World) -> None:
    """Seed §3.1: the jaws are rigid with the cameras but for their opening, which slides them across the
    frame's right-hand side (closed: the bottom, wide open: the top)."""
    arm = _tool_at_oru_a(arm_world)
    size = (120, 160)
    half, closed, wide = (
        arm_world.own_body_footprint(size, jaw_opening_m=opening) for opening in (0.04, 0.0, 0.08)
    )
    for footprint in (half, closed, wide):
        assert 0.02 < footprint.mean() < 0.2
        assert np.nonzero(footprint)[1].min() > size[1] // 2  # beside the left camera: the right half
    assert _rows_of(closed) > _rows_of(half) > _rows_of(wide)
    assert not (closed & wide).any()
    assert arm.jaw_opening_m == pytest.approx(0.04)  # put back
    q = arm.joint_positions
    q[0] += 0.3
    q[7] += 0.5
    arm.reset(q)
    np.testing.assert_array_equal(arm_world.own_body_footprint(size), half)


def test_the_jaws_open_where_they_are_told_and_the_frame_shows_them_there(arm_world: World) -> None:
    arm = _tool_at_oru_a(arm_world)
    size = (120, 160)
    try:
        arm.set_jaw_opening(0.0)
        assert arm.jaw_opening_m == pytest.approx(0.0)
        assert arm.joint_positions[0] == pytest.approx(ORU_A_X_M - ARM_HOME_TOOL_TIP_M[0])  # the joints stay
        view = arm_world.render_from_tool(size=size)
        footprint = arm_world.own_body_footprint(size)
        assert view.truss_mask is not None
        assert view.truss_mask[footprint].mean() > 0.95  # the frame's own jaws, where the footprint says
    finally:
        arm.set_jaw_opening(0.04)


def test_bad_jaw_input_names_the_argument(arm_world: World) -> None:
    with pytest.raises(InputError, match="opening_m"):
        arm_world.arm.set_jaw_opening(0.1)
    with pytest.raises(InputError, match="jaw_opening_m"):
        arm_world.own_body_footprint((120, 160), jaw_opening_m=-0.01)
    with pytest.raises(InputError, match="size"):
        arm_world.own_body_footprint((4, 4))
    plain = load("truss", seed=SEED)
    try:
        assert not plain.has_arm and arm_world.has_arm
        with pytest.raises(InputError, match="this world has no arm"):
            plain.own_body_footprint((120, 160))
    finally:
        plain.close()
