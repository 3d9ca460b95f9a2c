"""The mission's archive writes: the plan's vistas and references once, then the run and its findings."""

from __future__ import annotations

import math
from dataclasses import asdict, replace
from typing import TYPE_CHECKING

import numpy as np

from rsi.mission.records import MissionFinding, PlanPoint
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from collections.abc import Mapping

    from rsi.archive import Archive
    from rsi.imaging.compensation import Compensated
    from rsi.sim.world import World


def _filed_under(world: World, finding: MissionFinding) -> str:
    """The vista a finding is filed under: a non-visual one under the vista its instrument read (seed §3-4;
    of a layout's two tubings, the one nearest the finding), a visual one under its source."""
    vistas = world.mockup.instrument_vistas.get(finding.source, ())
    if not vistas:
        return finding.source
    return min(vistas, key=lambda name: math.dist(world.vista(name).target_m, finding.position_m))


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
    archive: Archive, run_id: int, findings: tuple[MissionFinding, ...], *, world: World
) -> None:
    """The run's findings (each filed under the vista of `world` it was seen from), then the run marked
    finished."""
    from rsi.archive import Finding

    archive.add_findings(
        run_id,
        [
            Finding(
                vista=_filed_under(world, f),
                kind=f.kind,
                confidence=f.confidence,
                position_m=f.position_m,
                bbox=f.bbox,
                area_px=None if f.flaw is None else f.flaw.area_px,
                size_m=f.size_m,
                score=f.score,
                extras={"source": f.source, "second_look": f.second_look},
            )
            for f in findings
        ],
    )
    archive.finish_run(run_id)
