"""The mission's result records, and the one rule of what counts towards recall.

A visual finding carries the :class:`rsi.detection.Flaw` it was made from; thermal and gas findings carry
their reading as `score`. :func:`counts_towards_recall` is the only place that says which anomalies count.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.plan_point import PlanPoint
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.detection.detect import Flaw
    from rsi.detection.roc import RocCurve
    from rsi.mission.coverage import Coverage
    from rsi.mission.sun import SunSetting
    from rsi.mission.transit import Transit
    from rsi.sim.anomalies import Anomaly, AnomalySet
    from rsi.sim.render import CameraPose

FloatArray = NDArray[np.float64]

SCORED_TYPES: tuple[str, ...] = ("impact", "missing_screw", "swapped_component", "thermal_spot", "gas_leak")
IMPACT_MIN_SIZE_M = (
    1e-3  # seed §2: flaws of ~1 mm are what the inspection must find; smaller ones do not count
)


def scored_type(kind: str) -> str:
    """The scored type of an anomaly or finding kind: hot and cold spots are one type, ``thermal_spot``."""
    if not isinstance(kind, str):
        raise InputError(f"kind must be an anomaly or finding kind (a str such as 'impact'); got {kind!r}.")
    return "thermal_spot" if kind in ("hot_spot", "cold_spot") else kind


def counts_towards_recall(anomaly: Anomaly) -> bool:
    """Whether `anomaly` counts towards recall: every anomaly but an impact under IMPACT_MIN_SIZE_M."""
    from rsi.sim.anomalies import Anomaly

    v.instance_of(anomaly, "anomaly", Anomaly, none_allowed=False)
    return anomaly.kind != "impact" or anomaly.size_m >= IMPACT_MIN_SIZE_M


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
    flaw : Flaw or None
        The detection a visual blob finding was made from (its box, area and first-look score), in the
        inspection's field frame; None for screws, components found by their disc, and sensor findings.
    ambient_score : float or None
        A visual blob read again in the ambient-lit images of both passes (the sun's light, same viewpoint,
        :mod:`rsi.mission.echoes`), signed noise sigmas; None where the sun does not light the place in
        both passes, and for every finding that is no impact-sized visual blob.
    other_strobe_score : float or None
        The same blob read again under the ISEE's other strobe, below the lens, in both passes
        (:mod:`rsi.mission.echoes`), signed noise sigmas; None where not read.
    """

    kind: str
    position_m: tuple[float, float, float]
    size_m: float
    confidence: float
    source: str
    score: float
    second_look: bool = False
    flaw: Flaw | None = None
    ambient_score: float | None = None
    other_strobe_score: float | None = None

    @property
    def bbox(self) -> tuple[int, int, int, int] | None:
        """Field-image box ``(row0, col0, row1, col1)`` of a visual blob finding (its flaw's), else None."""
        return None if self.flaw is None else self.flaw.bbox


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
        The LRT score of either sign (noise sigmas).
    valid : ndarray of shape (M, N), bool
        Pixels the test covered.
    impact_truth : ndarray of shape (M, N), bool
        Field pixels of the visible impacts that count towards recall (ground truth, for the run's ROC).
    impact_strengths : tuple of float
        Each of those impacts' strength: the difference at its most changed pixel in noise sigmas.
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
    visible: tuple[int, ...] = ()
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
        The run's empirical ROC (every inspection visit's score against the visible impacts that
        count) and the theoretical one for those impacts' measured strengths; empty when no counted impact
        was visible.
    overview_rgb : ndarray of shape (H, W, 3), uint8, or None
        The whole mock-up after the anomalies appeared, unmarked.
    overview_pose : CameraPose or None
        The overview picture's camera: projects findings and truth into it.
    transits : tuple of Transit
        Every move of the ISEE by the arm, in order, with its 44 Hz proximity trace (empty without the arm;
        out-of-reach vistas appear with an empty trace and their shortfall). See :mod:`rsi.mission.transit`.
    suns : tuple of SunSetting
        The solar simulator at each visit: mission-clock time, sun and lamp directions, lamp configuration
        (empty without the orbit).
    settings : MissionSettings
        The settings the mission ran with.
    plan_coverage : Coverage or None
        What the plan covers of the mock-up's inspectable surface at 0.5 mm per pixel and 45 deg, measured
        from the CAD (:func:`rsi.mission.coverage.coverage`; issue 15).
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
    settings: MissionSettings = field(default_factory=MissionSettings)
    plan_coverage: Coverage | None = field(default=None, repr=False, compare=False)

    @property
    def counts(self) -> tuple[bool, ...]:
        """Whether each ground-truth anomaly counts towards recall (:func:`counts_towards_recall`)."""
        return tuple(counts_towards_recall(anomaly) for anomaly in self.truth.anomalies)
