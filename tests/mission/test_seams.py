"""The model's seams (seed §2.3, "sharp depth deviations" at the pixel scale): small steps of the CAD depth
that two viewpoints sample differently, found on ray-cast depth maps whose geometry is known."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import NDArray

from rsi.mission.views import FAR_M, model_seams

FOCAL_PX = 760.0  # the ISEE camera's focal length at 480x640 (rsi.sim: 0.5 mm per pixel at 0.38 m)
SHAPE = (120, 160)


def _rays() -> NDArray[np.float64]:
    """Unit-depth ray directions (x, y, 1) of every pixel of a pinhole camera looking along +z."""
    rows, cols = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]].astype(np.float64)
    x = (cols - SHAPE[1] / 2 + 0.5) / FOCAL_PX
    y = (rows - SHAPE[0] / 2 + 0.5) / FOCAL_PX
    return np.stack([x, y, np.ones_like(x)], axis=-1)


def _plane_depth(
    normal: tuple[float, float, float], point: tuple[float, float, float]
) -> NDArray[np.float64]:
    rays = _rays()
    n = np.asarray(normal) / np.linalg.norm(normal)
    return np.asarray(np.dot(point, n) / (rays @ n))


def _cylinder_depth(radius_m: float, axis_z_m: float, axis_y_m: float = 0.0) -> NDArray[np.float64]:
    """Depth of a tank lying across the view (its axis along the image's x), FAR_M where a ray misses."""
    rays = _rays()
    # the ray t (x, y, 1) meets (t y - axis_y)^2 + (t - axis_z)^2 = r^2, a quadratic in t
    a = rays[..., 1] ** 2 + 1.0
    b = -2.0 * (rays[..., 1] * axis_y_m + axis_z_m)
    c = axis_y_m**2 + axis_z_m**2 - radius_m**2
    discriminant = b * b - 4 * a * c
    near = (-b - np.sqrt(np.maximum(discriminant, 0.0))) / (2 * a)
    return np.where(discriminant > 0, near, FAR_M)


def _interior(depth: NDArray[np.float64], margin_px: int) -> NDArray[np.bool_]:
    """Pixels at least `margin_px` from the frame's edge and from any pixel where the surface is missed."""
    from scipy.ndimage import binary_erosion

    hit = depth < FAR_M
    hit[:margin_px] = hit[-margin_px:] = False
    hit[:, :margin_px] = hit[:, -margin_px:] = False
    return np.asarray(binary_erosion(hit, iterations=margin_px))


@pytest.mark.parametrize("tilt_deg", [0.0, 30.0, 45.0, 60.0])
def test_a_plane_at_any_tilt_has_no_seam(tilt_deg: float) -> None:
    tilt = np.radians(tilt_deg)
    depth = _plane_depth((np.sin(tilt), 0.2 * np.sin(tilt), np.cos(tilt)), (0.0, 0.0, 0.38))
    assert not model_seams(depth).any()


def test_a_tank_has_seams_only_where_it_is_seen_grazing() -> None:
    axis_y, axis_z = 0.06, 0.45  # its upper limb in view
    depth = _cylinder_depth(0.07, axis_z, axis_y_m=axis_y)
    hit = depth < FAR_M
    points = _rays() * depth[..., None]
    normals = points - np.array([0.0, axis_y, axis_z])
    normals[..., 0] = 0.0
    cosine = -np.sum(normals * points, axis=-1) / (
        np.linalg.norm(normals, axis=-1) * np.linalg.norm(points, axis=-1)
    )
    incidence_deg = np.degrees(np.arccos(np.clip(cosine, -1.0, 1.0)))
    seams = model_seams(depth)
    # the curved skin up to 75 deg, far past the plan's 45 deg (its pixels there span 4 of its footprint)
    assert not seams[hit & (incidence_deg < 75.0)].any()
    assert seams[hit & (incidence_deg > 80.0)].all()  # the limb, seen edge-on
    limb = np.argmax(hit, axis=0)  # first row of the tank in each column
    assert np.all(seams[limb, np.arange(SHAPE[1])])  # the silhouette


def test_a_strap_two_millimetres_proud_of_its_tank_is_a_seam_along_both_edges() -> None:
    tank, strap = _cylinder_depth(0.07, 0.45), _cylinder_depth(0.072, 0.45)
    band = slice(70, 86)  # 16 columns: a 12 mm strap at 0.38 m
    depth = tank.copy()
    depth[:, band] = strap[:, band]
    seams = model_seams(depth)
    inside = _interior(tank, 3)
    rows = inside[:, 69] & inside[:, 86]
    assert rows.sum() > 40
    for edge in (69, 85):  # the columns either side of each edge
        assert np.all(seams[rows, edge : edge + 2].any(axis=1)), edge
    away = inside.copy()
    away[:, 66:90] = False
    assert not seams[away].any()  # the tank and the strap's own face have none


def test_a_blanket_a_tenth_of_a_millimetre_thick_is_no_seam() -> None:
    depth = _plane_depth((0.5, 0.0, 0.87), (0.0, 0.0, 0.38))
    depth[:, 80:] -= 1e-4  # Kapton on its plate: far under a pixel's footprint (0.5 mm)
    assert not model_seams(depth).any()
    depth[:, 100:] -= 2e-3  # a 2 mm plate edge is one
    assert model_seams(depth)[:, 99:101].any(axis=1).all()


def _seen_from(depth: NDArray[np.float64]) -> object:
    """A visit whose placed model shows `depth` to a camera of FOCAL_PX (what seen_head_on reads)."""
    from types import SimpleNamespace

    cad = SimpleNamespace(expected_depth_m=depth.astype(np.float32))
    pose = SimpleNamespace(focal_px=FOCAL_PX)
    return SimpleNamespace(capture=SimpleNamespace(cad=cad), believed_pose=pose)


def test_a_tank_is_seen_head_on_up_to_the_grazing_incidence_and_not_at_its_limb() -> None:
    from rsi.mission.settings import MissionSettings
    from rsi.mission.views import seen_head_on

    axis_y, axis_z = 0.06, 0.45
    depth = _cylinder_depth(0.07, axis_z, axis_y_m=axis_y)
    points = _rays() * depth[..., None]
    normals = points - np.array([0.0, axis_y, axis_z])
    normals[..., 0] = 0.0
    cosine = np.abs(np.sum(normals * points, axis=-1)) / (
        np.linalg.norm(normals, axis=-1) * np.linalg.norm(points, axis=-1)
    )
    incidence_deg = np.degrees(np.arccos(np.clip(cosine, 0.0, 1.0)))
    head_on = seen_head_on(_seen_from(depth), MissionSettings())  # type: ignore[arg-type]
    skin = _interior(depth, 1)  # the derivatives of a pixel beside the sky read the jump
    assert head_on[skin & (incidence_deg < 78.0)].all()
    limb = (depth < FAR_M) & (incidence_deg > 82.0)
    assert limb.sum() > 50  # the upper limb is in view
    assert not head_on[limb].any()


@pytest.mark.parametrize(("tilt_deg", "seen"), [(0.0, True), (60.0, True), (85.0, False)])
def test_a_plane_is_seen_head_on_below_the_grazing_incidence(tilt_deg: float, seen: bool) -> None:
    from rsi.mission.settings import MissionSettings
    from rsi.mission.views import seen_head_on

    tilt = np.radians(tilt_deg)
    depth = _plane_depth((np.sin(tilt), 0.0, np.cos(tilt)), (0.0, 0.0, 0.38))
    inside = _interior(np.where(depth > 0, depth, FAR_M), 2)
    head_on = seen_head_on(_seen_from(np.where(depth > 0, depth, FAR_M)), MissionSettings())  # type: ignore[arg-type]
    # at 85 deg the rays across the frame meet it between ~80 and ~90 deg: most of it is grazing
    share = head_on[inside].mean()
    assert share == 1.0 if seen else share < 0.5
