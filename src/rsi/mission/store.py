"""The mission's archive writes: the plan's vistas and references once, then the run and its findings."""

from __future__ import annotations

import math
from dataclasses import asdict, replace
from typing import TYPE_CHECKING

import numpy as np

from rsi.mission.plan_point import PlanPoint
from rsi.mission.records import MissionFinding
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from collections.abc import Mapping

    from rsi.archive import Archive
    from rsi.imaging.compensation import Compensated
    from rsi.sim.world import World


def filed_under(world: World, plan: tuple[PlanPoint, ...], finding: MissionFinding) -> str:
    """The plan point a finding is filed under: a visual one under its source, a non-visual one under the
    point whose vista's target is nearest to where its instrument read it (seed §3-4: the pyrometer's
    Kapton circle, the gas sensor's tubing), on any layout and any plan."""
    names = {point.name for point in plan}
    if finding.source in names or not plan:
        return finding.source
    return min(plan, key=lambda point: math.dist(world.vista(point.vista).target_m, finding.position_m)).name


def store_references(
    archive: Archive,
    *,
    world: World,
    plan: tuple[PlanPoint, ...],
    references: Mapping[str, Compensated],
    seed: int,
    run_settings: Mapping[str, object],
    settings: MissionSettings,
) -> int:
    """Every plan point's vista and reference image (seed §2.3: references taken once, revisited later),
    then a new run with the mission's settings; returns the run's id."""
    for point in plan:
        archive.add_vista(replace(world.vista(point.vista), name=point.name), replace=True)
        archive.store_reference(point.name, np.ascontiguousarray(references[point.name].image))
    stored = {**run_settings, **asdict(settings)}
    return archive.start_run(label="mission inspection pass", seed=seed, settings=stored)


def store_findings(
    archive: Archive,
    run_id: int,
    findings: tuple[MissionFinding, ...],
    *,
    world: World,
    plan: tuple[PlanPoint, ...],
) -> None:
    """The run's findings (each filed under the plan point it was seen from, :func:`filed_under`), then
    the run marked finished."""
    from rsi.archive import Finding

    archive.add_findings(
        run_id,
        [
            Finding(
                vista=filed_under(world, plan, f),
                kind=f.kind,
                confidence=f.confidence,
                position_m=f.position_m,
                bbox=f.bbox,
                area_px=None if f.flaw is None else f.flaw.area_px,
                size_m=f.size_m,
                score=f.score,
                extras={
                    "source": f.source,
                    "second_look": f.second_look,
                    "ambient_score": f.ambient_score,
                    "other_strobe_score": f.other_strobe_score,
                },
            )
            for f in findings
        ],
    )
    archive.finish_run(run_id)


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
