"""The ISEE's own jaws in its camera's view (seed §3.1): rigid with the camera, never taken for a flaw."""

from __future__ import annotations

import math
import os
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.mission import plan_vistas
from rsi.mission.settings import MISSION_SIZE, MissionSettings
from rsi.mission.tour import Tour
from rsi.mission.views import inspection_region, own_body, placed, sense
from rsi.mission.visual import StoredView, compare, in_depth
from rsi.sim.arm import JAW_LENGTH_M
from rsi.sim.world import load


@pytest.fixture(scope="module")
def tour() -> Iterator[Any]:
    # seed 1302 at the D tubing: a jaw's bright edge crosses the tank, 1-2 px off after registration
    world = load("truss", seed=1302, repeatability="space", arm=True)
    plan_vistas(world)
    yield Tour(world, seed=1302, size=MISSION_SIZE, arm=True, orbit=False)
    world.close()


def test_the_jaws_are_the_only_model_nearer_than_their_length(tour: Any) -> None:
    visit = tour.visit("D_tubing", "D_tubing", state="reference", truth=False)
    own = own_body(visit.cad)
    assert own.any()  # the jaws are in view at every vista of this plan
    assert np.all(visit.cad.truss[own])  # the model names them the robot's own, not inspected surface
    surface = visit.cad.expected_depth_m[~own & (visit.cad.expected_depth_m < 5.0)]
    assert surface.min() > 3 * JAW_LENGTH_M  # the mock-up lies at the standoff, far beyond the jaws


def test_the_jaws_in_view_leave_the_range_map_whole(tour: Any) -> None:
    # the stereo search spans the model's depths but the jaws': at 5 cm they asked for disparities past the
    # frame's width, and the matcher left every column of the frame unranged
    sensed = sense(tour.visit("D_tubing", "D_tubing", state="reference", truth=False))
    own = own_body(sensed.capture.cad)
    surface = ~own & (sensed.capture.cad.expected_depth_m < 5.0)
    assert own.any() and surface.sum() > 50_000
    assert np.isfinite(sensed.range_m[surface]).mean() > 0.5
    assert not np.isfinite(sensed.range_m[own]).any()


def test_placing_the_model_moves_the_scene_and_leaves_the_jaws(tour: Any) -> None:
    from rsi.imaging.compensation import compensate_field_pair

    visit = tour.visit("D_tubing", "D_tubing", state="inspection", truth=False)
    moved = placed(visit, compensate_field_pair(*visit.frames).image)
    assert moved is not visit  # space repeatability: the scene is found several pixels off
    own = own_body(visit.cad)
    np.testing.assert_array_equal(own_body(moved.cad), own)
    np.testing.assert_array_equal(moved.cad.expected_depth_m[own], visit.cad.expected_depth_m[own])
    for name, mask in visit.cad.components.items():
        assert not np.array_equal(moved.cad.components[name], mask)  # the components moved with the scene
        assert not (moved.cad.components[name] & own).any()


@pytest.mark.parametrize("vista", ["D_tubing", "A_door"])
def test_the_model_draws_the_jaws_where_the_camera_sees_them_whatever_the_pose(tour: Any, vista: str) -> None:
    visit = tour.visit(vista, vista, state="reference", truth=True)
    truth = tour.views[-1][1].depth_m
    assert truth is not None
    seen = truth < JAW_LENGTH_M  # the jaws in the rendered frame
    drawn = own_body(visit.cad)
    assert seen.sum() > 1000
    # the pose error is ~10 px at the standoff and tens of pixels at the jaws' few centimetres
    assert (seen & drawn).sum() / (seen | drawn).sum() > 0.99


def test_the_jaws_edges_do_not_hold_the_model_where_the_robot_believes_it(tour: Any) -> None:
    from rsi.sim.capture import CadView

    visit = tour.visit("B_tank", "B_tank", state="inspection", truth=False)
    shape = visit.cad.expected_depth_m.shape
    # a model of three plates at 0.5 m and a jaw at 5 cm across the lower right corner
    depth = np.full(shape, 0.5, np.float32)
    plates = np.zeros(shape, bool)
    for row, col in ((80, 100), (200, 300), (300, 120)):
        plates[row : row + 90, col : col + 140] = True
    jaw = np.zeros(shape, bool)
    jaw[330:, 420:] = True
    depth[jaw] = 0.05
    cad = CadView(depth, jaw, {"plates": plates & ~jaw})
    # the frame: the plates 6 px down and 5 px left of where the robot believes them, the jaw where it is
    # (it rides with the camera), its edges much the stronger
    image = np.full(shape, 40.0, np.float32)
    image[np.roll(np.roll(plates, 6, axis=0), -5, axis=1)] = 80.0
    image[jaw] = 250.0
    moved = placed(replace(visit, cad=cad, model=None), image)
    found = np.argwhere(moved.cad.components["plates"]).min(axis=0) - np.argwhere(plates & ~jaw).min(axis=0)
    assert tuple(found) == (6, -5)
    np.testing.assert_array_equal(own_body(moved.cad), jaw)


def _stored(reference: Any, second: Any, range_m: Any, second_range_m: Any) -> StoredView:
    """Two pristine visits as the reference pass keeps them, with no nuisance, screw or exposure record."""
    return StoredView(
        reference,
        second,
        np.ones(reference.image.shape, np.float32),
        range_m,
        {},
        1.0,
        1.0,
        second_range_m=second_range_m,
    )


def _comparison(tour: Any) -> tuple[Any, Any, Any]:
    """(view, pair, shift) of a flaw-free inspection of the D tubing against two pristine visits, the
    first of up to four draws whose registration moves the scene past the guard band (2 px): two visits'
    space errors (8-12 px each) can lie close together."""
    for _ in range(4):
        view, pair, shift = _one_comparison(tour)
        if math.hypot(*shift) > 3.0:
            break
    return view, pair, shift


def _one_comparison(tour: Any) -> tuple[Any, Any, Any]:
    settings = MissionSettings()
    reference = sense(tour.visit("D_tubing", "D_tubing", state="reference", truth=False))
    second = sense(tour.visit("D_tubing", "D_tubing", state="reference", truth=False))
    view = sense(tour.visit("D_tubing", "D_tubing", state="reference", truth=False))
    stored = _stored(reference.strobe, second.strobe, reference.range_m, second.range_m)
    inspection = replace(view.strobe, valid=view.strobe.valid & inspection_region(view, settings))
    seen = in_depth(stored, inspection, view, settings)
    return (
        view,
        compare(seen.reference, inspection, 1e-6, settings, registration=seen.aligned[0]),
        seen.shift_xy,
    )


@pytest.mark.parametrize("draw", range(3))
def test_no_compared_pixel_shows_the_references_jaws_moved_by_the_registration(tour: Any, draw: int) -> None:
    view, pair, shift = _comparison(tour)
    assert math.hypot(*shift) > 3.0  # space repeatability: the scene moved past the guard band (2 px)
    # the jaws lie on the same pixels in both visits; the registration draws the reference's ones `shift`
    # off, where the inspection sees the surface: none of them may be compared
    jaws = own_body(view.capture.cad).astype(np.float32)
    registration = pair.detection.registration
    moved, _ = registration.warp(jaws, photometric=False)
    assert moved.max() > 0.5
    assert not (pair.detection.valid & (moved > 0.01)).any()


def _compared_jaws(tour: Any, keep: Any) -> tuple[int, int]:
    """(reference jaw pixels, of them compared) where the arm's ISEE took the reference (its jaws in the
    frame) and the free camera the inspection (none), the reference kept by `keep(sensed)`."""
    from rsi.sim.capture import capture

    settings = MissionSettings()
    carried = sense(tour.visit("D_tubing", "D_tubing", state="reference", truth=False))
    tour.visit("A_door", "A_door", state="reference", truth=False)  # the arm goes on, out of that view
    free_view = tour.world.render("D_tubing", size=MISSION_SIZE, state="reference", truth=False, stereo=True)
    free = sense(capture(tour.world, free_view))
    assert not own_body(free.capture.cad).any()  # the free camera carries no jaws, and its model draws none
    reference = keep(carried, settings)
    stored = _stored(reference, reference, carried.range_m, carried.range_m)
    inspection = replace(free.strobe, valid=free.strobe.valid & inspection_region(free, settings))
    seen = in_depth(stored, inspection, free, settings)
    pair = compare(seen.reference, inspection, 1e-6, settings, registration=seen.aligned[0])
    jaws = own_body(carried.capture.cad)
    moved, _ = pair.detection.registration.warp(jaws.astype(np.float32), photometric=False)
    # a jaw pixel where the registration's shift puts most of it (the parallax about the shift moves the
    # surface behind by a fraction of a pixel more, so the bilinear fringe is not the jaw's)
    return int(jaws.sum()), int((pair.detection.valid & (moved > 0.5)).sum())


def test_jaws_only_the_reference_holds_are_never_compared(tour: Any) -> None:
    from rsi.mission.visual import stored_strobe

    # one pass's arm reached the vista, the other's did not (the tour's free-camera fallback): the
    # inspection's model draws no jaws, so only the reference's own record of them can keep them out
    jaws, compared = _compared_jaws(tour, stored_strobe)
    assert jaws > 1000
    assert compared == 0


def test_the_raw_reference_would_compare_its_jaws_with_the_surface_behind_them(tour: Any) -> None:
    # what stored_strobe is for: the reference's jaws fall on the free frame's inspected surface
    _, compared = _compared_jaws(tour, lambda sensed, _settings: sensed.strobe)
    assert compared > 100
