"""A plan from the CAD model and its coverage (issue 15): known synthetic cases (a plate, an occluder, a
surface seen only obliquely, a door), the hand plan measured, the truss plan, determinism, bad input."""

from __future__ import annotations

import itertools
import math
import os
from collections.abc import Iterator

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.errors import InputError
from rsi.mission import MissionSettings, PlanPoint, plan_cad
from rsi.mission.coverage import CoverageRules, Sight, coverage, inspectable_samples
from rsi.mission.plan import hand_plan_vistas, panel_vistas, plan_vistas
from rsi.mission.plan_cad import CadPlan, add_plan_vistas, generate_plan, tour_order
from rsi.sim.anomalies import AnomalySet, Candidates, Patch
from rsi.sim.mockup import DOOR_HINGE_AXIS, Door, Mockup, Part, truss_mockup, vista
from rsi.sim.world import World, load

FRONT = (0.0, -1.0, 0.0)
PLATE_Y_M = -0.4  # the plate's front face
RULES = CoverageRules()


FAR_HINGE = (5.0, 5.0, 5.0)


def _mockup(parts: list[Part], patches: list[Patch], hinge: tuple[float, float, float] = FAR_HINGE) -> Mockup:
    """A mock-up of `parts`; the scene has a door body always: a small door far away unless one is given."""
    if not any(part.component == "A_door" for part in parts):
        parts = [*parts, Part("door", "A_door", "box", (0.01, 0.01, 0.01), FAR_HINGE, "aluminium")]
    door = Door("A_door", "A_door_hinge", hinge, DOOR_HINGE_AXIS, "door")
    return Mockup(
        tuple(parts), door, Candidates(impact_patches=tuple(patches)), {}, {}, "test-plate", 1.8, {}, ()
    )


def _plate(half: tuple[float, float] = (0.1, 0.08)) -> tuple[Part, Patch]:
    """A 20 cm x 16 cm plate facing -y (the robot's side), its face a patch."""
    part = Part("plate", "P", "box", (half[0], 0.005, half[1]), (0.9, PLATE_Y_M + 0.005, 1.2), "aluminium")
    patch = Patch("plate_face", (0.9, PLATE_Y_M, 1.2), FRONT, (1.0, 0.0, 0.0), half, "plate")
    return part, patch


def _world(mockup: Mockup) -> World:
    return World(mockup, AnomalySet(()), seed=0, arm=False)


@pytest.fixture(scope="module")
def truss_plan() -> CadPlan:
    return generate_plan(truss_mockup())


# ------------------------------------------------------------------------------ the rules, known cases


def test_samples_carry_the_surface_area_exactly() -> None:
    part, patch = _plate()
    samples = inspectable_samples(_mockup([part], [patch]), 0.01)
    assert len(samples) == 20 * 16
    assert samples.area_m2.sum() == pytest.approx(patch.area_m2)
    np.testing.assert_allclose(samples.normals, np.tile(FRONT, (len(samples), 1)))


def test_a_flat_plate_is_covered_by_one_view() -> None:
    """At 0.5 mm pixels a frame spans about 0.24 m x 0.18 m (the corners, at 27 deg off axis, need the
    standoff 0.78 of the centre's): the 20 x 16 cm plate fits one view."""
    part, patch = _plate()
    plan = generate_plan(_mockup([part], [patch]), arm=False)
    assert len(plan.points) == 1
    assert plan.coverage.fraction == pytest.approx(1.0)
    assert plan.unreachable == ()


def test_a_wider_plate_needs_two_views() -> None:
    part, patch = _plate((0.2, 0.06))  # 40 cm: wider than any 0.5 mm/px frame (24 cm)
    plan = generate_plan(_mockup([part], [patch]), arm=False)
    assert len(plan.points) == 2
    assert plan.coverage.fraction >= 0.995


def test_resolution_and_incidence_rules() -> None:
    """Head-on at 0.45 m a pixel is 0.59 mm: nothing counts at 0.5 mm, all in the frame at 0.7 mm. A view
    60 deg off the normal, however near, covers nothing."""
    part, patch = _plate((0.05, 0.05))
    mockup = _mockup([part], [patch])
    far = vista("far", (0.9, PLATE_Y_M, 1.2), FRONT, (0.0, 0.0, 1.0), 0.45)
    assert Sight(mockup, RULES).seen(far).size == 0
    coarse = Sight(mockup, CoverageRules(max_pixel_m=7e-4))
    assert coarse.seen(far).size == len(coarse.samples)
    slant = (math.sin(math.radians(60)), -math.cos(math.radians(60)), 0.0)
    oblique = vista("oblique", (0.9, PLATE_Y_M, 1.2), slant, (0.0, 0.0, 1.0), 0.15)
    assert Sight(mockup, RULES).seen(oblique).size == 0


def test_a_point_behind_an_occluder_is_not_covered() -> None:
    part, patch = _plate()
    # a post 3 cm wide, 10 cm in front of the plate's left half
    post = Part("post", "P", "box", (0.015, 0.01, 0.2), (0.85, PLATE_Y_M - 0.1, 1.2), "aluminium")
    sight = Sight(_mockup([part, post], [patch]), RULES)
    ahead = vista("ahead", (0.9, PLATE_Y_M, 1.2), FRONT, (0.0, 0.0, 1.0), 0.28)
    seen = np.zeros(len(sight.samples), dtype=bool)
    seen[sight.seen(ahead)] = True
    camera = np.asarray(ahead.position_m)
    # where the line from the camera to each sample crosses the post's front plane
    points = sight.samples.points_m
    t = (PLATE_Y_M - 0.11 - camera[1]) / (points[:, 1] - camera[1])
    crossing_x = camera[0] + t * (points[:, 0] - camera[0])
    shadowed = np.abs(crossing_x - 0.85) < 0.015 - 0.004
    clear = np.abs(crossing_x - 0.85) > 0.015 + 0.004
    assert shadowed.any() and not seen[shadowed].any()
    assert seen[clear].all()


def test_the_door_is_opened_for_what_it_hides_and_closed_for_its_own_face() -> None:
    """A back plate behind a hinged door: its face needs the door open, the door's face needs it closed."""
    back, inside = _plate((0.05, 0.05))
    door = Part("door", "A_door", "box", (0.06, 0.002, 0.06), (0.9, PLATE_Y_M - 0.05, 1.2), "aluminium")
    door_face = Patch(
        "door_face", (0.9, PLATE_Y_M - 0.052, 1.2), FRONT, (1.0, 0.0, 0.0), (0.05, 0.05), "door"
    )
    mockup = _mockup([back, door], [inside, door_face], hinge=(0.84, PLATE_Y_M - 0.05, 1.2))
    sight = Sight(mockup, RULES)
    ahead = vista("ahead", (0.9, PLATE_Y_M, 1.2), FRONT, (0.0, 0.0, 1.0), 0.28)
    surface = sight.samples.surface
    closed, opened = sight.seen(ahead, 0.0), sight.seen(ahead, 1.4)
    assert set(surface[closed]) == {"door_face"}
    assert set(surface[opened]) == {"plate_face"}
    plan = generate_plan(mockup, arm=False)
    assert sorted(point.door_angle_rad for point in plan.points) == [0.0, 1.4]
    assert plan.coverage.fraction >= 0.995


def test_the_tour_keeps_the_door_open_points_together() -> None:
    points = [vista(f"v{k}", (0.1 * k, -0.4, 1.2), FRONT, (0.0, 0.0, 1.0), 0.3) for k in range(6)]
    doors = [0.0, 1.4, 0.0, 1.4, 0.0, 1.4]
    order = tour_order(points, doors, np.array([0.0, -0.9, 1.2]))
    sequence = [doors[k] for k in order]
    changes = sum(a != b for a, b in itertools.pairwise(sequence))
    assert sorted(order) == list(range(6)) and changes == 1


def test_generation_is_deterministic() -> None:
    part, patch = _plate((0.2, 0.06))
    first, second = (generate_plan(_mockup([part], [patch]), arm=False) for _ in range(2))
    assert first.vistas == second.vistas and first.points == second.points
    np.testing.assert_array_equal(first.coverage.first_seen, second.coverage.first_seen)


# ------------------------------------------------------------------------------------- the truss


@pytest.fixture(scope="module")
def truss_world() -> Iterator[World]:
    built = load("truss", seed=0)
    yield built
    built.close()


def test_the_hand_plan_covers_half_the_truss_at_half_a_millimetre(truss_world: World) -> None:
    """Its A, B and D views stand 0.5 m off (0.66 mm pixels): only the 0.35 m panel views count at 0.5 mm;
    at 1 mm per pixel it covers 93 %, the tank skins' flanks (over 45 deg) missing (docs/mission.md)."""
    points = plan_vistas(truss_world, MissionSettings(plan="hand"))
    fine = coverage(points, truss_world)
    assert 0.45 < fine.fraction < 0.55
    assert fine.by_kind()["screw"] == 0.0
    assert 0.9 < coverage(points, truss_world, CoverageRules(max_pixel_m=1e-3)).fraction < 0.96


def test_the_truss_plan_covers_99_percent_with_more_points_than_the_hand_plan(
    truss_plan: CadPlan,
) -> None:
    """The acceptance asks >= 99 % with <= 10 points; at 0.5 mm pixels, the ISEE's jaws hiding part of each
    frame the arm takes, the generator needs 30 for its 99.9 % (29 for 99.5 %; an exact set cover of the
    earlier candidates by area, 23 for 99 %: docs/mission.md), every site's disc seen. Points out of the
    arm's reach are flagged."""
    assert truss_plan.coverage.fraction >= 0.999
    kinds = truss_plan.coverage.by_kind()
    assert kinds["screw"] == kinds["peltier"] == kinds["leak"] == 1.0
    assert len(truss_plan.points) == 30
    assert truss_plan.generation_s < 60.0
    assert set(truss_plan.unreachable) < {point.name for point in truss_plan.points}
    assert all(name.startswith("cad_") for name in truss_plan.unreachable)


def test_the_truss_plan_sees_the_d_tank_s_lower_side(truss_plan: CadPlan) -> None:
    """The 0.995 cover's largest gap, where held-out missions 2269, 2281 and 2289 each missed a crater
    (docs/mission.md): every sample within 3 cm of (1.61, -0.425, 1.15) m is covered now (21 of 28 before)."""
    samples = truss_plan.coverage.samples
    near = np.linalg.norm(samples.points_m - np.array([1.61, -0.425, 1.15]), axis=1) < 0.03
    assert near.sum() > 20
    assert truss_plan.coverage.covered[near].all()


def test_the_plan_s_cover_is_a_setting(truss_plan: CadPlan) -> None:
    """`MissionSettings.plan_cover` stops the cover where asked: 99.5 % takes fewer points and leaves more."""
    looser = generate_plan(truss_mockup(), MissionSettings(plan_cover=0.995))
    assert 0.995 <= looser.coverage.fraction < truss_plan.coverage.fraction
    assert len(looser.points) < len(truss_plan.points)


def test_a_generated_plan_runs_on_a_world(truss_world: World, truss_plan: CadPlan) -> None:
    """Measured again where the arm's jaws hide part of each frame, as the generator weighed it; the free
    camera of a world without the arm sees a little more."""
    arm_world = load("truss", seed=0, arm=True)
    try:
        again = coverage(add_plan_vistas(arm_world, truss_plan), arm_world)
    finally:
        arm_world.close()
    assert again.fraction == pytest.approx(truss_plan.coverage.fraction)
    assert coverage(add_plan_vistas(truss_world, truss_plan), truss_world).fraction >= again.fraction


def test_a_needed_sample_is_not_traded_for_area() -> None:
    """Two views cover 99.5 % by area between them; a third alone sees a tiny needed sample (a screw's disc):
    the area cover leaves it out, the cover with `must` takes it, and pruning keeps it."""
    point = vista("p", (0.0, 0.0, 0.0), FRONT, (0.0, 0.0, 1.0), 0.3)
    area = np.array([0.5, 0.495, 0.005])
    views = [plan_cad.Candidate(point, 0.0, np.array(seen), True, "s") for seen in ([0], [1], [2], [0, 1])]
    by_area, _ = plan_cad.greedy_cover(views, area, 0.995)
    assert sorted(by_area) == [3]
    with_sites, _ = plan_cad.greedy_cover(views, area, 0.995, must=np.array([False, False, True]))
    assert sorted(with_sites) == [2, 3]


def test_a_plan_completes_what_another_leaves() -> None:
    """The 40 cm plate needs two views; with its left half covered already, one view completes it (named
    by the prefix), and with all of it covered none is added."""
    part, patch = _plate((0.2, 0.06))
    mockup = _mockup([part], [patch])
    samples = inspectable_samples(mockup, RULES.sample_spacing_m)
    left = samples.points_m[:, 0] < 0.9
    fill = generate_plan(mockup, arm=False, covered=left, prefix="fill")
    assert [point.name for point in fill.points] == ["fill_00"]
    assert fill.coverage.covered[~left].mean() >= 0.995
    assert fill.coverage.covered[left].mean() < 0.5
    done = generate_plan(mockup, arm=False, covered=np.ones(len(samples), dtype=bool))
    assert done.points == () and done.coverage.fraction == 0.0


def test_the_hand_plan_completed_from_the_cad_covers_the_truss_at_its_own_resolution() -> None:
    """At its own 1 mm pixels and 45 deg the hand plan covers 93 % (the tanks' flanks only beyond 45 deg);
    `plan="hand+cad"` flies it whole, then the generated points for the rest, and covers 99 %. The default
    is the generated plan on every layout (issue 15's twenty-seventh session)."""
    world = load("truss", seed=0, arm=True)
    try:
        hand = plan_vistas(world, MissionSettings(plan="hand"))
        completed = plan_vistas(world, MissionSettings(plan="hand+cad"))
        assert plan_vistas(world) == plan_vistas(world, MissionSettings(plan="cad"))  # the default
        rules = CoverageRules(max_pixel_m=1e-3)
        before, after = (coverage(points, world, rules).fraction for points in (hand, completed))
    finally:
        world.close()

    def first_frames(points: tuple[PlanPoint, ...]) -> list[PlanPoint]:
        return [point for point in points if point.behind_jaws_at_m is None]

    fills = [point for point in first_frames(completed) if point.name.startswith("fill_")]
    assert first_frames(completed) == first_frames(hand) + fills
    assert 1 <= len(fills) <= 8
    assert before < 0.95 and after >= 0.99


def test_missionsettings_plan_chooses_the_generator() -> None:
    world = _world(_mockup(*map(list, zip(_plate(), strict=True))))
    points = plan_vistas(world, MissionSettings(plan="cad"))
    # one view of the plate, or two where the ISEE's jaws would hide a corner of it
    assert 1 <= len(points) <= 2 and all(point.vista in world.vistas for point in points)
    assert coverage(points, world).fraction > 0.99


# ------------------------------------------------------------------------------------------ bad input


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: generate_plan("truss"), "source must be"),
        (lambda: generate_plan(truss_mockup(), target=1.5), "target"),
        (lambda: generate_plan(truss_mockup(), arm="yes"), "arm must be"),
        (lambda: generate_plan(truss_mockup(), settings=1), "settings"),
        (lambda: generate_plan(truss_mockup(), rules=1), "rules"),
        (lambda: CoverageRules(max_pixel_m=-1.0), "max_pixel_m"),
        (lambda: CoverageRules(max_incidence_deg=90.0), "max_incidence_deg"),
        (lambda: CoverageRules(margin_px=300), "margin_px=300"),
        (lambda: CoverageRules(size=480), "size must be"),
        (lambda: CoverageRules(sample_spacing_m=1.0), "sample_spacing_m"),
        (lambda: CoverageRules(depth_tolerance_m=0.0), "depth_tolerance_m"),
        (lambda: inspectable_samples("truss"), "mockup"),
        (lambda: inspectable_samples(truss_mockup(), 0.0), "spacing_m"),
        (lambda: inspectable_samples(_mockup([], [])), "no inspectable surface"),
        (lambda: MissionSettings(plan="manual"), "plan must be one of"),
        (lambda: MissionSettings(plan_cover=1.5), r"plan_cover must lie in \(0, 1\]"),
        (lambda: MissionSettings(plan_cover=0.0), "plan_cover must be > 0"),
        (lambda: generate_plan(truss_mockup(), covered=np.ones(3, dtype=bool)), "covered must be"),
        (lambda: generate_plan(truss_mockup(), prefix="1 st"), "prefix must be"),
    ],
)
def test_bad_input_is_refused_by_name(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()  # type: ignore[operator]


def test_coverage_and_plan_arguments_are_checked(truss_world: World) -> None:
    with pytest.raises(InputError, match="points must be a sequence"):
        coverage("A_door", truss_world)
    with pytest.raises(InputError, match="points must hold only PlanPoint"):
        coverage(["A_door"], truss_world)
    with pytest.raises(InputError, match="world"):
        coverage([PlanPoint("A_door", "A_door")], "truss")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="plan"):
        add_plan_vistas(truss_world, "plan")  # type: ignore[arg-type]


def test_a_surface_no_view_can_see_is_refused() -> None:
    """A patch sealed inside a box: every ray meets the box first."""
    box = Part("box", "P", "box", (0.1, 0.1, 0.1), (0.9, 0.0, 1.2), "aluminium")
    inside = Patch("inside", (0.9, 0.0, 1.2), FRONT, (1.0, 0.0, 0.0), (0.02, 0.02), "plate")
    with pytest.raises(InputError, match="no inspectable surface any candidate view covers"):
        generate_plan(_mockup([box], [inside]), arm=False)


def test_the_hand_plan_is_refused_on_another_layout() -> None:
    world = _world(_mockup(*map(list, zip(_plate(), strict=True))))
    for plan in ("hand", "hand+cad"):
        with pytest.raises(InputError, match="hand plan is the truss layout's"):
            plan_vistas(world, MissionSettings(plan=plan))


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: panel_vistas(0.0), "standoff_m"),
        (lambda: panel_vistas(0.35, (1.0, 2.0)), "centre"),
        (lambda: hand_plan_vistas(None, MissionSettings()), "world"),  # type: ignore[arg-type]
    ],
)
def test_the_hand_plan_refuses_bad_input_by_name(call: object, message: str) -> None:
    with pytest.raises(InputError, match=message):
        call()  # type: ignore[operator]
