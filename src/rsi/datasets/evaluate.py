"""Score rsi's detector on DeepPCB: matching rules, metrics and the evaluation driver.

Two matching rules are reported (``docs/deeppcb.md``):

- **centre in box** (class-agnostic): a ground-truth box is *found* if the centre of any detection lies
  inside it (corners inclusive); a detection is a *false alarm* if its centre lies in no box. Robust to the
  dataset's padded boxes, which a tight detection of a small defect overlaps by far less than IoU 0.33.
- **IoU > 0.33** (the dataset's official threshold): detections and boxes are paired one-to-one, greedily
  by decreasing IoU. The official rule also asks for the same class; rsi's detector is class-agnostic (it
  finds changes, it does not name them), so the class is ignored here and the figure is the
  *class-agnostic* IoU rule, an upper bound of the official one.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi._validate import (
    as_image,
    as_table,
    choice,
    in_range,
    instance_of,
    instance_or_default,
    positive_int,
    same_shape,
)
from rsi.datasets.deeppcb import DeepPcbPair, read_pair
from rsi.datasets.official import OFFICIAL_IOU, OfficialTally, box_iou
from rsi.datasets.pcb_features import DefectClassifier, _checked_features, rule_classes
from rsi.detection.flaw_models import FLAW_MODELS
from rsi.errors import InputError
from rsi.imaging._components import component_stats, nonzero_pixels, occupied, pixel_components
from rsi.imaging._warps import scratch
from rsi.imaging.registration import LOCAL_MODEL, REGISTRATION_MODELS, Registration

if TYPE_CHECKING:
    from rsi.detection.detect import Detection

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]

_BOX_COLUMNS = 4


def _safe_ratio(numerator: float, denominator: float) -> float:
    return numerator / denominator if denominator else 0.0


_CENTRE_COLUMNS = 2


@dataclass(frozen=True)
class DeepPcbSettings:
    """Detector settings used for every DeepPCB split (never tuned per split).

    Attributes
    ----------
    registration_model : str
        Motion model for :func:`rsi.register`. ``"local"``: the affine fit (some pairs differ by a 1% scale
        across the board, which leaves 4-6 px of shift at one side under a pure translation), then a smooth
        displacement field on the same pyramid level (seed §2.3: small mis-registrations are locally
        translational). Boards outside trainval are displaced by 1-3 px in a way that varies across the
        board; on trainval boards warped by such a field (``benchmarks/eval_deeppcb.py --distort-px 2``)
        the affine fit leaves 1.6 false alarms per image and F1 0.89, the local field 0.10 and 0.99. On
        trainval as it is both give F1 0.993 (``docs/deeppcb.md``); the field costs ~0.1 s per pair.
    registration_finest_level : int
        Finest pyramid level the registration refines (:func:`rsi.register`'s ``finest_level``). 1: the
        fit ends on the half-size images, at half the cost of full resolution; it lies within 0.06 px of
        the full-resolution fit for the median trainval pair (0.26 px at the 90th percentile, at the image
        corners), far inside the 3 px mis-registration floor the detector adds as noise, and the trainval
        figures do not move (``docs/deeppcb.md``). 2 (quarter size) costs 7 more false alarms in 1,000.
    registration_coarsest_level : int or None
        Coarsest pyramid level the registration refines (:func:`rsi.register`'s ``coarsest_level``; None:
        down to 128 px a side). 1: the fit starts and ends on the half-size images, from the identity (the
        pairs come pre-aligned, within a few pixels), without the quarter-size level before it; the fits
        lie within 0.01 px of the two-level ones for the median pair (``docs/deeppcb.md``).
    registration_row_step : int or None
        Rows the registration samples (:func:`rsi.register`'s ``row_step``; None: every row below 512).
        2: every other row of the half-size images, half the work; the fits move by 0.04 px for the median
        pair (0.2 px at the 90th percentile), far inside the 3 px floor.
    registration_photometric : bool
        Fit a gain and bias (:func:`rsi.register`'s ``photometric``). False: the images are binarised to 0
        and 255, so there is no exposure difference to fit, and the two photometric unknowns are a quarter of
        an affine fit's work. Measured on trainval, not tuned: a yes-or-no choice (``docs/deeppcb.md``).
    registration_field_tolerance_px : float
        The local field's convergence tolerance (:func:`rsi.register`'s ``field_tolerance_px``), pixels.
        0.1: thirty times below the 3 px mis-registration floor. On these binarised boards the field creeps
        by 0.03-0.05 px a step for its ten steps (on camera-like textures it converges in two or three), so
        the default 0.01 px ran every level to its step limit; 0.1 px stops it ~40 % sooner
        (``docs/deeppcb.md``).
    registration_presmooth : bool
        Smooth the full-resolution images before the registration's pyramid (:func:`rsi.register`'s
        ``presmooth``). False: the fit ends on the half-size images, which cv2.pyrDown's own Gaussian
        smooths; the full-resolution filtering of both images only fed them. Measured on trainval, a
        yes-or-no choice like the last.
    flaw_model, size, method : str, int, str
        Passed to :func:`rsi.detect`. The erosion variant of the disc model: every pixel of the disc of
        ``size`` (for 3, a plus of five) must change the same way, which a 1-px edge residual never does.
        A mousebite or a pin-hole 3 px across holds that plus whole, not a 3x3 square: leave-one-group-out
        chose the disc over the square in all seven folds (pooled official F 0.981 -> 0.984, F1 0.993 ->
        0.995, false alarms 0.045 -> 0.037 per image; ``docs/deeppcb.md``).
    p_false_alarm : float
        Per-pixel false-alarm probability the threshold is calibrated for.
    noise_sigma : float
        Noise std of each image, DN (0..255). On these binarised JPEGs it stands for the compression
        ringing around copper edges, not sensor noise; defects change a pixel by ~255 DN.
    misregistration_std_px : float
        Floor on the residual mis-registration std given to the detector's noise term
        ``sigma_s^2 |grad ref|^2`` (the local field's per-pixel std where larger). The field is precise to
        ~0.1 px, but etching and binarisation move copper edges by 1-3 px that no smooth field follows;
        this term stops them from scoring as flaws.
    merge_gap_px : int
        Detected components closer than this many pixels are one defect (a defect breaks into pieces: an
        open either side of its trace, group 44000's scratches into strands). 10 px, DeepPCB's own box
        margin, was chosen by leave-one-group-out between 6 and 10 (five of the seven folds chose 10 on the
        six other groups; pooled official F 0.980 -> 0.981, group 44000 0.897 -> 0.917, mAP 0.980 both;
        14 and 20 px merged distinct defects on every 10th pair, docs/deeppcb.md).
    min_area_px : int
        Smallest merged component (pixels of the detection mask) reported.
    border_px : int
        Detections within this many pixels of the image edge are ignored: the images are crops of a
        larger scan and the crop frame differs between template and test (e.g. a 5 px black stripe
        along one side of a template only). No ground-truth box centre lies within 9 px of an edge.
    box_padding_px : int
        Margin added on every side of a reported box, DeepPCB's own convention: its boxes exceed the
        defect's extent by 10 px a side (20 px wider and taller in at least 3/4 of matched boxes). Only
        the IoU rule looks at boxes.
    grow_to_changes : bool
        Grow each detection over the connected pixels that the single-pixel test flags at the same
        `p_false_alarm` (hysteresis: the erosion test seeds, the per-pixel test gives the extent). A thin
        scratch (1-2 px wide) passes the 3x3 erosion test only in pieces; DeepPCB's box covers all of it.
    sparse : bool
        Compute the detector's maps only near possible detections (:func:`rsi.detect`'s ``sparse_above``
        at the single-pixel threshold that :attr:`grow_to_changes` uses): the defects are those of the
        whole-frame maps, bit for bit (the bound ``|T| <= |d| / sqrt(v)``; tested, and checked on all
        1,000 trainval pairs), at about a third of the detector's time (``docs/deeppcb.md``).
    """

    registration_model: str = "local"
    registration_finest_level: int = 1
    registration_coarsest_level: int | None = 1
    registration_row_step: int | None = 2
    registration_photometric: bool = False
    registration_presmooth: bool = False
    registration_field_tolerance_px: float = 0.1
    flaw_model: str = "disc"
    size: int = 3
    method: str = "erosion"
    p_false_alarm: float = 1e-5
    noise_sigma: float = 40.0
    misregistration_std_px: float = 3.0
    merge_gap_px: int = 10
    min_area_px: int = 1
    border_px: int = 6
    box_padding_px: int = 10
    grow_to_changes: bool = True
    sparse: bool = True

    def __post_init__(self) -> None:
        choice(self.registration_model, "registration_model", REGISTRATION_MODELS)
        positive_int(self.registration_finest_level, "registration_finest_level", minimum=0)
        if self.registration_coarsest_level is not None:
            positive_int(
                self.registration_coarsest_level,
                "registration_coarsest_level",
                minimum=self.registration_finest_level,
            )
        if self.registration_row_step is not None:
            positive_int(self.registration_row_step, "registration_row_step")
        instance_of(self.registration_photometric, "registration_photometric", bool, none_allowed=False)
        instance_of(self.registration_presmooth, "registration_presmooth", bool, none_allowed=False)
        in_range(
            self.registration_field_tolerance_px,
            "registration_field_tolerance_px",
            low=0.0,
            low_inclusive=False,
        )
        choice(self.flaw_model, "flaw_model", FLAW_MODELS)
        choice(self.method, "method", ("lrt", "erosion"))
        positive_int(self.size, "size")
        in_range(
            self.p_false_alarm, "p_false_alarm", low=0.0, high=0.5, low_inclusive=False, high_inclusive=False
        )
        in_range(self.noise_sigma, "noise_sigma", low=0.0, low_inclusive=False)
        in_range(self.misregistration_std_px, "misregistration_std_px", low=0.0)
        positive_int(self.merge_gap_px, "merge_gap_px", minimum=0)
        positive_int(self.min_area_px, "min_area_px")
        positive_int(self.border_px, "border_px", minimum=0)
        positive_int(self.box_padding_px, "box_padding_px", minimum=0)


@dataclass(frozen=True)
class PcbDetections:
    """Defects found in one inspection image.

    Attributes
    ----------
    centres_xy : ndarray of shape (D, 2), float64
        Centroid (x = column, y = row) of each defect's detected pixels.
    boxes_xyxy : ndarray of shape (D, 4), int64
        ``(x1, y1, x2, y2)``, corners inclusive, DeepPCB's convention.
    classes : ndarray of shape (D,), int64, optional
        Class of each defect, a key of :data:`rsi.datasets.deeppcb.DEFECT_TYPES`; None when unnamed
        (then the official figures count every detection as unpaired).
    confidences : ndarray of shape (D,), float64, optional
        Ranking of the detections for average precision (higher first).
    areas_px, strengths : ndarray of shape (D,), float64, optional
        Mask pixels of each defect, and its largest score (when a score map was given to the grouping).
    features : ndarray of shape (D, F), float64, optional
        Topology features (:func:`rsi.datasets.pcb_features.defect_features`), to train a classifier on.
    """

    centres_xy: FloatArray
    boxes_xyxy: IntArray
    classes: IntArray | None = None
    confidences: FloatArray | None = None
    areas_px: FloatArray | None = None
    strengths: FloatArray | None = None
    features: FloatArray | None = None


@dataclass(frozen=True)
class EvaluationResult:
    """Figures of one evaluation run; recall, precision and F1 use the centre-in-box rule.

    Attributes
    ----------
    pairs, defects : int
        Image pairs and ground-truth boxes scored.
    recall, precision, f1 : float
        Found boxes / boxes; detections with their centre in a box / detections; harmonic mean.
    false_alarms_per_image : float
        Detections whose centre lies in no box, per pair.
    iou_recall, iou_precision : float
        Class-agnostic IoU > 0.33 rule, one-to-one matching.
    seconds_per_pair : float
        Wall time per pair, reading the images included.
    official_precision, official_recall, official_f, map, per_class, confusion
        DeepPCB's official rule (IoU > 0.33 and the same class; :mod:`rsi.datasets.official`).
    classes : str
        Who named the defects for the official figures: "rules", or "learned (fitted on ...)".
    """

    pairs: int
    defects: int
    recall: float
    precision: float
    f1: float
    false_alarms_per_image: float
    iou_recall: float
    iou_precision: float
    seconds_per_pair: float
    official_precision: float = 0.0
    official_recall: float = 0.0
    official_f: float = 0.0
    map: float = 0.0
    per_class: dict[str, dict[str, float]] = dataclasses.field(default_factory=dict)
    confusion: list[list[int]] = dataclasses.field(default_factory=list)
    classes: str = "rules"

    def to_dict(self) -> dict[str, Any]:
        """Return the figures as a plain dict (JSON-ready), keys in field order."""
        return dataclasses.asdict(self)


def centre_in_box(centres_xy: object, boxes_xyxy: object) -> tuple[BoolArray, BoolArray]:
    """Match detections to ground-truth boxes by the class-agnostic centre-in-box rule.

    Parameters
    ----------
    centres_xy : array_like of shape (D, 2)
        Detection centres, (x, y) pixels.
    boxes_xyxy : array_like of shape (K, 4)
        Ground-truth boxes ``(x1, y1, x2, y2)``, corners inclusive.

    Returns
    -------
    found : ndarray of shape (K,), bool
        Whether some detection centre lies in each box.
    false_alarm : ndarray of shape (D,), bool
        Whether each detection's centre lies in no box.

    Examples
    --------
    >>> found, false_alarm = centre_in_box([[5.0, 5.0], [50.0, 5.0]], [[0, 0, 10, 10], [20, 20, 30, 30]])
    >>> found.tolist(), false_alarm.tolist()
    ([True, False], [False, True])
    """
    centres = as_table(centres_xy, "centres_xy", _CENTRE_COLUMNS)
    boxes = as_table(boxes_xyxy, "boxes_xyxy", _BOX_COLUMNS)
    x, y = centres[:, :1], centres[:, 1:]
    inside = (x >= boxes[:, 0]) & (x <= boxes[:, 2]) & (y >= boxes[:, 1]) & (y <= boxes[:, 3])
    found: BoolArray = np.asarray(inside.any(axis=0), dtype=bool)
    false_alarm: BoolArray = ~np.asarray(inside.any(axis=1), dtype=bool)
    return found, false_alarm


def iou_match(
    detected_xyxy: object, truth_xyxy: object, *, iou_threshold: float = OFFICIAL_IOU
) -> tuple[BoolArray, BoolArray]:
    """Pair detections and boxes one-to-one, greedily by decreasing IoU, keeping pairs above a threshold.

    Parameters
    ----------
    detected_xyxy : array_like of shape (D, 4)
        Detection boxes, corners inclusive.
    truth_xyxy : array_like of shape (K, 4)
        Ground-truth boxes, corners inclusive.
    iou_threshold : float
        A pair counts when its IoU is strictly greater (DeepPCB: 0.33), in [0, 1).

    Returns
    -------
    found : ndarray of shape (K,), bool
        Whether each box got a detection.
    correct : ndarray of shape (D,), bool
        Whether each detection got a box.
    """
    threshold = in_range(iou_threshold, "iou_threshold", low=0.0, high=1.0, high_inclusive=False)
    iou = box_iou(detected_xyxy, truth_xyxy)
    correct = np.zeros(iou.shape[0], dtype=bool)
    found = np.zeros(iou.shape[1], dtype=bool)
    rows, cols = np.nonzero(iou > threshold)
    for index in np.argsort(-iou[rows, cols], kind="stable"):
        row, col = rows[index], cols[index]
        if not correct[row] and not found[col]:
            correct[row] = found[col] = True
    return found, correct


def _grown_boxes(stats: NDArray[Any], shrink_px: int, shape: tuple[int, int]) -> IntArray:
    # Bounding boxes of the dilated groups, shrunk by the dilation radius, are those of their pixels;
    # a negative shrink grows them. Clipped to the image.
    left, top = stats[:, cv2.CC_STAT_LEFT], stats[:, cv2.CC_STAT_TOP]
    right = left + stats[:, cv2.CC_STAT_WIDTH] - 1
    bottom = top + stats[:, cv2.CC_STAT_HEIGHT] - 1
    boxes = np.column_stack([left + shrink_px, top + shrink_px, right - shrink_px, bottom - shrink_px])
    boxes[:, 0::2] = np.clip(boxes[:, 0::2], 0, shape[1] - 1)
    boxes[:, 1::2] = np.clip(boxes[:, 1::2], 0, shape[0] - 1)
    return boxes.astype(np.int64)


def group_defects(
    mask: NDArray[np.bool_],
    *,
    merge_gap_px: int = 0,
    min_area_px: int = 1,
    grow_px: int = 0,
    score: NDArray[np.floating] | None = None,
) -> PcbDetections:
    """Group a detection mask into defects: merge pieces closer than a gap, drop small groups.

    Parameters
    ----------
    mask : ndarray of shape (M, N), bool
        Detected pixels (e.g. :attr:`rsi.Detection.mask`).
    merge_gap_px : int
        Pieces separated by at most this many pixels form one defect (0: 8-connected components).
    min_area_px : int
        Groups with fewer mask pixels are dropped.
    grow_px : int
        Each box is grown by this margin on every side, then clipped to the image (an erosion test's
        mask is its defect eroded by ``size // 2``; DeepPCB pads its boxes).
    score : ndarray of shape (M, N), optional
        A score map: each group's ``strengths`` is its largest value over the group's mask pixels.

    Returns
    -------
    PcbDetections
        Centres are the centroids of each group's mask pixels; ``areas_px`` their counts.
    """
    # A bool mask is read as its bytes (0/1), without a full-frame copy.
    if not isinstance(mask, np.ndarray) or mask.dtype.kind not in "biuf":
        raise InputError(
            f"mask must be a numpy bool or number array (rows, cols); got {type(mask).__name__}."
        )
    is_bool = mask.dtype == np.bool_
    pixels = mask.view(np.uint8) if is_bool else np.asarray(mask, dtype=np.uint8)
    if pixels.ndim != 2:
        raise InputError(f"mask must be 2-D (rows, cols); got shape {pixels.shape}. Pass one image's mask.")
    values = None
    if score is not None:
        values = as_image(score, "score")
        same_shape(values, pixels, ("score", "mask"))
    return _grouped(
        pixels,
        positive_int(merge_gap_px, "merge_gap_px", minimum=0),
        positive_int(min_area_px, "min_area_px"),
        positive_int(grow_px, "grow_px", minimum=0),
        values,
    )


def _grouped(
    pixels: NDArray[np.uint8],
    merge_gap_px: int,
    min_area_px: int,
    grow_px: int,
    values: NDArray[np.floating] | None,
) -> PcbDetections:
    """:func:`group_defects` of a checked 0/1 mask and score map (the DeepPCB grouping's own, finite)."""
    radius = (merge_gap_px + 1) // 2
    # Only the box holding the mask's pixels and their dilation is labelled (a few defects on a large
    # image); it starts on an even row and column, so the labels come in the whole frame's order.
    top, left, bottom, right = occupied(pixels, radius)
    joined: NDArray[Any] = np.ascontiguousarray(pixels[top:bottom, left:right])
    if radius:
        # Dilating by half the gap joins pieces at most the gap apart; the labels are read at mask pixels.
        disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * radius + 1, 2 * radius + 1))
        joined = cv2.dilate(joined, disk)
    # The dilated groups as pixels (their boxes), and the label of each mask pixel among them: the mask's
    # pixels are the dilation's too, found in both in row-major order.
    count, joined_rows, joined_cols, joined_owner = pixel_components(joined, 8)
    stats, _ = component_stats(count, joined_rows + top, joined_cols + left, joined_owner)
    rows, cols = nonzero_pixels(pixels[top:bottom, left:right])
    width = right - left
    owner = joined_owner[np.searchsorted(joined_rows * width + joined_cols, rows * width + cols)]
    rows, cols = rows + top, cols + left
    area = np.bincount(owner, minlength=count).astype(np.float64)
    keep = (np.arange(count) > 0) & (area >= min_area_px)
    safe_area = np.maximum(area, 1.0)
    centres = np.column_stack(
        [np.bincount(owner, cols, count) / safe_area, np.bincount(owner, rows, count) / safe_area]
    )[keep]
    boxes = _grown_boxes(stats[keep], radius - grow_px, (int(pixels.shape[0]), int(pixels.shape[1])))
    strengths = None
    if values is not None:
        peak = np.zeros(count)
        np.maximum.at(peak, np.asarray(owner, dtype=np.intp), values[rows, cols])
        strengths = peak[keep]
    return PcbDetections(centres_xy=centres, boxes_xyxy=boxes, areas_px=area[keep], strengths=strengths)


def _clear_border(mask: NDArray[np.bool_], border_px: int) -> None:
    if border_px:
        mask[:border_px] = False
        mask[-border_px:] = False
        mask[:, :border_px] = False
        mask[:, -border_px:] = False


# DeepPCB's pairs come pre-aligned: most within 1 px, a few 2-4 px, with up to ~1-3% scale along one axis
# (docs/deeppcb.md). A fit beyond these bounds has locked onto the wrong structure of a sparse board.
_MAX_LINEAR_DEPARTURE = 0.05
_MAX_SHIFT_PX = 20.0


def _plausible(fit: Registration) -> bool:
    matrix = fit.matrix / fit.matrix[2, 2]
    return bool(
        np.all(np.isfinite(matrix))
        and np.abs(matrix[:2, :2] - np.eye(2)).max() <= _MAX_LINEAR_DEPARTURE
        and np.abs(matrix[:2, 2]).max() <= _MAX_SHIFT_PX
        and abs(matrix[2, 0]) + abs(matrix[2, 1]) < 1e-3
    )


def register_pair(
    reference: NDArray[np.floating],
    inspection: NDArray[np.floating],
    model: str,
    finest_level: int = 0,
    coarsest_level: int | None = None,
    *,
    row_step: int | None = None,
    photometric: bool = True,
    presmooth: bool = True,
    field_tolerance_px: float | None = None,
) -> Registration:
    """Register a DeepPCB pair: start at the identity (the pairs are pre-aligned), keep a plausible fit.

    A sparse board (a few traces on blank board) lets the coarse phase-correlation start of
    :func:`rsi.register` pick a wrong peak; 20 of the 1,000 trainval pairs then diverged or locked onto a
    5-40 % scale, and every defect of the pair was missed. From the identity, the model's fit is kept if
    plausible, else a translation's, else the identity itself (``reason="implausible"``). `finest_level`,
    `coarsest_level`, `row_step`, `photometric`, `presmooth` and `field_tolerance_px` (the local model's
    only) are :func:`rsi.register`'s (``DeepPcbSettings``'s ``registration_*``; :func:`registration_options`
    gives them).
    """
    from rsi.imaging.registration import register

    # rsi.register checks both images (and names them): no second pass over them here.
    for candidate in (choice(model, "model", REGISTRATION_MODELS), "translation"):
        fit = register(
            reference,
            inspection,
            model=candidate,
            initial=np.eye(3),
            finest_level=finest_level,
            coarsest_level=coarsest_level,
            row_step=row_step,
            photometric=photometric,
            presmooth=presmooth,
            field_tolerance_px=field_tolerance_px if candidate == LOCAL_MODEL else None,
        )
        if _plausible(fit):
            return fit
    return Registration(
        model="translation",
        matrix=np.eye(3),
        gain=1.0,
        bias=0.0,
        converged=False,
        reason="implausible",
        iterations=0,
        residual_rms=float("nan"),
        shift_std_px=(float("nan"), float("nan")),
        elapsed_s=0.0,
    )


def _grown(seeds: BoolArray, extent: BoolArray) -> BoolArray:
    """Pixels of `extent` 8-connected to a seed (morphological reconstruction by labelling)."""
    union = np.bitwise_or(extent, seeds, out=scratch("grown union", seeds.shape, np.bool_)).view(np.uint8)
    # Only the box holding the pixels is labelled: the components, hence the pixels kept, are the same; and
    # only its pixels (a few per cent of it) are read and written.
    top, left, bottom, right = occupied(union)
    count, rows, cols, owner = pixel_components(np.ascontiguousarray(union[top:bottom, left:right]), 8)
    rows, cols = rows + top, cols + left
    keep = np.zeros(count, dtype=bool)
    keep[owner[seeds[rows, cols]]] = True
    chosen = keep[owner]
    grown: BoolArray = np.zeros(seeds.shape, dtype=bool)
    grown[rows[chosen], cols[chosen]] = True
    return grown


def detect_defects(
    reference: NDArray[Any],
    inspection: NDArray[Any],
    *,
    settings: DeepPcbSettings | None = None,
    classifier: DefectClassifier | None = None,
) -> PcbDetections:
    """Find defects on a PCB inspection image with rsi's core: register, detect, group, name.

    Parameters
    ----------
    reference, inspection : ndarray of shape (M, N)
        Grey template and tested board, DN (0..255).
    settings : DeepPcbSettings, optional
        Defaults to ``DeepPcbSettings()``.
    classifier : DefectClassifier, optional
        Names the defects from their topology features
        (:func:`rsi.datasets.pcb_features.fit_classifier`); None: the topology rules of
        :mod:`rsi.datasets.pcb_classes`.

    Returns
    -------
    PcbDetections
        In inspection-image pixels, with ``features`` to train a classifier on.
    """
    from rsi.detection.detect import detect

    chosen = instance_or_default(settings, "settings", DeepPcbSettings)
    if classifier is not None:
        instance_of(classifier, "classifier", DefectClassifier, none_allowed=False)
    reference_image = as_image(reference, "reference")
    inspection_image = as_image(inspection, "inspection")
    fit = register_pair(reference_image, inspection_image, **registration_options(chosen))
    detection = detect(
        reference_image,
        inspection_image,
        flaw_model=chosen.flaw_model,
        size=chosen.size,
        method=chosen.method,
        p_false_alarm=chosen.p_false_alarm,
        polarity="both",
        noise_sigma=chosen.noise_sigma,
        registration=fit,
        # seed §2.4: residual mis-registration is extra noise sigma_s^2 |grad ref|^2; the fit's statistical
        # std knows nothing of etching or local distortion, so it is floored at what these boards show.
        misregistration_std_px=chosen.misregistration_std_px,
        sparse_above=sparse_above(chosen),
    )
    return name_detection(group_detection(detection, chosen), detection, inspection_image, classifier)


def predicted_template(detection: Detection, inspection: NDArray[np.floating]) -> NDArray[np.floating]:
    """The template as the detector predicted it in the test's frame: the inspection less the difference
    where the test is valid, the inspection's own pixels elsewhere (``np.where(valid, inspection - d,
    inspection)``, without its full-size temporaries)."""
    from rsi.detection.detect import Detection

    instance_of(detection, "detection", Detection, none_allowed=False)
    test = as_image(inspection, "inspection")
    same_shape(test, detection.difference, ("inspection", "detection.difference"))
    return _template(detection, test)


def name_detection(
    found: PcbDetections,
    detection: Detection,
    inspection: NDArray[np.floating],
    classifier: DefectClassifier | None = None,
) -> PcbDetections:
    """:func:`name_defects` of `found` on the template `detection` predicted (:func:`predicted_template`)
    and the inspection it was run on: the template is made from checked arrays, so only the inspection is
    checked, once (``detect_defects``' last step)."""
    from rsi.detection.detect import Detection

    _check_to_name(found, classifier)
    instance_of(detection, "detection", Detection, none_allowed=False)
    test = as_image(inspection, "inspection")
    same_shape(test, detection.difference, ("inspection", "detection.difference"))
    return _named(found, _template(detection, test), test, classifier)


def _template(detection: Detection, test: NDArray[np.floating]) -> NDArray[np.floating]:
    """:func:`predicted_template` of a checked test image."""
    template: NDArray[np.floating] = test - detection.difference
    np.copyto(template, test, where=~detection.valid)
    return template


def registration_options(settings: DeepPcbSettings) -> dict[str, Any]:
    """:func:`register_pair`'s arguments for these settings (model, levels, rows, photometric, smoothing)."""
    instance_of(settings, "settings", DeepPcbSettings, none_allowed=False)
    return {
        "model": settings.registration_model,
        "finest_level": settings.registration_finest_level,
        "coarsest_level": settings.registration_coarsest_level,
        "row_step": settings.registration_row_step,
        "photometric": settings.registration_photometric,
        "presmooth": settings.registration_presmooth,
        "field_tolerance_px": settings.registration_field_tolerance_px,
    }


def _single_pixel_threshold(settings: DeepPcbSettings) -> float:
    """The single-pixel test's threshold at the settings' false-alarm probability (grown extent)."""
    from rsi.detection.roc import threshold_for

    return threshold_for(settings.p_false_alarm, polarity="both", method="lrt", flaw_model="single")


def sparse_above(settings: DeepPcbSettings) -> float | None:
    """:func:`rsi.detect`'s ``sparse_above`` for these settings: the lowest ``|d| / sigma`` the grouping
    reads (the grown extent's threshold), or None for whole-frame maps."""
    instance_of(settings, "settings", DeepPcbSettings, none_allowed=False)
    return _single_pixel_threshold(settings) if settings.sparse else None


def group_detection(detection: Detection, settings: DeepPcbSettings) -> PcbDetections:
    """The defects of one detection: border cleared, grown to the per-pixel extent, merged, padded."""
    from rsi.detection.detect import Detection

    instance_of(detection, "detection", Detection, none_allowed=False)
    instance_of(settings, "settings", DeepPcbSettings, none_allowed=False)
    # The full-frame maps here are temporaries of this call: this thread's scratch buffers, whose pages stay
    # mapped from one pair to the next (a fresh full-frame array costs its page faults, as much as its pass).
    shape = detection.mask.shape
    mask = scratch("group mask", shape, np.bool_)
    np.copyto(mask, detection.mask)
    _clear_border(mask, settings.border_px)
    # seed §2.4: the per-pixel statistic d / sigma, with the same noise model (mis-registration included).
    pixel_z = np.abs(detection.difference, out=scratch("group z", shape, np.float32))
    floored = np.maximum(detection.sigma, np.float32(1e-6), out=scratch("group sigma", shape, np.float32))
    np.divide(pixel_z, floored, out=pixel_z)
    # The erosion test's mask is the defect eroded by size // 2: grow that back, then pad like DeepPCB.
    undo_erosion = settings.size // 2 if settings.method == "erosion" else 0
    if settings.grow_to_changes:
        single = _single_pixel_threshold(settings)
        extent = np.greater(pixel_z, single, out=scratch("group extent", shape, np.bool_))
        extent &= detection.valid
        _clear_border(extent, settings.border_px)
        mask, undo_erosion = _grown(mask, extent), 0
    # |d| / sigma is finite by construction (sigma floored): the grouping need not check it again.
    return _grouped(
        mask.view(np.uint8),
        settings.merge_gap_px,
        settings.min_area_px,
        undo_erosion + settings.box_padding_px,
        pixel_z,
    )


def _check_to_name(found: PcbDetections, classifier: DefectClassifier | None) -> None:
    """`found` holds the grouping's strengths and areas, and `classifier` is None or a DefectClassifier."""

    instance_of(found, "found", PcbDetections, none_allowed=False)
    if classifier is not None:
        instance_of(classifier, "classifier", DefectClassifier, none_allowed=False)
    if found.strengths is None or found.areas_px is None:
        raise InputError("found must come from group_defects(..., score=...) (it holds no strengths/areas).")


def name_defects(
    found: PcbDetections,
    template: NDArray[np.floating],
    test: NDArray[np.floating],
    classifier: DefectClassifier | None = None,
) -> PcbDetections:
    """`found` with its topology features, classes and confidences (the classifier's, or the rules')."""

    _check_to_name(found, classifier)
    template_image = as_image(template, "template")
    test_image = as_image(test, "test")
    same_shape(template_image, test_image, ("template", "test"))
    return _named(found, template_image, test_image, classifier)


def _named(
    found: PcbDetections,
    template: NDArray[np.floating],
    test: NDArray[np.floating],
    classifier: DefectClassifier | None,
) -> PcbDetections:
    """:func:`name_defects` of checked images and detections that hold strengths and areas."""

    features = _checked_features(template, test, found.boxes_xyxy, found.strengths, found.areas_px)
    if classifier is None:
        # The features hold the rules' naming of each box (classify_defects), counted once.
        classes, confidences = rule_classes(features)
    else:
        classes, confidences = classifier.predict(features)
    return dataclasses.replace(found, classes=classes, confidences=confidences, features=features)


Detector = Callable[[NDArray[np.float32], NDArray[np.float32]], PcbDetections]
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class MatchCounts:
    """What one or more pairs contributed to the figures; counts add up across pairs and groups.

    Attributes
    ----------
    pairs, boxes, found, detections, false_alarms, iou_found, iou_correct : int
        Pairs; ground-truth boxes; boxes found (centre in box); detections; detections whose centre lies in
        no box; boxes and detections paired by the class-agnostic IoU > 0.33 rule.
    seconds : float
        Wall time spent on them, reading the images included.
    """

    pairs: int = 0
    boxes: int = 0
    found: int = 0
    detections: int = 0
    false_alarms: int = 0
    iou_found: int = 0
    iou_correct: int = 0
    seconds: float = 0.0

    def __add__(self, other: MatchCounts) -> MatchCounts:
        return MatchCounts(
            *(getattr(self, field.name) + getattr(other, field.name) for field in dataclasses.fields(self))
        )

    @property
    def f1(self) -> float:
        """The centre-in-box F1 of these counts (0 when undefined)."""
        return self.result().f1

    def result(self) -> EvaluationResult:
        """The figures of these counts."""
        recall = _safe_ratio(self.found, self.boxes)
        precision = _safe_ratio(self.detections - self.false_alarms, self.detections)
        return EvaluationResult(
            pairs=self.pairs,
            defects=self.boxes,
            recall=recall,
            precision=precision,
            f1=_safe_ratio(2.0 * recall * precision, recall + precision),
            false_alarms_per_image=_safe_ratio(self.false_alarms, self.pairs),
            iou_recall=_safe_ratio(self.iou_found, self.boxes),
            iou_precision=_safe_ratio(self.iou_correct, self.detections),
            seconds_per_pair=_safe_ratio(self.seconds, self.pairs),
        )


def match_counts(pair: DeepPcbPair, found: PcbDetections, seconds: float = 0.0) -> MatchCounts:
    """Score one pair's detections against its ground truth by both matching rules."""
    instance_of(pair, "pair", DeepPcbPair, none_allowed=False)
    instance_of(found, "found", PcbDetections, none_allowed=False)
    seconds = in_range(seconds, "seconds", low=0.0)
    hit, false_alarm = centre_in_box(found.centres_xy, pair.boxes_xyxy)
    iou_found, iou_correct = iou_match(found.boxes_xyxy, pair.boxes_xyxy)
    return MatchCounts(
        pairs=1,
        boxes=int(hit.size),
        found=int(hit.sum()),
        detections=int(false_alarm.size),
        false_alarms=int(false_alarm.sum()),
        iou_found=int(iou_found.sum()),
        iou_correct=int(iou_correct.sum()),
        seconds=seconds,
    )


def _check_pairs(pairs: object) -> None:
    if not isinstance(pairs, Sequence) or isinstance(pairs, (str, bytes)):
        raise InputError(
            f"pairs must be a sequence of DeepPcbPair (rsi.datasets.deeppcb.load_split); got {pairs!r:.60}."
        )
    if len(pairs) == 0:
        raise InputError("pairs is empty. Pass at least one DeepPcbPair (rsi.datasets.deeppcb.load_split).")
    for index, pair in enumerate(pairs):
        instance_of(pair, f"pairs[{index}]", DeepPcbPair, none_allowed=False)


def _check_callable(value: object, name: str, shape: str) -> None:
    if not callable(value):
        raise InputError(f"{name} must be a function called as {shape}; got {value!r:.60}.")


def count_pairs(
    pairs: Sequence[DeepPcbPair],
    detector: Detector,
    *,
    progress: Progress | None = None,
    tally: OfficialTally | None = None,
) -> list[MatchCounts]:
    """Run a detector over pairs; one :class:`MatchCounts` per pair (times include reading the images).

    With `tally` (:class:`rsi.datasets.official.OfficialTally`), each pair is also scored by the official
    rule.
    """

    _check_pairs(pairs)
    _check_callable(detector, "detector", "detector(reference, inspection) -> PcbDetections")
    if progress is not None:
        _check_callable(progress, "progress", "progress(pair_id, done, total)")
    if tally is not None:
        instance_of(tally, "tally", OfficialTally)
    counts = []
    for done, pair in enumerate(pairs, start=1):
        start = time.perf_counter()
        found = detector(*read_pair(pair))
        counts.append(match_counts(pair, found, time.perf_counter() - start))
        if tally is not None:
            unnamed = np.zeros(len(found.boxes_xyxy), dtype=np.int64)
            tally.add(
                pair.boxes_xyxy,
                pair.defect_types,
                found.boxes_xyxy,
                unnamed if found.classes is None else found.classes,
                np.zeros(len(unnamed)) if found.confidences is None else found.confidences,
            )
        if progress is not None:
            progress(pair.pair_id, done, len(pairs))
    return counts


def evaluate_pairs(
    pairs: Sequence[DeepPcbPair], detector: Detector, *, progress: Progress | None = None
) -> EvaluationResult:
    """Run a detector over pairs and score it by both matching rules.

    Parameters
    ----------
    pairs : sequence of DeepPcbPair
        From :func:`rsi.datasets.deeppcb.load_split`; at least one.
    detector : callable
        ``detector(reference, inspection) -> PcbDetections``.
    progress : callable, optional
        Called as ``progress(pair_id, done, total)`` after each pair (the CLI's progress bar).

    Returns
    -------
    EvaluationResult
    """

    tally = OfficialTally()
    counts = sum(count_pairs(pairs, detector, progress=progress, tally=tally), MatchCounts())
    return dataclasses.replace(counts.result(), **tally.figures())


def group_of(pair: DeepPcbPair) -> str:
    """The board group of a pair, the first folder of its id (e.g. ``"group20085"``)."""
    instance_of(pair, "pair", DeepPcbPair, none_allowed=False)
    return pair.pair_id.split("/", 1)[0]


@dataclass(frozen=True)
class LeaveOneGroupOut:
    """Leave-one-group-out figures: each group scored with the setting chosen on the others.

    Attributes
    ----------
    chosen : dict of str to str
        Per left-out group, the name of the setting that scored best (centre-in-box F1, then fewest false
        alarms) on the other groups.
    held_out : dict of str to MatchCounts
        Per group, its counts under the setting chosen without it.
    pooled : MatchCounts
        The sum of ``held_out`` over the groups.
    """

    chosen: dict[str, str]
    held_out: dict[str, MatchCounts]
    pooled: MatchCounts


def _check_counts(counts: object) -> None:
    """counts[setting][group] must be MatchCounts, keyed by names."""
    if not isinstance(counts, Mapping):
        raise InputError(f"counts must be a dict counts[setting][group] of MatchCounts; got {counts!r:.60}.")
    for setting, by_group in counts.items():
        if not isinstance(by_group, Mapping):
            raise InputError(
                f"counts[{setting!r:.40}] must be a dict of group -> MatchCounts; got {by_group!r:.60}."
            )
        for group, tally in by_group.items():
            instance_of(tally, f"counts[{setting!r:.40}][{group!r:.40}]", MatchCounts, none_allowed=False)


def leave_one_group_out(counts: dict[str, dict[str, MatchCounts]]) -> LeaveOneGroupOut:
    """Choose a setting on all groups but one, score that one; each group in turn.

    Parameters
    ----------
    counts : dict of str to dict of str to MatchCounts
        ``counts[setting][group]``: every setting scored on every group (the same groups for each).

    Returns
    -------
    LeaveOneGroupOut
        No setting is ever chosen per group on that group's own figures.
    """
    _check_counts(counts)
    if not counts:
        raise InputError("counts is empty. Pass counts[setting][group] for at least one setting.")
    groups = sorted(next(iter(counts.values())))
    if len(groups) < 2 or any(sorted(by_group) != groups for by_group in counts.values()):
        raise InputError(
            f"counts must hold the same groups (at least two) for every setting; got "
            f"{ {name: sorted(by_group) for name, by_group in counts.items()} }."
        )
    chosen, held_out = {}, {}
    for group in groups:

        def training(name: str, left_out: str = group) -> tuple[float, float]:
            total = sum((c for g, c in counts[name].items() if g != left_out), MatchCounts())
            return total.f1, -total.false_alarms / max(total.pairs, 1)

        best = max(counts, key=training)
        chosen[group] = best
        held_out[group] = counts[best][group]
    return LeaveOneGroupOut(chosen, held_out, sum(held_out.values(), MatchCounts()))
