"""The mission's planning, viewing, transit and proximity-demo functions, the parallax prediction, the plan's
report section and the simulator's obstacle and size helpers under hostile arguments (issue 17): 1,000
generated calls of each public function and class.

Each argument is drawn from :data:`hostile_values.HOSTILE_FAST` or, one time in :data:`RARE` + 1, a valid
value (a world with the arm, a vista, a plan candidate, a loop trace...), so most calls must be refused and a
few run for real. Functions that run for seconds when every argument is valid (:data:`REFUSED_ONLY`: a plan
generation, a transit, a closed-loop scenario) get only calls with at least one argument drawn from values
they must refuse, and must refuse them within :data:`REFUSED_FAST_S`. Calls are drawn :data:`PER_EXAMPLE` to
a hypothesis example (hypothesis costs about 1 ms an example).

The last test walks the whole package: every public callable of every module is fuzzed by one of the hostile
suites, or its module declares no public API (an empty ``__all__``: the mission's internals, called only by
``run_mission`` and ``run_batch`` with values they built and checked).
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import pkgutil
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, is_typeddict

import numpy as np
import pytest
from hostile_values import HOSTILE_FAST, call_tracked
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import rsi
from rsi.errors import InputError
from rsi.imaging import parallax
from rsi.imaging.compensation import Compensated
from rsi.mission import coverage as coverage_module
from rsi.mission import plan_cad, proximity_demo, records, transit, viewing
from rsi.mission.plan_point import PlanPoint
from rsi.report import plan as report_plan
from rsi.sim import arm as sim_arm
from rsi.sim import world as sim_world
from rsi.sim.anomalies import MissingScrew
from rsi.sim.world import World

MODULES = (
    "rsi.imaging.parallax",
    "rsi.report.plan",
    "rsi.mission.records",
    "rsi.mission.plan_point",
    "rsi.mission.coverage",
    "rsi.mission.plan_cad",
    "rsi.mission.transit",
    "rsi.mission.viewing",
    "rsi.mission.proximity_demo",
)
EXTRAS: dict[str, Callable[..., Any]] = {
    "rsi.sim.arm.Wall": sim_arm.Wall,
    "rsi.sim.arm.SteppedSurface": sim_arm.SteppedSurface,
    "rsi.sim.arm.CurvedSurface": sim_arm.CurvedSurface,
    "rsi.sim.arm.arm_mjcf": sim_arm.arm_mjcf,
    "rsi.sim.world.frame_size": sim_world.frame_size,
    "rsi.sim.world.arm_home_tool_tip_m": sim_world.arm_home_tool_tip_m,
}
REFUSED_ONLY = {
    "rsi.mission.plan_cad.generate_plan",
    "rsi.mission.plan_cad.candidate_vistas",
    "rsi.mission.plan_cad.weigh_candidates",
    "rsi.mission.plan_cad.ik_reaches",
    "rsi.mission.coverage.coverage",
    "rsi.mission.coverage.Sight",
    "rsi.mission.transit.transit",
    "rsi.mission.proximity_demo.simulate_proximity_demo",
    "rsi.mission.proximity_demo.full_push",
    "rsi.mission.proximity_demo.servo_approach",
    "rsi.mission.proximity_demo.follow_surface",
    "rsi.mission.proximity_demo.reading_sweep",
}
"""0.4 s to seconds a call when every argument is valid: a plan, every candidate view of a mock-up, a ray-cast
coverage, a transit, a loop scenario (tests/mission runs each for real)."""
CASES = 1000
PER_EXAMPLE = 10
RARE = 2
RARER = {"rsi.mission.proximity_demo.contour_scan": 6, "rsi.mission.proximity_demo.law_response": 6}
"""Valid values less often where a valid call takes 0.1 s (a whole profile, a law's response to a trace)."""
TIME_LIMIT_S = 20.0
REFUSED_FAST_S = 0.5
"""Most a refused call of :data:`REFUSED_ONLY` may take: the checks come before the simulation."""


def _public(module_name: str) -> Iterator[tuple[str, Callable[..., Any]]]:
    """The module's public functions and checked classes (``__all__``), as the other suites list them."""
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None)
    if names is None:
        names = [name for name in vars(module) if not name.startswith("_")]
    for name in names:
        obj = getattr(module, name)
        if getattr(obj, "__module__", None) != module_name or not _is_entry_point(obj):
            continue
        yield f"{module_name}.{name}", obj


def _is_entry_point(obj: object) -> bool:
    """A function, or a class that checks what it is built from (records and protocols are not)."""
    if not callable(obj):
        return False
    if inspect.isclass(obj):
        if issubclass(obj, BaseException) or getattr(obj, "_is_protocol", False) or is_typeddict(obj):
            return False
        is_enum = hasattr(obj, "__members__")
        return not is_enum and not (dataclasses.is_dataclass(obj) and not hasattr(obj, "__post_init__"))
    return True


SURFACE = {**dict(item for module in MODULES for item in _public(module)), **EXTRAS}


# ------------------------------------------------------------------------------------------- valid values


@pytest.fixture(scope="module")
def valid(world: World) -> dict[str, st.SearchStrategy[Any]]:
    """One valid value per parameter name, built once on the suite's world (drawn one time in RARE + 1)."""
    mockup = world.mockup
    point = world.vista("A_door")
    rules = coverage_module.CoverageRules()
    pose = viewing.viewing_pose(world, "A_door")
    trace = proximity_demo.full_push(rng=0).trace
    scenario = proximity_demo.servo_approach(rng=0)
    candidate = plan_cad.Candidate(point, 0.0, np.arange(3), True, "surface")
    images = np.random.default_rng(0).random((2, 40, 48)) * 100.0
    compensated = Compensated(
        image=images[0].astype(np.float32),
        variance=np.ones((40, 48), np.float32),
        valid=np.ones((40, 48), bool),
        interpolation_variance=np.zeros((40, 48), np.float32),
        row_step=1,
    )
    fit = parallax.fit_parallax(images[0], images[0], np.full((40, 48), 0.5))
    times = np.linspace(0.0, 2.0, 50)
    return {
        "world": st.just(world),
        "arm_world": st.just(world),
        "mockup": st.just(mockup),
        "source": st.just(mockup),
        "rules": st.just(rules),
        "vista": st.sampled_from(["A_door", "C_panel"]),
        "point": st.just(point),
        "first": st.just(point),
        "second": st.just(world.vista("C_panel")),
        "points": st.just([point, world.vista("C_panel")]),
        "doors": st.just([0.0, 0.0]),
        "start_m": st.just((0.9, -1.0, 1.0)),
        "pose": st.just(pose),
        "forward": st.just((0.0, 1.0, 0.0)),
        "up": st.just((0.0, 0.0, 1.0)),
        "rows": st.integers(1, 2048),
        "candidates": st.just([candidate]),
        "area": st.just(np.ones(3)),
        "target": st.floats(0.1, 1.0),
        "door_angle_rad": st.just(0.0),
        "door_open_rad": st.just(1.0),
        "standoff_m": st.floats(0.3, 0.6),
        "nearest_m": st.none(),
        "trace": st.just(trace),
        "scenario": st.just(scenario),
        "delay_s": st.floats(0.0, 0.1),
        "law": st.just(proximity_demo.ARM_LAW),
        "mode": st.sampled_from(["avoidance", "servo"]),
        "time_s": st.just(times),
        "distance_m": st.just(0.5 + 0.01 * np.exp(-times)),
        "error_m": st.just(np.zeros(50)),
        "discontinuity": st.just(np.zeros(50, bool)),
        "samples_to_recover": st.integers(0, 9),
        "command_m_s": st.just(np.sin(times)),
        "figures": st.just(None),
        "reference": st.sampled_from([images[0], compensated]),
        "inspection": st.just(images[1]),
        "range_m": st.just(np.full((40, 48), 0.5)),
        "fit": st.just(fit),
        "kind": st.sampled_from(["impact", "hot_spot"]),
        "anomaly": st.just(MissingScrew("s1", (0.9, -0.5, 1.2), (0.0, -1.0, 0.0), 6e-3, "aluminium")),
        "picture": st.just(np.zeros((30, 40, 3), np.uint8)),
        "points_m": st.just(np.array([[0.9, -0.47, 1.2]])),
        "covered": st.just(np.array([True])),
        "plan": st.just((PlanPoint("A_door", "A_door"),)),
        "distance": st.floats(0.1, 1.0),
        "size": st.just((24, 32)),
        "rng": st.integers(0, 9),
    }


def _arguments(
    function: Callable[..., Any], valid: dict[str, st.SearchStrategy[Any]], rare: int = RARE
) -> st.SearchStrategy:
    """Each parameter hostile, or one time in `rare` + 1 a valid value (the table's, else its default)."""
    drawn = {}
    for parameter in inspect.signature(function).parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        good = valid.get(parameter.name)
        if good is None and parameter.default is not inspect.Parameter.empty:
            good = st.just(parameter.default)
        drawn[parameter.name] = st.one_of(*[HOSTILE_FAST] * rare, *([good] if good is not None else []))
    return st.fixed_dictionaries(drawn)


# Values no parameter of REFUSED_ONLY takes: one of them in a call makes it certainly refused.
NEVER_VALID = st.sampled_from([object(), {1, 2}, b"\x00\xff", np.empty((2, 2), dtype=object)])
NOT_CHECKED = {"label", "stage"}  # transit records them as given (str of anything)


def _refused_arguments(
    function: Callable[..., Any], valid: dict[str, st.SearchStrategy[Any]]
) -> st.SearchStrategy:
    """:func:`_arguments`, with one checked parameter (drawn) given a value no parameter takes."""
    names = [name for name in inspect.signature(function).parameters if name not in NOT_CHECKED]
    return st.tuples(_arguments(function, valid), st.sampled_from(names), NEVER_VALID).map(
        lambda drawn: {**drawn[0], drawn[1]: drawn[2]}
    )


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("qualified_name", sorted(SURFACE))
def test_a_mission_function_lets_only_named_errors_escape(
    qualified_name: str,
    valid: dict[str, st.SearchStrategy[Any]],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.chdir(tmp_path)  # whatever a call writes lands here
    function = SURFACE[qualified_name]
    refused_only = qualified_name in REFUSED_ONLY
    rare = RARER.get(qualified_name, RARE)
    draw = _refused_arguments(function, valid) if refused_only else _arguments(function, valid, rare)

    @settings(
        max_examples=CASES // PER_EXAMPLE,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.lists(draw, min_size=PER_EXAMPLE, max_size=PER_EXAMPLE))
    def check(calls: list[dict[str, Any]]) -> None:
        for arguments in calls:
            problem, returned, took = call_tracked(function, arguments, limit_s=TIME_LIMIT_S)
            assert not problem, f"{qualified_name}({', '.join(arguments)}): {problem}"
            if refused_only:
                assert not returned, f"{qualified_name} accepted {arguments!r}"
                assert took < REFUSED_FAST_S, f"{qualified_name} took {took:.2f} s to refuse {arguments!r}"

    check()


# ------------------------------------------------------------------------- every public callable, fuzzed


def _package_surface() -> set[str]:
    """Every public callable of every public module of rsi (``__all__`` where a module has one)."""
    found = set()
    for info in pkgutil.walk_packages(rsi.__path__, "rsi."):
        if any(part.startswith("_") for part in info.name.split(".")[1:]):
            continue
        found |= {name for name, _ in _public(info.name)}
    return found


def _fuzzed_elsewhere() -> set[str]:
    import test_hostile_api
    import test_hostile_report
    import test_hostile_web
    import test_hostile_world

    return (
        set(test_hostile_api.SURFACE)
        | set(test_hostile_api.SLOW)  # each has its own test: a whole simulation or cluster per call
        | set(test_hostile_api.RECORDS)  # results rsi builds from checked values
        | set(test_hostile_report.SURFACE)
        | test_hostile_web.FUZZED
        | test_hostile_world.FUZZED
    )


def test_every_public_callable_of_the_package_is_fuzzed() -> None:
    # the CLI's commands are run by test_hostile_cli.py through typer, each with its options
    missing = {name for name in _package_surface() - set(SURFACE) - _fuzzed_elsewhere()}
    missing = {name for name in missing if not name.startswith("rsi.cli.")}
    assert not missing, f"public callables no hostile suite calls: {sorted(missing)}"


def test_the_walk_sees_a_public_function_and_skips_an_internal_module() -> None:
    surface = _package_surface()
    assert "rsi.mission.plan_cad.generate_plan" in surface
    assert "rsi.imaging.registration.register" in surface
    assert not any(name.startswith("rsi.mission.evidence.") for name in surface)
    assert importlib.import_module("rsi.mission.evidence").__all__ == []


# ------------------------------------------------------------------ each refusal added for this suite


def _refusals(world: World) -> list[tuple[Callable[..., Any], dict[str, Any], str]]:
    """(function, arguments, what the message must say): one per check this suite made."""
    point = world.vista("A_door")
    image = np.ones((30, 30))
    scenario = proximity_demo.servo_approach(rng=0)
    return [
        (viewing.world_arm, {"world": "w"}, "world must be a World"),
        (viewing.look_rotation, {"forward": (0, 0, 0), "up": (0, 0, 1)}, "forward must be a non-zero"),
        (viewing.look_rotation, {"forward": (0, 0, 1), "up": (0, 0, 2)}, "up must not be parallel"),
        (viewing.focal_px, {"rows": 0}, r"rows must be an integer in \[1, 1048576\]"),
        (viewing.pose_of, {"world": world, "point": "A_door"}, "point must be a Vista"),
        (viewing.reach_pose, {"world": world, "pose": None}, "pose must be a ViewingPose"),
        (viewing.reach_vistas, {"world": world, "points": point}, "points must be a list of Vista"),
        (viewing.expected_ranges_m, {"world": world, "pose": 1}, "pose must be a ViewingPose"),
        (plan_cad.candidate_vistas, {"mockup": world, "rules": None}, "mockup must be a Mockup"),
        (plan_cad.transfer_s, {"first": point, "second": (1, 2, 3)}, "second must be a Vista"),
        (
            plan_cad.tour_order,
            {"points": [point], "doors": [], "start_m": (0, 0, 0)},
            "doors must be a list of 1",
        ),
        (plan_cad.tour_figures, {"points": point, "start_m": (0, 0, 0)}, "points must be a list of Vista"),
        (
            plan_cad.greedy_cover,
            {"candidates": [], "area": np.ones(3), "target": 1.0},
            "at least one Candidate",
        ),
        (
            plan_cad.greedy_cover,
            {
                "candidates": [plan_cad.Candidate(point, 0.0, np.arange(5), True, "s")],
                "area": np.ones(3),
                "target": 1,
            },
            r"candidates\[0\].seen must be sample indices in \[0, 3\)",
        ),
        (plan_cad.greedy_cover, {"candidates": [], "area": -np.ones(3), "target": 1.0}, "area must be"),
        (
            plan_cad.greedy_cover,
            {
                "candidates": [plan_cad.Candidate(point, 0.0, np.arange(2), True, "s")],
                "area": np.ones(3),
                "target": 1,
                "must": np.ones(2, dtype=bool),
            },
            r"must must be a boolean array of one flag per sample \(3\)",
        ),
        (coverage_module.inspectable_items, {"mockup": None}, "mockup must be a Mockup"),
        (transit.approach_law, {"standoff_m": 1e300}, r"standoff_m must be in \(0.0, "),
        (records.scored_type, {"kind": np.zeros(3)}, "kind must be an anomaly or finding kind"),
        (records.counts_towards_recall, {"anomaly": "impact"}, "anomaly must be a Anomaly"),
        (
            proximity_demo.settle_figures,
            {"time_s": [0.0, 1.0], "distance_m": [1.0], "standoff_m": 0.5},
            "same shape",
        ),
        (
            proximity_demo.settle_figures,
            {"time_s": 1.0, "distance_m": 1.0, "standoff_m": 0.5},
            "time_s must be",
        ),
        (
            proximity_demo.following_error_m,
            {"error_m": [0.0], "discontinuity": [True], "samples_to_recover": 1},
            "bool array",
        ),
        (proximity_demo.command_spike_m_s, {"command_m_s": 0.5}, "command_m_s must be a 1-D array"),
        (proximity_demo.reconstruct_contour, {"trace": None, "delay_s": 0.0}, "trace must be a LoopTrace"),
        (proximity_demo.contour_scan, {"scenario": 1, "delay_s": 0.0}, "scenario must be a Scenario"),
        (
            proximity_demo.contour_scan,
            {"scenario": scenario, "delay_s": 1e9},
            "no in-range reading in its scan",
        ),
        (proximity_demo.full_push, {"law": "law"}, "law must be a ProximityLaw"),
        (proximity_demo.servo_approach, {"rng": -1}, "rng seed must be an integer >= 0"),
        (proximity_demo.simulate_proximity_demo, {"progress": 3}, "progress must be None or a callable"),
        (proximity_demo.acceptance, {"figures": {}}, "figures must be a DemoFigures"),
        (
            proximity_demo.law_response,
            {"trace": None, "law": None, "mode": "servo"},
            "trace must be a LoopTrace",
        ),
        (
            parallax.fit_parallax,
            {"reference": image, "inspection": image, "range_m": np.ones(3)},
            "range_m must have",
        ),
        (
            parallax.fit_parallax,
            {"reference": image, "inspection": image, "range_m": image, "gain": math.inf},
            "gain",
        ),
        (
            parallax.fit_parallax,
            {"reference": image, "inspection": image, "range_m": image, "max_iterations": 10**9},
            r"max_iterations must be an integer in \[1, 1000\]",
        ),
        (
            parallax.predict_reference,
            {"reference": image, "fit": None, "range_m": image},
            "reference must be a Compensated",
        ),
        (
            report_plan.coverage_png,
            {"picture": image, "pose": None, "points_m": image, "covered": image},
            "picture must be a uint8",
        ),
        (report_plan.plan_rows, {"result": None}, "result must be a MissionResult"),
        (report_plan.uncovered_rows, {"measured": []}, "measured must be a Coverage"),
    ]


def test_each_added_refusal_names_the_argument_and_the_fix(world: World) -> None:
    for function, arguments, message in _refusals(world):
        with pytest.raises(InputError, match=message):
            function(**arguments)


def test_plan_rows_of_a_run_without_coverage_says_so_instead_of_asserting(world: World) -> None:
    from rsi.mission import MissionResult

    bare = MissionResult.__new__(MissionResult)
    object.__setattr__(bare, "plan_coverage", None)
    with pytest.raises(InputError, match="result has no plan coverage"):
        report_plan.plan_rows(bare)
