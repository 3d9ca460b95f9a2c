"""A mission against its ground truth: recall and false findings per anomaly type, the misses and why, and
the run's ROC (seed §2.4) against the theory for the impacts it saw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rsi._validate import instance_of
from rsi.errors import InputError
from rsi.mission.records import (
    SCORED_TYPES,
    MissionFinding,
    MissionResult,
    VisitRecord,
    counts_towards_recall,
    scored_type,
)
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.detection.roc import RocCurve
    from rsi.sim.anomalies import Anomaly

# a finding matches an anomaly of its kind within these distances: a few localisation errors for the small
# anomalies, a component's half-width for a swap, the sensors' spot and station spacing for the others
_MATCH_RADIUS_M = {
    "impact": 0.01,
    "missing_screw": 0.01,
    "swapped_component": 0.05,
    "hot_spot": 0.03,
    "cold_spot": 0.03,
    "gas_leak": 0.03,
}


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
    nearest first. A targeted run (``MissionSettings.vistas``) counts only the visual anomalies some frame of
    it sees (the thermal spots and leaks, surveyed whatever the views, always count); the whole plan counts
    every anomaly, seen or not.

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
    targeted = bool(result.settings.vistas)
    seen = {k for visit in result.visits for k in visit.visible}
    for k, anomaly in enumerate(anomalies):
        kind_type = scored_type(anomaly.kind)
        if not counts_towards_recall(anomaly):
            continue
        if targeted and anomaly.kind not in _SURVEYED and k not in seen:
            continue  # a targeted run is scored on what its views see; the whole plan must see everything
        entry = per_type[kind_type]
        entry["truth"] += 1
        if k in matched:
            entry["found"] += 1
            entry["errors"].append(matched[k])
        else:
            misses.append(Miss(k, anomaly.kind, _why_missed(result, k, anomaly, used_findings)))
    for i, finding in enumerate(result.findings):
        if i not in used_findings:
            per_type[scored_type(finding.kind)]["false"] += 1
    return per_type, misses


_SURVEYED = ("hot_spot", "cold_spot", "gas_leak")  # read by the pyrometer and gas passes, whatever the views


def _why_missed(result: MissionResult, index: int, anomaly: Anomaly, used_findings: dict[int, int]) -> str:
    if anomaly.kind in _SURVEYED:
        return "sensor reading below its threshold or mislocated"
    seen_in = [visit.point for visit in result.visits if index in visit.visible]
    if not seen_in:
        return "not visible in any planned frame"
    wrong = [
        finding
        for i, finding in enumerate(result.findings)
        if i not in used_findings and finding.kind != anomaly.kind and _on_defect(finding, anomaly)
    ]
    if wrong:
        return f"seen in {', '.join(seen_in)} but reported as {wrong[0].kind}"
    return f"visible in {', '.join(seen_in)} but below the detection threshold"


def _on_defect(finding: MissionFinding, anomaly: Anomaly) -> bool:
    """Whether `finding` lies on what changed: within 2 cm of the anomaly, or of a swap's dent or
    discoloured patch and its radius (a patch on the 52 cm panel is far from the panel's site, where an
    impact found is no reading of the patch)."""
    from rsi.sim.anomalies import SwappedComponent

    centre, radius = anomaly.position_m, 0.02
    if isinstance(anomaly, SwappedComponent) and anomaly.defect_centre_m is not None:
        centre, radius = anomaly.defect_centre_m, 0.02 + anomaly.defect_radius_m
    return bool(np.linalg.norm(np.subtract(finding.position_m, centre)) <= radius)


def _check_visits(visits: object) -> None:
    if not isinstance(visits, (tuple, list)) or not all(isinstance(item, VisitRecord) for item in visits):
        raise InputError(
            f"visits must be a tuple of VisitRecord (a MissionResult's visits); got {type(visits).__name__}."
        )


def run_roc(visits: tuple[VisitRecord, ...], settings: MissionSettings) -> tuple[RocCurve, ...]:
    """The run's empirical ROC over every inspection visit, and the theory for the impacts it saw.

    Seed §2.4: P_D against P_F. The visits' score maps are stacked (a guard band keeps flaws of one from
    the next); the theory averages the model's P_D over the counted impacts' measured strengths (the
    difference at each impact's most changed pixel over the local noise sigma), both signs tested.
    """
    from rsi.detection.roc import RocCurve, empirical_roc, theoretical_roc
    from rsi.mission.visual import IMPACT_POLARITY

    _check_visits(visits)
    instance_of(settings, "settings", MissionSettings, none_allowed=False)
    images = [v.images for v in visits if v.images is not None and v.images.impact_truth.any()]
    if not images:
        return ()
    band = np.zeros((8, images[0].score.shape[1]), dtype=np.float32)
    score = np.vstack([part for im in images for part in (im.score, band)])
    truth = np.vstack([part for im in images for part in (im.impact_truth, band.astype(bool))])
    valid = np.vstack([part for im in images for part in (im.valid, band.astype(bool))])
    try:
        measured = empirical_roc(score, truth, valid=valid, label="this run (impacts >= 1 mm)")
    except InputError:  # every impact's centre fell where no comparison was made: nothing to measure
        return ()
    p_false_alarm = np.logspace(-7, 0, 100)
    strengths = [strength for im in images for strength in im.impact_strengths]
    curves = [
        theoretical_roc(
            settings.flaw_model,
            strength_sigma=strength,
            p_false_alarm=p_false_alarm,
            size=settings.flaw_size_px,
            polarity=IMPACT_POLARITY,
        )
        for strength in strengths
    ]
    mean_detection = np.mean([curve.p_detection for curve in curves], axis=0)
    label = "theory (measured impact strengths)"
    theory = RocCurve(p_false_alarm, mean_detection, curves[0].threshold, label)
    return (measured, theory)
