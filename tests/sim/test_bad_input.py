"""Bad input to the simulator's front door fails early with an InputError naming the argument (issue 3).

Unknown vista, camera, scene or component defect; an unreachable lamp target; a bad seed; a bad output path.
A refused folder write leaves nothing behind: no frame without its truth, no staging folder, no new folder.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import rsi.imaging.io
from rsi.datasets.rendered import render_vista_to_folder
from rsi.errors import InputError
from rsi.sim.anomalies import AnomalySettings
from rsi.sim.world import World, load

SMALL = (32, 48)
SPOT = (0.9, -0.47, 1.2)  # front of the middle bay, the world's default lamp spot
# From SPOT the rail (y = -2 m, z = 1 m) is reached along (1, -1, -0.2 / 1.53): the lamp at lambda = 2.43 m.
REACHABLE_LIGHT_FROM = (1.0, -1.0, -0.2 / 1.53)

WorldCall = Callable[[World], Any]


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        (lambda w: w.render("nowhere", size=SMALL), "vista"),
        (lambda w: w.vista("A_window"), "vista"),
        (lambda w: w.render(3, size=SMALL), "vista"),
        (lambda w: w.basis("periscope", size=SMALL), "camera"),
        (lambda w: w.basis(None, size=SMALL), "camera"),
        (lambda w: w.render_all_lights("periscope", size=SMALL), "camera"),
        (lambda w: w.render("A_door", size=SMALL, state="later"), "state"),
        (lambda w: w.render("A_door", size=SMALL, lit_field="both"), "lit_field"),
        (lambda w: w.render("A_door", size=SMALL, exposure_s=0.0), "exposure_s"),
        (lambda w: w.render("A_door", size=SMALL, truth=1), "truth"),
        (lambda w: w.set_door(3.0), "angle_rad"),
        (lambda w: w.set_halogen(1), "on"),
        (lambda w: w.set_strobe_energy(20.0), "factor"),
        (lambda w: w.set_strobe_energy(float("nan")), "factor"),
        (lambda w: w.set_shutter(0.1), "fraction"),
        (lambda w: w.set_shutter(1.5), "fraction"),
        (lambda w: w.set_shutter(float("nan")), "fraction"),
        (lambda w: w.switch_lamp("off"), "on"),
    ],
)
def test_unknown_names_and_bad_settings_are_refused_with_the_argument_named(
    world: World, call: WorldCall, argument: str
) -> None:
    with pytest.raises(InputError, match=argument):
        call(world)


def test_an_unknown_camera_lists_the_cameras_instead_of_aborting_mujoco(world: World) -> None:
    # MuJoCo itself would end the process on an out-of-range camera id
    with pytest.raises(InputError, match="isee_left") as caught:
        world.basis("periscope", size=SMALL)
    assert "periscope" in str(caught.value)


@pytest.mark.parametrize(
    ("call", "argument"),
    [
        # above the lamp's tilt range: the lamp would have to sit beyond the rail's end
        (lambda w: w.aim_lamp((0.9, -0.47, 5.0), light_from=(1.0, -1.0, 1.0)), "phi"),
        # past the rail's end along x: the pan range puts the lamp at or beyond the spot
        (lambda w: w.aim_lamp((9.0, -0.47, 1.2), light_from=(1.0, -1.0, 0.0)), "theta"),
        # a direction out of the plane through the spot and the rail
        (lambda w: w.aim_lamp(SPOT, light_from=(-1.0, -1.0, 0.0)), "light_from"),
        (lambda w: w.aim_lamp(SPOT, light_from=(1.0, -1.0, 0.0)), "light_from"),
        # brighter than the focus range can give at that distance
        (lambda w: w.aim_lamp(SPOT, light_from=REACHABLE_LIGHT_FROM, intensity_lux=1e6), "intensity_lux"),
        (lambda w: w.aim_lamp(SPOT, light_from=REACHABLE_LIGHT_FROM, intensity_lux=-5.0), "intensity_lux"),
        (lambda w: w.aim_lamp("front", light_from=REACHABLE_LIGHT_FROM), "spot_world_m"),
        (lambda w: w.aim_lamp((0.9, np.nan, 1.2), light_from=REACHABLE_LIGHT_FROM), "spot_world_m"),
        (lambda w: w.set_lamp("high noon"), "configuration"),
    ],
)
def test_an_unreachable_lamp_target_names_the_limit_and_leaves_the_lamp_alone(
    world: World, call: WorldCall, argument: str
) -> None:
    before = world.lamp
    with pytest.raises(InputError, match=argument):
        call(world)
    assert world.lamp == before


def test_the_reachable_direction_used_above_is_reachable(world: World) -> None:
    world.aim_lamp(SPOT, light_from=REACHABLE_LIGHT_FROM)
    assert world.lamp.lambda_m == pytest.approx(2.43, abs=1e-3)


@pytest.mark.parametrize("seed", [-1, 1.5, True, "7", None, np.float64(2.0)])
def test_a_bad_seed_is_refused(seed: object) -> None:
    with pytest.raises(InputError, match="seed"):
        load("truss", seed=seed)  # type: ignore[arg-type]


def test_a_numpy_integer_seed_is_a_seed() -> None:
    world = load("truss", seed=np.int64(3))  # type: ignore[arg-type]
    assert world.seed == 3 and isinstance(world.seed, int)
    world.close()


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"scene": "station"}, "scene"),
        ({"repeatability": "orbit"}, "repeatability"),
    ],
)
def test_an_unknown_scene_or_repeatability_is_refused(kwargs: dict[str, Any], argument: str) -> None:
    scene = kwargs.pop("scene", "truss")
    with pytest.raises(InputError, match=argument):
        load(scene, seed=1, **kwargs)


def test_an_unknown_component_defect_is_refused() -> None:
    with pytest.raises(InputError, match="component_defects"):
        AnomalySettings(component_defects=("melted",))


# ------------------------------------------------------------------------------------------ bad paths


def _listing(folder: Path) -> list[str]:
    return sorted(str(path.relative_to(folder)) for path in folder.rglob("*"))


def test_a_file_as_the_output_folder_is_refused_and_left_untouched(world: World, tmp_path: Path) -> None:
    blocker = tmp_path / "frames"
    blocker.write_text("keep me")
    with pytest.raises(InputError, match=r"out_dir=.*is a file"):
        render_vista_to_folder(world, "A_door", blocker, size=SMALL)
    assert blocker.read_text() == "keep me"
    assert _listing(tmp_path) == ["frames"]


def test_a_folder_under_a_file_is_refused(world: World, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(InputError, match=r"out_dir=.*lies under"):
        render_vista_to_folder(world, "A_door", blocker / "inside" / "deeper", size=SMALL)
    assert _listing(tmp_path) == ["file"]


def test_a_folder_in_the_way_of_an_output_file_is_refused_before_writing(
    world: World, tmp_path: Path
) -> None:
    (tmp_path / "A_door_inspection_depth_m.tif").mkdir()
    with pytest.raises(InputError, match=r"out_dir=.*A_door_inspection_depth_m.tif"):
        render_vista_to_folder(world, "A_door", tmp_path, size=SMALL)
    assert _listing(tmp_path) == ["A_door_inspection_depth_m.tif"]


@pytest.mark.parametrize("out_dir", [None, 3, ""])
def test_an_output_folder_that_is_no_path_is_refused(world: World, out_dir: object) -> None:
    with pytest.raises(InputError, match="out_dir"):
        render_vista_to_folder(world, "A_door", out_dir, size=SMALL)  # type: ignore[arg-type]


def test_an_unknown_vista_creates_no_folder(world: World, tmp_path: Path) -> None:
    with pytest.raises(InputError, match="vista"):
        render_vista_to_folder(world, "nowhere", tmp_path / "new", size=SMALL)
    assert _listing(tmp_path) == []


def test_a_write_that_fails_midway_leaves_nothing_half_written(
    world: World, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    real_write = rsi.imaging.io.write_image
    written: list[str] = []

    def write_then_fill_the_disk(path: os.PathLike[str], image: np.ndarray) -> None:
        if len(written) == 2:
            raise OSError(28, "No space left on device")
        real_write(path, image)
        written.append(os.fspath(path))

    monkeypatch.setattr(rsi.imaging.io, "write_image", write_then_fill_the_disk)
    existing, new = tmp_path / "existing", tmp_path / "new" / "deeper"
    existing.mkdir()
    for folder in (existing, new):
        with pytest.raises(InputError, match=r"out_dir=.*No space left on device"):
            render_vista_to_folder(world, "A_door", folder, size=SMALL)
        written.clear()
    assert _listing(tmp_path) == ["existing"]  # no frame without its truth, no staging, no created folder


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_refused(world: World, tmp_path: Path) -> None:
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        with pytest.raises(InputError, match=r"out_dir=.*not writable"):
            render_vista_to_folder(world, "A_door", locked, size=SMALL)
    finally:
        locked.chmod(0o700)


def test_a_good_folder_gets_every_file_and_no_staging(world: World, tmp_path: Path) -> None:
    paths = render_vista_to_folder(world, "A_door", tmp_path / "new" / "deeper", size=SMALL)
    assert _listing(tmp_path / "new" / "deeper") == sorted(path.name for path in paths.values())
