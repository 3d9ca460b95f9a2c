"""DeepPCB's official scoring rule, written anew in Python 3: IoU > 0.33 and the same class.

Tang et al. (arXiv:1902.06197) score detections with an adaptation of the ICDAR 2015 "IoU" evaluation
script: in each image a detection and a ground-truth box are paired when both are still unpaired, their
classes agree and their IoU exceeds 0.33, going through the ground-truth boxes in file order and, for each,
the detections in order (first come, first paired: not the best IoU). Precision is paired detections over
detections, recall paired boxes over boxes, the F-score their harmonic mean, all summed over the images.
Average precision follows the same script's ``compute_ap``: the detections of a class, over every image,
sorted by decreasing confidence; at each paired one, the precision so far (paired so far / rank) is added;
the sum is divided by the class's ground-truth boxes. mAP is the mean over the classes that have boxes.
(The script itself was not available to us; these are its published rules. Boxes are corners-inclusive
pixels, as DeepPCB's annotation.)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TypedDict

import numpy as np
from numpy.typing import NDArray

from rsi._validate import as_float_array, as_table, positive_int
from rsi.datasets.deeppcb import DEFECT_TYPES
from rsi.errors import InputError

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]
CLASSES = tuple(DEFECT_TYPES)
NONE = 0  # the confusion matrix's row of unpaired detections and column of missed boxes
OFFICIAL_IOU = 0.33  # Tang et al. 2019: a detection is correct when IoU > 0.33 (and the class agrees)
_BOX_COLUMNS = 4


def box_iou(first_xyxy: object, second_xyxy: object) -> FloatArray:
    """Intersection over union of every pair of boxes, corners inclusive (a box covers whole pixels).

    Parameters
    ----------
    first_xyxy : array_like of shape (D, 4)
    second_xyxy : array_like of shape (K, 4)

    Returns
    -------
    ndarray of shape (D, K), float64
    """
    first = as_table(first_xyxy, "first_xyxy", _BOX_COLUMNS)
    second = as_table(second_xyxy, "second_xyxy", _BOX_COLUMNS)
    a, b = first[:, None, :], second[None, :, :]
    width = np.clip(np.minimum(a[..., 2], b[..., 2]) - np.maximum(a[..., 0], b[..., 0]) + 1.0, 0.0, None)
    height = np.clip(np.minimum(a[..., 3], b[..., 3]) - np.maximum(a[..., 1], b[..., 1]) + 1.0, 0.0, None)
    intersection = width * height
    area_a = (a[..., 2] - a[..., 0] + 1.0) * (a[..., 3] - a[..., 1] + 1.0)
    area_b = (b[..., 2] - b[..., 0] + 1.0) * (b[..., 3] - b[..., 1] + 1.0)
    iou: FloatArray = intersection / (area_a + area_b - intersection)
    return iou


def _classes(value: object, name: str, count: int) -> IntArray:
    """One whole-number class per box, `count` of them."""
    classes = as_float_array(value, name).reshape(-1)
    if classes.size != count or not np.all(np.isfinite(classes) & (classes == np.round(classes))):
        raise InputError(f"{name} must hold {count} whole-number classes (one per box); got {value!r:.80}.")
    return classes.astype(np.int64)


def pair_official(
    truth_xyxy: object, truth_classes: object, detected_xyxy: object, detected_classes: object
) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """One image's pairing by the official rule: IoU > 0.33, same class, boxes then detections in order.

    Returns
    -------
    found : ndarray of shape (K,), bool
        Whether each ground-truth box was paired.
    correct : ndarray of shape (D,), bool
        Whether each detection was paired.
    """
    iou = box_iou(truth_xyxy, detected_xyxy)
    truth = _classes(truth_classes, "truth_classes", iou.shape[0])
    detected = _classes(detected_classes, "detected_classes", iou.shape[1])
    found = np.zeros(iou.shape[0], dtype=bool)
    correct = np.zeros(iou.shape[1], dtype=bool)
    for box in range(iou.shape[0]):
        for detection in range(iou.shape[1]):
            if (
                not correct[detection]
                and truth[box] == detected[detection]
                and iou[box, detection] > OFFICIAL_IOU
            ):
                found[box] = correct[detection] = True
                break
    return found, correct


def average_precision(confidences: object, correct: object, boxes: int) -> float:
    """The ICDAR script's ``compute_ap``: precision at each paired detection, by confidence, over boxes."""
    scores = as_float_array(confidences, "confidences").reshape(-1)
    flags = as_float_array(correct, "correct").reshape(-1)
    if flags.size != scores.size or not np.all((flags == 0) | (flags == 1)):
        raise InputError(
            f"correct must hold {scores.size} booleans (one per confidence); got {correct!r:.80}."
        )
    if np.isnan(scores).any():
        raise InputError("confidences contain NaN; pass a number per detection (inf ranks first or last).")
    count = positive_int(boxes, "boxes", minimum=0, maximum=2**53)  # an exact float: the AP divides by it
    paired = flags.astype(bool)[np.argsort(-scores, kind="stable")]
    if count == 0 or paired.size == 0:
        return 0.0
    ranks = np.arange(1, paired.size + 1)
    return float(np.sum((np.cumsum(paired) / ranks)[paired]) / count)


class OfficialFigures(TypedDict):
    """The official figures (the keys `rsi eval deeppcb` reports)."""

    official_precision: float
    official_recall: float
    official_f: float
    map: float
    per_class: dict[str, dict[str, float]]
    confusion: list[list[int]]


@dataclass
class OfficialTally:
    """Accumulates images for the official figures, the per-class table and the confusion matrix."""

    boxes: dict[int, int] = field(default_factory=lambda: dict.fromkeys(CLASSES, 0))
    found: dict[int, int] = field(default_factory=lambda: dict.fromkeys(CLASSES, 0))
    # Detections by class; class NONE (0) holds unnamed ones, which are never paired.
    detections: dict[int, list[tuple[float, bool]]] = field(
        default_factory=lambda: {c: [] for c in (NONE, *CLASSES)}
    )
    confusion: IntArray = field(default_factory=lambda: np.zeros((len(CLASSES) + 1,) * 2, dtype=np.int64))

    def add(
        self,
        truth_xyxy: object,
        truth_classes: object,
        detected_xyxy: object,
        detected_classes: object,
        confidences: object,
    ) -> None:
        """Score one image; classes are keys of :data:`rsi.datasets.deeppcb.DEFECT_TYPES` (0: unnamed)."""
        truth = np.asarray(truth_classes, dtype=np.int64).reshape(-1)
        detected = np.asarray(detected_classes, dtype=np.int64).reshape(-1)
        scores = np.asarray(confidences, dtype=np.float64).reshape(-1)
        found, correct = pair_official(truth_xyxy, truth, detected_xyxy, detected)
        for cls, hit in zip(truth.tolist(), found.tolist(), strict=True):
            self.boxes[cls] += 1
            self.found[cls] += int(hit)
        for cls, score, hit in zip(detected.tolist(), scores.tolist(), correct.tolist(), strict=True):
            self.detections[cls].append((score, hit))
        self._confuse(truth_xyxy, truth, detected_xyxy, detected)

    def __add__(self, other: OfficialTally) -> OfficialTally:
        """The tally of both sets of images."""
        return OfficialTally(
            boxes={cls: self.boxes[cls] + other.boxes[cls] for cls in CLASSES},
            found={cls: self.found[cls] + other.found[cls] for cls in CLASSES},
            detections={cls: self.detections[cls] + other.detections[cls] for cls in self.detections},
            confusion=self.confusion + other.confusion,
        )

    def _confuse(
        self, truth_xyxy: object, truth: IntArray, detected_xyxy: object, detected: IntArray
    ) -> None:
        # Class-agnostic pairing (IoU > 0.33, greedy by IoU), then count (true class, detected class).
        iou = box_iou(truth_xyxy, detected_xyxy)
        used_truth = np.zeros(iou.shape[0], dtype=bool)
        used_detection = np.zeros(iou.shape[1], dtype=bool)
        rows, cols = np.nonzero(iou > OFFICIAL_IOU)
        for index in np.argsort(-iou[rows, cols], kind="stable"):
            row, col = rows[index], cols[index]
            if not used_truth[row] and not used_detection[col]:
                used_truth[row] = used_detection[col] = True
                self.confusion[truth[row], detected[col]] += 1
        for cls in truth[~used_truth]:
            self.confusion[cls, NONE] += 1
        for cls in detected[~used_detection]:
            self.confusion[NONE, cls] += 1

    def figures(self) -> OfficialFigures:
        """official_precision, official_recall, official_f, map and per_class (precision, recall, ap)."""
        boxes = sum(self.boxes.values())
        found = sum(self.found.values())
        detections = sum(len(items) for items in self.detections.values())
        paired = sum(hit for items in self.detections.values() for _, hit in items)
        precision = paired / detections if detections else 0.0
        recall = found / boxes if boxes else 0.0
        per_class: dict[str, dict[str, float]] = {}
        for cls in CLASSES:
            items = self.detections[cls]
            hits = sum(hit for _, hit in items)
            per_class[DEFECT_TYPES[cls]] = {
                "boxes": self.boxes[cls],
                "detections": len(items),
                "precision": hits / len(items) if items else 0.0,
                "recall": self.found[cls] / self.boxes[cls] if self.boxes[cls] else 0.0,
                "ap": average_precision([s for s, _ in items], [h for _, h in items], self.boxes[cls]),
            }
        with_boxes = [per_class[DEFECT_TYPES[cls]]["ap"] for cls in CLASSES if self.boxes[cls]]
        return OfficialFigures(
            official_precision=precision,
            official_recall=recall,
            official_f=2 * precision * recall / (precision + recall) if precision + recall else 0.0,
            map=float(np.mean(with_boxes)) if with_boxes else 0.0,
            per_class=per_class,
            confusion=self.confusion.tolist(),
        )
