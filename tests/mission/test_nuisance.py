"""The mission's nuisance models and evidence fusion, on synthetic inputs with known answers."""

from __future__ import annotations

import os
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.imaging.compensation import Compensated
from rsi.mission.mission import (
    AMBIENT_TARGET_DN,
    IMPACT_MERGE_M,
    SHADOW_JAG_PX,
    MissionFinding,
    _ambient_dn,
    _explained_by,
    _Explanation,
    _half_pixel_shifted,
    _Look,
    _merge_impacts,
    _metered_energy,
    _metered_shutter,
    _parallax_scale,
    _screw_relief_m,
    _with_shadow_edges,
    _without_discoloured,
)

SHAPE = (40, 60)


def _image(values: np.ndarray) -> Compensated:
    return Compensated(
        image=values.astype(np.float32),
        valid=np.ones(values.shape, bool),
        variance=np.full(values.shape, 2.0, np.float32),
        interpolation_variance=np.zeros(values.shape, np.float32),
        row_step=1,
    )


def _finding(kind: str, x: float, score: float, source: str = "A_door") -> MissionFinding:
    return MissionFinding(kind, (x, -0.472, 1.2), 0.002, 0.9, source, score)


def test_half_pixel_shift_moves_a_ramp_by_half_its_slope() -> None:
    ramp = np.tile(np.arange(SHAPE[1], dtype=np.float32) * 4.0, (SHAPE[0], 1))
    shifted = _half_pixel_shifted(_image(ramp))
    inner = (slice(2, -2), slice(2, -2))
    np.testing.assert_allclose(shifted.image[inner], ramp[inner] - 2.0, atol=1e-3)
    assert shifted.valid[inner].all()


def test_parallax_scale_is_one_on_the_registered_plane_and_grows_off_it() -> None:
    ramp = np.tile(np.arange(SHAPE[1], dtype=np.float32) * 3.0, (SHAPE[0], 1))
    flat = SimpleNamespace(depth_m=np.full(SHAPE, 0.5, np.float32))
    np.testing.assert_allclose(_parallax_scale(_image(ramp), flat, 2.0), 1.0)  # type: ignore[arg-type]
    stepped = np.full(SHAPE, 0.5, np.float32)
    stepped[:, 40:] = 0.4  # a part 10 cm proud of the plate: 2 px * (0.5 / 0.4 - 1) = 0.5 px of parallax
    scale = _parallax_scale(_image(ramp), SimpleNamespace(depth_m=stepped), 2.0)  # type: ignore[arg-type]
    # first order: 1 + (0.5 px * 3 DN/px)^2 / 2 DN^2
    assert scale[20, 55] == pytest.approx(1.0 + (0.5 * 3.0) ** 2 / 2.0, rel=1e-3)
    assert scale[20, 5] == pytest.approx(1.0)
    no_shift = _parallax_scale(_image(ramp), SimpleNamespace(depth_m=stepped), 0.0)  # type: ignore[arg-type]
    np.testing.assert_allclose(no_shift, 1.0)  # without a viewpoint error nothing is off the plane


def test_shadow_edges_add_variance_along_the_reference_edge_only() -> None:
    raw = np.full((SHAPE[0], SHAPE[1]), 8, np.uint8)
    raw[:, 30:] = 120  # a vertical sun-shadow edge in the ambient (every row, lit or not)
    frame = SimpleNamespace(raw=raw, lit_field="odd")
    image = _image(np.full(SHAPE, 50.0))
    edged = _with_shadow_edges(image, SimpleNamespace(frame=frame))  # type: ignore[arg-type]
    extra = edged.interpolation_variance
    assert extra[:, :25].max() == 0.0 and extra[:, 35:].max() == 0.0
    # Sobel/8 across a 112 DN step peaks at 56 DN/px beside it: (0.5 px * 56)^2
    assert extra[:, 29:31].max() == pytest.approx((SHADOW_JAG_PX * 112 / 2) ** 2, rel=1e-3)
    np.testing.assert_allclose(edged.variance - image.variance, extra)
    textured = SimpleNamespace(
        raw=(8 + (np.indices(SHAPE).sum(axis=0) % 2) * 6).astype(np.uint8), lit_field="odd"
    )
    # a checkerboard texture of 6 DN (gradient below SHADOW_EDGE_DN_PX) is no shadow edge
    assert _with_shadow_edges(image, SimpleNamespace(frame=textured)).interpolation_variance.max() == 0.0  # type: ignore[arg-type]


def test_one_impact_seen_from_two_vistas_is_one_finding() -> None:
    findings = [
        _finding("impact", 0.300, 9.0, "A_door"),
        _finding("impact", 0.300 + IMPACT_MERGE_M / 2, 12.0, "A_door_open"),
        _finding("impact", 0.300 + 3 * IMPACT_MERGE_M, 7.0, "A_kapton"),
        _finding("missing_screw", 0.300, 0.2, "A_door"),
    ]
    merged = _merge_impacts(findings)
    impacts = sorted((f.source, f.score) for f in merged if f.kind == "impact")
    assert impacts == [("A_door_open", 12.0), ("A_kapton", 7.0)]  # the stronger sighting stands
    assert [f.kind for f in merged].count("missing_screw") == 1


def test_metering_lifts_the_dark_panel_and_leaves_bright_aluminium() -> None:
    from rsi.sim.world import MAX_STROBE_ENERGY, load

    world: Any = load("truss", seed=0)
    try:
        panel = _metered_energy(world, world.render("C_panel", size=(120, 160)))
        plate = _metered_energy(world, world.render("D_tubing", size=(120, 160)))
    finally:
        world.close()
    assert 1.5 < panel <= MAX_STROBE_ENERGY  # solar cells read a few tens of DN at the seed's flash
    assert plate == 1.0  # never dimmer than the seed's 1.3 lm s


def test_metering_shortens_the_shutter_on_sunlit_metal_only() -> None:
    from rsi.sim.world import MIN_SHUTTER, load

    world: Any = load("truss", seed=0)
    try:
        door = world.render("A_door", size=(120, 160))  # the lab sun on brushed aluminium
        panel = world.render("C_panel", size=(120, 160))  # in the truss's shadow
        shutter = _metered_shutter(world, door)
        assert _ambient_dn(world, door) > 1.5 * AMBIENT_TARGET_DN
        assert MIN_SHUTTER <= shutter < 1 / 1.5
        assert _ambient_dn(world, door) * shutter == pytest.approx(AMBIENT_TARGET_DN, rel=1e-6)
        assert _metered_shutter(world, panel) == 1.0
        # the strobe gets the headroom the sun gave back
        assert _metered_energy(world, door, shutter) >= _metered_energy(world, door)
    finally:
        world.close()


def test_screw_relief_tells_a_head_from_its_hole() -> None:
    from rsi.mission.mission import SCREW_RELIEF_LOST_M, plan_vistas
    from rsi.sim.mockup import SCREW_HEIGHT_M
    from rsi.sim.world import load

    world: Any = load("truss", seed=6)  # screws B_1 and B_3 removed
    try:
        plan_vistas(world)
        view = world.render("B_tank")
        assert view.depth_m is not None
        sites = {s.name: s for s in world.mockup.candidates.screw_sites}
        relief = {name: _screw_relief_m(view.depth_m, view, sites[name]) for name in sites if "_B_" in name}
    finally:
        world.close()
    removed = {a.site for a in world.anomalies.anomalies if a.kind == "missing_screw"} & set(relief)
    assert removed == {"screw_B_1", "screw_B_3"}
    for name, height in relief.items():
        expected = 0.0 if name in removed else SCREW_HEIGHT_M
        assert height == pytest.approx(expected, abs=0.3 * SCREW_RELIEF_LOST_M)


def test_a_discolouring_explains_only_blobs_on_its_own_pixels() -> None:
    mask = np.zeros((60, 80), bool)
    mask[:, :40] = True  # the discoloured component fills the left half
    view = SimpleNamespace(component_masks={"B_tank": mask})
    explanation = _Explanation((0.0, 0.0, 0.0), 0.2, "B_tank")
    on_it = _Look((0.05, 0.0, 0.0), 2e-6, 9.0, (20, 10, 22, 12), False)
    beside = _Look((0.05, 0.0, 0.0), 2e-6, 9.0, (20, 60, 22, 62), False)
    far = _Look((0.5, 0.0, 0.0), 2e-6, 9.0, (20, 10, 22, 12), False)
    assert _explained_by(on_it, view, explanation)  # type: ignore[arg-type]
    assert not _explained_by(beside, view, explanation)  # type: ignore[arg-type]
    assert not _explained_by(far, view, explanation)  # type: ignore[arg-type]
    dent = _Explanation((0.0, 0.0, 0.0), 0.07)
    assert _explained_by(beside, view, dent)  # type: ignore[arg-type]
    spot = _Look((0.05, 0.0, 0.0), 2e-6, 9.0, (20, 60, 22, 62), False, darkening=0.5)
    assert not _explained_by(spot, view, dent)  # type: ignore[arg-type]  # an impact on the crater
    faint = _Look((0.05, 0.0, 0.0), 2e-6, 9.0, (20, 60, 22, 62), False, darkening=0.3)
    wide = _Look((0.05, 0.0, 0.0), 5e-5, 9.0, (20, 60, 30, 70), False, darkening=0.5)
    assert _explained_by(faint, view, dent) and _explained_by(wide, view, dent)  # type: ignore[arg-type]
    assert not _explained_by(on_it, SimpleNamespace(component_masks={}), explanation)  # type: ignore[arg-type]


def test_a_found_discolouring_leaves_the_photometric_fit() -> None:
    import cv2

    from rsi.mission.mission import _compare

    rng = np.random.default_rng(5)
    texture = cv2.GaussianBlur(rng.standard_normal((120, 160)).astype(np.float32), (0, 0), 2.0)
    reference = 80.0 + 40.0 * texture / texture.std()
    inspection = reference + rng.normal(0.0, 1.0, reference.shape)
    inspection[:, :90] *= 0.45  # a replacement tank reflecting 0.45 of the original fills the left
    inspection[60:63, 130:133] -= 25.0  # a spot on the plate beside it
    tank = np.zeros(reference.shape, bool)
    tank[:, :90] = True
    images = (_image(reference), _image(reference), _image(inspection))
    scale = np.ones(reference.shape, np.float32)
    whole = _compare(images[0], images[2], 1e-4, scale)
    view = SimpleNamespace(component_masks={"B_tank": tank})
    explanation = _Explanation((0.0, 0.0, 0.0), 0.2, "B_tank")
    *kept, pair = _without_discoloured(
        view,  # type: ignore[arg-type]
        [explanation],
        images,
        pair=whole,
        scale=scale,
        p_false_alarm=1e-4,
    )
    assert not kept[2].valid[:, :90].any() and kept[2].valid[:, 100:].all()
    spot = (slice(59, 64), slice(129, 134))
    assert pair.detection.score[spot].max() > max(8.0, 2 * whole.detection.score[spot].max())
    unchanged = _without_discoloured(
        view, [_Explanation((0.0, 0.0, 0.0), 0.07)], images, pair=whole, scale=scale, p_false_alarm=1e-4
    )  # type: ignore[arg-type]
    assert unchanged[3] is whole  # a dent leaves the fit alone
