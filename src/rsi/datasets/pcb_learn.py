"""DeepPCB's figures with the defects named by a classifier never fitted on the pairs it names, and the
whole evaluation of a split (:func:`evaluate_deeppcb`, issue 12, item 3).

The classifier (:mod:`rsi.datasets.pcb_features`) is trained on the detections of training pairs only: each
detection paired class-agnostically with a ground-truth box (IoU > 0.33) takes its class, an unpaired one
class 0 ("no defect"). The test split is named by one fitted on trainval (the dataset's own protocol);
trainval is cross-fitted by board group, each group named by a classifier fitted on the other groups.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import cast

import numpy as np
from numpy.typing import NDArray

from rsi._validate import choice, instance_of, instance_or_default
from rsi.datasets.deeppcb import DeepPcbPair, PathLike, load_split, read_pair
from rsi.datasets.evaluate import (
    DeepPcbSettings,
    EvaluationResult,
    MatchCounts,
    PcbDetections,
    Progress,
    detect_defects,
    evaluate_pairs,
    group_of,
    match_counts,
)
from rsi.datasets.official import OFFICIAL_IOU, OfficialTally, box_iou
from rsi.datasets.pcb_features import DefectClassifier, fit_classifier
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def training_labels(pair: DeepPcbPair, found: PcbDetections) -> IntArray:
    """The class of the ground-truth box each detection pairs with (IoU > 0.33, one-to-one, greedy by
    IoU, class ignored), 0 for a detection that pairs with none."""
    instance_of(pair, "pair", DeepPcbPair, none_allowed=False)
    instance_of(found, "found", PcbDetections, none_allowed=False)
    iou = box_iou(found.boxes_xyxy, pair.boxes_xyxy)
    labels = np.zeros(iou.shape[0], dtype=np.int64)
    taken = np.zeros(iou.shape[1], dtype=bool)
    rows, cols = np.nonzero(iou > OFFICIAL_IOU)
    for index in np.argsort(-iou[rows, cols], kind="stable"):
        row, col = rows[index], cols[index]
        if labels[row] == 0 and not taken[col]:
            labels[row], taken[col] = pair.defect_types[col], True
    return labels


def train_classifier(
    pairs: list[DeepPcbPair], settings: DeepPcbSettings | None = None, *, progress: Progress | None = None
) -> DefectClassifier:
    """Run the detector on training pairs and fit the classifier to their detections (see the module).

    `progress` is called as ``progress(stage, done, total)`` after each pair.
    """
    _check_pair_list(pairs)
    found = _detected(pairs, instance_or_default(settings, "settings", DeepPcbSettings), progress, "training")
    return _fitted(found)


def evaluate_learned(
    root: PathLike, split: str, *, settings: DeepPcbSettings | None = None, progress: Progress | None = None
) -> EvaluationResult:
    """A split's figures with the defects named by the classifier, never one fitted on the pairs it names.

    The test split is named by a classifier fitted on the trainval pairs of the same `root` (the dataset's
    own protocol); trainval is cross-fitted by board group: each group is named by a classifier fitted on
    the detections of the other groups only. The class-agnostic figures are the detector's, as with the
    rules (:func:`evaluate_deeppcb`). The result's ``classes`` says which classifier
    named them: "learned (fitted on trainval)" or "learned (fitted on the other board groups)".

    Raises
    ------
    InputError
        If trainval holds a single board group (nothing to cross-fit on); pass ``classes="rules"``.
    DatasetError
        If a split file, an image or an annotation is missing (the test split needs trainval's too).
    """
    chosen = instance_or_default(settings, "settings", DeepPcbSettings)
    if progress is not None and not callable(progress):
        raise InputError(
            f"progress must be a function called as progress(stage, done, total); got {progress!r:.60}."
        )
    scored = load_split(root, split)
    if split == "test":
        classifier = train_classifier(list(load_split(root, "trainval")), chosen, progress=progress)
        named = _detected(scored, chosen, progress, "scoring", classifier)
        return dataclasses.replace(_figures(named), classes="learned (fitted on trainval)")
    found = _detected(scored, chosen, progress, "scoring")
    groups = sorted({group_of(pair) for pair, _, _ in found})
    if len(groups) < 2:
        raise InputError(
            f"classes='learned' on trainval fits each board group's classifier on the other groups; "
            f"{root!s:.80} holds only {groups}. Pass classes='rules' (CLI: --classes rules)."
        )
    folds = {group: _fitted([item for item in found if group_of(item[0]) != group]) for group in groups}
    named = [
        (pair, _renamed(detections, folds[group_of(pair)]), seconds) for pair, detections, seconds in found
    ]
    return dataclasses.replace(_figures(named), classes="learned (fitted on the other board groups)")


Found = list[tuple[DeepPcbPair, PcbDetections, float]]


def _check_pair_list(pairs: object) -> None:
    is_list = isinstance(pairs, (list, tuple)) and len(pairs) > 0
    if not is_list or not all(isinstance(pair, DeepPcbPair) for pair in cast(list[object], pairs)):
        raise InputError(
            "pairs must be a non-empty list of DeepPcbPair (rsi.datasets.deeppcb.load_split); "
            f"got {pairs!r:.60}."
        )


def _detected(
    pairs: Sequence[DeepPcbPair],
    settings: DeepPcbSettings,
    progress: Progress | None,
    stage: str,
    classifier: DefectClassifier | None = None,
) -> Found:
    """Each pair's detections with the wall seconds they took, reading both JPEGs included."""
    found = []
    for done, pair in enumerate(pairs, start=1):
        start = time.perf_counter()
        detections = detect_defects(*read_pair(pair), settings=settings, classifier=classifier)
        found.append((pair, detections, time.perf_counter() - start))
        if progress is not None:
            progress(f"{stage} {pair.pair_id}", done, len(pairs))
    return found


def _fitted(found: Found) -> DefectClassifier:
    features = np.concatenate([cast(FloatArray, detections.features) for _, detections, _ in found])
    labels = np.concatenate([training_labels(pair, detections) for pair, detections, _ in found])
    return fit_classifier(features, labels)


def _renamed(detections: PcbDetections, classifier: DefectClassifier) -> PcbDetections:
    classes, confidences = classifier.predict(detections.features)
    return dataclasses.replace(detections, classes=classes, confidences=confidences)


def _figures(found: Found) -> EvaluationResult:
    """Both matching rules' figures of detections already named."""
    tally, counts = OfficialTally(), MatchCounts()
    for pair, detections, seconds in found:
        tally.add(
            pair.boxes_xyxy,
            pair.defect_types,
            detections.boxes_xyxy,
            detections.classes,
            detections.confidences,
        )
        counts += match_counts(pair, detections, seconds)
    return dataclasses.replace(counts.result(), **tally.figures())


# Where the defects' classes come from (evaluate_deeppcb's `classes`).
CLASS_SOURCES = ("learned", "rules")


def evaluate_deeppcb(
    root: PathLike,
    split: str,
    *,
    settings: DeepPcbSettings | None = None,
    progress: Progress | None = None,
    classes: str = "learned",
) -> EvaluationResult:
    """Evaluate rsi's PCB detector on a DeepPCB split.

    Parameters
    ----------
    root : str or os.PathLike
        The DeepPCB folder (holding ``PCBData/``).
    split : {"trainval", "test"}
        Official split; the same ``settings`` serve every split.
    settings : DeepPcbSettings, optional
        Defaults to ``DeepPcbSettings()``.
    progress : callable, optional
        Called as ``progress(stage, done, total)`` after each pair (the CLI's progress bar).
    classes : {"learned", "rules"}
        Who names the defects for the official figures. "learned": the classifier of
        :mod:`rsi.datasets.pcb_features`, never fitted on the pairs it names (the test split by one fitted on
        trainval, ~1 min more; trainval cross-fitted by board group: :func:`evaluate_learned`). "rules":
        the topology rules of :mod:`rsi.datasets.pcb_classes`, nothing fitted. The class-agnostic figures
        are the same with either.

    Returns
    -------
    EvaluationResult

    Examples
    --------
    >>> result = evaluate_deeppcb("../shared/data/deeppcb", "trainval")  # doctest: +SKIP
    >>> sorted(result.to_dict())[:3]  # doctest: +SKIP
    ['classes', 'confusion', 'defects']
    """
    chosen = DeepPcbSettings() if settings is None else settings
    if not isinstance(chosen, DeepPcbSettings):
        raise InputError(f"settings must be a DeepPcbSettings; got {type(chosen).__name__}.")
    if choice(classes, "classes", CLASS_SOURCES) == "learned":
        return evaluate_learned(root, split, settings=chosen, progress=progress)

    def detector(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> PcbDetections:
        return detect_defects(reference, inspection, settings=chosen)

    return evaluate_pairs(load_split(root, split), detector, progress=progress)
