"""Rendering: basis images add up, no shadow acne, clear error for a missing backend."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from rsi.sim import scene
from rsi.sim.render import import_mujoco
from rsi.sim.scene import LIGHT_GROUPS
from rsi.sim.world import AMBIENT_RENDER_LEVEL, World

SIZE = (120, 160)


def test_basis_images_add_up_to_the_all_lights_render(world: World) -> None:
    point = world.vista("D_tubing")
    world.place_camera(point.position_m, point.forward, point.up)
    model = world.model
    saved = [model.light_diffuse.copy(), model.light_specular.copy(), model.light_ambient.copy()]
    # The classic renderer clamps the lit colour to 1 before multiplying by the texture, so lights whose sum
    # passes 1 clip unseen; at a fifth of the levels no sum of the groups does, the pristine tank's
    # specular highlight included (at a third it clipped there: only a seed with that tank swapped passed).
    model.light_diffuse[:] = saved[0] / 5.0
    model.light_specular[:] = saved[1] / 5.0
    model.light_ambient[:] = saved[2] / 5.0
    try:
        basis = world.basis(size=SIZE)
        together = world.render_all_lights(size=SIZE)
    finally:
        model.light_diffuse[:], model.light_specular[:], model.light_ambient[:] = saved
    lit = together > 0
    assert lit.mean() > 0.5
    difference = (sum(basis.values()) - together)[lit]
    # one uint8 render per group and the all-lights one, each rounded by up to half a step, plus the
    # luminance weights' rounding (half a unit); the sun's and the lamps' step is 1 / AMBIENT_RENDER_LEVEL
    steps = [1.0 / AMBIENT_RENDER_LEVEL if group in ("sun", "lamps") else 1.0 for group in basis]
    assert np.abs(difference).max() <= 0.5 * (sum(steps) + 1) + 0.5
    assert abs(float(difference.mean())) < 0.25


def _closer(world: World, vista: str, standoff_m: float) -> None:
    point = world.vista(vista)
    forward = np.asarray(point.forward, dtype=float)
    world.place_camera(np.asarray(point.position_m) + (0.5 - standoff_m) * forward, forward, point.up)


def test_glare_past_the_renderer_s_clip_stays_linear_in_the_light(world: World) -> None:
    # 0.25 m from the brushed tank the flash (1/d^2) and its specular return pass the classic renderer's
    # clamp at 1 over much of the frame; a camera sees that light (seed §2.1), so the basis must scale with
    # the lights as they do below the clip: at a quarter of every level, a quarter of the image
    _closer(world, "B_tank", 0.25)
    model = world.model
    full = world.basis(size=SIZE)["strobe"]
    saved = [model.light_diffuse.copy(), model.light_specular.copy(), model.light_ambient.copy()]
    model.light_diffuse[:] = saved[0] / 4.0
    model.light_specular[:] = saved[1] / 4.0
    model.light_ambient[:] = saved[2] / 4.0
    try:
        quarter = world.basis(size=SIZE)["strobe"]
    finally:
        model.light_diffuse[:], model.light_specular[:], model.light_ambient[:] = saved
    assert (full > 255).mean() > 0.05  # past the 8-bit render: the clip is really crossed here
    lit = quarter > 5
    # each render is within a unit of its own level (the lit colour and its product with the texel are
    # both 8-bit): 1 + 4 below the clip; a glare pixel of `full` read at a 16th of it, `quarter`'s at a 4th
    error = np.abs(full - 4 * quarter)[lit]
    assert np.percentile(error, 99) <= 1.0 + 4.0
    assert error.max() <= 16.0 + 4.0 * 4.0


def test_a_weaker_flash_is_rendered_dimmer_and_reads_the_same_light(world: World) -> None:
    # the strobe group is rendered at the flash it fires (World.set_strobe_energy): the same basis image in
    # the same units, quantised at that level, and glare past the seed flash's clip read all the same
    _closer(world, "B_tank", 0.25)
    seed_flash = world.basis(size=SIZE)["strobe"]
    world.set_strobe_energy(0.25)
    try:
        weaker = world.basis(size=SIZE)["strobe"]
    finally:
        world.set_strobe_energy(1.0)
    assert (seed_flash > 255).mean() > 0.05
    error = np.abs(weaker - seed_flash)[seed_flash > 5]
    # within a unit of each render's level: 1 and 4 below the clip (the glare's: 16 and 16)
    assert np.percentile(error, 99) <= 1.0 + 4.0
    assert error.max() <= 16.0 + 16.0


def test_a_render_level_outside_0_to_1_is_refused(world: World) -> None:
    from rsi.errors import InputError
    from rsi.sim.render import SceneRenderer

    renderer = SceneRenderer(world.model, *SIZE)
    try:
        for level in (0.0, 1.5, float("nan"), True):
            with pytest.raises(InputError, match="level"):
                renderer.luminance(world.data, "isee", state="inspection", lights=(0,), level=level)
    finally:
        renderer.close()


def test_lamp_on_a_flat_panel_leaves_no_isolated_dark_dots(world: World) -> None:
    point = world.vista("A_kapton")
    world.place_camera(point.position_m, point.forward, point.up)
    size = (240, 320)
    sun = world.basis(size=size)["sun"]
    _, segments = world._renderer(size).depth_and_segments(world.data, "isee", state="inspection")
    panel = np.isin(segments, [world._id("geom", name) for name in ("A_fill", "A_body")])
    panel = cv2.erode(panel.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert panel.sum() > 5000
    assert np.median(sun[panel]) > 60  # the lamp lights the face
    local = cv2.medianBlur(np.clip(sun, 0, 255).astype(np.uint8), 5).astype(np.float32)
    dark = (sun < 0.7 * local) & panel
    _count, _labels, stats, _ = cv2.connectedComponentsWithStats(dark.astype(np.uint8), connectivity=8)
    isolated = int(np.sum(stats[1:, cv2.CC_STAT_AREA] <= 2))
    assert isolated == 0


def _panel_strobe(same_draw: Callable[[], World], quads: int | None = None) -> NDArray[np.float32]:
    built = same_draw()
    try:
        if quads is not None:  # read when the renderer's context is made, at the first frame
            built.model.vis.quality.numquads = quads
        return built.render("C_panel", size=SIZE, truth=False).basis["strobe"]
    finally:
        built.close()


def _largest_change(before: NDArray[np.float32], after: NDArray[np.float32]) -> float:
    lit = after > 5.0
    return float(np.abs(before - after)[lit].max() / np.percentile(after[lit], 99))


def test_a_face_s_strobe_image_does_not_depend_on_how_finely_its_box_is_drawn(
    same_draw: Callable[[], World], monkeypatch: pytest.MonkeyPatch
) -> None:
    # MuJoCo lights each vertex and interpolates: the panel drawn as a grid mesh (rsi.sim.scene
    # MESHED_BOX_M) is its strobe image as MuJoCo's own box at 70 quads a side (7 mm) within 2 % of its
    # bright level; at MuJoCo's default of 4 quads against 8 the image moved by 16 %
    meshed = _panel_strobe(same_draw)
    monkeypatch.setattr(scene, "MESHED_BOX_M", np.inf)
    assert _largest_change(meshed, _panel_strobe(same_draw, 70)) < 0.02
    assert _largest_change(_panel_strobe(same_draw, 4), _panel_strobe(same_draw, 8)) > 0.1


def test_no_box_is_drawn_with_quads_over_a_centimetre_and_a_half(world: World) -> None:
    # the inspection frames' boxes: the large ones grid meshes, the small ones MuJoCo's numquads a side
    mujoco = import_mujoco()
    model = world.model
    boxes = model.geom_type == mujoco.mjtGeom.mjGEOM_BOX
    assert boxes.any() and (model.geom_type == mujoco.mjtGeom.mjGEOM_MESH).any()
    longest = 2.0 * model.geom_size[boxes].max(axis=1)
    assert np.all(longest / model.vis.quality.numquads <= scene.BOX_QUAD_M + 1e-12)


def test_live_video_s_coarser_drawing_leaves_the_model_s_settings_as_they_were(world: World) -> None:
    from rsi.sim.render import SceneRenderer

    quality = world.model.vis.quality
    before = (quality.offsamples, quality.numslices, quality.numstacks, quality.numquads)
    renderer = SceneRenderer(world.model, *SIZE, fast=True)
    renderer.close()
    assert (quality.offsamples, quality.numslices, quality.numstacks, quality.numquads) == before


def test_an_unknown_gl_backend_fails_only_when_rendering_with_a_clear_error() -> None:
    code = (
        "import rsi.sim as s; w = s.load('truss', seed=1); print('built', len(w.anomalies));\n"
        "try:\n    w.render('A_door', size=(32, 32))\n"
        "except Exception as e:\n    print(type(e).__name__, e)"
    )
    environment = {**os.environ, "MUJOCO_GL": "nonsense"}
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=environment, check=True
    )
    assert "built" in result.stdout
    assert "RenderBackendError" in result.stdout
    assert "MUJOCO_GL='nonsense'" in result.stdout and "apt-get install" in result.stdout


@pytest.mark.parametrize("size", [(8, 64), (64, 4096), [64, 64]])
def test_bad_sizes_are_refused(world: World, size: object) -> None:
    with pytest.raises(ValueError, match="size"):
        world.render("A_door", size=size)  # type: ignore[arg-type]


def test_the_continuous_lights_basis_is_their_full_level_render_within_its_rounding(world: World) -> None:
    # rendered at AMBIENT_RENDER_LEVEL: a step of 1 / level render units, the same image where nothing clips
    from rsi.sim.render import SceneRenderer

    point = world.vista("A_kapton")
    world.place_camera(point.position_m, point.forward, point.up)
    sun = world.basis(size=SIZE)["sun"]
    mujoco = import_mujoco()
    lights = tuple(
        mujoco.mj_name2id(world.model, mujoco.mjtObj.mjOBJ_LIGHT, name) for name in LIGHT_GROUPS["sun"]
    )
    renderer = SceneRenderer(world.model, *SIZE)
    try:
        full = renderer.luminance(world.data, "isee", state="inspection", lights=lights)
    finally:
        renderer.close()
    lit = full > 20.0
    assert lit.mean() > 0.2
    assert np.abs(sun - full)[lit].max() <= 1.0 / AMBIENT_RENDER_LEVEL + 1.0
