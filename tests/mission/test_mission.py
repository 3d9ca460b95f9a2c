"""The mission over the mock-up: determinism, each anomaly found or its miss explained, archive, bad input."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.archive import Archive
from rsi.errors import InputError
from rsi.mission import (
    ORBIT_START_S,
    PLAN,
    SCORED_TYPES,
    MissionFinding,
    MissionResult,
    MissionScore,
    MissionSettings,
    run_mission,
    score_mission,
)
from rsi.sim.anomalies import AnomalySettings
from rsi.sim.mockup import truss_mockup
from rsi.sim.world import load

SEED = 0
SMALL = (240, 320)
STILL = {"arm": False, "orbit": False}  # free camera, fixed lamp: fast (the arm's mission: test_motion.py)
# The mechanics and the cases below lie in the hand plan's views: the points that complete it (the truss's
# default, flown by test_transit.py, test_cli.py's demo and the report's test) add minutes and nothing here
HAND_PLAN = MissionSettings(plan="hand")
# A case on one component flies only the views of it (a targeted re-inspection, MissionSettings.vistas)
PANEL_VIEWS = dataclasses.replace(HAND_PLAN, vistas=tuple(p.vista for p in PLAN if p.vista.startswith("C_")))


VISITS: list[tuple[str, tuple[MissionFinding, ...]]] = []  # on_visit's calls in the archived run


@pytest.fixture(scope="module")
def archived(tmp_path_factory: pytest.TempPathFactory) -> tuple[MissionResult, Path]:
    path = tmp_path_factory.mktemp("mission") / "archive.db"
    stages: list[tuple[str, int, int]] = []
    with Archive.open(path) as archive:
        result = run_mission(
            SEED,
            archive=archive,
            size=SMALL,
            progress=lambda *stage: stages.append(stage),
            on_visit=lambda vista, found: VISITS.append((vista, found)),
            settings=HAND_PLAN,
            **STILL,
        )
    assert [done for _, done, _ in stages] == list(range(1, 2 * len(PLAN) + 3))
    assert result.plan == PLAN
    return result, path


def test_each_visit_reports_what_it_found_before_the_fusion(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    assert [vista for vista, _ in VISITS] == [point.name for point in result.plan]
    provisional = {(vista, finding.kind) for vista, found in VISITS for finding in found}
    visual = [f for f in result.findings if f.source in {point.name for point in result.plan}]
    assert visual  # seed 0 has visual findings to trace back
    for finding in visual:  # every fused finding was first reported by the visit it came from
        assert (finding.source, finding.kind) in provisional


def test_same_seed_same_findings(archived: tuple[MissionResult, Path]) -> None:
    first, _ = archived
    again = run_mission(SEED, size=SMALL, settings=HAND_PLAN, **STILL)
    assert again.findings == first.findings
    assert np.array_equal(again.gas_ppm, first.gas_ppm)
    assert again.pyrometer_k == first.pyrometer_k


def test_every_anomaly_is_found_or_its_miss_explained(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    score = score_mission(result)
    assert isinstance(score, MissionScore)
    assert set(score.per_type) == set(SCORED_TYPES)
    missed = {miss.index for miss in score.misses}
    for kind, entry in score.per_type.items():
        assert entry.found + sum(1 for m in score.misses if _type(m.kind) == kind) == entry.truth
    for miss in score.misses:
        assert miss.reason
    # the sensors find the thermal spots and the leak (they do not depend on image size)
    assert score.per_type["thermal_spot"].recall == 1.0
    assert score.per_type["gas_leak"].recall == 1.0
    assert score.per_type["gas_leak"].localisation_error_m < 0.01
    for index, anomaly in enumerate(result.truth.anomalies):
        if anomaly.kind in ("hot_spot", "cold_spot", "gas_leak"):
            assert index not in missed


def _type(kind: str) -> str:
    return "thermal_spot" if kind in ("hot_spot", "cold_spot") else kind


def test_archive_gets_references_and_a_finished_run(archived: tuple[MissionResult, Path]) -> None:
    result, path = archived
    with Archive.open(path) as archive:
        for point in PLAN:
            reference = archive.reference(point.name)
            assert isinstance(reference, np.ndarray)
            assert reference.shape == SMALL  # full resolution: two frames, strobes in opposite fields
        assert result.run_id is not None
        run = archive.run(result.run_id)
        assert run.status == "finished"
        assert run.seed == SEED
        assert len(archive.findings(result.run_id)) == len(result.findings)


def test_plan_covers_every_component_and_screw() -> None:
    names = {point.name for point in PLAN}
    assert {"A_door", "A_door_open", "A_kapton", "B_tank", "D_tubing"} <= names
    assert any(point.door_angle_rad > 1.0 for point in PLAN)  # inside the electrical ORU
    world = load("truss", seed=SEED)
    try:
        from rsi.mission import plan_vistas
        from rsi.mission.views import visible

        screws = truss_mockup().candidates.screw_sites
        positions = np.asarray([site.position_m for site in screws])
        seen = np.zeros(len(screws), dtype=bool)
        for point in plan_vistas(world):
            world.set_door(point.door_angle_rad)
            seen |= visible(_sensed(world, point.vista, size=SMALL), positions)
        assert seen.all(), [site.name for site, ok in zip(screws, seen, strict=True) if not ok]
    finally:
        world.close()


def _sensed(world: Any, vista: str, **options: Any) -> Any:
    """The visit as the mission receives it: the ISEE's capture and its stereo range map."""
    from rsi.mission.views import sense
    from rsi.sim.capture import capture

    return sense(capture(world, world.render(vista, state="reference", stereo=True, **options)))


def test_close_panel_views_cover_the_cells_at_half_a_millimetre_per_pixel() -> None:
    from rsi.mission import MissionSettings, plan_vistas
    from rsi.mission.views import pixel_size_m, visible

    PANEL_STANDOFF_M = MissionSettings().panel_standoff_m

    world = load("truss", seed=SEED)
    try:
        panels = [point for point in plan_vistas(world, HAND_PLAN) if point.name.startswith("C_panel")]
        patch = next(p for p in truss_mockup().candidates.impact_patches if p.name == "C_cells")
        half_u, half_v = patch.half_extent_m
        grid = np.array(
            [
                (patch.centre_m[0] + u, patch.centre_m[1] + w, patch.centre_m[2])
                for u in np.linspace(-half_u, half_u, 9)
                for w in np.linspace(-half_v, half_v, 7)
            ]
        )
        seen = np.zeros(len(grid), dtype=bool)
        for point in panels:
            view = _sensed(world, point.vista)
            seen |= visible(view, grid)
            assert pixel_size_m(view, patch.centre_m) < 0.5e-3  # a 1 mm impact spans two pixels or more
        assert world.vista(panels[0].vista).standoff_m == PANEL_STANDOFF_M
    finally:
        world.close()
    assert seen.all()  # every part of the cells that may carry an impact is in some close view


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"seed": -1}, "seed"),
        ({"seed": 1.5}, "seed"),
        ({"seed": True}, "seed"),
        ({"seed": 2**63}, "seed"),
        ({"seed": 0, "repeatability": "moon"}, "repeatability"),
        ({"seed": 0, "active": "yes"}, "active"),
        ({"seed": 0, "progress": 3}, "progress"),
        ({"seed": 0, "on_visit": "print"}, "on_visit"),
        ({"seed": 0, "archive": "archive.db"}, "archive"),
        ({"seed": 0, "size": (10, 10)}, "size"),
        ({"seed": 0, "size": [240, 320]}, "size"),
        ({"seed": 0, "settings": {"p_false_alarm": 1e-6}}, "settings"),
        ({"seed": 0, "arm": 1}, "arm"),
        ({"seed": 0, "orbit": None}, "orbit"),
        ({"seed": 0, "anomalies": {"impact_count": 3}}, "anomalies"),
        ({"seed": 0, "layout": "truss-c"}, "layout"),
    ],
)
def test_bad_input_names_the_argument(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        run_mission(**kwargs)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"p_false_alarm": 0.7}, "p_false_alarm"),
        ({"p_false_alarm": -1e-9}, "p_false_alarm"),
        ({"p_preliminary": 1e-12}, "p_preliminary"),
        ({"flaw_model": "blob"}, "flaw_model"),
        ({"flaw_size_px": 3.0}, "flaw_size_px"),
        ({"gas_dwell_s": float("nan")}, "gas_dwell_s"),
        ({"depth_jump_m": 0.0}, "depth_jump_m"),
        ({"nuisance_window_px": True}, "nuisance_window_px"),
        ({"plan": "manual"}, "plan"),
        ({"vistas": "B_tank"}, "vistas"),
        ({"vistas": ("B_tank", "")}, "vistas"),
    ],
)
def test_settings_refuse_bad_values_by_name(changes: dict[str, object], message: str) -> None:
    from rsi.mission import MissionSettings

    with pytest.raises(InputError, match=message):
        MissionSettings(**changes)  # type: ignore[arg-type]


def test_a_targeted_plan_flies_only_the_vistas_asked_for_and_refuses_one_it_lacks() -> None:
    from rsi.mission import plan_vistas

    world = load("truss", seed=SEED)
    try:
        whole = plan_vistas(world, HAND_PLAN)
        chosen = ("B_tank", "A_kapton")
        targeted = plan_vistas(world, dataclasses.replace(HAND_PLAN, vistas=chosen))
        assert targeted == tuple(point for point in whole if point.vista in chosen)  # the plan's order
        refused = r"vistas \['nowhere'\] are not in the plan.*--vista.*its vistas: A_door"
        with pytest.raises(InputError, match=refused):
            plan_vistas(world, dataclasses.replace(HAND_PLAN, vistas=("B_tank", "nowhere")))
    finally:
        world.close()


def test_settings_reach_the_result_and_change_the_plan() -> None:
    from rsi.mission import MissionSettings, plan_vistas

    settings = MissionSettings(door_open_rad=1.0, panel_standoff_m=0.4, plan="hand")  # both hand-plan views
    world = load("truss", seed=SEED)
    try:
        plan = plan_vistas(world, settings)
        assert next(p for p in plan if p.name == "A_door_open").door_angle_rad == 1.0
        assert world.vista("C_panel_centre").standoff_m == 0.4
    finally:
        world.close()


def test_a_read_only_archive_is_refused_before_the_passes(archived: tuple[MissionResult, Path]) -> None:
    _, path = archived
    with Archive.open(path, read_only=True) as archive, pytest.raises(InputError, match="read-only"):
        run_mission(SEED, archive=archive)


def test_score_needs_a_mission_result() -> None:
    with pytest.raises(InputError, match="result"):
        score_mission("findings")  # type: ignore[arg-type]


def test_world_add_vista_refuses_duplicates_and_non_vistas() -> None:
    world = load("truss", seed=SEED)
    try:
        with pytest.raises(InputError, match="already exists"):
            world.add_vista(world.vista("A_door"))
        with pytest.raises(InputError, match="Vista"):
            world.add_vista("A_door")  # type: ignore[arg-type]
    finally:
        world.close()


def test_visit_images_are_the_comparison_in_the_field_frame(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    field = SMALL
    for visit in result.visits:
        images = visit.images
        assert images is not None
        for array in (images.reference, images.inspection, images.difference, images.score, images.valid):
            assert array.shape == field
        # the difference is the inspection minus the registered reference, by construction
        assert np.allclose(images.inspection - images.reference, images.difference, atol=1e-3)
        assert len(images.impact_strengths) <= int(images.impact_truth.any()) * images.impact_truth.sum()


def test_run_roc_is_monotone_and_theory_spans_the_probabilities(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    if not any(v.images is not None and v.images.impact_truth.any() for v in result.visits):
        pytest.skip("seed 0 at this size shows no counted impact")
    measured, theory = result.roc
    # a lower threshold never detects less nor false-alarms less
    assert np.all(np.diff(measured.threshold) <= 0)
    assert np.all(np.diff(measured.p_false_alarm) >= 0) and np.all(np.diff(measured.p_detection) >= 0)
    assert theory.p_false_alarm[0] == pytest.approx(1e-7) and theory.p_false_alarm[-1] == pytest.approx(1.0)
    assert np.all(np.diff(theory.p_detection) >= -1e-12) and theory.p_detection[-1] == pytest.approx(1.0)


def test_run_roc_is_empty_when_no_impact_centre_was_compared(archived: tuple[MissionResult, Path]) -> None:
    """Space repeatability can leave every impact where nothing was compared: no measured curve, no error."""
    from rsi.mission.score import run_roc

    result, _ = archived
    if not any(v.images is not None and v.images.impact_truth.any() for v in result.visits):
        pytest.skip("seed 0 at this size shows no counted impact")
    blind = tuple(
        v
        if v.images is None
        else dataclasses.replace(
            v, images=dataclasses.replace(v.images, valid=v.images.valid & ~v.images.impact_truth)
        )
        for v in result.visits
    )
    assert run_roc(blind, result.settings) == ()


def test_overview_pose_projects_every_anomaly_into_the_picture(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    assert result.overview_rgb is not None and result.overview_pose is not None
    rows, cols, channels = result.overview_rgb.shape
    assert channels == 3 and result.overview_rgb.dtype == np.uint8
    xy, along = result.overview_pose.project(np.asarray([a.position_m for a in result.truth.anomalies]))
    assert np.all(along > 0)
    assert np.all((xy[:, 0] >= 0) & (xy[:, 0] < cols) & (xy[:, 1] >= 0) & (xy[:, 1] < rows))


def test_inspection_region_keeps_components_and_drops_struts_and_depth_jumps() -> None:
    from rsi.mission import MissionSettings
    from rsi.mission.views import inspection_region

    DEPTH_JUMP_M = MissionSettings().depth_jump_m

    world = load("truss", seed=SEED)
    try:
        from rsi.mission.views import sense
        from rsi.sim.capture import capture

        view = world.render("B_tank", size=SMALL, stereo=True)
        sensed = sense(capture(world, view))  # the same visit, as the robot receives it
    finally:
        world.close()
    region = inspection_region(sensed, MissionSettings())
    assert view.truss_mask is not None and view.depth_m is not None
    assert not (region & view.truss_mask).any()
    # no kept pixel has a neighbour across a depth jump (the tank's silhouette against its plate)
    depth = view.depth_m
    step = np.abs(np.diff(depth, axis=1)) > DEPTH_JUMP_M
    crossing = (region[:, 1:] & step) | (region[:, :-1] & step)
    # the robot places jumps from its model at the believed pose and from the matched range: a gap of a
    # pixel or two that only the true pose shows (aliasing at a silhouette) may slip through, no more
    assert crossing.sum() <= 1e-3 * region.sum()
    assert region.mean() > 0.3  # the plate and the tank stay


def test_screws_and_the_swapped_component_are_found_at_full_size() -> None:
    # the seed mock-up's draw of seed 26: screws B_2 and D_2 missing, the A ORU dented (seed §4 defects)
    off_panel = dataclasses.replace(HAND_PLAN, vistas=("A_door", "A_kapton", "B_tank", "D_tubing"))
    result = run_mission(
        26, active=False, arm=False, orbit=False, anomalies=AnomalySettings.seed_mockup(), settings=off_panel
    )
    score = score_mission(result)
    assert score.per_type["missing_screw"].found == score.per_type["missing_screw"].truth >= 1
    # the image-change fallback for heads stereo cannot resolve costs ~0.25 false screws per run (issue 13
    # benchmark, seeds 0-15): one here is the rate, two would not be
    assert score.per_type["missing_screw"].false_findings <= 1
    assert score.per_type["swapped_component"].found == score.per_type["swapped_component"].truth == 1
    # the A ORU's dent is now pressed into the fill plate the cameras see (issue 13's hidden-dent fix): its
    # crater's shading shows in three views (A_door, A_door_open, A_kapton) as small dark blobs that only
    # the view which finds the dent explains. Six is what this seed gives with the range-map dent check; the
    # crater's image predicted from the reference and the range map is the next step (README roadmap)
    assert score.per_type["impact"].false_findings <= 6


def test_impacts_on_a_discoloured_replacement_are_found_on_its_own_pixels_and_seen_again() -> None:
    # Truss seed 2 replaced the solar panel by one reflecting 1.22 times as much, and two impacts of 2.7 mm
    # sit on its cells. The frame's comparison leaves a discoloured component's pixels out; its own
    # comparison (its own gain and bias, seed §2.3) finds them, and no line or glint of it becomes an
    # impact. At space repeatability nothing on the panel places the pose, and the second look finds the
    # blob by registering the two visits, not where the believed poses put it (11 px off on this seed).
    later = (ORBIT_START_S[0], ORBIT_START_S[1] + 300.0)
    result = run_mission(2, repeatability="space", orbit_start_s=later, settings=PANEL_VIEWS)
    truth = result.truth.anomalies
    panel = next(k for k, a in enumerate(truth) if a.KIND == "swapped_component" and a.site == "C_panel")
    assert truth[panel].defect == "discoloured" and truth[panel].reflectance_factor > 1.0  # type: ignore[attr-defined]
    on_panel = {k for k, a in enumerate(truth) if a.KIND == "impact" and a.site == "C_cells"}
    assert len(on_panel) >= 2
    score = score_mission(result)
    assert not on_panel & {miss.index for miss in score.misses}
    assert panel in score.matches.values()
    false_on_panel = [
        finding
        for k, finding in enumerate(result.findings)
        if k not in score.matches and finding.kind == "impact" and finding.source.startswith("C_panel")
    ]
    assert false_on_panel == []  # (an edge of the ORU's door pocket, mis-registered in space, may show)


def test_score_matches_each_finding_to_an_anomaly_of_its_kind(archived: tuple[MissionResult, Path]) -> None:
    result, _ = archived
    score = score_mission(result)
    # every finding outside `matches` is a false finding, and no anomaly is matched twice
    assert len(result.findings) - len(score.matches) == score.false_findings
    assert len(set(score.matches.values())) == len(score.matches)
    for finding_index, anomaly_index in score.matches.items():
        finding, anomaly = result.findings[finding_index], result.truth.anomalies[anomaly_index]
        assert finding.kind == anomaly.kind
        assert np.linalg.norm(np.subtract(finding.position_m, anomaly.position_m)) <= 0.05


def test_an_impact_beside_a_discoloured_tank_keeps_its_second_look() -> None:
    # Truss seed 13 replaced the B tank by a discoloured one, and a 2.8 mm impact sits on the plate below
    # it. Both looks compare the frame without the tank's pixels, registered again for their own gain and
    # bias; from a start at no shift the second look's registration ran 780 px off, its comparison held no
    # pixel and the impact was rejected. Started from the registration in depth, it is confirmed.
    result = run_mission(13, settings=dataclasses.replace(HAND_PLAN, vistas=("B_tank",)))
    truth = result.truth.anomalies
    tank = next(k for k, a in enumerate(truth) if a.KIND == "swapped_component" and a.site == "B_tank")
    assert truth[tank].defect == "discoloured"  # type: ignore[attr-defined]
    below = next(k for k, a in enumerate(truth) if a.KIND == "impact" and a.site == "B_plate_bottom")
    score = score_mission(result)
    assert {below, tank} <= set(score.matches.values())
    # a targeted run is scored on what its frames see: seed 13 has visual anomalies beyond the tank's view
    seen = {k for visit in result.visits for k in visit.visible}
    unseen = [a for k, a in enumerate(truth) if k not in seen and a.KIND in ("impact", "missing_screw")]
    assert unseen and all(miss.reason != "not visible in any planned frame" for miss in score.misses)
    counted = sum(s.truth for name, s in score.per_type.items() if name in ("impact", "missing_screw"))
    whole = score_mission(dataclasses.replace(result, settings=HAND_PLAN))  # the same run, as a whole plan
    assert sum(whole.per_type[name].truth for name in ("impact", "missing_screw")) > counted


def test_a_found_impact_is_seen_again_under_the_other_strobe(archived: tuple[MissionResult, Path]) -> None:
    from rsi.mission.visual import thresholds

    result, path = archived
    score = score_mission(result)
    impacts = [
        finding
        for index, finding in enumerate(result.findings)
        if finding.kind == "impact" and index in score.matches and finding.other_strobe_score is not None
    ]
    assert impacts  # seed 0's impacts are read under the ISEE's other strobe (seed §3 B)
    # a flaw is a change of the surface: both strobes by the lens show it (seed §2.5)
    preliminary = thresholds(result.settings).preliminary
    assert all(abs(finding.other_strobe_score) > preliminary for finding in impacts)  # type: ignore[arg-type]
    with Archive.open(path, create=False) as archive:
        stored = [f.extras for f in archive.findings(archive.runs()[-1].run_id) if f.kind == "impact"]
    assert {"ambient_score", "other_strobe_score"} <= set(stored[0])
