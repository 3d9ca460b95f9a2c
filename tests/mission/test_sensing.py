"""The mission sees what the robot's sensors give, never the simulator's truth (issue 13, seed §2.3, §3 D).

- No module that produces findings reads the truth: checked on their source, attribute by attribute.
- The believed pose is the commanded one through the encoders: the visit's repeatability error is not in it.
- The stereo range map is matched, with the matcher's errors and holes, within the physics of the rig.
"""

from __future__ import annotations

import ast
import math
import os
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.errors import InputError
from rsi.imaging.stereo import StereoRig, range_map
from rsi.mission.views import sense
from rsi.sim.capture import Capture, capture
from rsi.sim.world import ENCODER_POSITION_SIGMA_M, World, load

MISSION = Path(__file__).parents[2] / "src" / "rsi" / "mission"
# the modules that turn the ISEE's data into findings
FINDING_MODULES = ("visual.py", "evidence.py", "views.py", "exposure.py", "surveys.py")
# what only the simulator knows about a visit (rsi.sim.world.View) or the world (its anomalies, fields)
TRUTH_ATTRIBUTES = frozenset(
    {
        "depth_m",
        "flaw_masks",
        "flaw_mask",
        "truss_mask",
        "component_masks",
        "ambient_lux",
        "strobe_lux_s",
        "basis",
        "pose",
        "pose_error_px",
        "anomalies",
        "render",
        "render_from_tool",
        "next_frame",
        "views",
    }
)
# what the world alone knows: its fields and its repeatability draws (the sensors' models read them)
WORLD_TRUTH = frozenset({"temperature_k", "gas_concentration_ppm", "repeatability", "anomalies"})
SIZE = (240, 320)


def _attributes(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.attr for node in ast.walk(tree) if isinstance(node, ast.Attribute)}


def _world_attributes(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {
        node.attr
        for node in ast.walk(tree)
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "world"
    }


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}


@pytest.mark.parametrize("module", FINDING_MODULES)
def test_no_finding_module_reads_the_truth(module: str) -> None:
    read = _attributes(MISSION / module) & TRUTH_ATTRIBUTES
    assert not read, f"{module} reads the simulator's truth: {sorted(read)}"
    assert not _world_attributes(MISSION / module) & WORLD_TRUTH
    assert not _imports(MISSION / module) & {"rsi.mission.truth", "rsi.mission.score"}


def test_the_run_hands_truth_only_to_scoring() -> None:
    # run.py drives the tour and fuses findings: truth reaches only the records (rsi.mission.truth) and the
    # result's truth for score_mission
    read = _attributes(MISSION / "run.py") & TRUTH_ATTRIBUTES
    assert read <= {"anomalies", "views"}, sorted(read)


def test_the_check_sees_a_truth_read() -> None:
    # the scans above must be able to fail: the truth module reads the masks, the run the world's truth
    assert "flaw_masks" in _attributes(MISSION / "truth.py")
    assert "anomalies" in _world_attributes(MISSION / "run.py")


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    built = load("truss", seed=4)
    yield built
    built.close()


def test_a_capture_holds_no_truth(world: World) -> None:
    taken = capture(world, world.render("B_tank", size=SIZE, stereo=True))
    assert isinstance(taken, Capture)
    assert not set(Capture.__dataclass_fields__) & TRUTH_ATTRIBUTES
    odd, even = taken.frames
    assert (odd.lit_field, even.lit_field) == ("odd", "even")


def test_the_model_draws_the_isee_only_in_frames_the_isee_took() -> None:
    from rsi.mission.views import own_body
    from rsi.sim.arm import JAW_LENGTH_M

    # the free camera (the arm's fallback where it cannot reach) carries no jaws: its frame shows the
    # surface where the arm's camera would see them (truss seed 11, lab: a 3.9 mm impact on the solar
    # cells lay under jaws the model drew and the frame did not hold, and was never looked at)
    built = load("truss", seed=4, arm=True)
    try:
        tool = built.render_from_tool(size=SIZE, stereo=True)
        free = built.render("C_panel", size=SIZE, stereo=True)
        jaws = own_body(capture(built, tool).cad)
        assert tool.carried and not free.carried and jaws.any()
        assert float(tool.depth_m[jaws].max()) < JAW_LENGTH_M  # the tool's frame holds its jaws
        taken = capture(built, free)
        assert not own_body(taken.cad).any() and not own_body(taken.model(taken.believed_pose)).any()
        assert float(free.depth_m[jaws].min()) > JAW_LENGTH_M  # and the free frame a surface there
    finally:
        built.close()


def test_the_believed_pose_is_the_commanded_pose_not_the_true_one() -> None:
    built = load("truss", seed=4, repeatability="space")
    try:
        vista = built.vista("B_tank")
        for _ in range(3):
            view = built.render("B_tank", size=SIZE)
            assert view.believed_pose is not None
            believed = np.linalg.norm(view.believed_pose.position_m - np.asarray(vista.position_m))
            true = np.linalg.norm(view.pose.position_m - np.asarray(vista.position_m))
            assert believed < 6 * ENCODER_POSITION_SIGMA_M  # the encoders' noise only
            assert true > 1e-3  # "space": ~10 px at the standoff, millimetres the robot does not know
    finally:
        built.close()


def test_the_range_map_is_matched_within_the_rigs_physics(world: World) -> None:
    view = world.render("B_tank", size=(480, 640), stereo=True)
    sensed = sense(capture(world, view))
    truth = view.depth_m
    assert truth is not None
    surface = truth < 10.0
    raw = range_map(*sensed.capture.stereo, sensed.capture.rig, depth_limits_m=(0.2, 2.0))
    matched = np.isfinite(raw) & surface
    error = (raw - truth)[matched]
    inliers = np.abs(error) < 0.03
    # holes and false matches exist (the matcher's, not a renderer's), but most of the surface is matched
    assert 0.0 < 1.0 - matched.sum() / surface.sum() < 0.5
    assert inliers.mean() > 0.8
    # sigma_Z = Z^2 sigma_d / (f B): the median absolute error is 0.67 sigma for Gaussian errors; SGBM's
    # sub-pixel disparity is good to well under a pixel, and no better than a twentieth of one
    rig = sensed.capture.rig
    per_px = float(np.median(rig.depth_sigma_m(truth[matched][inliers], 1.0)))
    spread = float(np.median(np.abs(error[inliers])))
    assert 0.05 * 0.674 * per_px < spread < 0.674 * per_px
    # the mission keeps the matches its model finds plausible, and the model's depth stands in elsewhere
    expected = sensed.capture.cad.expected_depth_m
    kept = np.isfinite(sensed.range_m)
    assert np.all(np.abs(sensed.range_m[kept] - expected[kept]) <= 0.03)
    assert np.isfinite(sensed.surface_m[surface]).all()


@pytest.mark.parametrize("near_m", [0.4, 0.1])
def test_every_column_searches_the_disparities_its_position_allows(world: World, near_m: float) -> None:
    # OpenCV's matcher leaves its first minDisparity + numDisparities columns empty: a near limit of 0.1 m
    # (a close surface, the ISEE's jaws) asks for ~460 px of disparity and left 460 of 640 columns unranged
    view = world.render("B_tank", size=(480, 640), stereo=True)
    assert view.stereo is not None and view.depth_m is not None
    rig = StereoRig(view.pose.focal_px, (480, 640), 0.06)
    ranges = range_map(*view.stereo, rig, depth_limits_m=(near_m, 2.0))
    truth = view.depth_m
    columns = np.arange(640)[None, :]
    with np.errstate(divide="ignore"):
        disparity = rig.focal_px * rig.baseline_m / truth
    seen_by_both = (truth < 10.0) & (columns >= disparity + 3)  # the right camera sees the point
    left, right = seen_by_both & (columns < 320), seen_by_both & (columns >= 320)
    matched = np.isfinite(ranges)
    assert left.sum() > 10_000 and right.sum() > 10_000
    assert matched[left].mean() > 0.6
    assert matched[left].mean() > 0.8 * matched[right].mean()


def test_no_range_is_given_where_the_right_camera_cannot_see(world: World) -> None:
    # a point whose disparity exceeds its column is outside the right frame: any match there is the padding's
    view = world.render("B_tank", size=(480, 640), stereo=True)
    assert view.stereo is not None
    rig = StereoRig(view.pose.focal_px, (480, 640), 0.06)
    ranges = range_map(*view.stereo, rig, depth_limits_m=(0.2, 2.0))
    rows, columns = np.nonzero(np.isfinite(ranges))
    assert columns.size > 0
    disparity = rig.focal_px * rig.baseline_m / ranges[rows, columns]
    assert np.all(columns >= disparity - 1e-3)


def test_sigma_z_is_the_derivative_of_triangulation() -> None:
    rig = StereoRig(focal_px=800.0, shape=(480, 640), baseline_m=0.06)
    z, d = 0.5, 800.0 * 0.06 / 0.5
    assert rig.depth_sigma_m(z, 0.25) == pytest.approx(
        800.0 * 0.06 / (d - 0.125) - 800.0 * 0.06 / (d + 0.125), rel=1e-3
    )


@pytest.mark.parametrize("least_disparity_px", [0, 16])
def test_a_near_limit_closer_than_the_frame_can_show_searches_the_whole_width(
    world: World, least_disparity_px: int
) -> None:
    # the search is clamped to the frame: every disparity from the far limit's to the width's, whatever
    # the near limit asks (OpenCV's matcher fails where they reach the width exactly)
    view = world.render("B_tank", size=SIZE, stereo=True)
    assert view.stereo is not None
    rig = StereoRig(view.pose.focal_px, SIZE, 0.06)
    far = rig.focal_px * rig.baseline_m / (least_disparity_px + 0.5)
    ranges = range_map(*view.stereo, rig, depth_limits_m=(1e-4, far))
    assert ranges.shape == SIZE
    assert np.isfinite(ranges).any()


@pytest.mark.parametrize(
    ("limits", "message"),
    [
        ((0.5, 0.4), "near < far"),
        ((0.0, 1.0), "depth_limits_m"),
        ((0.001, 0.002), "frame width"),
        (0.5, "pair"),
    ],
)
def test_bad_range_limits_are_refused_by_name(
    world: World, limits: tuple[float, float], message: str
) -> None:
    view = world.render("B_tank", size=SIZE, stereo=True)
    assert view.stereo is not None
    rig = StereoRig(view.pose.focal_px, SIZE, 0.06)
    with pytest.raises(InputError, match=message):
        range_map(*view.stereo, rig, depth_limits_m=limits)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"focal_px": -1.0, "shape": SIZE, "baseline_m": 0.06}, "focal_px"),
        ({"focal_px": 500.0, "shape": SIZE, "baseline_m": 0.0}, "baseline_m"),
        ({"focal_px": 500.0, "shape": (4, 320), "baseline_m": 0.06}, "shape"),
        ({"focal_px": 500.0, "shape": [240, 320], "baseline_m": 0.06}, "shape"),
    ],
)
def test_a_bad_rig_is_refused_by_name(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(InputError, match=message):
        StereoRig(**kwargs)  # type: ignore[arg-type]


def test_mismatched_frames_are_refused(world: World) -> None:
    view = world.render("B_tank", size=SIZE, stereo=True)
    assert view.stereo is not None
    with pytest.raises(InputError, match="agree"):
        range_map(*view.stereo, StereoRig(500.0, (480, 640), 0.06), depth_limits_m=(0.2, 2.0))
    with pytest.raises(InputError, match="Frame"):
        range_map(view.stereo[0], "right", StereoRig(500.0, SIZE, 0.06), depth_limits_m=(0.2, 2.0))  # type: ignore[arg-type]


def test_capture_needs_a_stereo_view(world: World) -> None:
    with pytest.raises(InputError, match="stereo=True"):
        capture(world, world.render("B_tank", size=SIZE))


def test_cad_projection_and_reflash_refuse_bad_input(world: World) -> None:
    with pytest.raises(InputError, match="pose"):
        world.cad_projection("here")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="own_body"):
        world.cad_projection(world.render("B_tank", size=SIZE).pose, own_body="yes")  # type: ignore[arg-type]
    view = world.render("B_tank", size=SIZE)
    with pytest.raises(InputError, match="strobe_energy"):
        world.reflash(view, strobe_energy=math.inf, shutter=1.0)
    with pytest.raises(InputError, match="shutter"):
        world.reflash(view, strobe_energy=1.0, shutter=5.0)
    with pytest.raises(InputError, match="view"):
        world.reflash("view", strobe_energy=1.0, shutter=1.0)  # type: ignore[arg-type]


def test_the_gas_survey_finds_each_of_two_leaks() -> None:
    from rsi.mission import MissionSettings
    from rsi.mission.surveys import gas_pass
    from rsi.sim.anomalies import AnomalySettings

    # seed §4 draws from three holes; two on at once, both strong enough to stand above the threshold
    draw = AnomalySettings(
        anomaly_free_probability=0.0,
        active_leak_count_range=(2, 2),
        leak_exit_ppm_range=(20000.0, 20000.0),
    )
    built = load("truss", seed=3, settings=draw)
    try:
        leaks = built.anomalies.gas_leaks
        findings, _, _ = gas_pass(built, np.random.default_rng(0), MissionSettings())
    finally:
        built.close()
    assert len(leaks) == 2 and len(findings) == 2
    for leak in leaks:
        nearest = min(np.linalg.norm(np.subtract(f.position_m, leak.position_m)) for f in findings)
        assert nearest < 0.03  # the scoring radius of a leak
