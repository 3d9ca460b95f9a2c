"""The MuJoCo world, the arm, the renderer, the sun and the mission's entry points under hostile arguments
(issue 17): 1,000 generated calls of each public method and function that takes arguments.

One world (with the arm) is loaded for the module and every method is called on it. Each argument is drawn
from :data:`hostile_values.HOSTILE_FAST` or, less often, a valid value, so most calls must be refused and a
few run for real (frames at 24 x 32). The rule of :func:`hostile_values.call_keeps_the_rule` holds for
every call, and a refused call must have rendered nothing: the checks come before the expensive work.
``load`` and ``run_mission`` get only calls with at least one bad argument, each refused fast.
"""

from __future__ import annotations

import functools
import inspect
from collections.abc import Callable, Iterator, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hostile_values import HOSTILE_FAST, call_keeps_the_rule, call_tracked
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rsi.sim
from rsi.errors import InputError
from rsi.mission import run_mission, score_mission
from rsi.mission.sun import (
    lab_world_from_lvlh,
    lamp_light_direction,
    lamp_move_s,
    light_by_sun,
    pass_starts,
    sun_setting,
)
from rsi.mission.tour import Tour
from rsi.sensors.gas import MosGasSensor
from rsi.sensors.pyrometer import Pyrometer
from rsi.sim import render as render_module
from rsi.sim import world as world_module
from rsi.sim.arm import HOME_Q, Arm, Wall, add_obstacle, arm_spec, attach_arm, track_path
from rsi.sim.render import SceneRenderer
from rsi.sim.solar_simulator import LampMount, RateLimits
from rsi.sim.world import World

CASES = 1000
PER_EXAMPLE = 10
"""Calls drawn in one hypothesis example: hypothesis costs about 1 ms an example however cheap the call."""
TIME_LIMIT_S = 20.0
REFUSED_FAST_S = 0.5
"""Most a refused load or run_mission may take: a world takes ~1.5 s to build and a mission minutes."""
FUZZED = {
    f"{function.__module__}.{function.__qualname__}"
    for function in (
        rsi.sim.load,
        world_module.load,
        World,
        Arm,
        add_obstacle,
        arm_spec,
        attach_arm,
        track_path,
        SceneRenderer,
        render_module.backend_name,
        render_module.import_mujoco,
        lab_world_from_lvlh,
        lamp_light_direction,
        lamp_move_s,
        light_by_sun,
        pass_starts,
        sun_setting,
        Tour,
        run_mission,
        score_mission,
    )
}
"""Qualified names of the functions and classes this suite calls (with the World's, the Arm's and the
renderer's methods); test_hostile_mission.py checks the whole package against it."""

Strategies = Mapping[str, st.SearchStrategy[Any]]


def _settings(cases: int) -> settings:
    return settings(max_examples=cases, deadline=None, database=None, suppress_health_check=list(HealthCheck))


class Renders:
    """Counts the frames the renderer finishes (a refused call must have finished none)."""

    count = 0


@pytest.fixture(scope="module", autouse=True)
def _counted_renders() -> Iterator[None]:
    originals = {name: getattr(SceneRenderer, name) for name in ("rgb", "depth_and_segments")}

    def counted(method: Callable[..., Any]) -> Callable[..., Any]:
        @functools.wraps(method)
        def wrapper(*args: Any, **kwargs: Any) -> Any:
            result = method(*args, **kwargs)
            Renders.count += 1
            return result

        return wrapper

    with pytest.MonkeyPatch.context() as patch:
        for name, method in originals.items():
            patch.setattr(SceneRenderer, name, counted(method))
        yield


def _arguments(function: Callable[..., Any], valid: Strategies, *, rare: int) -> st.SearchStrategy[dict]:
    """Each parameter hostile, or one time in `rare` + 1 a valid value (`valid`, else its default)."""
    drawn = {}
    for parameter in inspect.signature(function).parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        good = valid.get(parameter.name)
        if good is None and parameter.default is not inspect.Parameter.empty:
            good = st.just(parameter.default)
        options = [HOSTILE_FAST] * rare + ([good] if good is not None else [])
        drawn[parameter.name] = st.one_of(*options)
    return st.fixed_dictionaries(drawn)


def _fuzz(function: Callable[..., Any], label: str, valid: Strategies, *, rare: int = 1) -> None:
    """CASES calls of `function`, each keeping the rule; a refused one must have rendered nothing."""

    @_settings(CASES // PER_EXAMPLE)
    @given(st.lists(_arguments(function, valid, rare=rare), min_size=PER_EXAMPLE, max_size=PER_EXAMPLE))
    def check(calls: list[dict[str, Any]]) -> None:
        for arguments in calls:
            before = Renders.count
            problem, returned, _ = call_tracked(function, arguments, limit_s=TIME_LIMIT_S)
            if not problem and not returned and Renders.count > before:
                problem = f"refused after rendering {Renders.count - before} frame(s): check first"
            assert not problem, f"{label}({', '.join(arguments)}): {problem}"

    check()


# ------------------------------------------------------------------------------------------ the world

SPOT_M = (0.9, -0.47, 1.2)
SIZE = (24, 32)


def _world_values(world: World) -> dict[str, st.SearchStrategy[Any]]:
    point = world.vista("A_door")
    site = world.mockup.candidates.peltier_sites[0]
    return {
        "point": st.sampled_from([point, replace(point, name="hostile_extra")]),
        "name": st.sampled_from(world.vistas),
        "vista": st.sampled_from(world.vistas),
        "configuration": st.just(world.lamp),
        "spot_world_m": st.just(SPOT_M),
        "light_from": st.just((0.3, -1.0, 0.2)),
        "intensity_lux": st.just(1950.0),
        "on": st.booleans(),
        "angle_rad": st.floats(0.0, 1.92),
        "factor": st.floats(0.1, 8.0),
        "fraction": st.floats(0.2, 1.0),
        "position_m": st.just((0.9, -1.0, 1.2)),
        "forward": st.just((0.0, 1.0, 0.0)),
        "up": st.just((0.0, 0.0, 1.0)),
        "points_m": st.just(np.array([SPOT_M, (0.5, -0.5, 1.0)])),
        "time_s": st.floats(0.0, 100.0),
        "site": st.just(site),
        "standoff_m": st.just(0.3),
        "pyrometer": st.just(Pyrometer()),
        "sensor": st.just(MosGasSensor()),
        "rng": st.just(np.random.default_rng(0)),
        "camera": st.just("isee"),
        "size": st.just(SIZE),
        "state": st.sampled_from(["inspection", "reference"]),
        "stereo": st.booleans(),
        "truth": st.booleans(),
        "own_body": st.booleans(),
        "jaw_opening_m": st.sampled_from([None, 0.0, 0.04, 0.08]),
        "lit_field": st.sampled_from(["odd", "even"]),
        "exposure_s": st.sampled_from([None, 1e-4]),
        "unsensed_offset_m": st.just((0.0, 0.0)),
        "strobe_energy": st.floats(0.5, 2.0),
        "shutter": st.floats(0.2, 1.0),
        "key": st.sampled_from(["reference/A_door/0", "inspection/B_tank/1"]),
    }


# Methods that render: valid arguments one time in RARE_RENDER + 1 each, so a few hundredths of the calls run.
RENDERING = {
    "render": 4,
    "render_from_tool": 4,
    "basis": 6,
    "render_all_lights": 4,
    "overview": 3,
    "overview_picture": 3,
    "cad_projection": 3,
    "own_body_footprint": 3,
}
WORLD_METHODS = (
    "add_vista",
    "vista",
    "set_lamp",
    "aim_lamp",
    "switch_lamp",
    "set_door",
    "set_strobe_energy",
    "set_shutter",
    "set_halogen",
    "place_camera",
    "temperature_k",
    "gas_concentration_ppm",
    "read_pyrometer",
    "read_gas",
    "set_fast_rendering",
    "basis",
    "render_all_lights",
    "render",
    "render_from_tool",
    "cad_projection",
    "own_body_footprint",
    "next_frame",
    "reflash",
    "ambient_frame",
    "other_strobe_frames",
    "overview",
    "overview_picture",
    "begin_visit",
)
# Without arguments: one call each is the whole input space.
WORLD_READOUTS = ("readouts", "close")


def test_every_public_world_method_is_fuzzed() -> None:
    public = {
        name
        for name, member in vars(World).items()
        if not name.startswith("_") and inspect.isfunction(member)
    }
    assert public == set(WORLD_METHODS) | set(WORLD_READOUTS)


@pytest.fixture(scope="module")
def view(world: World) -> Any:
    return world.render("A_door", size=SIZE, stereo=True)


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("method", WORLD_METHODS)
def test_a_world_method_lets_only_named_errors_escape(
    world: World, view: Any, method: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    valid = {**_world_values(world), "view": st.just(view), "pose": st.just(view.believed_pose)}
    _fuzz(getattr(world, method), f"World.{method}", valid, rare=RENDERING.get(method, 1))


@pytest.mark.parametrize("method", WORLD_READOUTS)
def test_a_world_readout_keeps_the_rule(world: World, method: str) -> None:
    assert not call_keeps_the_rule(getattr(world, method), {}, limit_s=TIME_LIMIT_S)


def test_a_world_without_an_arm_names_the_fix(world: World) -> None:
    bare = World.__new__(World)
    bare._arm = None
    problem = call_keeps_the_rule(lambda: bare.arm, {}, limit_s=TIME_LIMIT_S)
    assert not problem


# -------------------------------------------------------------------------------------------- the arm

ARM_METHODS = (
    "reset",
    "random_configuration",
    "camera_pose",
    "camera_name",
    "site_position_m",
    "step_velocity",
    "set_jaw_opening",
)
ARM_READOUTS = (
    "tool_pose",
    "jacobian",
    "arm_angle_rad",
    "arm_angle_jacobian",
    "rangefinder_distances_m",
    "force_torque",
)
_ARM_VALUES: dict[str, st.SearchStrategy[Any]] = {
    "joint_positions": st.sampled_from([None, HOME_Q]),
    "jaw_opening_m": st.floats(0.0, 0.08),
    "opening_m": st.floats(0.0, 0.08),
    "rng": st.integers(0, 9),
    "margin": st.floats(0.0, 0.4),
    "camera": st.sampled_from(["left", "right"]),
    "name": st.sampled_from(["tool", "elbow", "range_left"]),
    "twist_or_velocity": st.sampled_from([np.zeros(6), np.array([0.01, 0.0, 0.0])]),
    "dt_s": st.just(1 / 44),
    "additional_task_rate": st.just(0.0),
    "frame": st.sampled_from(["world", "tool"]),
}


def test_every_public_arm_method_is_fuzzed() -> None:
    public = {
        name for name, member in vars(Arm).items() if not name.startswith("_") and inspect.isfunction(member)
    }
    assert public == set(ARM_METHODS) | set(ARM_READOUTS)


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("method", ARM_METHODS)
def test_an_arm_method_lets_only_named_errors_escape(world: World, method: str) -> None:
    _fuzz(getattr(world.arm, method), f"Arm.{method}", _ARM_VALUES)
    world.arm.reset()


@pytest.mark.parametrize("method", ARM_READOUTS)
def test_an_arm_readout_keeps_the_rule(world: World, method: str) -> None:
    assert not call_keeps_the_rule(getattr(world.arm, method), {}, limit_s=TIME_LIMIT_S)


def _arm_made(**kwargs: Any) -> None:
    Arm(**kwargs)


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_arm_construction_and_binding_let_only_named_errors_escape(world: World) -> None:
    values = {
        "obstacles": st.sampled_from([(), (Wall(0.3),)]),
        "mode": st.sampled_from(["kinematic", "servo"]),
        "settings": st.none(),
        "position_gain": st.sampled_from([None, 0.5]),
        "model": st.just(world.model),
        "data": st.just(world.data),
        "prefix": st.just("arm_"),
    }
    _fuzz(functools.wraps(Arm)(_arm_made), "Arm", values, rare=3)
    _fuzz(Arm.bind, "Arm.bind", values, rare=2)
    world.arm.reset()


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_the_arm_model_builders_let_only_named_errors_escape() -> None:
    values = {
        "spec": st.builds(arm_spec),
        "obstacle": st.just(Wall(0.3)),
        "obstacles": st.sampled_from([(), (Wall(0.3),)]),
        "name": st.just("wall"),
        "home_tool_tip_m": st.just((0.9, -1.0, 1.0)),
        "prefix": st.sampled_from(["a_", "b_"]),
    }
    _fuzz(add_obstacle, "add_obstacle", values, rare=3)
    _fuzz(arm_spec, "arm_spec", values, rare=3)
    _fuzz(attach_arm, "attach_arm", values, rare=3)


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_track_path_lets_only_named_errors_escape() -> None:
    values = {
        "path": st.sampled_from(["line", "circle"]),
        "speed_m_s": st.just(1.0),
        "rate_hz": st.just(20.0),
        "mode": st.just("kinematic"),
        "arm_angle_set_rad": st.none(),
    }
    _fuzz(track_path, "track_path", values, rare=3)


# ------------------------------------------------------------------------------------- the renderer


def test_the_backend_readouts_keep_the_rule() -> None:
    for function in (render_module.backend_name, render_module.import_mujoco):
        assert not call_keeps_the_rule(function, {}, limit_s=TIME_LIMIT_S)


def _renderer_made_and_freed(**kwargs: Any) -> None:
    SceneRenderer(**kwargs).close()


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_the_renderer_lets_only_named_errors_escape(world: World, view: Any) -> None:
    values = {
        "model": st.just(world.model),
        "height": st.just(SIZE[0]),
        "width": st.just(SIZE[1]),
        "show_rangefinders": st.booleans(),
        "fast": st.just(True),
        "data": st.just(world.data),
        "camera": st.just("isee"),
        "state": st.sampled_from(["inspection", "reference"]),
        "lights": st.just((0,)),
        "points_m": st.just(np.array([SPOT_M])),
    }
    _fuzz(functools.wraps(SceneRenderer)(_renderer_made_and_freed), "SceneRenderer", values, rare=3)
    renderer = SceneRenderer(world.model, *SIZE, fast=True)
    try:
        for method in ("rgb", "luminance", "depth_and_segments"):
            _fuzz(getattr(renderer, method), f"SceneRenderer.{method}", values, rare=3)
    finally:
        renderer.close()
    _fuzz(view.believed_pose.project, "CameraPose.project", values)


# ------------------------------------------------------------------------------------ sun and tour


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize(
    "function",
    [sun_setting, light_by_sun, lamp_light_direction, lamp_move_s, pass_starts, lab_world_from_lvlh],
    ids=lambda function: function.__name__,
)
def test_a_sun_function_lets_only_named_errors_escape(world: World, function: Callable[..., Any]) -> None:
    values = {
        "spot_world_m": st.just(SPOT_M),
        "time_s": st.floats(0.0, 6000.0),
        "orbit": st.none(),
        "world_from_lvlh": st.none(),
        "label": st.just("A_door"),
        "stage": st.just("reference"),
        "world": st.just(world),
        "setting": st.just(sun_setting(SPOT_M, 400.0)),
        "first": st.just(world.lamp),
        "second": st.just(world.lamp),
        "rates": st.sampled_from([None, RateLimits()]),
        "start_s": st.just((400.0, 5953.6)),
        "mount": st.sampled_from([None, LampMount()]),
    }
    _fuzz(function, function.__name__, values, rare=2)


def _tour_values(world: World) -> dict[str, st.SearchStrategy[Any]]:
    return {
        "world": st.just(world),
        "seed": st.integers(0, 9),
        "size": st.just(SIZE),
        "arm": st.booleans(),
        "orbit": st.booleans(),
        "stage": st.sampled_from(["reference", "inspection"]),
        "start_s": st.floats(0.0, 6000.0),
        "label": st.just("A_door"),
        "vista": st.sampled_from(["A_door", "C_panel"]),
        "state": st.sampled_from(["inspection", "reference"]),
        "truth": st.booleans(),
        "strobe_energy": st.floats(0.5, 2.0),
        "shutter": st.floats(0.2, 1.0),
        "exposure_s": st.floats(1e-5, 1.0),
    }


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_a_tour_lets_only_named_errors_escape(world: World) -> None:
    values = _tour_values(world)
    _fuzz(Tour, "Tour", values, rare=2)
    tour = Tour(world, seed=0, size=SIZE, arm=False, orbit=False)
    _fuzz(tour.start_pass, "Tour.start_pass", values)
    _fuzz(tour.reflash, "Tour.reflash (before a visit)", values)
    _fuzz(tour.ambient_frame, "Tour.ambient_frame (before a visit)", values)
    _fuzz(tour.other_strobe_frames, "Tour.other_strobe_frames (before a visit)", values)
    _fuzz(tour.visit, "Tour.visit", values, rare=5)
    _fuzz(tour.reflash, "Tour.reflash", values, rare=3)
    _fuzz(tour.ambient_frame, "Tour.ambient_frame", values)
    _fuzz(tour.other_strobe_frames, "Tour.other_strobe_frames", values)


# ---------------------------------------------------------------------- load and the mission, refused


def _is_valid(parameter: str, value: object) -> bool:
    """Whether `value` would pass load's or run_mission's check of `parameter` (the draw avoids those)."""
    if parameter == "seed":
        return isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**63
    if parameter in ("arm", "orbit", "active"):
        return isinstance(value, bool)
    if parameter in ("progress", "on_visit"):
        return value is None or callable(value)
    if parameter in ("scene", "repeatability"):
        return isinstance(value, str) and value in ("truss", "lab", "space")
    return value is None  # settings, anomalies, archive, camera: no valid object among the hostile values


BAD_SIZES = st.sampled_from([(24, 32), (64,), (64, 64, 3), (63, 64), (64.0, 64.0), [64, 64], 64, (2**70, 64)])
BAD_STARTS = st.sampled_from([(-1.0, 0.0), (float("nan"), 1.0), (0.0,), 400.0, (1e400, 0.0), "0,0"])


def _refused_arguments(function: Callable[..., Any]) -> st.SearchStrategy[dict[str, Any]]:
    """Every parameter valid or hostile, and one of them (drawn) certainly refused."""
    names = [name for name in inspect.signature(function).parameters]
    defaults = {name: p.default for name, p in inspect.signature(function).parameters.items()}

    def bad(name: str) -> st.SearchStrategy[Any]:
        if name == "size":
            return BAD_SIZES
        if name == "orbit_start_s":
            return BAD_STARTS
        return HOSTILE_FAST.filter(lambda value: not _is_valid(name, value))

    def any_value(name: str) -> st.SearchStrategy[Any]:
        default = defaults[name]
        valid = st.just(0) if name == "seed" else st.just(default)
        return (
            st.one_of(HOSTILE_FAST, valid)
            if default is not inspect.Parameter.empty or name == "seed"
            else HOSTILE_FAST
        )

    return st.sampled_from(names).flatmap(
        lambda refused: st.fixed_dictionaries(
            {name: bad(name) if name == refused else any_value(name) for name in names}
        )
    )


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
# rsi.sim.world.load: rsi.sim.load passes its keywords through (``**kwargs``), so its signature names none
@pytest.mark.parametrize("function", [world_module.load, run_mission], ids=["load", "run_mission"])
def test_load_and_run_mission_refuse_bad_arguments_before_any_work(function: Callable[..., Any]) -> None:
    @_settings(CASES // PER_EXAMPLE)
    @given(st.lists(_refused_arguments(function), min_size=PER_EXAMPLE, max_size=PER_EXAMPLE))
    def check(calls: list[dict[str, Any]]) -> None:
        for arguments in calls:
            problem, returned, took = call_tracked(function, arguments, limit_s=TIME_LIMIT_S)
            assert not problem, f"{function.__name__}: {problem}"
            assert not returned, f"{function.__name__}({arguments!r}) accepted a bad argument"
            assert took < REFUSED_FAST_S, f"{function.__name__} took {took:.2f} s to refuse {arguments!r}"

    check()


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_score_mission_lets_only_named_errors_escape() -> None:
    _fuzz(score_mission, "score_mission", {})


# ------------------------------------------------------------- each check added for this suite, by hand


def _raises(call: Callable[[], object], match: str) -> None:
    with pytest.raises(InputError, match=match):
        call()


def test_the_world_checks_its_camera_placement_and_sensors(world: World, view: Any) -> None:
    _raises(lambda: world.place_camera(10**400, (0, 1, 0)), r"position_m must be a number")
    _raises(lambda: world.place_camera((0, 0, 1), (0, 0, 0)), r"forward must be a non-zero direction")
    _raises(lambda: world.place_camera((0, 0, 1), (0, 1, 0), None), r"up must be three finite numbers")
    _raises(
        lambda: world.place_camera((0, 0, 1), (0, 0, 1), (0, 0, 2)), r"up=\(0, 0, 2\) is parallel to forward"
    )
    site, good = (
        world.mockup.candidates.peltier_sites[0],
        {"pyrometer": Pyrometer(), "rng": np.random.default_rng(0)},
    )
    _raises(lambda: world.read_pyrometer(None, standoff_m=0.3, **good), r"site must be a Site")
    _raises(
        lambda: world.read_pyrometer(site, standoff_m=-1.0, **good), r"standoff_m must be in \[0.0, inf\]"
    )
    _raises(
        lambda: world.read_pyrometer(site, standoff_m=0.3, pyrometer=1, rng=good["rng"]),
        r"pyrometer must be a Pyrometer",
    )
    _raises(
        lambda: world.read_pyrometer(site, standoff_m=0.3, pyrometer=Pyrometer(), rng=0),
        r"rng must be a Generator",
    )
    _raises(
        lambda: world.gas_concentration_ppm(np.zeros((1, 3)), 10**400), r"time_s must be a number or an array"
    )
    before = Renders.count
    _raises(
        lambda: world.render_from_tool(size=SIZE, unsensed_offset_m=(1.0,)), r"unsensed_offset_m must be two"
    )
    assert Renders.count == before  # refused before any frame
    _raises(lambda: view.believed_pose.project(np.zeros(3)), r"points_m must have shape \(K, 3\)")


def test_a_world_is_built_from_checked_parts(world: World) -> None:
    _raises(lambda: rsi.sim.load("truss", seed=0, camera="ccd"), r"camera must be a CameraModel")
    _raises(lambda: World(None, world.anomalies, seed=0), r"mockup must be a Mockup")  # type: ignore[arg-type]
    _raises(lambda: World(world.mockup, None, seed=0), r"anomalies must be a AnomalySet")  # type: ignore[arg-type]
    _raises(lambda: Tour(None, seed=0, size=SIZE), r"world must be a World")  # type: ignore[arg-type]
    _raises(lambda: Tour(world, seed=0, size=(8, 8)), r"size must be an integer >= 16")


def test_the_arm_checks_its_arguments(world: World) -> None:
    arm = world.arm
    _raises(lambda: arm.reset("home"), r"joint_positions must be a number or an array")
    _raises(lambda: arm.random_configuration("x"), r"rng must be a numpy Generator")
    _raises(lambda: arm.random_configuration(0, margin=0.5), r"margin must be in \[0.0, 0.5\)")
    _raises(lambda: arm.site_position_m(np.zeros(1)), r"name must be one of")
    _raises(lambda: arm.step_velocity("fast", 0.02), r"twist_or_velocity must be a number or an array")
    _raises(lambda: Arm(obstacles=None), r"obstacles must be a tuple of Wall")  # type: ignore[arg-type]
    _raises(lambda: arm_spec(obstacles=Wall(0.3)), r"obstacles must be a tuple of Wall")  # type: ignore[arg-type]
    _raises(lambda: Arm(settings=1), r"settings must be a RedundancySettings")  # type: ignore[arg-type]
    _raises(lambda: Arm.bind(None, world.data), r"model must be a mujoco.MjModel")
    _raises(lambda: Arm.bind(world.model, None), r"data must be the mujoco.MjData of model")
    _raises(lambda: add_obstacle(None, Wall(0.3)), r"spec must be a mujoco.MjSpec")
    _raises(lambda: add_obstacle(arm_spec(), Wall(0.3), name=1), r"name must be a str")  # type: ignore[arg-type]
    _raises(
        lambda: attach_arm(arm_spec(), home_tool_tip_m=(0, 0), prefix="a_"),
        r"home_tool_tip_m must be 3 finite numbers",
    )
    _raises(lambda: attach_arm(arm_spec(), home_tool_tip_m=(0, 0, 0), prefix=1), r"prefix must be a str")  # type: ignore[arg-type]
    _raises(
        lambda: attach_arm(arm_spec(), home_tool_tip_m=(0, 0, 0), prefix=""),
        r"prefix='' gives the arm a name",
    )
    world.arm.reset()


def test_track_path_refuses_a_run_of_hours() -> None:
    _raises(lambda: track_path(rate_hz=2**63), r"rate_hz must be in \(0.0, 1000.0\]")
    _raises(lambda: track_path(speed_m_s=1e-300), r"ask for .* control steps, over 100000")


def test_the_renderer_checks_its_model_size_and_lights(world: World) -> None:
    _raises(lambda: SceneRenderer(None, *SIZE), r"model must be a mujoco.MjModel")
    _raises(lambda: SceneRenderer(world.model, 0, 32), r"height must be an integer in \[1, 2048\]")
    _raises(lambda: SceneRenderer(world.model, 24, 10**400), r"width must be an integer in \[1, 2048\]")
    _raises(lambda: SceneRenderer(world.model, *SIZE, fast=None), r"fast must be True or False")  # type: ignore[arg-type]
    renderer = SceneRenderer(world.model, *SIZE, fast=True)
    try:
        _raises(lambda: renderer.rgb(None, "isee"), r"data must be the mujoco.MjData")
        _raises(lambda: renderer.rgb(world.data, "isee", state="dusk"), r"state='dusk' is not known")
        _raises(
            lambda: renderer.rgb(world.data, "isee", lights=(99,)), r"lights must be a tuple of light ids"
        )
    finally:
        renderer.close()


def test_the_sun_functions_check_their_arguments(world: World) -> None:
    _raises(lambda: sun_setting(SPOT_M, 10**400), r"time_s must be finite")
    _raises(
        lambda: sun_setting(SPOT_M, 0.0, world_from_lvlh=10**400), r"world_from_lvlh must be a 3x3 rotation"
    )
    _raises(lambda: lab_world_from_lvlh(True), r"mount must be a LampMount")  # type: ignore[arg-type]
    setting = sun_setting(SPOT_M, 0.0)
    _raises(lambda: light_by_sun(None, setting), r"world must be a World")  # type: ignore[arg-type]
    _raises(lambda: lamp_light_direction(world, "up"), r"spot_world_m must be a number")
    _raises(lambda: lamp_move_s(None, world.lamp), r"first must be a LampConfiguration")  # type: ignore[arg-type]
    _raises(lambda: lamp_move_s(world.lamp, world.lamp, rates=1), r"rates must be a RateLimits")  # type: ignore[arg-type]
