"""Geometry of one visit's view as the robot knows it: pixels to world points and back, what the frame
sees, the region it inspects, and the strobe image (seed §2.1-2.3, §3 D).

Everything here reads a :class:`Sensed` visit: the ISEE's frames and stereo pair, the pose the robot
*believes* (seed §2.3: not the true one), the stereo range map, and the robot's CAD model projected from the
believed pose. Nothing reads the simulator's truth (rendered depth, true pose, anomaly masks).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi.mission.settings import FRAME_MARGIN_PX, MissionSettings

if TYPE_CHECKING:
    from rsi.imaging.compensation import Compensated
    from rsi.mission.plan_point import PlanPoint
    from rsi.sim.anomalies import Site
    from rsi.sim.capture import Capture
    from rsi.sim.render import CameraPose
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]
F32 = NDArray[np.float32]
FAR_M = 10.0  # a range at or beyond this is no surface: the renderer's far plane, the matcher's "no answer"
# the stereo search spans the CAD model's nearest range less 30 % to its farthest plus 50 %: the pose
# error and a dent move surfaces by centimetres, not by tens of percent
_NEAR_MARGIN, _FAR_MARGIN = 0.7, 1.5
# A matched range further than this from the model's is a false match, not the surface: the believed pose
# misses by at most ~7 mm at the standoff ("space" repeatability), a dent is <= 10 mm deep, and dark solar
# cells and plain plates give SGBM matches tens of centimetres off (seeds 3 and 5, C_panel: p90 0.22 m).
_RANGE_GATE_M = 0.03


@dataclass(frozen=True)
class Sensed:
    """One visit as the mission uses it: the ISEE's capture and the range map matched from its stereo pair.

    Attributes
    ----------
    capture : Capture
        Frames, stereo pair, believed pose and CAD expectation (:mod:`rsi.sim.capture`).
    range_m : ndarray of shape (M, N), float32
        Stereo range along the view axis (seed §3 D), NaN where the matcher gave no answer or one further
        than ``_RANGE_GATE_M`` from the CAD model's expected depth (a false match).
    surface_m : ndarray of shape (M, N), float32
        `range_m`, and the model's depth in its holes: the best range the robot has, to place what it finds.
    strobe : Compensated
        The full-resolution strobe image of its two frames, strobes in opposite fields. Seed §2.2
        intra-frame compensation keeps one field: every other row, 1.3 mm apart at the standoff, so a ~1 mm
        impact may fall between the lit rows. Two frames with the strobe on the odd and then the even field
        give every row, each compensated within its own frame.
    """

    capture: Capture
    range_m: F32
    surface_m: F32
    strobe: Compensated

    @property
    def believed_pose(self) -> CameraPose:
        return self.capture.believed_pose


def sense(capture: Capture) -> Sensed:
    """The capture with its CAD model and believed pose placed on the frame (:func:`placed`), the stereo
    range map of its calibrated pair (seed §3 D) searched over the depths the model expects in view, and
    that map with the model's depth in its holes."""
    from rsi.imaging.compensation import compensate_field_pair
    from rsi.imaging.stereo import range_map

    strobe = compensate_field_pair(*capture.frames)
    capture = placed(capture, strobe.image)
    expected = capture.cad.expected_depth_m
    # the ISEE's own jaws (seed §3.1) are never ranged: at 5 cm they asked for disparities past the frame
    surface = (expected < FAR_M) & ~own_body(capture.cad)
    near, far = (
        (float(expected[surface].min()), float(expected[surface].max())) if surface.any() else (0.2, 2.0)
    )
    ranges = range_map(
        *capture.stereo, capture.rig, depth_limits_m=(_NEAR_MARGIN * near, min(_FAR_MARGIN * far, FAR_M))
    )
    with np.errstate(invalid="ignore"):
        plausible = np.abs(ranges - expected) <= _RANGE_GATE_M
    matched = np.where(plausible, ranges, np.float32(np.nan)).astype(np.float32)
    return Sensed(capture, matched, np.where(plausible, ranges, expected).astype(np.float32), strobe)


def reflashed(sensed: Sensed, again: Capture) -> Sensed:
    """The visit with its frames taken again from the same pose (`again`: seed §2.1 metering).

    Nothing moved: the stereo pair, its range maps and the model placed on the frame (:func:`placed`) stay
    the visit's. `again` comes from the tour with the model where the believed pose draws it, so its own
    placement would lose the viewpoint error that :func:`placed` found.
    """
    from dataclasses import replace

    from rsi.imaging.compensation import compensate_field_pair

    kept = replace(again, cad=sensed.capture.cad, believed_pose=sensed.capture.believed_pose)
    return replace(sensed, capture=kept, strobe=compensate_field_pair(*again.frames))


# The model is searched this far over the frame for the visit's viewpoint error, at the model's median depth:
# "space" repeatability moves the image by up to 12 px at the standoff (rsi.sim.world.REPEATABILITY_PX)
_PLACE_SEARCH_PX = 16
# An edge of the model is a step of inverse depth over a 3x3 Sobel of this much (1/m): 2 cm at 0.5 m
_EDGE_INVERSE_DEPTH = 0.05
# Seed §2.3 "sharp depth deviations" at the pixel scale. A step of the model smaller than a depth jump (a
# strap 2 mm proud of its tank: 0.5-0.7 mm along the view ray of an oblique CAD vista) shows its side face
# and edge as a sliver a pixel or less wide; two viewpoints sample it differently (aliasing that no
# resampling of the reference predicts), and its edge read as a line of 1-2 mm "impacts" from the CAD
# plan's oblique views (seed 0 at 300 s: 12 false findings on truss, 16 on truss-b). Under 0.4 mm of
# second difference: planes at any tilt, a tank's curve up to 75 deg of incidence, a 0.1 mm blanket
# (tests/mission/test_seams.py); 0.4 mm is about one pixel's footprint at the plan's 0.5 mm per pixel.
_SEAM_STEP_M = 4e-4
# The model is placed only on enough edges (none on the panel's centre view, which has no edge); a sample
# of this many of them scores each candidate offset (a mean over thousands of pixels, to a fraction of a
# pixel's blur)
_MIN_EDGE_PX = 500
_PLACE_SAMPLE_PX = 4000
# The parallax of an edge is its depth's ratio to the median depth, held to this range: the jaws are left
# out and the mock-up lies within a few times the standoff
_PARALLAX_RATIO = (0.25, 4.0)


def placed(capture: Capture, image: NDArray[np.float32]) -> Capture:
    """The capture with its believed pose corrected by the visit's viewpoint error and its CAD model drawn
    from there (seed §2.3).

    The pose the robot believes misses the viewpoint error (repeatability, flexure: lab 1-2 px, space
    about 10 px at the standoff), so the model drawn from it lies off the frame: sites are looked for in
    the wrong pixels, findings placed millimetres off, and the guard bands about the model's silhouettes
    miss the edges they guard. The error is a lateral offset of the camera (seed §2.3: arm flexibility and
    thermal expansion; the same rigid-scene motion the registration in depth fits), which moves each edge
    of the model by its parallax: ``s Z0 / Z`` for an offset that moves the surfaces at the model's median
    depth ``Z0`` by ``s``. The offset that puts the most image edge strength under the model's edges
    moved so (:func:`_viewpoint_offset`) corrects the pose, and the robot's model is drawn again from the
    corrected pose (``capture.model``); a capture without a model to draw has its maps moved by the
    offset, in whole pixels. Without enough model edges in view the capture is left as it is.

    One whole-pixel shift of the maps, the placement before, left the silhouettes of near tubes and tanks
    2-7 px off in the CAD plan's close views at space repeatability (truss-b seed 0: p90 6-11 px from the
    rendered depth's jumps), and the depth-jump guard of 2 px let their edges through as lines of impacts;
    drawn from the corrected pose, the model's jumps lie on the rendered ones (median 0 px, p90 <= 2 px).
    """
    from dataclasses import replace

    found = _viewpoint_offset(capture.cad, image)
    if found is None:
        return capture
    (dy, dx), depth = found
    pose = capture.believed_pose
    # the content moves left (-x) when the camera moves right (rotation[:, 0]) and down (+row) when it
    # moves up (rotation[:, 1]); a camera moved across by T moves the surfaces at depth Z by f T / Z
    across = (-dx * pose.rotation[:, 0] + dy * pose.rotation[:, 1]) * depth / pose.focal_px
    moved_pose = replace(pose, position_m=pose.position_m + across)
    if capture.model is not None:
        return replace(capture, cad=capture.model(moved_pose), believed_pose=moved_pose)
    return replace(capture, cad=_shifted_model(capture.cad, (round(dy), round(dx))), believed_pose=moved_pose)


def _shifted_model(cad: Any, shift: tuple[int, int]) -> Any:
    """`cad`'s maps moved by whole pixels (dy, dx), the ISEE's own jaws where they are."""
    from dataclasses import replace

    # the ISEE's own jaws ride with the camera: the viewpoint error moves the scene, not them
    own = own_body(cad)
    ahead = _shifted(own.astype(np.float32), shift, 0.0) > 0.5
    # what the jaws hid from the model before it moved is unknown: no surface to inspect there
    scene = np.where(ahead, np.float32(FAR_M), _shifted(cad.expected_depth_m, shift, float(FAR_M)))
    return replace(
        cad,
        expected_depth_m=np.where(own, cad.expected_depth_m, scene).astype(np.float32),
        truss=((_shifted(cad.truss.astype(np.float32), shift, 0.0) > 0.5) & ~ahead) | own,
        components={
            name: (_shifted(mask.astype(np.float32), shift, 0.0) > 0.5) & ~ahead & ~own
            for name, mask in cad.components.items()
        },
        parts=None if cad.parts is None else _shifted(cad.parts, shift, -1.0).astype(np.int32),
    )


def own_body(cad: Any) -> NDArray[np.bool_]:
    """Pixels of the ISEE itself in a CadView: nearer than its jaws reach (seed §3.1: 11 cm).

    The jaws and the housing are rigid with the camera, so they sit on the same pixels at every visit
    whatever the arm's repeatability, and no surface of the mock-up can be nearer: the proximity servo
    keeps the jaws' tips off it.
    """
    from rsi.sim.arm import JAW_LENGTH_M

    return np.asarray(cad.expected_depth_m < JAW_LENGTH_M)


def grown(mask: NDArray[np.bool_], reach_px: int) -> NDArray[np.bool_]:
    """`mask` grown by `reach_px` pixels every way (a square's dilation)."""
    import cv2

    side = 2 * reach_px + 1
    return np.asarray(cv2.dilate(mask.astype(np.uint8), np.ones((side, side), np.uint8)) > 0)


def jaws_region(
    world: World, opening_m: float, size: tuple[int, int], margin_px: int = FRAME_MARGIN_PX
) -> NDArray[np.bool_]:
    """Pixels of the arm's ISEE frame that its jaws hide at `opening_m`, grown by `margin_px`.

    The jaws are rigid with the camera but for their opening (:meth:`rsi.sim.world.World.own_body_footprint`);
    the band about them is lost to the comparison as a frame's border is (the registration's shift and the
    detector's windows, seed §2.3-2.4).
    """
    return grown(world.own_body_footprint(size, jaw_opening_m=opening_m), margin_px)


def point_region(
    world: World, point: PlanPoint, size: tuple[int, int], margin_px: int = FRAME_MARGIN_PX
) -> NDArray[np.bool_] | None:
    """The pixels a plan point's frame inspects, as far as the ISEE's jaws go; None: every pixel (a world
    without the arm, or a vista the arm cannot reach: the free camera takes it and holds no jaws).

    Not where its own jaws stand (:func:`jaws_region`); for a second frame behind another's jaws
    (``point.behind_jaws_at_m``), only where those hid the mock-up.
    """
    from rsi.mission.viewing import reach

    if not world.has_arm or not reach(world, point.vista).reachable:
        return None
    region = ~jaws_region(world, point.jaw_opening_m, size, margin_px)
    if point.behind_jaws_at_m is not None:
        region &= jaws_region(world, point.behind_jaws_at_m, size, margin_px)
    return region


def _viewpoint_offset(cad: Any, image: NDArray[np.float32]) -> tuple[tuple[float, float], float] | None:
    """((dy, dx), Z0): the image offset at the model's median depth Z0 of the lateral camera offset whose
    parallax puts the model's edges on the most image edge strength; None without enough model edges.

    Each model edge lies at the depth of its occluding side (the nearer of a step) and moves by the offset
    times ``Z0 / Z``. Every whole-pixel offset within _PLACE_SEARCH_PX is scored by the mean edge strength
    (Sobel magnitude, a pixel of blur) under a sample of the moved edges, and the best is refined to a
    fraction of a pixel by a parabola through its neighbours. The best offset must lie inside the search
    window: one on its border is out of reach, and the model stays where the robot believes it.
    """
    import cv2

    # the jaws' edges ride with the camera (own_body): they would vote for no offset at all
    own = own_body(cad)
    jaws = cv2.dilate(own.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
    depth = np.minimum(cad.expected_depth_m, np.float32(FAR_M)).astype(np.float32)
    occluding = cv2.erode(depth, np.ones((3, 3), np.uint8))
    rows, cols = np.nonzero(model_edges(cad) & ~jaws & (occluding < FAR_M))
    if rows.size < _MIN_EDGE_PX:
        return None
    seen = (depth < FAR_M) & ~own
    median = float(np.median(depth[seen]))
    step = max(1, rows.size // _PLACE_SAMPLE_PX)
    rows, cols = rows[::step], cols[::step]
    ratio = np.clip(median / occluding[rows, cols], *_PARALLAX_RATIO)
    strength = np.hypot(
        cv2.Sobel(image.astype(np.float32), cv2.CV_32F, 1, 0, ksize=3),
        cv2.Sobel(image.astype(np.float32), cv2.CV_32F, 0, 1, ksize=3),
    )
    strength[jaws] = 0.0
    # a pixel of blur: an edge a fraction of a pixel off still counts
    reach = math.ceil(_PLACE_SEARCH_PX * float(ratio.max())) + 1
    strength = np.pad(cv2.GaussianBlur(strength, (0, 0), 1.0), reach)
    offsets = np.arange(-_PLACE_SEARCH_PX, _PLACE_SEARCH_PX + 1)
    across = cols[None, :] + reach + np.rint(offsets[:, None] * ratio[None, :]).astype(np.intp)
    score = np.stack(
        [strength[rows + reach + np.rint(dy * ratio).astype(np.intp), across].mean(axis=1) for dy in offsets]
    )
    best_row, best_col = np.unravel_index(int(np.argmax(score)), score.shape)
    last = offsets.size - 1
    if best_row in (0, last) or best_col in (0, last):
        return None
    dy = offsets[best_row] + _vertex(score[best_row - 1 : best_row + 2, best_col])
    dx = offsets[best_col] + _vertex(score[best_row, best_col - 1 : best_col + 2])
    return (float(dy), float(dx)), median


def _vertex(three: NDArray[np.float64]) -> float:
    """Offset of the maximum of the parabola through three equally spaced scores from the middle one."""
    curvature = three[0] - 2.0 * three[1] + three[2]
    return 0.0 if curvature >= 0.0 else float(np.clip(0.5 * (three[0] - three[2]) / curvature, -0.5, 0.5))


def model_edges(cad: Any) -> NDArray[np.bool_]:
    """Pixels of the model's depth steps and of its components' and truss's outlines (a CadView's maps)."""
    import cv2

    inverse = (1.0 / np.minimum(cad.expected_depth_m, FAR_M)).astype(np.float32)
    steps = np.hypot(
        cv2.Sobel(inverse, cv2.CV_32F, 1, 0, ksize=3), cv2.Sobel(inverse, cv2.CV_32F, 0, 1, ksize=3)
    )
    labels = np.zeros(inverse.shape, np.uint8)
    for number, mask in enumerate(cad.components.values(), start=1):
        labels[mask] = number
    labels[cad.truss] = 255
    outlines = cv2.morphologyEx(labels, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    return np.asarray((steps > _EDGE_INVERSE_DEPTH) | outlines, dtype=bool)


def _shifted(values: NDArray[np.floating], shift: tuple[int, int], fill: float) -> F32:
    """`values` moved by whole pixels (dy, dx), `fill` where nothing moved in."""
    dy, dx = shift
    out = np.full(values.shape, fill, dtype=np.float32)
    rows, cols = values.shape
    out[max(dy, 0) : rows + min(dy, 0), max(dx, 0) : cols + min(dx, 0)] = values[
        max(-dy, 0) : rows + min(-dy, 0), max(-dx, 0) : cols + min(-dx, 0)
    ]
    return out


def field_to_world(sensed: Sensed, row: float, col: float) -> tuple[float, float, float] | None:
    """World point seen at field pixel (row, col) from the range there and the believed pose (None: sky)."""
    depth = sensed.surface_m
    frame_row = min(max(round(row), 0), depth.shape[0] - 1)
    column = min(max(round(col), 0), depth.shape[1] - 1)
    distance = float(depth[frame_row, column])
    pose = sensed.believed_pose
    rows, cols = pose.shape
    if not math.isfinite(distance) or distance >= FAR_M:
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


def pixel_size_m(sensed: Sensed, position: tuple[float, float, float]) -> float:
    """Size of one frame pixel on the surface at `position`, metres."""
    _, along = sensed.believed_pose.project(np.asarray([position]))
    return float(along[0]) / sensed.believed_pose.focal_px


def to_field(sensed: Sensed, points_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Field row, column and depth of world points in this view."""
    xy, along = sensed.believed_pose.project(points_m)
    return xy[:, 1], xy[:, 0], along


def visible(sensed: Sensed, points_m: FloatArray, tolerance_m: float = 0.006) -> NDArray[np.bool_]:
    """Which points the frame should see: inside, and not hidden in the CAD model from the believed pose.

    Where a site is, and what hides it (a door, a tank), is the robot's model; the range map measures
    what is there, and would call a removed screw or a dent "hidden".
    """
    depth = sensed.capture.cad.expected_depth_m
    xy, along = sensed.believed_pose.project(points_m)
    rows, cols = depth.shape
    seen = np.zeros(len(points_m), dtype=bool)
    for k, ((x, y), distance) in enumerate(zip(xy, along, strict=True)):
        col, row = round(x), round(y)
        if 8 <= col < cols - 8 and 8 <= row < rows - 8 and distance > 0:
            seen[k] = abs(float(depth[row, col]) - distance) < tolerance_m
    return seen


def surface_distance_m(shape: tuple[int, ...], sensed: Sensed, position_m: tuple[float, float, float]) -> Any:
    """Each pixel's distance (on the surface, metres) from a world point's projection."""
    row, col, _ = to_field(sensed, np.asarray([position_m]))
    rows, cols = np.indices(shape[:2])
    return np.hypot(rows - row[0], cols - col[0]) * pixel_size_m(sensed, position_m)


def disc(
    shape: tuple[int, ...], sensed: Sensed, position_m: tuple[float, float, float], radius_m: float
) -> Any:
    """Pixels within `radius_m` (on the surface) of a world point's projection."""
    return surface_distance_m(shape, sensed, position_m) <= radius_m


def seen_screws(world: World, sensed: Sensed) -> list[Site]:
    sites = world.mockup.candidates.screw_sites
    seen = visible(sensed, np.asarray([site.position_m for site in sites]))
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def seen_components(world: World, sensed: Sensed) -> list[Site]:
    """Component sites whose centre the view sees (depth within 2 cm: a tank's front, a panel's face)."""
    sites = world.mockup.candidates.component_sites
    seen = visible(sensed, np.asarray([site.position_m for site in sites]), tolerance_m=0.02)
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def near_model_edges(sensed: Sensed, reach_px: int) -> NDArray[np.bool_]:
    """Pixels within `reach_px` of an edge of the view's placed model (:func:`model_edges`).

    Seed §2.3: the prediction in depth holds the parallax of every surface the model has, but an outline
    drawn from the model stays off by what placing it leaves (a pixel or two) and the stereo range smooths a
    step over its window: only there can an edge stay mis-registered by the viewpoint's repeatability.
    """
    return grown(model_edges(sensed.capture.cad), reach_px)


def model_seams(depth_m: NDArray[np.floating]) -> NDArray[np.bool_]:
    """Pixels where a model's depth map steps by more than ``_SEAM_STEP_M`` against its neighbours' trend
    (a strap 2 mm proud of its tank, a panel's rim, and every silhouette).

    The second difference of the depth along a row or a column is ~0 on a plane seen at any angle and on a
    tank's curve (a 70 mm radius bends 1e-3 mm over a 0.5 mm pixel), and is the step itself at a seam.
    """
    depth = np.minimum(np.asarray(depth_m, dtype=np.float64), FAR_M)
    bend = np.zeros(depth.shape)
    bend[:, 1:-1] = np.abs(depth[:, 2:] - 2.0 * depth[:, 1:-1] + depth[:, :-2])
    bend[1:-1, :] = np.maximum(bend[1:-1, :], np.abs(depth[2:, :] - 2.0 * depth[1:-1, :] + depth[:-2, :]))
    return np.asarray(bend > _SEAM_STEP_M, dtype=bool)


def near_model_seams(sensed: Sensed, reach_px: int) -> NDArray[np.bool_]:
    """Pixels within `reach_px` of a seam of the view's placed model (:func:`model_seams`)."""
    return grown(model_seams(sensed.capture.cad.expected_depth_m), reach_px)


def inspection_region(sensed: Sensed, settings: MissionSettings) -> NDArray[np.bool_]:
    """Pixels of the view's component surfaces, away from the truss frame and from range jumps.

    Seed §2.3: one registration per frame cannot align surfaces at different depths after a viewpoint
    error (parallax), and the truss struts behind a plate or a tank's silhouette then differ by whole edges.
    The robot knows its CAD model and believes its pose; the stereo pair measures the range (seed §3): the
    region is the components' surfaces, less a guard band (``settings.inspection_guard_px``) around the
    model's truss and around every jump of more than ``settings.depth_jump_m`` in the model's depth or in
    the measured range.
    """
    import cv2

    cad = sensed.capture.cad
    side = 2 * settings.inspection_guard_px + 1
    band = np.ones((side, side), np.uint8)
    off = cv2.dilate(cad.truss.astype(np.uint8), band).astype(bool)
    # the model's silhouettes and the measured range's jumps: the matcher smooths a jump over its window
    for depth in (cad.expected_depth_m, sensed.surface_m):
        near = np.minimum(depth, np.float32(FAR_M))
        off |= (cv2.dilate(near, band) - cv2.erode(near, band) > settings.depth_jump_m) | (depth >= FAR_M)
    return ~off


def seen_head_on(sensed: Sensed, settings: MissionSettings) -> NDArray[np.bool_]:
    """Pixels whose model surface the camera sees within ``settings.grazing_incidence_deg`` of its normal.

    The normal of the placed model's surface at each pixel is the cross product of the surface point's
    derivatives along the row and the column (the point ``Z (x, y, 1)``, x and y the pixel's ray); the
    incidence is its angle to the ray. Depth jumps and the sky read as grazing (they are out of the region
    anyway).
    """
    depth = np.minimum(sensed.capture.cad.expected_depth_m, np.float32(FAR_M)).astype(np.float64)
    pose = sensed.believed_pose
    rows, cols = depth.shape
    x = (np.arange(cols, dtype=np.float64)[None, :] - (cols - 1) / 2) / pose.focal_px
    y = (np.arange(rows, dtype=np.float64)[:, None] - (rows - 1) / 2) / pose.focal_px
    ray = np.stack(np.broadcast_arrays(x, y, np.ones_like(depth)), axis=-1)
    along_rows, along_cols = (np.asarray(part, dtype=np.float64) for part in np.gradient(depth))
    across = along_cols[..., None] * ray
    across[..., 0] += depth / pose.focal_px
    down = along_rows[..., None] * ray
    down[..., 1] += depth / pose.focal_px
    normal = np.cross(across, down)
    cosine = np.abs(np.sum(normal * ray, axis=-1)) / (
        np.linalg.norm(normal, axis=-1) * np.linalg.norm(ray, axis=-1) + 1e-30
    )
    return np.asarray(cosine > math.cos(math.radians(settings.grazing_incidence_deg)))


def within_strobe_beam(sensed: Sensed, settings: MissionSettings) -> NDArray[np.bool_]:
    """Pixels whose surface the strobe lights from well inside its beam: at most the beam's half-angle
    less ``settings.strobe_beam_margin_deg`` off its axis, seen from the strobe beside the lens (seed §2.1).

    The strobe's light falls off at its beam's edge, and where the edge crosses a surface depends on the
    surface's distance and the pose: a few millimetres of viewpoint error move a steep fall of the strobe
    image, which no comparison tells from a flaw. At the CAD plan's closest standoffs (~0.21 m) the frame's
    far corners reach 31 deg of a 32 deg beam. Sky pixels (no surface) count as inside: the region drops
    them anyway.
    """
    from rsi.sim.scene import STROBE_CUTOFF_DEG, STROBE_OFFSET_M

    depth = np.where(sensed.surface_m < FAR_M, sensed.surface_m, np.nan)
    pose = sensed.believed_pose
    rows, cols = depth.shape
    row, col = np.mgrid[0:rows, 0:cols].astype(np.float32)
    across = (col - (cols - 1) / 2) / np.float32(pose.focal_px) * depth - STROBE_OFFSET_M[0]
    up = -(row - (rows - 1) / 2) / np.float32(pose.focal_px) * depth - STROBE_OFFSET_M[1]
    off_axis_deg = np.degrees(np.arctan2(np.hypot(across, up), depth + STROBE_OFFSET_M[2]))
    with np.errstate(invalid="ignore"):
        beyond: NDArray[np.bool_] = off_axis_deg > STROBE_CUTOFF_DEG - settings.strobe_beam_margin_deg
    return ~beyond


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
