"""Geometry of one visit's view: pixels to world points and back, what the frame sees, the region it
inspects, and the images the robot's camera and stereo pair give (seed §2.1-2.3, §3 D).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.imaging.compensation import Compensated
    from rsi.sim.anomalies import Site
    from rsi.sim.world import View, World

FloatArray = NDArray[np.float64]


def field_to_world(view: View, row: float, col: float) -> tuple[float, float, float] | None:
    """World point seen at field pixel (row, col) from the frame's depth and camera pose (None: sky)."""
    depth = view.depth_m
    assert depth is not None
    frame_row = min(max(round(row), 0), depth.shape[0] - 1)
    column = min(max(round(col), 0), depth.shape[1] - 1)
    distance = float(depth[frame_row, column])
    pose = view.pose
    rows, cols = pose.shape
    if not math.isfinite(distance) or distance > 10.0:
        return None
    local = np.array(
        [
            (column - (cols - 1) / 2) / pose.focal_px * distance,
            -(frame_row - (rows - 1) / 2) / pose.focal_px * distance,
            -distance,
        ]
    )
    point = pose.position_m + pose.rotation @ local
    return (float(point[0]), float(point[1]), float(point[2]))


def pixel_size_m(view: View, position: tuple[float, float, float]) -> float:
    """Size of one frame pixel on the surface at `position`, metres."""
    _, along = view.pose.project(np.asarray([position]))
    return float(along[0]) / view.pose.focal_px


def to_field(view: View, points_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Field row, column and depth of world points in this view."""
    xy, along = view.pose.project(points_m)
    return xy[:, 1], xy[:, 0], along


def visible(view: View, points_m: FloatArray, tolerance_m: float = 0.006) -> NDArray[np.bool_]:
    """Which points the frame sees (inside, not hidden: the depth there agrees with the point's)."""
    depth = view.depth_m
    assert depth is not None
    xy, along = view.pose.project(points_m)
    rows, cols = depth.shape
    seen = np.zeros(len(points_m), dtype=bool)
    for k, ((x, y), distance) in enumerate(zip(xy, along, strict=True)):
        col, row = round(x), round(y)
        if 8 <= col < cols - 8 and 8 <= row < rows - 8 and distance > 0:
            seen[k] = abs(float(depth[row, col]) - distance) < tolerance_m
    return seen


def surface_distance_m(shape: tuple[int, ...], view: View, position_m: tuple[float, float, float]) -> Any:
    """Each pixel's distance (on the surface, metres) from a world point's projection."""
    row, col, _ = to_field(view, np.asarray([position_m]))
    rows, cols = np.indices(shape[:2])
    return np.hypot(rows - row[0], cols - col[0]) * pixel_size_m(view, position_m)


def disc(shape: tuple[int, ...], view: View, position_m: tuple[float, float, float], radius_m: float) -> Any:
    """Pixels within `radius_m` (on the surface) of a world point's projection."""
    return surface_distance_m(shape, view, position_m) <= radius_m


def seen_screws(world: World, view: View) -> list[Site]:
    sites = world.mockup.candidates.screw_sites
    seen = visible(view, np.asarray([site.position_m for site in sites]))
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def seen_components(world: World, view: View) -> list[Site]:
    """Component sites whose centre the view sees (depth within 2 cm: a tank's front, a panel's face)."""
    sites = world.mockup.candidates.component_sites
    seen = visible(view, np.asarray([site.position_m for site in sites]), tolerance_m=0.02)
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def inspection_region(view: View, settings: MissionSettings) -> NDArray[np.bool_]:
    """Pixels of the view's component surfaces, away from the truss frame and from depth jumps.

    Seed §2.3: one registration per frame cannot align surfaces at different depths after a viewpoint
    error (parallax), and the truss struts behind a plate or a tank's silhouette then differ by whole edges.
    The robot knows its CAD model and the pose (the stereo pair gives depth, seed §3): the region is the
    components' surfaces, less a guard band (``settings.inspection_guard_px``) around the truss and around
    every depth jump of more than ``settings.depth_jump_m``.
    """
    import cv2

    depth, truss = view.depth_m, view.truss_mask
    assert depth is not None and truss is not None
    side = 2 * settings.inspection_guard_px + 1
    band = np.ones((side, side), np.uint8)
    near = np.minimum(depth, np.float32(10.0))
    jump = cv2.dilate(near, band) - cv2.erode(near, band) > settings.depth_jump_m
    off = cv2.dilate(truss.astype(np.uint8), band).astype(bool) | jump | (depth >= 10.0)
    return ~off


def stereo_depth(view: View, rng: np.random.Generator, settings: MissionSettings) -> NDArray[np.float32]:
    """The ISEE stereo pair's range map (seed §3): the view's depth with the disparity noise of matching.

    sigma_Z = Z^2 sigma_d / (f B) with sigma_d = settings.stereo_disparity_noise_px, baseline B of the pair.
    """
    from rsi.sim.scene import STEREO_BASELINE_M

    depth = view.depth_m
    assert depth is not None
    focal_baseline = view.pose.focal_px * STEREO_BASELINE_M
    sigma = depth * depth * np.float32(settings.stereo_disparity_noise_px / focal_baseline)
    noisy = depth + sigma * rng.standard_normal(depth.shape).astype(np.float32)
    return np.asarray(np.where(depth < 10.0, noisy, depth), dtype=np.float32)


def strobe_image(world: World, view: View) -> Compensated:
    """The visit's full-resolution strobe image: its frame and the next, strobes in opposite fields.

    Seed §2.2 intra-frame compensation keeps one field: every other row, 1.3 mm apart at the standoff, so a
    ~1 mm impact may fall between the lit rows. Two frames with the strobe on the odd and then the even
    field give every row, each compensated within its own frame.
    """
    from rsi.imaging.compensation import compensate_field_pair

    return compensate_field_pair(view.frame, world.next_frame(view, lit_field="even"))
