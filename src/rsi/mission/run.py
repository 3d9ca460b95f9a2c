"""Seed §2-§4 together: one inspection mission over the truss mock-up, as a list of steps.

A mission plans vista points that cover every component (the inside of the electrical ORU with its door
open included), takes a *reference pass* on the pristine mock-up, then an *inspection pass* after the seeded
anomalies appeared, and fuses what it sees and senses into findings:

- **visual** (seed §2, :mod:`rsi.mission.visual`): each visit's strobe image is compensated (seed §2.2),
  registered to its references and tested by the calibrated likelihood-ratio test (seed §2.3-2.4);
- **temperature** and **gas** (seed §3-4, :mod:`rsi.mission.surveys`): the pyrometer over the Kapton
  circles, the MOS sensor along the tubing;
- **active inspection** (seed §2.5): a doubtful detection gets a second look.

:func:`rsi.mission.score_mission` matches the findings to the world's ground truth. See docs/mission.md.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from rsi import _validate as v
from rsi.errors import InputError
from rsi.imaging.compensation import compensate_field_pair
from rsi.mission.coverage import coverage
from rsi.mission.evidence import Explanation
from rsi.mission.exposure import ambient_bracket, metered, settle
from rsi.mission.fusion import fuse_findings
from rsi.mission.plan import plan_vistas
from rsi.mission.plan_point import PlanPoint
from rsi.mission.records import MissionFinding, MissionResult, VisitRecord
from rsi.mission.score import run_roc
from rsi.mission.screws import head_glint, screw_relief_m
from rsi.mission.settings import MISSION_SIZE, OVERVIEW_SIZE, REPEATABILITY, MissionSettings
from rsi.mission.surveys import gas_pass, pyrometer_pass
from rsi.mission.truth import with_truth
from rsi.mission.viewing import pose_error_m
from rsi.mission.views import seen_screws, sense
from rsi.mission.visual import StoredView, Visit, inspect_visit, stored_strobe
from rsi.sim.anomalies import AnomalySettings
from rsi.sim.mockup import LAYOUT_NAMES as LAYOUTS
from rsi.sim.orbit import orbital_period_s

if TYPE_CHECKING:
    from rsi.archive import Archive
    from rsi.mission.tour import Tour
    from rsi.sim.world import World

ProgressFn = Callable[[str, int, int], None]
VisitFn = Callable[[str, tuple[MissionFinding, ...]], None]

# The reference pass begins 26 deg past orbit noon, the inspection pass one orbit later at the same phase:
# a sun 20 deg apart between the passes raised false impacts 4 -> 15 on seed 0 (docs/mission.md).
ORBIT_START_S = (400.0, 400.0 + orbital_period_s())
# `rsi demo` takes its inspection pass this much later than ORBIT_START_S[1], under another sun: a real
# station is never inspected under the same sun twice (seed §2: lighting variation, the first challenge;
# issue 14). The sun turns 360 deg per orbital_period_s() (5553.6 s at the default 400 km), so 300 s is
# 360 * 300 / 5553.6 = 19.4 deg. run_mission's own default stays ORBIT_START_S.
SUN_OFFSET_S = 300.0


def run_mission(
    seed: int,
    *,
    settings: MissionSettings | None = None,
    archive: Archive | None = None,
    repeatability: str = "lab",
    active: bool = True,
    progress: ProgressFn | None = None,
    on_visit: VisitFn | None = None,
    size: tuple[int, int] = MISSION_SIZE,
    arm: bool = True,
    orbit: bool = True,
    orbit_start_s: tuple[float, float] = ORBIT_START_S,
    anomalies: AnomalySettings | None = None,
    layout: str = "truss",
) -> MissionResult:
    """Reference pass, inspection pass and sensor passes over the seeded mock-up (seed §2-§4).

    Parameters
    ----------
    seed : int
        Seed of the world (anomalies, viewpoint errors, camera and sensor noise), >= 0. The same seed gives
        the same findings.
    settings : MissionSettings, optional
        Detection, evidence, metering and survey settings; ``MissionSettings()`` by default.
    archive : Archive, optional
        Receives the plan's vista points, the reference images (compensated, float32) and one finished
        inspection run with its findings.
    repeatability : {"lab", "space"}
        Viewpoint repeatability of each visit (seed §2.3).
    active : bool
        Active inspection (seed §2.5): detections between the preliminary and confirming thresholds get a
        second look and are confirmed or rejected on the fused evidence. False: one look, one threshold.
    progress : callable, optional
        ``progress(stage, done, total)`` after each visit and sensor pass; `total` grows by the points
        visited again after the inspection pass (a swap found later that their view showed).
    on_visit : callable, optional
        ``on_visit(vista, findings)`` after each inspection visit, with what that visit found: provisional,
        before the findings of all the vistas are fused (a flaw two vistas saw is one finding in the result)
        and before the pyrometer and gas passes; a point visited again is heard again, its new findings
        replacing the first visit's. For a live view of a running mission (the console).
    size : (int, int)
        Frame (rows, cols), each >= 64.
    arm : bool
        Move the ISEE with the arm and rail to each reachable vista (retract, transfer, approach under the
        proximity law; seed §3.1) and take the frame from where the arm holds the camera; vistas out of
        reach (the solar panel's, from above) keep the free camera. False: the free camera teleported to
        each vista.
    orbit : bool
        Light each visit by the orbit's sun at its mission-clock time (seed §4.1); False keeps the lamp
        where the world put it.
    orbit_start_s : (float, float)
        Orbit time (s after orbit noon) at which the reference and the inspection pass begin, each >= 0;
        by default 400 s and one orbit (5553.6 s) later, so both passes see about the same sun.
    anomalies : AnomalySettings, optional
        How the world's anomalies are drawn (counts and parameter ranges, :class:`rsi.sim.AnomalySettings`);
        the simulator's default draw when None.
    layout : {"truss", "truss-b"}
        The mock-up (:data:`rsi.sim.LAYOUTS`); the plan comes from its CAD model unless ``settings.plan``
        asks for the truss's hand plan.

    Returns
    -------
    MissionResult

    Raises
    ------
    InputError
        Naming the argument: a negative or non-integer seed, settings that are not MissionSettings, an
        unknown repeatability, a non-bool `active`, `arm` or `orbit`, a non-callable `progress` or
        `on_visit`, a bad
        `size`, something that is not an Archive, `orbit_start_s` not two times >= 0 s, or `anomalies` not an
        AnomalySettings.
    """
    from rsi.mission.sun import pass_starts
    from rsi.mission.tour import Tour
    from rsi.sim.world import load

    settings = _checked(seed, settings, archive, repeatability, progress, active=active, arm=arm, orbit=orbit)
    _check_callback(on_visit, "on_visit", "on_visit(vista, findings)")
    v.choice(layout, "layout", LAYOUTS)
    if anomalies is not None and not isinstance(anomalies, AnomalySettings):
        raise InputError(
            f"anomalies must be None or an rsi.sim.AnomalySettings; got {type(anomalies).__name__}."
        )
    seed = int(seed)
    shape, starts = _size(size), pass_starts(orbit_start_s)
    clock = _Clock()
    streams = _Streams.spawned(seed)
    world = load(layout, seed=streams.world, repeatability=repeatability, arm=arm, settings=anomalies)
    plan = plan_vistas(world, settings)
    plan_coverage = coverage(plan, world)  # issue 15: what the plan sees of the CAD, for the report
    tour = Tour(world, seed=streams.tour, size=shape, arm=arm, orbit=orbit)
    report = _Progress(progress, total=2 * len(plan) + 2)
    sensor_rng = np.random.default_rng(streams.sensors)
    try:
        with _blas_on_one_thread():
            tour.start_pass("reference", starts[0])
            stored = _reference_pass(world, plan, tour, report, settings=settings)
            clock.lap("reference")
            tour.start_pass("inspection", starts[1])
            visual, visits = _inspection_pass(
                world, plan, stored, tour, report, active=active, settings=settings, on_visit=on_visit
            )
            clock.lap("inspection")
            thermal, readings = pyrometer_pass(world, sensor_rng, settings)
            report("pyrometer")
            gas, stations, gas_ppm = gas_pass(world, sensor_rng, settings)
            report("gas")
            pose_errors = {point.name: pose_error_m(world, point.vista, shape[0]) for point in plan}
            sites = world.mockup.candidates.component_sites
            findings = (*fuse_findings(visual, sites, settings, pose_errors), *thermal, *gas)
            overview_rgb, overview_pose = world.overview(size=OVERVIEW_SIZE)
            run_settings = {"repeatability": repeatability, "active": active}
            run_id = _archived(archive, world, plan, stored, findings, seed, run_settings, settings)
            clock.lap("sensors")
    finally:
        world.close()
    return MissionResult(
        seed=seed,
        repeatability=repeatability,
        active=active,
        size=shape,
        plan=plan,
        findings=findings,
        visits=visits,
        truth=world.anomalies,
        pyrometer_k=readings,
        gas_ppm=gas_ppm,
        gas_stations_m=stations,
        run_id=run_id,
        timings_s=clock.timings(transits_s=sum(transit.wall_s for transit in tour.transits)),
        roc=run_roc(visits, settings),
        overview_rgb=overview_rgb,
        overview_pose=overview_pose,
        transits=tuple(tour.transits),
        suns=tuple(tour.suns),
        settings=settings,
        plan_coverage=plan_coverage,
    )


def _reference_pass(
    world: World,
    plan: tuple[PlanPoint, ...],
    tour: Tour,
    report: _Progress,
    *,
    settings: MissionSettings,
) -> dict[str, StoredView]:
    """Two pristine visits per plan point: the reference and a second reference (the nuisance map and the
    second opinion of every detection), the relief of every site the reference sees in the stereo range
    map, and the metered shutter and strobe energy."""
    from rsi.detection.nuisance import nuisance_scale

    stored: dict[str, StoredView] = {}
    for point in plan:
        settle(world, door_angle_rad=point.door_angle_rad)
        tour.set_jaws(point.jaw_opening_m)
        pre_flash = sense(tour.visit(point.name, point.vista, state="reference", truth=False))
        view, shutter, energy = metered(tour, pre_flash, settings)
        # kept for this point's later visits, inspection pass included
        world.set_shutter(shutter)
        world.set_strobe_energy(energy)
        reference = stored_strobe(view, settings)
        ambient = ambient_bracket(tour, view, settings, shutter=shutter)
        other_strobe = stored_strobe(view, settings, compensate_field_pair(*tour.other_strobe_frames()))
        depth = view.range_m
        screws = seen_screws(world, view)
        reliefs = {site.name: screw_relief_m(depth, view, site) for site in screws}
        glints = {site.name: head_glint(view, site) for site in screws}
        again = sense(tour.visit(point.name, point.vista, state="reference", truth=False))
        second = stored_strobe(again, settings)
        scale = nuisance_scale(
            reference,
            second,
            flaw_model=settings.flaw_model,
            size=settings.flaw_size_px,
            misregistration_std_px=settings.misregistration_std_px,
            window_px=settings.nuisance_window_px,
            spread_px=settings.nuisance_spread_px,
        )
        stored[point.name] = StoredView(
            reference,
            second,
            scale,
            depth,
            reliefs,
            energy,
            shutter,
            second_range_m=again.range_m,
            glints=glints,
            ambient=ambient,
            other_strobe=other_strobe,
            surface_m=view.surface_m,
            second_surface_m=again.surface_m,
        )
        report(f"reference {point.name}")
    return stored


def _inspection_pass(
    world: World,
    plan: tuple[PlanPoint, ...],
    stored: dict[str, StoredView],
    tour: Tour,
    report: _Progress,
    *,
    active: bool,
    settings: MissionSettings,
    on_visit: VisitFn | None,
) -> tuple[list[MissionFinding], tuple[VisitRecord, ...]]:
    """Every plan point visited again after the anomalies appeared, with the reference pass's exposure;
    then the points whose view showed a swap that only a later visit found, visited once more.

    A swap is the component's (:func:`rsi.mission.visual.inspect_visit`, `known`): what one visit found,
    every later one knows, and an earlier one that showed the component without finding it had it in its
    photometric fit. As seed §2.5's active inspection goes back where a reading is in doubt, such a point is
    visited again knowing the swap (in a passive mission too: the reading was wrong, not doubtful), and that
    visit's findings take the place of the first one's (its screws, each judged once, stay).
    """
    visits: dict[str, tuple[Visit, VisitRecord]] = {}
    checked: frozenset[str] = frozenset()
    known: tuple[Explanation, ...] = ()
    for point in plan:
        visit, record = _visited(
            world, point, stored, tour, active=active, settings=settings, checked=checked, known=known
        )
        visits[point.name] = (visit, record)
        checked, known = visit.screws_checked, visit.explanations
        _announced(point, visit, on_visit, report)
    again = [point for point in plan if visits[point.name][0].unaware_of(known)]
    report.extend(len(again))
    # each screw was judged by the visits that saw it first (its second look included), and stays judged
    every_screw = frozenset(site.name for site in world.mockup.candidates.screw_sites)
    for point in again:
        visit, record = _visited(
            world, point, stored, tour, active=active, settings=settings, checked=every_screw, known=known
        )
        screws = tuple(f for f in visits[point.name][0].findings if f.kind == "missing_screw")
        visit = replace(visit, findings=screws + visit.findings)
        visits[point.name] = (visit, record)
        _announced(point, visit, on_visit, report, again=True)
    settle(world, door_angle_rad=0.0)
    findings = [finding for visit, _ in visits.values() for finding in visit.findings]
    return findings, tuple(record for _, record in visits.values())


def _visited(
    world: World,
    point: PlanPoint,
    stored: dict[str, StoredView],
    tour: Tour,
    *,
    active: bool,
    settings: MissionSettings,
    checked: frozenset[str],
    known: tuple[Explanation, ...],
) -> tuple[Visit, VisitRecord]:
    """One inspection visit of `point` with the reference pass's exposure, and its record with the truth of
    what its view showed (the simulator's, for scoring only)."""
    world.set_door(point.door_angle_rad)
    tour.set_jaws(point.jaw_opening_m)
    world.set_strobe_energy(stored[point.name].strobe_energy)
    world.set_shutter(stored[point.name].shutter)
    first = len(tour.views)
    visit = inspect_visit(
        world,
        point,
        stored[point.name],
        screws_checked=checked,
        active=active,
        settings=settings,
        tour=tour,
        known=known,
    )
    return visit, with_truth(visit.record, visit.pair, tour.views[first][1], world.anomalies)


def _announced(
    point: PlanPoint, visit: Visit, on_visit: VisitFn | None, report: _Progress, *, again: bool = False
) -> None:
    if on_visit is not None:
        on_visit(point.name, tuple(visit.findings))
    report(f"inspection {point.name}{' again' if again else ''}")


def _archived(  # noqa: PLR0917 - the run's parts, each needed once
    archive: Archive | None,
    world: World,
    plan: tuple[PlanPoint, ...],
    stored: dict[str, StoredView],
    findings: tuple[MissionFinding, ...],
    seed: int,
    run_settings: dict[str, object],
    settings: MissionSettings,
) -> int | None:
    """The references, the run and its findings in `archive` (None: nothing stored, no run id)."""
    from rsi.mission.store import store_findings, store_references

    if archive is None:
        return None
    run_id = store_references(
        archive,
        world=world,
        plan=plan,
        references={name: view.reference for name, view in stored.items()},
        seed=seed,
        run_settings=run_settings,
        settings=settings,
    )
    store_findings(archive, run_id, findings, world=world, plan=plan)
    return run_id


@contextmanager
def _blas_on_one_thread() -> Iterator[None]:
    """BLAS and OpenMP on one thread for a mission run on the main thread, as they were before it
    afterwards. The simulated cameras' renderer (Mesa's llvmpipe without a GPU) spreads every frame over all
    cores, and the mission's matrix products are small (a frame's pixels by a few columns), where
    OpenBLAS's threads only wait for one another and for the renderer: `rsi demo --layout truss-b` took
    187 s with them on a 2-core machine and 162 s with OMP_NUM_THREADS=1 (issue 15). OpenCV keeps its pool:
    its stereo matcher runs 20 ms a frame on two threads against 27-36 on one, while the renderer waits.

    OpenBLAS's thread count is the process's, and changing it while another thread is inside a BLAS call
    is not safe (threadpoolctl issue #205): a mission on any other thread (the console's, a batch worker's)
    leaves it as it is, for whatever else runs beside it."""
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1):
        yield


@dataclass(frozen=True)
class _Streams:
    """The mission's random streams, spawned once from its seed and handed down: the world (anomalies,
    viewpoint errors, camera and encoder noise), the tour (the arm's misses, the rangefinders' noise) and
    the pyrometer and gas sensors' noise. Stereo has no stream of its own: its errors are the matcher's."""

    world: np.random.SeedSequence
    tour: np.random.SeedSequence
    sensors: np.random.SeedSequence

    @classmethod
    def spawned(cls, seed: int) -> _Streams:
        return cls(*np.random.SeedSequence(seed).spawn(3))


class _Clock:
    """Wall time of the mission's stages: each lap from the previous one, and the total."""

    def __init__(self) -> None:
        self._start_s = self._last_s = time.perf_counter()
        self._laps: dict[str, float] = {}

    def lap(self, stage: str) -> None:
        now = time.perf_counter()
        self._laps[stage], self._last_s = now - self._last_s, now

    def timings(self, *, transits_s: float) -> dict[str, float]:
        return {**self._laps, "total": time.perf_counter() - self._start_s, "transits": transits_s}


class _Progress:
    """Counts the mission's stages for ``progress(stage, done, total)``; the total grows by the points
    visited again (:func:`_inspection_pass`)."""

    def __init__(self, progress: ProgressFn | None, *, total: int) -> None:
        self._progress, self._done, self._total = progress, 0, total

    def __call__(self, stage: str) -> None:
        self._done += 1
        if self._progress is not None:
            self._progress(stage, self._done, self._total)

    def extend(self, stages: int) -> None:
        self._total += stages


def _check_callback(callback: object, name: str, call: str) -> None:
    if callback is not None and not callable(callback):
        raise InputError(f"{name} must be None or a callable {call}; got {callback!r}.")


def _checked(
    seed: object,
    settings: object,
    archive: object,
    repeatability: object,
    progress: object,
    **flags: object,
) -> MissionSettings:
    """The settings to run with, once every argument of run_mission has been checked by name."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**63:
        raise InputError(f"seed must be an integer in [0, 2**63) (the archive's integer); got {seed!r}.")
    if settings is not None and not isinstance(settings, MissionSettings):
        raise InputError(
            f"settings must be None or an rsi.mission.MissionSettings; got {type(settings).__name__}."
        )
    v.choice(repeatability, "repeatability", REPEATABILITY)
    for name, flag in flags.items():
        if not isinstance(flag, bool):
            raise InputError(f"{name} must be True or False; got {flag!r}.")
    _check_callback(progress, "progress", "progress(stage, done, total)")
    if archive is not None:
        from rsi.archive import Archive

        if not isinstance(archive, Archive):
            raise InputError(
                f"archive must be None or an rsi.archive.Archive; got {type(archive).__name__}. "
                "Open one with rsi.archive.Archive.open(path)."
            )
        if archive.read_only:
            raise InputError(
                "archive was opened read-only and the mission stores its references and run there; "
                "open it writable (rsi.archive.Archive.open(path))."
            )
    return MissionSettings() if settings is None else settings


def _size(size: object) -> tuple[int, int]:
    if not isinstance(size, tuple) or len(size) != 2:
        raise InputError(f"size must be a (rows, cols) tuple; got {size!r}. Try size=(480, 640).")
    rows, cols = (v.positive_int(side, "size", minimum=64) for side in size)
    return (rows, cols)
