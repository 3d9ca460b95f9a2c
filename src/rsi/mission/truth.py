"""The simulator's truth about a mission's visits, for scoring and the report only.

No module that produces findings reads this (``tests/mission/test_sensing.py`` proves it): the visits'
findings come from what the ISEE gave (:class:`rsi.sim.capture.Capture`); here the simulator's record of
the same visit (:class:`rsi.sim.world.View`: the anomalies' masks) is attached to the visit's record, to
score the run's ROC and to name the anomalies the visit could have seen.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.mission.records import VisitImages, VisitRecord, counts_towards_recall

if TYPE_CHECKING:
    from rsi.detection.detect import Detection
    from rsi.detection.pair import PairResult
    from rsi.sim.anomalies import AnomalySet
    from rsi.sim.world import View


def with_truth(record: VisitRecord, pair: PairResult, view: View, truth: AnomalySet) -> VisitRecord:
    """`record` with the anomalies its view showed and the comparison's images with the impacts' truth."""
    return replace(record, visible=tuple(sorted(view.flaw_masks)), images=visit_images(pair, view, truth))


def visit_images(pair: PairResult, view: View, truth: AnomalySet) -> VisitImages:
    """The comparison's images for the report, and the truth of the impacts that count (for the ROC)."""
    detection = pair.detection
    impacts = np.zeros_like(detection.valid)
    for index, mask in view.flaw_masks.items():
        anomaly = truth.anomalies[index]
        if anomaly.kind == "impact" and counts_towards_recall(anomaly):
            impacts |= mask
    inspection = np.asarray(pair.inspection, dtype=np.float32)
    return VisitImages(
        reference=(inspection - detection.difference).astype(np.float32),
        inspection=inspection,
        difference=detection.difference,
        score=detection.score,
        valid=detection.valid,
        impact_truth=impacts,
        impact_strengths=impact_strengths(detection, impacts),
    )


def impact_strengths(detection: Detection, truth: NDArray[np.bool_]) -> tuple[float, ...]:
    """Each truth impact's strength: the difference at its most changed pixel (either sign: the mission
    tests both) over that pixel's noise sigma."""
    import cv2

    count, labels = cv2.connectedComponents(truth.astype(np.uint8), connectivity=8)
    strengths = []
    for label in range(1, count):
        inside = (labels == label) & detection.valid
        if not inside.any():
            continue
        peak = int(np.argmax(np.where(inside, np.abs(detection.difference), -np.inf)))
        sigma = float(detection.sigma.flat[peak])
        strengths.append(abs(float(detection.difference.flat[peak])) / max(sigma, 1e-6))
    return tuple(strengths)


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
