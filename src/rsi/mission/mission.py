"""Seed §2-§4 together: one inspection mission over the truss mock-up, and its score against ground truth.

A mission plans vista points that cover every component (the inside of the electrical ORU with its door
open included), takes a *reference pass* on the pristine mock-up, then an *inspection pass* after the seeded
anomalies appeared, and fuses what it sees and senses into findings:

- **visual** (seed §2): each strobe/ambient interlaced frame is compensated (seed §2.2), registered to its
  reference and tested by the calibrated likelihood-ratio test (seed §2.3-2.4); dark changes become impact
  findings (small) or swapped-component findings (large), placed in the world through the frame's depth
  and camera pose; every screw the frame sees is compared with its reference (a removed screw leaves a
  dark hole where a bright head was);
- **temperature** (seed §3-4): the pyrometer reads each black Kapton circle, with the emissivity of the
  surface it actually sees (:func:`rsi.sim.fields.emissivity`) -> hot and cold spots;
- **gas** (seed §3-4): the MOS sensor dwells at stations along the tubing -> the active leak, located
  along the tubing;
- **active inspection** (seed §2.5, first further-work item): a detection between a preliminary and the
  confirming threshold triggers a second look (another visit: a new viewpoint error and new camera noise)
  and the two looks' evidence is fused.

:func:`score_mission` matches the findings to the world's ground truth per anomaly type. See docs/mission.md.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.mockup import SCREW_HEIGHT_M
from rsi.sim.orbit import orbital_period_s

if TYPE_CHECKING:
    from rsi.archive import Archive
    from rsi.detection.detect import Detection
    from rsi.detection.roc import RocCurve
    from rsi.imaging.compensation import Compensated
    from rsi.mission.motion import SunSetting, Tour, Transit
    from rsi.mission.pair import PairResult
    from rsi.sim.anomalies import Anomaly, AnomalySet, Site
    from rsi.sim.mockup import Vista
    from rsi.sim.render import CameraPose
    from rsi.sim.world import View, World

FloatArray = NDArray[np.float64]
ProgressFn = Callable[[str, int, int], None]

MISSION_SIZE = (480, 640)  # the seed's video frame (seed §2.1)
OVERVIEW_SIZE = (600, 800)
# Per-pixel false-alarm probability of the confirming test (seed §2.4: the threshold follows from the P_F
# asked for). ~2e6 pixels are tested per mission; rendering nuisances (aliasing, parallax, shadow edges)
# leave the statistic's tails heavier than N(0, 1), and 1e-9 (6.0 sigma) is the operating point at which
# 20 seeds give at most one false finding per run (docs/mission.md).
P_FALSE_ALARM = 1e-9
# Preliminary threshold of active inspection (seed §2.5): a detection above this but below the confirming
# threshold earns a second look.
P_PRELIMINARY = 1e-4
FLAW_MODEL = "uniform"
FLAW_SIZE_PX = 3
MISREGISTRATION_STD_PX = 0.3
# Empirical nuisance from two pristine reference visits (seed §2.3-2.4, see _nuisance_scale): the local
# mean of z^2 over this window, then its maximum over the spread (the next visit's pose error differs).
NUISANCE_WINDOW_PX = 9
NUISANCE_SPREAD_PX = 9
# A small dark blob must lose at least this fraction of the reference's brightness over a 3x3 window to be
# an impact: the planted impacts darken the surface by 30-70 % (seed §4), which a 3x3 window of 0.66 mm
# pixels sees as >= 0.08 for a 1 mm impact on the dark solar cells; brightening residues lose nothing.
IMPACT_DARKENING_MIN = 0.05
SURROUND_PX = 3  # ring around a blob: the surface it lies on
DISCOLOURED_MARGIN_PX = 4  # a found discolouring's pixels leave the photometric fit with this margin
SPOT_AREA_MAX_M2 = 1.5e-5  # a spot on a dent: 4.4 mm across, a 3 mm impact (seed §4) and 2 px of blur
DENT_SPOT_DARKENING_MIN = 0.4  # a crater's slopes shade compact patches down by up to 0.35 (seeds 5, 12, 13)
INSPECTION_GUARD_PX = 2
DEPTH_JUMP_M = 0.02
DOOR_OPEN_RAD = 1.4
PANEL_STANDOFF_M = 0.35
# A dark blob bigger than this (world area) is a changed component, not a ~1 mm impact.
COMPONENT_AREA_M2 = 1.0e-4
# A missing screw leaves a 3.6 mm hole where the 8 mm head was: the head disc loses this fraction of its
# brightness or more; a present screw seen again changes by a few per cent (misregistration, noise).
SCREW_RELIEF_LOST_M = 1.0e-3  # half the 2 mm head: present heads and removed ones differ by ~20 sigma
COMPONENT_DISC_M = 0.05
COMPONENT_CHANGE_MIN = 0.05  # changed fraction of the disc: discoloured 0.16-0.63, pristine <= 0.012
COMPONENT_DIMMING_MIN = 0.1  # discoloured replacements reflect 0.4-0.8 of the original (seed §4 defects)
DENT_RELIEF_MIN_M = 1.5e-3  # dents are 2-10 mm deep (seed §4 mock-up defects)
STEREO_DISPARITY_NOISE_PX = 0.1
IMPACT_MERGE_M = 0.008  # two views' sightings of one impact: their localisation errors are a few mm
SCREW_MATCH_M = 0.008  # a visual detection this close to a screw site is that screw's evidence
SHADOW_EDGE_DN_PX = 10.0  # ambient gradient of a sun-shadow edge; brushed and grained skins stay below
SHADOW_JAG_PX = 0.5
STROBE_TARGET_DN = 180.0  # metering: the brightest 0.5 % of the surface this far up the 8-bit range
METER_PERCENTILE = 99.5
AMBIENT_TARGET_DN = 40.0  # metering: sunlight's share of the frame, below which the shutter stays the seed's
MIN_STROBE_ENERGY = 1.0  # a dimmer flash loses more to noise than it saves from saturation (measured)
THERMAL_THRESHOLD_K = 3.0  # pyrometer noise 0.1 K; a Peltier spot is 30 K (seed §4)
GAS_THRESHOLD_PPM = 2.0  # MOS noise is ~0.02 ppm in clean air
GAS_STANDOFF_M = 0.1
GAS_STATION_SPACING_M = 0.01
GAS_DWELL_S = 20.0
GAS_SURVEY_START_S = 60.0  # after the visual pass; the leaks start within 30 s (seed §4)
REPEATABILITY = ("lab", "space")
# The reference pass begins 26 deg past orbit noon, the inspection pass one orbit later at the same phase:
# a sun 20 deg apart between the passes raised false impacts 4 -> 15 on seed 0 (docs/mission.md).
ORBIT_START_S = (400.0, 400.0 + orbital_period_s())
_AMBIENT_K = 293.15


@dataclass(frozen=True)
class PlanPoint:
    """One vista point of the mission plan.

    Attributes
    ----------
    name : str
        Unique name (the archive's vista name).
    vista : str
        The world's vista it is taken from.
    door_angle_rad : float
        Opening of the electrical ORU's door while the frame is taken.
    """

    name: str
    vista: str
    door_angle_rad: float = 0.0


@dataclass(frozen=True)
class MissionFinding:
    """A fused finding of the inspection pass.

    Attributes
    ----------
    kind : str
        ``"impact"``, ``"missing_screw"``, ``"swapped_component"``, ``"hot_spot"``, ``"cold_spot"`` or
        ``"gas_leak"``.
    position_m : (float, float, float)
        World position, metres.
    size_m : float
        Estimated size (impact diameter, screw head, component extent, Kapton circle, station spacing).
    confidence : float
        In [0, 1].
    source : str
        Plan point (visual), ``"pyrometer"`` or ``"gas"``.
    score : float
        The evidence: LRT peak (the weaker of the comparisons with the two pristine visits; fused over both
        looks for a second look), the screw head's lost relief (m),
        temperature difference (K) or peak concentration (ppm).
    second_look : bool
        Whether active inspection took a second look before this was reported.
    bbox : (int, int, int, int) or None
        Field-image box ``(row0, col0, row1, col1)`` for visual findings.
    """

    kind: str
    position_m: tuple[float, float, float]
    size_m: float
    confidence: float
    source: str
    score: float
    second_look: bool = False
    bbox: tuple[int, int, int, int] | None = None


@dataclass(frozen=True)
class VisitImages:
    """One inspection visit's comparison, in the inspection's field frame (what the report crops).

    Attributes
    ----------
    reference : ndarray of shape (M, N), float32
        The compensated reference registered onto the inspection (its prediction of the inspection).
    inspection : ndarray of shape (M, N), float32
        The compensated inspection field.
    difference : ndarray of shape (M, N), float32
        Inspection minus prediction.
    score : ndarray of shape (M, N), float32
        The dark-flaw LRT score (noise sigmas).
    valid : ndarray of shape (M, N), bool
        Pixels the test covered.
    impact_truth : ndarray of shape (M, N), bool
        Field pixels of the visible impacts that count towards recall (ground truth, for the run's ROC).
    impact_strengths : tuple of float
        Each of those impacts' strength: the difference at its darkest pixel in noise sigmas.
    row_step : int
        Frame rows per image row: 1 for the mission's full-resolution images (two frames, strobes in
        opposite fields), 2 for an intra-frame field.
    """

    reference: NDArray[np.float32]
    inspection: NDArray[np.float32]
    difference: NDArray[np.float32]
    score: NDArray[np.float32]
    valid: NDArray[np.bool_]
    impact_truth: NDArray[np.bool_]
    impact_strengths: tuple[float, ...] = ()
    row_step: int = 1


@dataclass(frozen=True)
class VisitRecord:
    """What one plan point's inspection visit saw.

    Attributes
    ----------
    point : str
        Plan point name.
    translation_xy : (float, float)
        Registration of reference to inspection, field pixels.
    detections : int
        Flaws above the preliminary threshold.
    second_looks : int
        Detections that triggered a second look.
    confirmed, rejected : int
        Second looks that confirmed / rejected their detection.
    visible : tuple of int
        Indices of ground-truth anomalies visible in the frame (from the simulator's truth masks).
    images : VisitImages or None
        The comparison's images (for the report and the run's ROC).
    """

    point: str
    translation_xy: tuple[float, float]
    detections: int
    second_looks: int
    confirmed: int
    rejected: int
    visible: tuple[int, ...]
    images: VisitImages | None = field(default=None, repr=False, compare=False)


@dataclass(frozen=True)
class MissionResult:
    """Everything one mission produced.

    Attributes
    ----------
    seed : int
        The world's seed.
    repeatability : str
        Viewpoint repeatability of the visits.
    active : bool
        Whether active inspection was on.
    size : (int, int)
        Frame size.
    plan : tuple of PlanPoint
    findings : tuple of MissionFinding
    visits : tuple of VisitRecord
    truth : AnomalySet
        The world's ground truth (for scoring and the report).
    pyrometer_k : dict of str to float
        Reading at each Kapton site.
    gas_ppm : ndarray of shape (S,)
        Concentration estimated at each gas station (end of its dwell).
    gas_stations_m : ndarray of shape (S, 3)
        Station positions.
    run_id : int or None
        The archive's run, when an archive was given.
    timings_s : dict of str to float
        ``reference``, ``inspection``, ``sensors``, ``total``, and ``transits`` (wall time of the arm's
        simulated transits, part of the passes).
    roc : tuple of RocCurve
        The run's empirical ROC (every inspection visit's dark score against the visible impacts that
        count) and the theoretical one for those impacts' measured strengths; empty when no counted impact
        was visible.
    overview_rgb : ndarray of shape (H, W, 3), uint8, or None
        The whole mock-up after the anomalies appeared, unmarked.
    overview_pose : CameraPose or None
        The overview picture's camera: projects findings and truth into it.
    transits : tuple of Transit
        Every move of the ISEE by the arm, in order, with its 44 Hz proximity trace (empty without the arm;
        out-of-reach vistas appear with an empty trace and their shortfall). See :mod:`rsi.mission.motion`.
    suns : tuple of SunSetting
        The solar simulator at each visit: mission-clock time, sun and lamp directions, lamp configuration
        (empty without the orbit).
    """

    seed: int
    repeatability: str
    active: bool
    size: tuple[int, int]
    plan: tuple[PlanPoint, ...]
    findings: tuple[MissionFinding, ...]
    visits: tuple[VisitRecord, ...]
    truth: AnomalySet
    pyrometer_k: dict[str, float]
    gas_ppm: FloatArray
    gas_stations_m: FloatArray
    run_id: int | None
    timings_s: dict[str, float] = field(default_factory=dict)
    roc: tuple[RocCurve, ...] = ()
    overview_rgb: NDArray[np.uint8] | None = field(default=None, repr=False, compare=False)
    overview_pose: CameraPose | None = field(default=None, repr=False, compare=False)
    transits: tuple[Transit, ...] = ()
    suns: tuple[SunSetting, ...] = ()


# ------------------------------------------------------------------------------------------------- plan


def _extra_vistas() -> tuple[Vista, ...]:
    """Views the mock-up does not list: five close views of the solar panel (seed §4 C).

    At the 0.5 m standoff a pixel is 0.66 mm on the dark cells: a millimetre impact covers two pixels and
    the cells' 0.8 mm texels alias from visit to visit. At PANEL_STANDOFF_M a pixel is 0.46 mm; four views,
    the image's rows across the truss, cover the panel and its corner screws, and a fifth looks straight at
    the component's site, where a replacement's dent would be: in the corners of the other four a crater is
    seen obliquely and its shading hides the spots in it.
    """
    from rsi.sim.mockup import truss_mockup, vista

    centre = truss_mockup().vistas["C_panel"].target_m
    corners = [
        (f"C_panel_{side}_{edge}", dx, dy)
        for side, dx in (("west", -0.125), ("east", 0.125))
        for edge, dy in (("front", -0.095), ("back", 0.095))
    ]
    return tuple(
        vista(
            name,
            (centre[0] + dx, centre[1] + dy, centre[2]),
            (0.0, 0.0, 1.0),
            (0.0, 1.0, 0.0),
            PANEL_STANDOFF_M,
        )
        for name, dx, dy in [*corners, ("C_panel_centre", 0.0, 0.0)]
    )


PLAN: tuple[PlanPoint, ...] = (
    PlanPoint("A_door", "A_door"),
    PlanPoint("A_door_open", "A_door", DOOR_OPEN_RAD),
    PlanPoint("A_kapton", "A_kapton"),
    PlanPoint("B_tank", "B_tank"),
    PlanPoint("C_panel_west_front", "C_panel_west_front"),
    PlanPoint("C_panel_west_back", "C_panel_west_back"),
    PlanPoint("C_panel_east_front", "C_panel_east_front"),
    PlanPoint("C_panel_east_back", "C_panel_east_back"),
    PlanPoint("C_panel_centre", "C_panel_centre"),
    PlanPoint("D_tubing", "D_tubing"),
)


def plan_vistas(world: World) -> tuple[PlanPoint, ...]:
    """Add the plan's extra vistas to `world` (once) and return the plan (every component covered)."""
    for point in _extra_vistas():
        if point.name not in world.vistas:
            world.add_vista(point)
    return PLAN


# ------------------------------------------------------------------------------------------------ visual


def _with_reference_interpolation(reference: Compensated, inspection: Compensated) -> tuple[Any, Any]:
    """Both images with the ambient-interpolation variance of the reference, dilated by the repeatability.

    Seed §2.2: under the same ambient the interpolation errors of reference and inspection are the same and
    cancel. The inspection's own estimate would also count a new flaw's sharp edge as interpolation error
    and hide the flaw behind it, so the flaw-free reference's map is used for both.
    """
    import cv2

    shared = np.asarray(
        cv2.dilate(reference.interpolation_variance, np.ones((5, 5), np.uint8)), dtype=np.float32
    )

    def rebuilt(image: Compensated) -> Compensated:
        sensor = image.variance - image.interpolation_variance
        return replace(image, variance=(sensor + shared).astype(np.float32), interpolation_variance=shared)

    return rebuilt(reference), rebuilt(inspection)


def _nuisance_scale(first: Compensated, second: Compensated) -> NDArray[np.float32]:
    """The larger of the two references' excess and the reference's own sub-pixel-phase excess."""
    return np.maximum(_pair_excess(first, second), _pair_excess(first, _half_pixel_shifted(first)))


def _parallax_scale(reference: Compensated, view: View, shift_px: float) -> NDArray[np.float32]:
    """Variance factor for surfaces off the plane one translation registers (seed §2.3, parallax).

    A viewpoint error that shifts the image by ``shift_px`` at the median depth z0 shifts a surface at
    depth z by ``shift_px * z0 / z``: it stays mis-registered by ``delta = shift_px |z0 / z - 1|``, which to
    first order changes the difference by ``delta |grad I|`` (the detector's own mis-registration model).
    """
    import cv2

    depth = view.depth_m
    assert depth is not None
    surface = depth < 10.0
    seen = surface & reference.valid
    if not seen.any():
        return np.ones(depth.shape, np.float32)
    z0 = float(np.median(depth[seen]))
    delta = np.where(surface, shift_px * np.abs(z0 / np.maximum(depth, 1e-3) - 1.0), 0.0).astype(np.float32)
    gx = cv2.Sobel(reference.image, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(reference.image, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    extra = delta * delta * (gx * gx + gy * gy)
    spread = np.ones((NUISANCE_SPREAD_PX, NUISANCE_SPREAD_PX), np.uint8)
    extra = np.asarray(cv2.dilate(extra, spread), dtype=np.float32)
    return (1.0 + extra / np.maximum(reference.variance, np.float32(1e-6))).astype(np.float32)


def _half_pixel_shifted(image: Compensated) -> Compensated:
    """`image` resampled half a pixel along both axes: the sub-pixel phase no second visit may have had.

    A feature thinner than a pixel (a door gap, a grid line) renders differently at each sampling phase and
    no interpolation predicts it; two reference visits show that only where their phases happened to differ.
    """
    import cv2

    shape = (image.image.shape[1], image.image.shape[0])
    matrix = np.array([[1.0, 0.0, 0.5], [0.0, 1.0, 0.5]], dtype=np.float32)

    def moved(values: NDArray[np.float32]) -> NDArray[np.float32]:
        warped = cv2.warpAffine(
            values, matrix, shape, flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE
        )
        return np.asarray(warped, dtype=np.float32)

    valid = moved(image.valid.astype(np.float32)) > 0.999
    return replace(
        image,
        image=moved(image.image),
        variance=moved(image.variance),
        interpolation_variance=moved(image.interpolation_variance),
        valid=valid,
    )


def _pair_excess(first: Compensated, second: Compensated) -> NDArray[np.float32]:
    """Per-pixel factor by which the noise model under-states what two pristine visits differ by.

    Seed §2.3-2.4: mis-registration and compensation errors "can be interpreted as increasing the noise".
    Two reference visits of the same vista (independent pose errors and camera noise) contain no flaw, so
    their calibrated LRT statistic z should be N(0, 1). Where texture aliasing, parallax, relief or the
    panel's cell lines make it wider, the local mean of z^2 (a ``NUISANCE_WINDOW_PX`` box, then the maximum
    over ``NUISANCE_SPREAD_PX`` to cover the next visit's different pose error) is that excess; floored at 1
    it multiplies both images' variance before the inspection is tested.
    """
    import cv2

    from rsi.mission.pair import inspect_pair

    ref, other = _with_reference_interpolation(first, second)
    # `second` predicts `first`: the statistic lies in the first reference's frame, where it is used
    pair = inspect_pair(
        other,
        ref,
        flaw_model=FLAW_MODEL,
        size=FLAW_SIZE_PX,
        p_false_alarm=P_FALSE_ALARM,
        polarity="both",
        misregistration_std_px=MISREGISTRATION_STD_PX,
    )
    statistic = np.where(pair.detection.valid, pair.detection.statistic, np.float32(0.0))
    energy = cv2.blur((statistic * statistic).astype(np.float32), (NUISANCE_WINDOW_PX, NUISANCE_WINDOW_PX))
    spread = np.ones((NUISANCE_SPREAD_PX, NUISANCE_SPREAD_PX), np.uint8)
    scale = np.asarray(cv2.dilate(energy, spread), dtype=np.float32)
    return np.maximum(scale, np.float32(1.0))


def _strobe_image(world: World, view: View) -> Compensated:
    """The visit's full-resolution strobe image: its frame and the next, strobes in opposite fields.

    Seed §2.2 intra-frame compensation keeps one field: every other row, 1.3 mm apart at the standoff, so a
    ~1 mm impact may fall between the lit rows. Two frames with the strobe on the odd and then the even
    field give every row, each compensated within its own frame.
    """
    from rsi.imaging.compensation import compensate_field_pair

    return compensate_field_pair(view.frame, world.next_frame(view, lit_field="even"))


def _inspection_region(view: View) -> NDArray[np.bool_]:
    """Pixels of the view's component surfaces, away from the truss frame and from depth jumps.

    Seed §2.3: one registration per frame cannot align surfaces at different depths after a viewpoint
    error (parallax), and the truss struts behind a plate or a tank's silhouette then differ by whole edges.
    The robot knows its CAD model and the pose (the stereo pair gives depth, seed §3): the region is the
    components' surfaces, less a guard band of INSPECTION_GUARD_PX around the truss and around every depth
    jump of more than DEPTH_JUMP_M.
    """
    import cv2

    depth, truss = view.depth_m, view.truss_mask
    assert depth is not None and truss is not None
    band = np.ones((2 * INSPECTION_GUARD_PX + 1, 2 * INSPECTION_GUARD_PX + 1), np.uint8)
    near = np.minimum(depth, np.float32(10.0))
    jump = cv2.dilate(near, band) - cv2.erode(near, band) > DEPTH_JUMP_M
    off = cv2.dilate(truss.astype(np.uint8), band).astype(bool) | jump | (depth >= 10.0)
    return ~off


def _with_shadow_edges(image: Compensated, view: View) -> Compensated:
    """The reference with the compensation error of a sharp ambient edge at another visit added.

    Seed §2.2 interpolates each lit row's ambient from the unlit rows around it. Along a sharp sun-shadow
    edge that is exact only while the edge runs straight across the rows; the next visit sees the edge a
    fraction of a pixel elsewhere, jagged by the shadow's sampling, and its interpolation misses by up to
    the edge's contrast. The reference's own unlit rows show where such edges are: their gradient times
    SHADOW_JAG_PX is the one-sigma error added to the interpolation variance the comparison shares.
    """
    import cv2

    raw = view.frame.raw.astype(np.float32)
    unlit = raw[0::2] if view.frame.lit_field == "odd" else raw[1::2]
    gx = cv2.Sobel(unlit, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(unlit, cv2.CV_32F, 0, 1, ksize=3, scale=0.0625)  # field rows are two frame rows apart
    gradient = np.sqrt(gx * gx + gy * gy)
    edge = np.where(gradient > SHADOW_EDGE_DN_PX, gradient * np.float32(SHADOW_JAG_PX), np.float32(0.0))
    extra = np.repeat(edge * edge, 2, axis=0)[: image.image.shape[0]]
    interpolation = (image.interpolation_variance + extra).astype(np.float32)
    return replace(image, variance=image.variance + extra, interpolation_variance=interpolation)


def _restricted(image: Compensated, region: NDArray[np.bool_]) -> Compensated:
    return replace(image, valid=image.valid & region)


def _compare(
    reference: Compensated,
    inspection: Compensated,
    p_false_alarm: float,
    scale: NDArray[np.float32] | None = None,
) -> PairResult:
    from rsi.mission.pair import inspect_pair

    ref, insp = _with_reference_interpolation(reference, inspection)
    if scale is not None:
        ref = replace(ref, variance=(ref.variance * scale).astype(np.float32))
        insp = replace(insp, variance=(insp.variance * scale).astype(np.float32))
    return inspect_pair(
        ref,
        insp,
        flaw_model=FLAW_MODEL,
        size=FLAW_SIZE_PX,
        p_false_alarm=p_false_alarm,
        polarity="dark",
        misregistration_std_px=MISREGISTRATION_STD_PX,
    )


def _field_to_world(view: View, row: float, col: float) -> tuple[float, float, float] | None:
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


def _pixel_m(view: View, position: tuple[float, float, float]) -> float:
    """Size of one frame pixel on the surface at `position`, metres."""
    _, along = view.pose.project(np.asarray([position]))
    return float(along[0]) / view.pose.focal_px


def _to_field(view: View, points_m: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Field row, column and depth of world points in this view."""
    xy, along = view.pose.project(points_m)
    return xy[:, 1], xy[:, 0], along


def _visible(view: View, points_m: FloatArray, tolerance_m: float = 0.006) -> NDArray[np.bool_]:
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


def _surface_distance_m(shape: tuple[int, ...], view: View, position_m: tuple[float, float, float]) -> Any:
    """Each pixel's distance (on the surface, metres) from a world point's projection."""
    row, col, _ = _to_field(view, np.asarray([position_m]))
    rows, cols = np.indices(shape[:2])
    return np.hypot(rows - row[0], cols - col[0]) * _pixel_m(view, position_m)


def _disc(shape: tuple[int, ...], view: View, position_m: tuple[float, float, float], radius_m: float) -> Any:
    """Pixels within `radius_m` (on the surface) of a world point's projection."""
    return _surface_distance_m(shape, view, position_m) <= radius_m


def _screw_relief_m(depth_m: NDArray[np.float32], view: View, site: Site) -> float:
    """Height of the screw head above the plate around it in the stereo range map (seed §3, §4 screws).

    A head stands SCREW_HEIGHT_M proud; a removed one leaves the plate and a flat hole. The image alone
    tells them apart poorly (the hole is as dark as the slot, the plate as bright as the head, and the
    head's pattern correlates with the hole's at 0.43 against 0.42 for a present head, seeds 0-19);
    the relief's median over ~45 head pixels has a noise of ~0.1 mm. NaN when the view holds too few.
    """
    distance = _surface_distance_m(depth_m.shape, view, site.position_m)
    radius = 0.5 * site.size_m
    usable = np.isfinite(depth_m) & (depth_m < 10.0)
    head = (distance <= 0.6 * radius) & usable
    plate = (distance >= 1.5 * radius) & (distance <= 2.5 * radius) & usable
    if head.sum() < 5 or plate.sum() < 10:
        return math.nan
    return float(np.median(depth_m[plate]) - np.median(depth_m[head]))


def _component_change(pair: PairResult, view: View, site: Site) -> float:
    """Fraction of the component's central disc whose difference exceeds 3 noise sigmas (seed §4 swaps).

    A discoloured replacement darkens the whole component (measured 0.16-0.63 over seeds 0-5 where one
    was, <= 0.012 on pristine ones); a 5 cm disc at the site's centre is the part every view of it shows.
    """
    detection = pair.detection
    disc = _disc(detection.difference.shape, view, site.position_m, COMPONENT_DISC_M) & detection.valid
    if disc.sum() < 50:
        return 0.0
    z = np.abs(detection.difference[disc]) / np.maximum(detection.sigma[disc], np.float32(1e-6))
    return float(np.mean(z > 3.0))


def _component_dimming(pair: PairResult, view: View, site: Site) -> float:
    """Relative change of the component's brightness in its central disc, before photometric matching.

    Seed §2.3 registration fits a gain and a bias, and where one component fills the frame (the solar
    panel) that fit absorbs its discolouring whole. The strobe's energy is the same on both passes
    (metered once per vista), so the raw ratio of the medians is the reflectance change itself.
    """
    detection = pair.detection
    registration = detection.registration
    disc = _disc(detection.difference.shape, view, site.position_m, COMPONENT_DISC_M) & detection.valid
    if registration is None or disc.sum() < 50:
        return 0.0
    predicted = pair.inspection[disc] - detection.difference[disc]
    warped = (predicted - np.float32(registration.bias)) / np.float32(registration.gain)
    before = float(np.median(warped))
    return float(np.median(pair.inspection[disc])) / before - 1.0 if before > 1.0 else 0.0


def _relief_m(depth_m: NDArray[np.float32], view: View, site: Site) -> float:
    """Depth of the site's centre below its surroundings: central 3 cm disc against a 4.5-7 cm ring."""
    distance = _surface_distance_m(depth_m.shape, view, site.position_m)
    inner, ring = distance <= 0.03, (distance >= 0.045) & (distance <= 0.07)
    usable = np.isfinite(depth_m) & (depth_m < 10.0)
    inner, ring = inner & usable, ring & usable
    if inner.sum() < 20 or ring.sum() < 20:
        return 0.0
    return float(np.median(depth_m[inner]) - np.median(depth_m[ring]))


def _stereo_depth(view: View, rng: np.random.Generator) -> NDArray[np.float32]:
    """The ISEE stereo pair's range map (seed §3): the view's depth with the disparity noise of matching.

    sigma_Z = Z^2 sigma_d / (f B) with sigma_d = STEREO_DISPARITY_NOISE_PX, baseline B of the pair.
    """
    from rsi.sim.scene import STEREO_BASELINE_M

    depth = view.depth_m
    assert depth is not None
    sigma = depth * depth * np.float32(STEREO_DISPARITY_NOISE_PX / (view.pose.focal_px * STEREO_BASELINE_M))
    noisy = depth + sigma * rng.standard_normal(depth.shape).astype(np.float32)
    return np.asarray(np.where(depth < 10.0, noisy, depth), dtype=np.float32)


def _confidence(margin: float) -> float:
    """Confidence from a margin over the threshold in noise sigmas: Phi(margin), in [0.5, 1)."""
    return float(0.5 * special.erfc(-margin / math.sqrt(2.0)))


@dataclass
class _Look:
    """One dark blob of a visit, kept until it is classified."""

    position_m: tuple[float, float, float]
    area_m2: float
    score: float
    bbox: tuple[int, int, int, int]
    second_look: bool
    darkening: float = 0.0


def _darkening(pair: PairResult, bbox: tuple[int, int, int, int]) -> float:
    """Largest fraction of the reference's brightness a 3x3 window of the blob lost (0: none)."""
    import cv2

    detection = pair.detection
    row0, col0, row1, col1 = bbox
    r0, c0 = max(row0 - 1, 0), max(col0 - 1, 0)
    r1, c1 = min(row1 + 1, detection.difference.shape[0]), min(col1 + 1, detection.difference.shape[1])
    difference = np.where(detection.valid[r0:r1, c0:c1], detection.difference[r0:r1, c0:c1], 0.0)
    predicted = pair.inspection[r0:r1, c0:c1] - detection.difference[r0:r1, c0:c1]
    lost = cv2.blur(-difference.astype(np.float32), (3, 3), borderType=cv2.BORDER_REPLICATE)
    bright = cv2.blur(np.maximum(predicted, 0.0).astype(np.float32), (3, 3), borderType=cv2.BORDER_REPLICATE)
    fraction = lost / np.maximum(bright, np.float32(1.0))
    return float(fraction.max()) if fraction.size else 0.0


def _blobs(pair: PairResult, view: View) -> list[_Look]:
    """Each dark blob of the comparison as a look at its peak: the preliminary threshold grows a millimetre
    spot's blob into the noise around it, and its centroid can leave the 5x5 window in which the other
    reference's comparison and the second look are read (:func:`_second_look_score`)."""
    looks: list[_Look] = []
    score = pair.detection.score
    for flaw in pair.flaws:
        row0, col0, row1, col1 = flaw.bbox
        peak_row, peak_col = np.unravel_index(
            np.argmax(score[row0:row1, col0:col1]), (row1 - row0, col1 - col0)
        )
        position = _field_to_world(view, float(row0 + peak_row), float(col0 + peak_col))
        if position is None:
            continue
        pixel = _pixel_m(view, position)
        look = _Look(position, flaw.area_px * pixel * pixel, flaw.score, flaw.bbox, False)
        look.darkening = _darkening(pair, flaw.bbox)
        looks.append(look)
    return looks


def _screw_checks(
    world: World,
    view: View,
    source: str,
    *,
    depth_m: NDArray[np.float32],
    reliefs: Mapping[str, float],
    done: set[str],
) -> list[MissionFinding]:
    """Screws the frame sees and no earlier visit checked: a head 2 mm proud of the plate, or gone (seed §4:
    screws randomly removed), by its relief in the stereo range map against the reference's."""
    findings = []
    screws = [s for s in world.mockup.candidates.screw_sites if s.name not in done]
    seen = _visible(view, np.asarray([s.position_m for s in screws])) if screws else np.zeros(0, bool)
    for site, visible in zip(screws, seen, strict=True):
        if not visible:
            continue
        done.add(site.name)
        before = reliefs.get(site.name, math.nan)
        lost = (before if math.isfinite(before) else SCREW_HEIGHT_M) - _screw_relief_m(depth_m, view, site)
        if lost > SCREW_RELIEF_LOST_M:
            findings.append(
                MissionFinding(
                    kind="missing_screw",
                    position_m=site.position_m,
                    size_m=site.size_m,
                    confidence=_confidence((lost - SCREW_RELIEF_LOST_M) / 2e-4),
                    source=source,
                    score=lost,
                )
            )
    return findings


def _without_discoloured(
    view: View,
    explanations: list[_Explanation],
    images: tuple[Compensated, Compensated, Compensated],
    *,
    pair: PairResult,
    scale: NDArray[np.float32],
    p_false_alarm: float,
) -> tuple[Compensated, Compensated, Compensated, PairResult]:
    """Reference, second reference, inspection and their comparison without a discoloured component.

    Seed §2.3 fits one gain and bias to the whole frame: a replacement that reflects half as much and fills
    half the frame drags that fit, and the rest of the view (a plate beside a discoloured tank) is left
    +12 DN off, which inflates the comparison's robust noise scale 15-fold and hides impacts there. Once
    the swap is found, its pixels (the CAD projection, a few pixels wider for the pose error) leave the fit.
    """
    import cv2

    masks = [
        view.component_masks[e.component]
        for e in explanations
        if e.component is not None and e.component in view.component_masks
    ]
    if not masks:
        return (*images, pair)
    band = np.ones((2 * DISCOLOURED_MARGIN_PX + 1, 2 * DISCOLOURED_MARGIN_PX + 1), np.uint8)
    changed = cv2.dilate(np.logical_or.reduce(masks).astype(np.uint8), band).astype(bool)
    reference, other, inspection = (_restricted(image, ~changed) for image in images)
    return reference, other, inspection, _compare(reference, inspection, p_false_alarm, scale)


def _second_look_score(pair: PairResult, view: View, position: tuple[float, float, float]) -> float:
    """Peak score of the second look within 2 px of where the first look's blob is (seed §2.5)."""
    row, col, _ = _to_field(view, np.asarray([position]))
    score = pair.detection.score
    r, c = round(row[0]), round(col[0])
    window = score[max(r - 2, 0) : r + 3, max(c - 2, 0) : c + 3]
    return float(window.max()) if window.size else 0.0


def _threshold(p_false_alarm: float) -> float:
    from rsi.detection.flaw_models import flaw_kernel
    from rsi.detection.roc import thresholds

    weights = flaw_kernel(FLAW_MODEL, size=FLAW_SIZE_PX)
    return float(thresholds(np.array([p_false_alarm]), polarity="dark", method="lrt", weights=weights)[0])


# --------------------------------------------------------------------------------------------- sensors


def _pyrometer_pass(world: World, rng: np.random.Generator) -> tuple[list[MissionFinding], dict[str, float]]:
    """Read each Kapton circle with the pyrometer aimed from 0.5 m (seed §3-4) -> hot and cold spots."""
    from rsi.sensors.pyrometer import Pyrometer, read_pyrometer
    from rsi.sim.fields import emissivity

    instrument = Pyrometer()
    sites = world.mockup.candidates.peltier_sites
    spot_radius_m = 0.5 * float(instrument.spot_diameter_m(0.5))
    low, high = {"lab": (0.0, 1e-3), "space": (2e-3, 6e-3)}[world.repeatability]
    findings: list[MissionFinding] = []
    readings: dict[str, float] = {}
    for site in sites:
        normal = np.asarray(site.normal)
        u = np.cross(normal, (0.0, 0.0, 1.0))
        u = u / np.linalg.norm(u) if np.linalg.norm(u) > 1e-9 else np.array([1.0, 0.0, 0.0])
        w = np.cross(normal, u)
        # the laser-sighted spot misses the circle's centre by the arm's repeatability
        miss, angle = rng.uniform(low, high), rng.uniform(0.0, 2 * math.pi)
        centre = np.asarray(site.position_m) + miss * (math.cos(angle) * u + math.sin(angle) * w)
        radii, angles = np.meshgrid(np.linspace(0.0, spot_radius_m, 4), np.linspace(0, 2 * math.pi, 8))
        points = centre + radii.reshape(-1, 1) * (
            np.cos(angles).reshape(-1, 1) * u + np.sin(angles).reshape(-1, 1) * w
        )
        temperature = world.temperature_k(points)
        eps = emissivity(points, site.surface, kapton_sites=sites)
        # the optics average radiance over the spot, i.e. one reading of the mean scene
        reading = read_pyrometer(float(np.mean(temperature)), float(np.mean(eps)), instrument, rng=rng)
        temperature_k = float(reading.temperature_k)
        readings[site.name] = temperature_k
        delta = temperature_k - _AMBIENT_K
        if abs(delta) > THERMAL_THRESHOLD_K:
            findings.append(
                MissionFinding(
                    kind="hot_spot" if delta > 0 else "cold_spot",
                    position_m=tuple(float(x) for x in centre),  # type: ignore[arg-type]
                    size_m=site.size_m,
                    confidence=_confidence((abs(delta) - THERMAL_THRESHOLD_K) / instrument.noise_std_k),
                    source="pyrometer",
                    score=delta,
                )
            )
    return findings, readings


def _gas_stations(world: World) -> FloatArray:
    """Stations 0.1 m in front of the tubing's horizontal runs, where the leak holes are (seed §4 F)."""
    leaks = world.mockup.candidates.leak_sites
    front = np.asarray(leaks[0].normal)
    heights = sorted({round(site.position_m[2], 4) for site in leaks})
    xs = [site.position_m[0] for site in leaks]
    # the whole run of each tube, one station per spacing, plus a margin of one jet half-width
    low, high = min(xs) - 0.1, max(xs) + 0.1
    count = round((high - low) / GAS_STATION_SPACING_M) + 1
    y = leaks[0].position_m[1] + GAS_STANDOFF_M * front[1]
    stations = [(x, y, z) for z in heights for x in np.linspace(low, high, count)]
    return np.asarray(stations, dtype=np.float64)


def _gas_pass(world: World, rng: np.random.Generator) -> tuple[list[MissionFinding], FloatArray, FloatArray]:
    """Dwell the MOS sensor at each station (seed §3 H) and locate the leak along the tubing."""
    from rsi.sensors.gas import MosGasSensor, read_gas

    sensor = MosGasSensor()
    stations = _gas_stations(world)
    per_station = int(GAS_DWELL_S * sensor.sample_rate_hz)
    samples = np.repeat(np.arange(len(stations)), per_station)
    times = GAS_SURVEY_START_S + np.arange(samples.size) / sensor.sample_rate_hz
    concentration = world.gas_concentration_ppm(stations[samples], times)
    readings = read_gas(concentration, sensor, rng=rng)
    tail = int(2.0 * sensor.sample_rate_hz)  # the last 2 s of each dwell, the sensor nearly settled
    estimate = readings.estimated_ppm.reshape(len(stations), per_station)[:, -tail:].mean(axis=1)
    findings: list[MissionFinding] = []
    best = int(np.argmax(estimate))
    if estimate[best] > GAS_THRESHOLD_PPM:
        position = stations[best].copy()
        # the jet is round: a parabola through the neighbours on the same run refines the peak
        if 0 < best < len(stations) - 1 and stations[best - 1][2] == stations[best + 1][2] == position[2]:
            left, mid, right = estimate[best - 1 : best + 2]
            curvature = left - 2 * mid + right
            if curvature < 0:
                position[0] += 0.5 * (left - right) / curvature * GAS_STATION_SPACING_M
        position[1] = world.mockup.candidates.leak_sites[0].position_m[1]  # on the tubing, not the station
        findings.append(
            MissionFinding(
                kind="gas_leak",
                position_m=(float(position[0]), float(position[1]), float(position[2])),
                size_m=GAS_STATION_SPACING_M,
                confidence=_confidence(float(estimate[best]) / GAS_THRESHOLD_PPM - 1.0),
                source="gas",
                score=float(estimate[best]),
            )
        )
    return findings, stations, estimate


# -------------------------------------------------------------------------------------------- mission


def _check(seed: object, archive: object, repeatability: object, active: object, progress: object) -> int:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be an integer >= 0; got {seed!r}.")
    v.choice(repeatability, "repeatability", REPEATABILITY)
    if not isinstance(active, bool):
        raise InputError(f"active must be True or False; got {active!r}.")
    if progress is not None and not callable(progress):
        raise InputError(
            f"progress must be None or a callable progress(stage, done, total); got {progress!r}."
        )
    if archive is not None:
        from rsi.archive import Archive

        if not isinstance(archive, Archive):
            raise InputError(
                f"archive must be None or an rsi.archive.Archive; got {type(archive).__name__}. "
                "Open one with rsi.archive.Archive.open(path)."
            )
    return int(seed)


def _sensor_passes(
    world: World, seed: int, report: Callable[[str], None]
) -> tuple[list[MissionFinding], dict[str, float], list[MissionFinding], FloatArray, FloatArray]:
    rng = np.random.default_rng(np.random.SeedSequence([seed, 7]))
    thermal, readings = _pyrometer_pass(world, rng)
    report("pyrometer")
    gas, stations, gas_ppm = _gas_pass(world, rng)
    report("gas")
    return thermal, readings, gas, stations, gas_ppm


def _check_flags(**flags: object) -> None:
    for name, flag in flags.items():
        if not isinstance(flag, bool):
            raise InputError(f"{name} must be True or False; got {flag!r}.")


def _size(size: object) -> tuple[int, int]:
    if not isinstance(size, tuple) or len(size) != 2:
        raise InputError(f"size must be a (rows, cols) tuple; got {size!r}. Try size=(480, 640).")
    rows, cols = (v.positive_int(side, "size", minimum=64) for side in size)
    return (rows, cols)


@dataclass(frozen=True)
class _ReferencePass:
    references: dict[str, Compensated]
    seconds: dict[str, Compensated]
    scales: dict[str, NDArray[np.float32]]
    reliefs: dict[str, dict[str, float]]
    energies: dict[str, float]
    shutters: dict[str, float]


def _reference_pass(
    world: World,
    plan: tuple[PlanPoint, ...],
    shape: tuple[int, int],
    report: Callable[[str], None],
    *,
    stereo_rng: np.random.Generator,
    tour: Tour,
) -> _ReferencePass:
    """Two pristine visits per plan point: the reference, a second reference, their nuisance scale, the
    relief of every component site the reference sees (from the stereo range map), the shutter and the
    strobe energy."""
    references: dict[str, Compensated] = {}
    seconds: dict[str, Compensated] = {}
    scales: dict[str, NDArray[np.float32]] = {}
    reliefs: dict[str, dict[str, float]] = {}
    energies: dict[str, float] = {}
    shutters: dict[str, float] = {}
    for point in plan:
        _settle(world, door_angle_rad=point.door_angle_rad)
        view = tour.visit(point.name, point.vista, state="reference")
        shutter = shutters[point.name] = _metered_shutter(world, view)
        energy = energies[point.name] = _metered_energy(world, view, shutter)
        # kept for this point's later visits, inspection pass included
        world.set_shutter(shutter)
        world.set_strobe_energy(energy)
        view = _reflashed(world, view, energy, shutter)
        references[point.name] = _with_shadow_edges(_strobe_image(world, view), view)
        depth = _stereo_depth(view, stereo_rng)
        reliefs[point.name] = {
            site.name: _relief_m(depth, view, site) for site in _seen_components(world, view)
        } | {site.name: _screw_relief_m(depth, view, site) for site in _seen_screws(world, view)}
        # a second pristine visit: the nuisance map and the second reference of every detection
        again = tour.visit(point.name, point.vista, state="reference", truth=False)
        seconds[point.name] = _with_shadow_edges(_strobe_image(world, again), again)
        scales[point.name] = _nuisance_scale(references[point.name], seconds[point.name])
        report(f"reference {point.name}")
    return _ReferencePass(references, seconds, scales, reliefs, energies, shutters)


def _ambient_dn(world: World, view: View, region: NDArray[np.bool_] | None = None) -> float:
    """The pre-flash's ambient in DN at its METER_PERCENTILE over the inspection region (0 if none)."""
    camera = world.camera
    region = _inspection_region(view) if region is None else region
    if not region.any():
        return 0.0
    lux = float(np.percentile(view.ambient_lux[region], METER_PERCENTILE))
    return lux * view.frame.exposure_s * camera.electrons_per_lux_s / camera.gain_e_per_dn


def _metered_shutter(world: World, view: View) -> float:
    """Shutter (fraction of the pre-flash's) that holds the sunlit surface's ambient to AMBIENT_TARGET_DN.

    Seed §2.2 subtracts the ambient, so sunlight is only noise and compensation error to the strobe image:
    at the seed's shutter a sunlit aluminium face reads ~170 DN of ambient alone, and strobe plus ambient
    saturate where an impact may be. The ~20 us flash fits in any shutter down to MIN_SHUTTER.
    """
    from rsi.sim.world import MIN_SHUTTER

    ambient = _ambient_dn(world, view)
    if ambient <= AMBIENT_TARGET_DN:
        return 1.0
    return float(np.clip(AMBIENT_TARGET_DN / ambient, MIN_SHUTTER, 1.0))


def _settle(world: World, *, door_angle_rad: float) -> None:
    """The door at `door_angle_rad`, the strobe and the shutter back at the seed's settings (seed §2.1)."""
    world.set_door(door_angle_rad)
    world.set_strobe_energy(1.0)
    world.set_shutter(1.0)


def _metered_energy(world: World, view: View, shutter: float = 1.0) -> float:
    """Strobe energy that lifts the surface's brightest strobe pixels to STROBE_TARGET_DN (seed §2.1).

    The view is the pre-flash at the seed's 1.3 lm s. Dark solar cells and Kapton then read a few tens of DN,
    where read noise and 8-bit quantisation swamp a millimetre impact; more flash raises the contrast in
    proportion and the shot noise only as its square root. Never less than the seed's energy.
    """
    from rsi.sim.world import MAX_STROBE_ENERGY

    camera = world.camera
    dn_per_lux_s = camera.electrons_per_lux_s / camera.gain_e_per_dn
    region = _inspection_region(view)
    if not region.any():
        return 1.0
    strobe = float(np.percentile(view.strobe_lux_s[region], METER_PERCENTILE)) * dn_per_lux_s
    headroom = STROBE_TARGET_DN - camera.black_level_dn - _ambient_dn(world, view, region) * shutter
    if strobe <= 0.0:
        return MAX_STROBE_ENERGY
    return float(np.clip(headroom / strobe, MIN_STROBE_ENERGY, MAX_STROBE_ENERGY))


def _reflashed(world: World, view: View, energy: float, shutter: float) -> View:
    """The visit's frame taken again from the same pose, the strobe at `energy` times the pre-flash and the
    shutter at `shutter` times its own."""
    if energy == 1.0 and shutter == 1.0:
        return view
    flashed = replace(
        view,
        strobe_lux_s=(view.strobe_lux_s * np.float32(energy)).astype(np.float32),
        frame=replace(view.frame, exposure_s=view.frame.exposure_s * shutter),
    )
    return replace(flashed, frame=world.next_frame(flashed, lit_field=view.frame.lit_field))


def _seen_screws(world: World, view: View) -> list[Site]:
    sites = world.mockup.candidates.screw_sites
    seen = _visible(view, np.asarray([site.position_m for site in sites]))
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def _seen_components(world: World, view: View) -> list[Site]:
    """Component sites whose centre the view sees (depth within 2 cm: a tank's front, a panel's face)."""
    sites = world.mockup.candidates.component_sites
    seen = _visible(view, np.asarray([site.position_m for site in sites]), tolerance_m=0.02)
    return [site for site, visible in zip(sites, seen, strict=True) if visible]


def run_mission(
    seed: int,
    *,
    archive: Archive | None = None,
    repeatability: str = "lab",
    active: bool = True,
    progress: ProgressFn | None = None,
    size: tuple[int, int] = MISSION_SIZE,
    arm: bool = True,
    orbit: bool = True,
    orbit_start_s: tuple[float, float] = ORBIT_START_S,
) -> MissionResult:
    """Reference pass, inspection pass and sensor passes over the seeded mock-up (seed §2-§4).

    Parameters
    ----------
    seed : int
        Seed of the world (anomalies, viewpoint errors, camera and sensor noise), >= 0. The same seed gives
        the same findings.
    archive : Archive, optional
        Receives the plan's vista points, the reference images (compensated, float32) and one finished
        inspection run with its findings.
    repeatability : {"lab", "space"}
        Viewpoint repeatability of each visit (seed §2.3).
    active : bool
        Active inspection (seed §2.5): detections between the preliminary and confirming thresholds get a
        second look and are confirmed or rejected on the fused evidence. False: one look, one threshold.
    progress : callable, optional
        ``progress(stage, done, total)`` after each visit and sensor pass.
    size : (int, int)
        Frame (rows, cols), each >= 64.
    arm : bool
        Move the ISEE with the arm and rail to each reachable vista (retract, transfer, approach under the
        proximity law; seed §3.1) and take the frame from where the arm holds the camera; vistas out of
        reach (the solar panel's, from above) keep the free camera. False: the free camera teleported to
        each vista (``World.render``), as before.
    orbit : bool
        Light each visit by the orbit's sun at its mission-clock time (seed §4.1); False keeps the lamp
        where the world put it.
    orbit_start_s : (float, float)
        Orbit time (s after orbit noon) at which the reference and the inspection pass begin, each >= 0;
        by default 400 s and one orbit (5553.6 s) later, so both passes see about the same sun.

    Returns
    -------
    MissionResult

    Raises
    ------
    InputError
        Naming the argument: a negative or non-integer seed, an unknown repeatability, a non-bool `active`,
        a non-callable `progress`, a bad `size` or something that is not an Archive; a non-bool `arm` or
        `orbit`, or `orbit_start_s` not two times >= 0 s.
    """
    from rsi.mission.motion import Tour, pass_starts
    from rsi.sim.world import load

    seed = _check(seed, archive, repeatability, active, progress)
    shape = _size(size)
    starts = pass_starts(orbit_start_s)
    _check_flags(arm=arm, orbit=orbit)
    start_s = time.perf_counter()
    world = load("truss", seed=seed, repeatability=repeatability, arm=arm)
    plan = plan_vistas(world)
    tour = Tour(world, seed=seed, size=shape, arm=arm, orbit=orbit)
    total = 2 * len(plan) + 2
    done = 0

    def report(stage: str) -> None:
        nonlocal done
        done += 1
        if progress is not None:
            progress(stage, done, total)

    try:
        # ---- reference pass: the pristine mock-up (seed §2.3: references taken once, revisited later)
        stereo_rng = np.random.default_rng(np.random.SeedSequence([seed, 11]))
        tour.start_pass("reference", starts[0])
        stored = _reference_pass(world, plan, shape, report, stereo_rng=stereo_rng, tour=tour)
        references = stored.references
        reference_s = time.perf_counter() - start_s
        run_id = _store_references(
            archive,
            world=world,
            plan=plan,
            references=references,
            seed=seed,
            repeatability=repeatability,
            active=active,
        )

        # ---- inspection pass
        tour.start_pass("inspection", starts[1])
        visual, visits = _inspection_pass(
            world, plan, stored, shape=shape, active=active, stereo_rng=stereo_rng, tour=tour, report=report
        )
        inspection_s = time.perf_counter() - start_s - reference_s

        sensors_start = time.perf_counter()
        thermal, readings, gas, stations, gas_ppm = _sensor_passes(world, seed, report)
        findings = tuple(_merge_impacts(_merge_components(visual)) + thermal + gas)
        overview_rgb, overview_pose = world.overview(size=OVERVIEW_SIZE)
        if archive is not None and run_id is not None:
            _store_findings(archive, run_id, findings)
            archive.finish_run(run_id)
    finally:
        world.close()
    timings = {
        "reference": reference_s,
        "inspection": inspection_s,
        "sensors": time.perf_counter() - sensors_start,
        "total": time.perf_counter() - start_s,
        "transits": sum(transit.wall_s for transit in tour.transits),
    }
    return MissionResult(
        seed=seed,
        repeatability=repeatability,
        active=active,
        size=shape,
        plan=plan,
        findings=findings,
        visits=tuple(visits),
        truth=world.anomalies,
        pyrometer_k=readings,
        gas_ppm=gas_ppm,
        gas_stations_m=stations,
        run_id=run_id,
        timings_s=timings,
        roc=_run_roc(tuple(visits)),
        overview_rgb=overview_rgb,
        overview_pose=overview_pose,
        transits=tuple(tour.transits),
        suns=tuple(tour.suns),
    )


def _inspection_pass(
    world: World,
    plan: tuple[PlanPoint, ...],
    stored: _ReferencePass,
    *,
    shape: tuple[int, int],
    active: bool,
    stereo_rng: np.random.Generator,
    tour: Tour,
    report: Callable[[str], None],
) -> tuple[list[MissionFinding], list[VisitRecord]]:
    """Every plan point visited again after the anomalies appeared, with the reference pass's settings."""
    confirm, preliminary = _threshold(P_FALSE_ALARM), _threshold(P_PRELIMINARY)
    visual: list[MissionFinding] = []
    visits: list[VisitRecord] = []
    screws_done: set[str] = set()
    for point in plan:
        world.set_door(point.door_angle_rad)
        world.set_strobe_energy(stored.energies[point.name])
        world.set_shutter(stored.shutters[point.name])
        found, record = _inspect_point(
            world,
            point=point,
            reference=stored.references[point.name],
            scale=stored.scales[point.name],
            other=stored.seconds[point.name],
            reliefs=stored.reliefs[point.name],
            stereo_rng=stereo_rng,
            shape=shape,
            active=active,
            confirm=confirm,
            preliminary=preliminary,
            screws_done=screws_done,
            tour=tour,
        )
        visual += found
        visits.append(record)
        report(f"inspection {point.name}")
    _settle(world, door_angle_rad=0.0)
    return visual, visits


def _inspect_point(
    world: World,
    *,
    point: PlanPoint,
    reference: Compensated,
    scale: NDArray[np.float32],
    other: Compensated,
    shape: tuple[int, int],
    active: bool,
    confirm: float,
    preliminary: float,
    screws_done: set[str],
    reliefs: Mapping[str, float],
    stereo_rng: np.random.Generator,
    tour: Tour,
) -> tuple[list[MissionFinding], VisitRecord]:
    """One visit: compare with the reference, check the screws, take second looks (seed §2.3-2.5)."""
    view = tour.visit(point.name, point.vista, state="inspection")
    region = _inspection_region(view)
    pair_inspection = _restricted(_strobe_image(world, view), region)
    pair = _compare(reference, pair_inspection, P_PRELIMINARY if active else P_FALSE_ALARM, scale)
    registration = pair.detection.registration
    translation = (0.0, 0.0) if registration is None else tuple(float(t) for t in registration.translation_xy)
    # the registration's shift sets each surface's parallax; test again with that nuisance counted
    scale = scale * _parallax_scale(reference, view, math.hypot(*translation))
    pair = _compare(reference, pair_inspection, P_PRELIMINARY if active else P_FALSE_ALARM, scale)
    findings: list[MissionFinding] = []

    depth = _stereo_depth(view, stereo_rng)
    findings += _screw_checks(world, view, point.name, depth_m=depth, reliefs=reliefs, done=screws_done)
    checks = _component_checks(pair, view, point.name, reliefs=reliefs, depth_m=depth, world=world)
    findings += [finding for finding, _ in checks]
    reference, other, pair_inspection, pair = _without_discoloured(
        view,
        [explanation for _, explanation in checks],
        (reference, other, pair_inspection),
        pair=pair,
        scale=scale,
        p_false_alarm=P_PRELIMINARY if active else P_FALSE_ALARM,
    )
    screw_positions = np.asarray([s.position_m for s in world.mockup.candidates.screw_sites])

    explanations = [explanation for _, explanation in checks]
    looks = _unexplained(_blobs(pair, view), view, explanations, screw_positions)
    if looks:
        # a flaw is new against *both* pristine visits; a blob that one reference's sampling (aliasing, a
        # compensation artefact of that visit) made is not: the weaker of the two comparisons is kept
        other_pair = _compare(other, pair_inspection, P_PRELIMINARY, scale)
        for look in looks:
            look.score = min(look.score, _second_look_score(other_pair, view, look.position_m))
        looks = [
            look
            for look in looks
            if look.score > (preliminary if active else confirm)
            and (look.area_m2 > COMPONENT_AREA_M2 or look.darkening >= IMPACT_DARKENING_MIN)
        ]
    doubtful = [look for look in looks if look.score <= confirm]
    second_looks = confirmed = rejected = 0
    if active and doubtful:
        # seed §2.5 active inspection: another visit (new viewpoint error, new noise) of the same vista
        second = tour.visit(point.name, point.vista, state="inspection")
        second_image = _restricted(_strobe_image(world, second), _inspection_region(second))
        second_pair = _compare(reference, second_image, P_PRELIMINARY, scale)
        # against both pristine visits again: an artefact of one reference's sampling would confirm itself
        second_other = _compare(other, second_image, P_PRELIMINARY, scale)
        for look in doubtful:
            second_looks += 1
            again = min(
                _second_look_score(second_pair, second, look.position_m),
                _second_look_score(second_other, second, look.position_m),
            )
            # both looks share the reference's noise: correlation 1/2, so Var(s1 + s2) = 3
            fused = (look.score + again) / math.sqrt(3.0)
            # the second look must see the blob itself: a fused score carried by the first alone is no echo
            if fused > confirm and again > preliminary:
                confirmed += 1
                look.score = fused
                look.second_look = True
            else:
                rejected += 1
    kept = [look for look in looks if look.score > confirm]
    for look in kept:
        kind = "swapped_component" if look.area_m2 > COMPONENT_AREA_M2 else "impact"
        findings.append(
            MissionFinding(
                kind=kind,
                position_m=look.position_m,
                size_m=2.0 * math.sqrt(look.area_m2 / math.pi),
                confidence=_confidence(look.score - confirm),
                source=point.name,
                score=look.score,
                second_look=look.second_look,
                bbox=look.bbox,
            )
        )
    record = VisitRecord(
        point=point.name,
        translation_xy=(translation[0], translation[1]),
        detections=len(looks),
        second_looks=second_looks,
        confirmed=confirmed,
        rejected=rejected,
        visible=tuple(sorted(view.flaw_masks)),
        images=_visit_images(pair, view, world.anomalies),
    )
    return findings, record


def _visit_images(pair: PairResult, view: View, truth: AnomalySet) -> VisitImages:
    detection = pair.detection
    impacts = np.zeros_like(detection.valid)
    for index, mask in view.flaw_masks.items():
        anomaly = truth.anomalies[index]
        if anomaly.kind == "impact" and _counts(anomaly):
            impacts |= mask
    inspection = np.asarray(pair.inspection, dtype=np.float32)
    return VisitImages(
        reference=(inspection - detection.difference).astype(np.float32),
        inspection=inspection,
        difference=detection.difference,
        score=detection.score,
        valid=detection.valid,
        impact_truth=impacts,
        impact_strengths=_impact_strengths(detection, impacts),
    )


def _run_roc(visits: tuple[VisitRecord, ...]) -> tuple[RocCurve, ...]:
    """The run's empirical ROC over every inspection visit, and the theory for the impacts it saw.

    Seed §2.4: P_D against P_F. The visits' score maps are stacked (a guard band keeps flaws of one from
    the next); the theory averages the model's P_D over the counted impacts' measured strengths (the
    difference at each impact's darkest pixel over the local noise sigma).
    """
    from rsi.detection.roc import RocCurve, empirical_roc, theoretical_roc

    images = [v.images for v in visits if v.images is not None and v.images.impact_truth.any()]
    if not images:
        return ()
    band = np.zeros((8, images[0].score.shape[1]), dtype=np.float32)
    score = np.vstack([part for im in images for part in (im.score, band)])
    truth = np.vstack([part for im in images for part in (im.impact_truth, band.astype(bool))])
    valid = np.vstack([part for im in images for part in (im.valid, band.astype(bool))])
    measured = empirical_roc(score, truth, valid=valid, label="this run (impacts >= 1 mm)")
    p_false_alarm = np.logspace(-7, 0, 100)
    strengths = [strength for im in images for strength in im.impact_strengths]
    curves = [
        theoretical_roc(FLAW_MODEL, strength_sigma=s, p_false_alarm=p_false_alarm, size=FLAW_SIZE_PX)
        for s in strengths
    ]
    mean_detection = np.mean([curve.p_detection for curve in curves], axis=0)
    label = "theory (measured impact strengths)"
    theory = RocCurve(p_false_alarm, mean_detection, curves[0].threshold, label)
    return (measured, theory)


def _impact_strengths(detection: Detection, truth: NDArray[np.bool_]) -> tuple[float, ...]:
    """Each truth impact's strength: the difference at its darkest pixel over that pixel's noise sigma."""
    import cv2

    count, labels = cv2.connectedComponents(truth.astype(np.uint8), connectivity=8)
    strengths = []
    for label in range(1, count):
        inside = (labels == label) & detection.valid
        if not inside.any():
            continue
        darkest = int(np.argmin(np.where(inside, detection.difference, np.inf)))
        sigma = float(detection.sigma.flat[darkest])
        strengths.append(max(-float(detection.difference.flat[darkest]), 0.0) / max(sigma, 1e-6))
    return tuple(strengths)


@dataclass(frozen=True)
class _Explanation:
    """Where a swap found in a visit shows in its difference image: within `radius_m` of `centre_m`, and
    only on `component`'s own pixels when given (a discoloured replacement's change ends at its outline)."""

    centre_m: tuple[float, float, float]
    radius_m: float
    component: str | None = None


def _unexplained(
    looks: list[_Look], view: View, explanations: list[_Explanation], screw_positions: FloatArray
) -> list[_Look]:
    """Looks that are no screw's evidence and no part of a swap found in the view."""
    kept = []
    for look in looks:
        here = np.asarray(look.position_m)
        if np.min(np.linalg.norm(screw_positions - here, axis=1)) <= SCREW_MATCH_M:
            continue
        if any(_explained_by(look, view, explanation) for explanation in explanations):
            continue
        kept.append(look)
    return kept


def _explained_by(look: _Look, view: View, explanation: _Explanation) -> bool:
    distance = float(np.linalg.norm(np.subtract(look.position_m, explanation.centre_m)))
    if distance > explanation.radius_m:
        return False
    if explanation.component is None:
        # a dent's crater changes the image over centimetres: a millimetre spot much darker than the
        # reference there is an impact on the dented face (seed §4 plants both independently)
        return look.area_m2 > SPOT_AREA_MAX_M2 or look.darkening < DENT_SPOT_DARKENING_MIN
    mask = view.component_masks.get(explanation.component)
    if mask is None:
        return False
    # the blob's own pixels may be a decal (an impact spot is not the component): its surround decides
    row0, col0, row1, col1 = look.bbox
    r0, c0 = max(row0 - SURROUND_PX, 0), max(col0 - SURROUND_PX, 0)
    surround = mask[r0 : row1 + SURROUND_PX, c0 : col1 + SURROUND_PX]
    return bool(surround.mean() > 0.5)


def _component_checks(
    pair: PairResult,
    view: View,
    source: str,
    *,
    reliefs: Mapping[str, float],
    depth_m: NDArray[np.float32],
    world: World,
) -> list[tuple[MissionFinding, _Explanation]]:
    """Each component site the view sees, checked for a swap (seed §4): discoloured or dented.

    A discoloured replacement changes the strobe image over the whole component, unless it fills the frame
    and the registration's gain absorbs it (then its raw brightness tells); a dent shows in the stereo range
    map, sunk below its surroundings by millimetres. Each finding comes with the radius around it within
    which the difference image shows the swap itself (blobs there are not impacts, those elsewhere are); a
    discolouring changed only the component's own surface, which the view's CAD projection tells.
    """
    found = []
    for site in _seen_components(world, view):
        change = _component_change(pair, view, site)
        sunk = _relief_m(depth_m, view, site) - reliefs.get(site.name, math.nan)
        if abs(sunk) > DENT_RELIEF_MIN_M:  # a dent: its disc changed, the rest of the skin did not
            score, margin = sunk, (abs(sunk) - DENT_RELIEF_MIN_M) / 2e-4
            size = min(site.size_m, 2 * COMPONENT_DISC_M)
            explained = _Explanation(site.position_m, 0.5 * size + 0.02)
        elif change > COMPONENT_CHANGE_MIN:
            score, margin, size = change, (change - COMPONENT_CHANGE_MIN) / 0.01, site.size_m
            explained = _Explanation(site.position_m, 0.5 * size + 0.02, site.name)
        elif abs(dimming := _component_dimming(pair, view, site)) > COMPONENT_DIMMING_MIN:
            score, margin, size = dimming, (abs(dimming) - COMPONENT_DIMMING_MIN) / 0.01, site.size_m
            explained = _Explanation(site.position_m, 0.0)
        else:
            continue
        finding = MissionFinding(
            kind="swapped_component",
            position_m=site.position_m,
            size_m=size,
            confidence=_confidence(margin),
            source=source,
            score=score,
        )
        found.append((finding, explained))
    return found


def _merge_components(findings: list[MissionFinding]) -> list[MissionFinding]:
    """One swapped-component finding per component site: its blobs (from several views) merged."""
    from rsi.sim.mockup import truss_mockup

    sites = truss_mockup().candidates.component_sites
    merged: dict[str, list[MissionFinding]] = {}
    others: list[MissionFinding] = []
    for finding in findings:
        if finding.kind != "swapped_component":
            others.append(finding)
            continue
        site = _component_of(finding.position_m, sites)
        if site is None:
            others.append(replace(finding, kind="impact"))
            continue
        merged.setdefault(site.name, []).append(finding)
    for name, group in merged.items():
        site = next(s for s in sites if s.name == name)
        best = max(group, key=lambda f: f.confidence)
        others.append(replace(best, position_m=site.position_m))
    return others


def _merge_impacts(findings: list[MissionFinding]) -> list[MissionFinding]:
    """One impact finding per site seen from overlapping vistas: the strongest sighting stands for it."""
    impacts = sorted((f for f in findings if f.kind == "impact"), key=lambda f: -f.score)
    kept: list[MissionFinding] = []
    for finding in impacts:
        here = np.asarray(finding.position_m)
        if all(np.linalg.norm(here - np.asarray(k.position_m)) > IMPACT_MERGE_M for k in kept):
            kept.append(finding)
    return [f for f in findings if f.kind != "impact"] + kept


def _component_of(position: tuple[float, float, float], sites: tuple[Site, ...]) -> Site | None:
    """The component site nearest to `position` within its half extent plus 5 cm."""
    best, best_distance = None, math.inf
    for site in sites:
        distance = float(np.linalg.norm(np.asarray(position) - np.asarray(site.position_m)))
        if distance < 0.5 * site.size_m + 0.05 and distance < best_distance:
            best, best_distance = site, distance
    return best


def _store_references(
    archive: Archive | None,
    *,
    world: World,
    plan: tuple[PlanPoint, ...],
    references: Mapping[str, Compensated],
    seed: int,
    repeatability: str,
    active: bool,
) -> int | None:
    if archive is None:
        return None
    for point in plan:
        archive.add_vista(replace(world.vista(point.vista), name=point.name), replace=True)
        archive.store_reference(point.name, np.ascontiguousarray(references[point.name].image))
    settings = {
        "repeatability": repeatability,
        "active": active,
        "p_false_alarm": P_FALSE_ALARM,
        "p_preliminary": P_PRELIMINARY,
        "flaw_model": FLAW_MODEL,
    }
    return archive.start_run(label="mission inspection pass", seed=seed, settings=settings)


def _store_findings(archive: Archive, run_id: int, findings: tuple[MissionFinding, ...]) -> None:
    from rsi.archive import Finding

    vista_of_sensor = {"pyrometer": "A_kapton", "gas": "D_tubing"}
    archive.add_findings(
        run_id,
        [
            Finding(
                vista=vista_of_sensor.get(f.source, f.source),
                kind=f.kind,
                confidence=f.confidence,
                position_m=f.position_m,
                bbox=f.bbox,
                size_m=f.size_m,
                score=f.score,
                extras={"source": f.source, "second_look": f.second_look},
            )
            for f in findings
        ],
    )


# ------------------------------------------------------------------------------------------------ score

SCORED_TYPES: tuple[str, ...] = ("impact", "missing_screw", "swapped_component", "thermal_spot", "gas_leak")
IMPACT_MIN_SIZE_M = 1e-3  # issue 5: impacts of at least 1 mm count towards recall
_MATCH_RADIUS_M = {
    "impact": 0.01,
    "missing_screw": 0.01,
    "swapped_component": 0.05,
    "hot_spot": 0.03,
    "cold_spot": 0.03,
    "gas_leak": 0.03,
}
_TYPE_OF = {"hot_spot": "thermal_spot", "cold_spot": "thermal_spot"}


@dataclass(frozen=True)
class Miss:
    """An anomaly no finding matched, and why (from the visits' truth)."""

    index: int
    kind: str
    reason: str


@dataclass(frozen=True)
class TypeScore:
    """Score of one anomaly type.

    Attributes
    ----------
    truth : int
        Anomalies of the type that count (impacts >= 1 mm).
    found : int
        Of those, matched by a finding of the same kind.
    false_findings : int
        Findings of the type that match no anomaly (impacts matching an impact < 1 mm are not false).
    localisation_error_m : float
        Mean distance of matched findings from the truth (nan when none).
    """

    truth: int
    found: int
    false_findings: int
    localisation_error_m: float

    @property
    def recall(self) -> float:
        """found / truth (1.0 when there is nothing to find)."""
        return self.found / self.truth if self.truth else 1.0


@dataclass(frozen=True)
class MissionScore:
    """A mission against its ground truth.

    Attributes
    ----------
    per_type : dict of str to TypeScore
        Keys :data:`SCORED_TYPES` (hot and cold spots together as ``thermal_spot``).
    false_findings : int
        Findings matching no anomaly, all types.
    misses : tuple of Miss
        Every counted anomaly not found, with the reason.
    matches : dict of int to int
        Finding index -> index of the anomaly it matched; a finding absent here is false (one matching an
        impact under 1 mm is here, though that impact does not count towards recall).
    """

    per_type: dict[str, TypeScore]
    false_findings: int
    misses: tuple[Miss, ...]
    matches: dict[int, int] = field(default_factory=dict)


def score_mission(result: MissionResult) -> MissionScore:
    """Match a mission's findings to its world's ground truth, per anomaly type.

    A finding matches an anomaly of the same kind within the kind's radius (1 cm for impacts and screws,
    3 cm for thermal spots and leaks, 5 cm for a component's site); each anomaly and finding is used once,
    nearest first.

    Raises
    ------
    InputError
        If `result` is not a MissionResult.
    """
    if not isinstance(result, MissionResult):
        raise InputError(f"result must be a MissionResult from run_mission; got {type(result).__name__}.")
    anomalies = result.truth.anomalies
    pairs: list[tuple[float, int, int]] = []
    for i, finding in enumerate(result.findings):
        for k, anomaly in enumerate(anomalies):
            if anomaly.kind != finding.kind:
                continue
            distance = float(np.linalg.norm(np.asarray(finding.position_m) - np.asarray(anomaly.position_m)))
            if distance <= _MATCH_RADIUS_M[anomaly.kind]:
                pairs.append((distance, i, k))
    used_findings: dict[int, int] = {}
    matched: dict[int, float] = {}
    for distance, i, k in sorted(pairs):
        if i in used_findings or k in matched:
            continue
        used_findings[i] = k
        matched[k] = distance
    per_type, misses = _tally(result, matched, used_findings)
    scores = {
        name: TypeScore(
            truth=entry["truth"],
            found=entry["found"],
            false_findings=entry["false"],
            localisation_error_m=float(np.mean(entry["errors"])) if entry["errors"] else math.nan,
        )
        for name, entry in per_type.items()
    }
    return MissionScore(
        per_type=scores,
        false_findings=sum(score.false_findings for score in scores.values()),
        misses=tuple(misses),
        matches=dict(sorted(used_findings.items())),
    )


def _tally(
    result: MissionResult, matched: dict[int, float], used_findings: dict[int, int]
) -> tuple[dict[str, dict[str, Any]], list[Miss]]:
    """Per type: anomalies that count, found, false findings and matched distances; and the misses."""
    anomalies = result.truth.anomalies
    per_type: dict[str, dict[str, Any]] = {
        name: {"truth": 0, "found": 0, "false": 0, "errors": []} for name in SCORED_TYPES
    }
    misses: list[Miss] = []
    for k, anomaly in enumerate(anomalies):
        kind_type = _TYPE_OF.get(anomaly.kind, anomaly.kind)
        if not _counts(anomaly):
            continue
        entry = per_type[kind_type]
        entry["truth"] += 1
        if k in matched:
            entry["found"] += 1
            entry["errors"].append(matched[k])
        else:
            misses.append(Miss(k, anomaly.kind, _why_missed(result, k, anomaly)))
    for i, finding in enumerate(result.findings):
        if i not in used_findings:
            per_type[_TYPE_OF.get(finding.kind, finding.kind)]["false"] += 1
    return per_type, misses


def _counts(anomaly: Anomaly) -> bool:
    return anomaly.kind != "impact" or anomaly.size_m >= IMPACT_MIN_SIZE_M


def _why_missed(result: MissionResult, index: int, anomaly: Anomaly) -> str:
    if anomaly.kind in ("hot_spot", "cold_spot", "gas_leak"):
        return "sensor reading below its threshold or mislocated"
    seen_in = [visit.point for visit in result.visits if index in visit.visible]
    if not seen_in:
        return "not visible in any planned frame"
    wrong = [f for f in result.findings if _near(f, anomaly, 0.02) and f.kind != anomaly.kind]
    if wrong:
        return f"seen in {', '.join(seen_in)} but reported as {wrong[0].kind}"
    return f"visible in {', '.join(seen_in)} but below the detection threshold"


def _near(finding: MissionFinding, anomaly: Anomaly, radius_m: float) -> bool:
    distance = np.linalg.norm(np.asarray(finding.position_m) - np.asarray(anomaly.position_m))
    return bool(distance <= radius_m)


__all__ = [
    "PLAN",
    "Miss",
    "MissionFinding",
    "MissionResult",
    "MissionScore",
    "PlanPoint",
    "TypeScore",
    "VisitRecord",
    "plan_vistas",
    "run_mission",
    "score_mission",
]
