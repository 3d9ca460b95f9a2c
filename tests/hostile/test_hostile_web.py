"""The operator console's public functions and classes with hostile arguments (issue 17), 1,000 cases each.

The rule of hostile_values.py: return, or raise an rsi error or a ValueError/TypeError naming an argument.
Constructors that start real machinery when given valid arguments (a console's loops and camera process, a
server's app, a camera process, a twin world's renderer) are drawn from hostile values only: the suite checks
that they refuse, by name and at once; tests/web runs them for real. The HTTP routes and the control socket
are fuzzed on the live server in tests/web/test_hostile_routes.py.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hostile_values import HOSTILE_FAST, call_keeps_the_rule
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rsi.sim.world import World
from rsi.web import app, console, live, mission_job, scene, server, teleop, worker

CASES = 1000
PER_EXAMPLE = 10  # calls drawn in one hypothesis example (about 1 ms an example, however cheap the call)
TIME_LIMIT_S = 10.0
Strategies = Mapping[str, st.SearchStrategy[Any]]

# Every public callable of rsi.web, and how the suite calls it.
WITH_VALID_DRAWS = (
    server.console_settings,
    server.check_archive,
    teleop.clamp_operator,
    teleop.teleop_step,
    live.video_message,
    live.AckWindow,
    scene.scene_geometry,
    scene.moving_poses,
    mission_job.MissionJob,
)
REFUSED_ONLY = (  # valid arguments start threads, processes or renderers: tests/web runs those
    console.Console,
    app.create_app,
    app.TokenGate,
    live.LiveCameras,
    worker.CameraProcess,
    teleop.teleop_loop,
    server.serve,
)
WITHOUT_ARGUMENTS = (console.new_client_id, server.websocket_protocol, server.uvicorn_options)
MODULES = (app, console, live, mission_job, scene, server, teleop, worker)
FUZZED = {
    f"{function.__module__}.{function.__qualname__}"
    for function in (*WITH_VALID_DRAWS, *REFUSED_ONLY, *WITHOUT_ARGUMENTS)
}
"""Qualified names of what this suite calls (test_hostile_mission.py checks the whole package against it)."""


def test_every_public_callable_of_the_console_is_fuzzed() -> None:
    public = set()
    for module in MODULES:
        for name in module.__all__:
            obj = getattr(module, name)
            if callable(obj) and not (inspect.isclass(obj) and issubclass(obj, BaseException)):
                public.add(obj)
    records = {live.LiveFrame, live.FrameHub, console.StopEvent, teleop.TeleopStep, server.ConsoleSettings}
    records |= {worker.Shot, live.LiveState}
    assert public - records == set(WITH_VALID_DRAWS) | set(REFUSED_ONLY) | set(WITHOUT_ARGUMENTS)


def _arguments(function: Callable[..., Any], valid: Strategies, *, hostile_only: bool) -> st.SearchStrategy:
    """Each parameter hostile, or (unless `hostile_only`) one time in two a valid value."""
    drawn = {}
    for parameter in inspect.signature(function).parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        good = valid.get(parameter.name)
        if good is None and parameter.default is not inspect.Parameter.empty:
            good = st.just(parameter.default)
        use_good = good is not None and not hostile_only
        drawn[parameter.name] = st.one_of(HOSTILE_FAST, good) if use_good else HOSTILE_FAST
    return st.fixed_dictionaries(drawn)


def _fuzz(function: Callable[..., Any], valid: Strategies, *, hostile_only: bool = False) -> None:
    @settings(
        max_examples=CASES // PER_EXAMPLE,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(
        st.lists(
            _arguments(function, valid, hostile_only=hostile_only), min_size=PER_EXAMPLE, max_size=PER_EXAMPLE
        )
    )
    def check(calls: list[dict[str, Any]]) -> None:
        for arguments in calls:
            problem = call_keeps_the_rule(function, arguments, limit_s=TIME_LIMIT_S)
            assert not problem, f"{function.__qualname__}({', '.join(arguments)}): {problem}"

    check()


def _valid_values(world: World, tmp_path: Path) -> dict[str, st.SearchStrategy[Any]]:
    frame = live.LiveFrame("raw", 1, 0.0, 0.01, b"\xff\xd8\xff")
    loop = teleop.teleop_loop(world.arm, seed=0)
    return {
        "host": st.sampled_from(["127.0.0.1", "::1"]),
        "port": st.integers(0, 65535),
        "archive": st.just(tmp_path / "archive.db"),
        "seed": st.integers(0, 9),
        "layout": st.sampled_from(["truss", "truss-b"]),
        "token": st.sampled_from([None, "a" * 24]),
        "command_m_s": st.sampled_from([np.zeros(3), [0.01, 0.0, -0.01]]),
        "operator_m_s": st.sampled_from([np.zeros(3), [0.0, 0.0, 0.01]]),
        "loop": st.just(loop),
        "held": st.booleans(),
        "frame": st.just(frame),
        "size": st.integers(1, 8),
        "scope": st.just({"headers": [(b"authorization", b"Bearer abc")], "query_string": b"token=x"}),
        "world": st.just(world),
        "step": st.none(),
        "bodies": st.just([1, 2]),
        "archive_path": st.just(tmp_path / "jobs.db"),
        "path": st.just(tmp_path / "checked.db"),
    }


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("function", WITH_VALID_DRAWS, ids=lambda f: f.__qualname__)
def test_a_console_function_lets_only_named_errors_escape(
    function: Callable[..., Any], world: World, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    _fuzz(function, _valid_values(world, tmp_path))
    world.arm.reset()


def _job_started(archive_path: Path, seed: object, setting: object) -> None:
    """MissionJob.start with every setting but the two that would launch a mission."""
    if isinstance(setting, str) and setting in mission_job.SETTINGS and not isinstance(seed, bool):
        return  # a valid setting with a seed in range starts a mission: tests/web launches one
    mission_job.MissionJob(archive_path).start(seed, setting)  # type: ignore[arg-type]


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
def test_a_mission_job_refuses_what_it_cannot_run(tmp_path: Path) -> None:
    valid = {"archive_path": st.just(tmp_path / "jobs.db"), "seed": st.integers(0, 9)}
    _fuzz(_job_started, valid)


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("function", REFUSED_ONLY, ids=lambda f: f.__qualname__)
def test_a_console_constructor_refuses_hostile_arguments_by_name(
    function: Callable[..., Any], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    _fuzz(function, {}, hostile_only=True)


@pytest.mark.parametrize("function", WITHOUT_ARGUMENTS, ids=lambda f: f.__qualname__)
def test_a_console_function_without_arguments_keeps_the_rule(function: Callable[..., Any]) -> None:
    assert not call_keeps_the_rule(function, {}, limit_s=TIME_LIMIT_S)
