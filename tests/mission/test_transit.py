"""The ISEE carried between vista points by the arm under the proximity law, and a mission's visits (issue 5
item 1; seed §3.1, §4.1): arrival, guard, law, reach, the tour, determinism, bad input."""

from __future__ import annotations

import math
import os
import threading
from collections.abc import Iterator

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.control.blending import proximity_term
from rsi.errors import InputError
from rsi.mission import PLAN, MissionSettings, PlanPoint, plan_vistas, run_mission
from rsi.mission.sun import SUN_DIRECTION_TOLERANCE_RAD
from rsi.mission.tour import Tour
from rsi.mission.transit import (
    ARRIVAL_TOLERANCE_M,
    ARRIVAL_TOLERANCE_RAD,
    GUARD_LAW,
    PHASE_TIMEOUT_S,
    Transit,
    approach_law,
    transit,
)
from rsi.mission.viewing import reach, viewing_pose
from rsi.sim import orbit as orbits
from rsi.sim.world import World, load

SEED = 0
TINY = (64, 80)
# the hand plan completed from the CAD model: the arm's views of the truss by name (A_door, B_tank, fill_00)
COMPLETED_HAND_PLAN = MissionSettings(plan="hand+cad")
REACHABLE = {"A_door", "A_door_open", "A_kapton", "B_tank", "D_tubing"}
PERIOD_S = orbits.orbital_period_s()


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    built = load("truss", seed=SEED, arm=True)
    plan_vistas(built, COMPLETED_HAND_PLAN)
    yield built
    built.close()


@pytest.fixture(scope="module")
def tour_transits(world: World) -> dict[str, Transit]:
    """One transit to each plan point in the plan's order, as a pass makes them (door opened for its view)."""
    moved = {}
    for index, point in enumerate(PLAN):
        world.set_door(point.door_angle_rad)
        moved[point.name] = transit(world, point.vista, rng=index, label=point.name)
    world.set_door(0.0)
    return moved


# ------------------------------------------------------------------------------------------- reach


def test_the_arm_reaches_the_front_views_and_not_the_panel_from_above(
    tour_transits: dict[str, Transit],
) -> None:
    reached = {name for name, moved in tour_transits.items() if moved.reached}
    assert reached == REACHABLE
    for name in ("C_panel_west_front", "C_panel_west_back", "C_panel_east_front", "C_panel_east_back"):
        moved = tour_transits[name]
        # the camera 0.35 m above the panel top (z = 1.93 m) is ~1.1 m beyond the wrist's reach from the rail
        assert not moved.reach.reachable and 0.9 < moved.reach.shortfall_m < 1.3
        assert moved.time_s.size == 0 and moved.pose is None and math.isnan(moved.position_error_m)
    for name in REACHABLE:
        assert tour_transits[name].reach.shortfall_m < -0.2  # 20 cm or more inside the reach


def test_each_reachable_pose_is_reached_within_tolerance(tour_transits: dict[str, Transit]) -> None:
    for name in REACHABLE:
        moved = tour_transits[name]
        assert moved.pose is not None
        assert moved.position_error_m < ARRIVAL_TOLERANCE_M
        assert moved.position_error_m < 2e-3  # the rangefinders' noise along the axis, measured ~1 mm
        assert moved.orientation_error_rad < ARRIVAL_TOLERANCE_RAD
        # the camera looks along the vista's forward, the image's up the vista's up
        assert np.allclose(moved.camera_rotation, moved.pose.camera_rotation, atol=ARRIVAL_TOLERANCE_RAD)
        assert set(moved.phase.tolist()) == {"retract", "transfer", "approach"}


def test_the_approach_servos_where_both_rays_expect_one_surface(tour_transits: dict[str, Transit]) -> None:
    for name in REACHABLE:
        moved = tour_transits[name]
        assert moved.approach_law is not None
        agree = float(np.ptp(moved.expected_range_m)) <= 5e-3
        assert moved.servo == agree
        if agree:  # the law's standoff is what the rangefinders read at the pose
            assert moved.approach_law.standoff_m == pytest.approx(moved.expected_range_m.mean(), abs=1e-12)
            assert np.allclose(moved.range_true_m[-1], moved.expected_range_m, atol=3e-3)
    # D: one ray on the tubing, the other on the plate behind it
    assert not tour_transits["D_tubing"].servo


# ------------------------------------------------------------------------------------------- guard


def test_the_guard_keeps_every_range_and_clearance_safe(tour_transits: dict[str, Transit]) -> None:
    for moved in tour_transits.values():
        if not moved.time_s.size:
            continue
        law = moved.approach_law
        assert law is not None
        finite = moved.range_true_m[np.isfinite(moved.range_true_m)]
        assert finite.min() > GUARD_LAW.min_distance_m
        assert finite.min() > law.avoidance_start_m  # never into region B of the law in force
        assert moved.min_clearance_m > 0.2  # nothing of the arm came within 20 cm of the mock-up
        assert np.all(moved.clearance_m > 0.0)


def test_the_commanded_speed_is_the_generator_plus_the_law(tour_transits: dict[str, Transit]) -> None:
    for moved in tour_transits.values():
        if not moved.time_s.size:
            continue
        assert moved.approach_law is not None
        approach = moved.phase == "approach"
        for index in range(moved.time_s.size):
            if approach[index]:
                law, mode = moved.approach_law, "servo" if moved.servo else "avoidance"
            else:
                law, mode = GUARD_LAW, "avoidance"
            expected, _, _ = proximity_term(moved.range_reading_m[index], law, mode=mode)
            assert moved.proximity_m_s[index] == float(expected)
            assert moved.command_m_s[index] == pytest.approx(
                moved.trajectory_m_s[index] + moved.proximity_m_s[index], abs=1e-15
            )
        # the approach's feed-forward stays within +-Vjs, so region C cannot be overridden (seed §3.1)
        assert np.all(np.abs(moved.trajectory_m_s[approach]) <= moved.approach_law.joystick_speed_m_s + 1e-6)
        assert np.all(np.isnan(moved.axis_error_m[~approach]))
        assert np.isfinite(moved.axis_error_m[approach]).all()


def test_the_law_stops_the_arm_short_of_a_surface_nearer_than_planned(world: World) -> None:
    # the law believes the surface is 0.1 m farther than it is: the generator pushes to the pose at full
    # +Vjs, region C of the law holds the arm off (seed §3.1: the avoidance cannot be overridden)
    law = approach_law(0.60)
    moved = transit(world, "A_kapton", rng=5, law=law)
    approach = moved.phase == "approach"
    assert not moved.reached
    assert moved.range_true_m[approach].min() > law.hold_distance_m - 3e-3
    assert moved.pose is not None and moved.position_error_m > 0.04
    assert np.all(moved.command_m_s[approach][-20:] < 0.02)  # at rest, not creeping on


def test_a_transfer_the_guard_holds_short_of_a_close_staging_point_ends_there(world: World) -> None:
    # a CAD-plan standoff (0.25 m): the staging point 0.2 m back on the axis lies inside GUARD_LAW's range,
    # whose avoidance holds the arm off it; the transfer ends there (it waited out its 12 s timeout) and the
    # approach arrives as from any staging point
    from rsi.sim.mockup import vista

    base = world.vista("B_tank")
    if "B_tank_close" not in world.vistas:
        world.add_vista(vista("B_tank_close", base.target_m, tuple(-np.asarray(base.forward)), base.up, 0.25))
    moved = transit(world, "B_tank_close", rng=7, label="B_tank_close")
    transfer = moved.phase == "transfer"
    assert moved.reached and moved.position_error_m < ARRIVAL_TOLERANCE_M
    assert 0 < transfer.sum() < PHASE_TIMEOUT_S * PROXIMITY_SAMPLE_RATE_HZ / 4


def test_same_seed_same_visits_frames_and_suns() -> None:
    runs = []
    for _ in range(2):
        built = load("truss", seed=SEED, arm=True)
        tour = Tour(built, seed=SEED, size=TINY)
        tour.start_pass("inspection", 500.0)
        frames = [tour.visit(name, name, state="inspection").frames[0].raw for name in ("A_kapton", "B_tank")]
        runs.append((frames, tour.transits, tour.suns))
        built.close()
    (first_frames, first, first_suns), (second_frames, second, second_suns) = runs
    assert all(np.array_equal(a, b) for a, b in zip(first_frames, second_frames, strict=True))
    assert first_suns == second_suns
    for one, two in zip(first, second, strict=True):
        for name in ("time_s", "range_true_m", "range_reading_m", "command_m_s", "clearance_m", "camera_m"):
            assert np.array_equal(getattr(one, name), getattr(two, name)), name
        assert np.array_equal(one.phase, two.phase)


def test_a_second_look_leaves_every_later_visit_as_it_was() -> None:
    """Each visit draws from its own stream (pass, plan point, its how-many-th visit there): a second look
    at one point takes nothing from the next point's viewpoint error or noise (free camera, no orbit: the
    same light at every visit)."""
    frames = []
    for looks in (1, 2):
        built = load("truss", seed=SEED)
        tour = Tour(built, seed=SEED, size=TINY, arm=False, orbit=False)
        tour.start_pass("inspection", 500.0)
        for _ in range(looks):
            tour.visit("A_kapton", "A_kapton", state="inspection", truth=False)
        taken = tour.visit("B_tank", "B_tank", state="inspection", truth=False)
        frames.append((taken.frames[0].raw, tour.views[-1][1].pose_error_px, tour.views[1][1].pose_error_px))
        built.close()
    (one, error_one, _), (two, error_two, second_look) = frames
    assert np.array_equal(one, two) and error_one == error_two
    assert second_look != tour.views[0][1].pose_error_px  # the second look is a visit of its own


# -------------------------------------------------------------------------------------------- tour


def test_a_visit_takes_the_frame_from_where_the_arm_holds_the_camera(world: World) -> None:
    tour = Tour(world, seed=SEED, size=TINY)
    tour.start_pass("reference", 400.0)
    taken = tour.visit("A_kapton", "A_kapton", state="reference", truth=False)
    label, view = tour.views[-1]
    moved = tour.transits[-1]
    assert moved.reached and taken.vista == view.vista == label == "A_kapton"
    assert np.allclose(view.pose.position_m, moved.camera_m, atol=1e-12)
    # the repeatability error, drawn as World.render draws it ("lab": 1-2 px), plus the arm's own miss
    assert 0.8 < math.hypot(*view.pose_error_px) < 2.2
    # the robot believes the commanded pose: the repeatability error (flexure, seed §2.3) is not in it
    unknown_px = (
        np.linalg.norm(taken.believed_pose.position_m - view.pose.position_m) * view.pose.focal_px / 0.5
    )
    assert 0.5 < unknown_px < 2.5
    sun = tour.suns[-1]
    assert sun.time_s == pytest.approx(400.0 + moved.duration_s)
    assert tour.clock_s == pytest.approx(sun.time_s + 1 / 30)
    # out of reach: the free camera of World.render, the shortfall recorded
    panel = tour.visit("C_panel_west_front", "C_panel_west_front", state="reference", truth=False)
    assert panel.vista == "C_panel_west_front" and not tour.transits[-1].reach.reachable


def test_every_point_that_completes_the_hand_plan_is_in_the_arms_reach(world: World) -> None:
    fills = [
        point.vista for point in plan_vistas(world, COMPLETED_HAND_PLAN) if point.vista.startswith("fill_")
    ]
    assert fills  # the hand plan leaves the tanks' flanks to them (plan.completion_vistas)
    assert all(reach(world, vista).reachable for vista in fills)  # plan_cad prefers the views the arm reaches


def _blas_threads() -> set[int]:
    return {int(pool["num_threads"]) for pool in threadpool_info() if pool["user_api"] == "blas"}


def test_a_mission_on_another_thread_leaves_the_processs_blas_threads_alone() -> None:
    # OpenBLAS's thread count is the process's: changing it under another thread's BLAS call is not safe
    threads_during: list[set[int]] = []

    def mission() -> None:
        run_mission(
            SEED,
            size=TINY,
            arm=False,
            orbit=False,
            active=False,
            settings=MissionSettings(plan="hand", vistas=("A_door",)),
            on_visit=lambda vista, findings: threads_during.append(_blas_threads()),
        )

    with threadpool_limits(limits=2, user_api="blas"):
        worker = threading.Thread(target=mission)
        worker.start()
        worker.join()
    assert threads_during and all(threads == {2} for threads in threads_during)


def test_the_mission_moves_the_arm_and_follows_the_sun() -> None:
    # the completed hand plan's kinds of point: the hand plan's in reach (with a second frame behind the
    # jaws) and out of it (the panel from above), and a point that completes the hand plan
    chosen = ("A_door", "B_tank", "C_panel_centre", "fill_00")
    threads_during: list[set[int]] = []
    with threadpool_limits(limits=2, user_api="blas"):
        result = run_mission(
            SEED,
            size=TINY,
            active=False,
            settings=MissionSettings(plan="hand+cad", vistas=chosen),
            on_visit=lambda vista, findings: threads_during.append(_blas_threads()),
        )
        threads_after = _blas_threads()
    # BLAS on one thread while the renderer shares the cores, the caller's setting back afterwards
    assert threads_during and all(threads == {1} for threads in threads_during)
    assert threads_after == {2}
    points = len(result.plan)
    visits = 3 * points  # two reference visits and one inspection visit per point
    assert len(result.transits) == visits and len(result.suns) == visits
    fills = {p.name for p in result.plan if p.vista.startswith("fill_")}
    behind = {p.name: p.vista for p in result.plan if p.behind_jaws_at_m is not None and p.name not in fills}
    assert fills and behind and set(behind.values()) <= REACHABLE
    # the completing point was chosen among the views the arm reaches (plan_cad prefers them)
    in_reach = {p.name for p in result.plan} & REACHABLE
    assert in_reach == {"A_door", "A_door_open", "B_tank"}
    assert {t.label for t in result.transits if t.reached} == in_reach | set(behind) | fills
    stages = [s.stage for s in result.suns]
    assert stages == ["reference"] * 2 * points + ["inspection"] * points
    times = np.array([s.time_s for s in result.suns])
    assert np.all(np.diff(times[: 2 * points]) > 0) and times[2 * points] > PERIOD_S
    assert result.timings_s["transits"] > 0.0
    # ORU A lies in the orbit plane of the lab's placement: its sun is reproduced exactly
    for setting in result.suns:
        if setting.label.startswith("A_"):
            assert setting.reachable and setting.direction_error_rad < SUN_DIRECTION_TOLERANCE_RAD


# --------------------------------------------------------------------------------------- bad input


def test_bad_input_names_the_argument(world: World) -> None:
    plain = load("truss", seed=SEED)
    cases = [
        (lambda: transit(plain, "A_door"), "world"),
        (lambda: Tour(plain, seed=0, size=TINY, arm=True), "world"),
        (lambda: transit(world, "nowhere"), "vista"),
        (lambda: reach(world, "nowhere"), "vista"),
        (lambda: viewing_pose(world, "A_door", offset_m=(math.nan, 0.0)), "offset_m"),
        (lambda: transit(world, "A_door", clock_s=-1.0), "clock_s"),
        (lambda: transit(world, "A_door", law="fast"), "law"),  # type: ignore[arg-type]
        (lambda: approach_law(0.9), "standoff_m"),
        (lambda: approach_law(-0.1), "standoff_m"),
        (lambda: approach_law(0.5, math.nan), "nearest_m"),
        (lambda: Tour(world, seed=0, size=TINY, arm="yes"), "arm"),  # type: ignore[arg-type]
        (lambda: Tour(world, seed=0, size=TINY, orbit=1), "orbit"),  # type: ignore[arg-type]
        (lambda: Tour(world, seed=0, size=TINY).start_pass("rehearsal", 0.0), "stage"),
        (lambda: Tour(world, seed=0, size=TINY).start_pass("reference", -1.0), "start_s"),
        (lambda: Tour(world, seed=0, size=TINY).visit("", "A_door", state="reference"), "label"),
        (lambda: Tour(world, seed=0, size=TINY).visit(["A"], "A_door", state="reference"), "label"),  # type: ignore[arg-type]
        (lambda: Tour(world, seed=0, size=TINY).visit("X", "nowhere", state="reference"), "vista"),
        (lambda: run_mission(0, arm="yes"), "arm"),  # type: ignore[arg-type]
        (lambda: run_mission(0, orbit=None), "orbit"),  # type: ignore[arg-type]
        (lambda: run_mission(0, orbit_start_s=[0.0, 1.0]), "orbit_start_s"),  # type: ignore[arg-type]
    ]
    try:
        for call, argument in cases:
            with pytest.raises(InputError) as caught:
                call()
            message = str(caught.value)
            assert argument in message, (argument, message)
    finally:
        plain.close()


def test_an_unknown_plan_point_is_refused_before_anything_moves(world: World) -> None:
    before = world.arm.joint_positions
    with pytest.raises(InputError, match=r"vista must be one of .*plan_vistas"):
        Tour(world, seed=0, size=TINY).visit("Z", PlanPoint("Z", "Z_nowhere").vista, state="inspection")
    assert np.array_equal(world.arm.joint_positions, before)
