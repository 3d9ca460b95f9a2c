"""Application layer: the inspection mission and its parts, one pair's inspection, the batch.

- :func:`run_mission` (:mod:`rsi.mission.run`) - the passes over the mock-up as a list of steps;
  :class:`MissionSettings` (:mod:`~rsi.mission.settings`) every tuned number with its reason;
- :mod:`~rsi.mission.plan` the vista points, :mod:`~rsi.mission.exposure` metering,
  :mod:`~rsi.mission.visual` one visit, :mod:`~rsi.mission.evidence` what a comparison shows,
  :mod:`~rsi.mission.views` a view's geometry, :mod:`~rsi.mission.surveys` pyrometer and gas,
  :mod:`~rsi.mission.store` the archive writes;
- :func:`score_mission` (:mod:`~rsi.mission.score`) against ground truth; the records in
  :mod:`~rsi.mission.records`; many scored missions tallied with Wilson intervals
  (:class:`Tally`, :func:`tally_run`, :mod:`~rsi.mission.tally`);
- :func:`inspect_pair` (from :mod:`rsi.detection.pair`) one reference/inspection pair;
  :mod:`~rsi.mission.batch` many pairs on dask.

Importing this package loads no simulator, renderer or image library; they load when a function runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi._lazy import lazy_getattr
from rsi.mission.plan_point import PlanPoint
from rsi.mission.records import (
    IMPACT_MIN_SIZE_M,
    SCORED_TYPES,
    MissionFinding,
    MissionResult,
    VisitImages,
    VisitRecord,
    counts_towards_recall,
    scored_type,
)
from rsi.mission.settings import MISSION_SIZE, MissionSettings
from rsi.mission.tally import (
    AnomalyFree,
    Outcome,
    Rate,
    Recall,
    RunTally,
    Stratum,
    Tally,
    poisson_rate_interval,
    tally_run,
    wilson_interval,
)

if TYPE_CHECKING:
    from rsi.detection.pair import PairResult, Score, inspect_pair, score_flaws
    from rsi.mission.plan import PLAN, plan_vistas
    from rsi.mission.run import ORBIT_START_S, SUN_OFFSET_S, run_mission
    from rsi.mission.score import Miss, MissionScore, TypeScore, score_mission

# the names that load the simulator or the image libraries, resolved on first use (PEP 562)
_LAZY = {
    "PairResult": "rsi.detection.pair",
    "Score": "rsi.detection.pair",
    "inspect_pair": "rsi.detection.pair",
    "score_flaws": "rsi.detection.pair",
    "PLAN": "rsi.mission.plan",
    "plan_vistas": "rsi.mission.plan",
    "ORBIT_START_S": "rsi.mission.run",
    "SUN_OFFSET_S": "rsi.mission.run",
    "run_mission": "rsi.mission.run",
    "Miss": "rsi.mission.score",
    "MissionScore": "rsi.mission.score",
    "TypeScore": "rsi.mission.score",
    "score_mission": "rsi.mission.score",
}


__getattr__ = lazy_getattr(__name__, _LAZY)


__all__ = [
    "IMPACT_MIN_SIZE_M",
    "MISSION_SIZE",
    "ORBIT_START_S",
    "PLAN",
    "SCORED_TYPES",
    "SUN_OFFSET_S",
    "AnomalyFree",
    "Miss",
    "MissionFinding",
    "MissionResult",
    "MissionScore",
    "MissionSettings",
    "Outcome",
    "PairResult",
    "PlanPoint",
    "Rate",
    "Recall",
    "RunTally",
    "Score",
    "Stratum",
    "Tally",
    "TypeScore",
    "VisitImages",
    "VisitRecord",
    "counts_towards_recall",
    "inspect_pair",
    "plan_vistas",
    "poisson_rate_interval",
    "run_mission",
    "score_flaws",
    "score_mission",
    "scored_type",
    "tally_run",
    "wilson_interval",
]
