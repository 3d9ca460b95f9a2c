"""Every public function and class of the library, called with hostile arguments (issue 17).

Each is called with a mix of defaults, plausible values and hostile ones (beyond-float ints, NaN, inf,
subnormals, text, bytes, paths to devices, ragged or complex or object arrays, wrong objects). Whatever it
gets, it must return, or raise an rsi error, or a ValueError/TypeError naming one of its arguments
(:func:`hostile_values.call_keeps_the_rule`), within a time limit and under the memory cap of conftest.py.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import random
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, is_typeddict

import numpy as np
import pytest
from hostile_values import HOSTILE, call_keeps_the_rule, fast_value
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rsi.archive import Archive, Finding

MODULES = (
    "rsi.sensors.proximity",
    "rsi.sensors.pyrometer",
    "rsi.sensors.gas",
    "rsi.sensors.lamps",
    "rsi.sensors.force_torque",
    "rsi.control.proximity_law",
    "rsi.control.blending",
    "rsi.control.redundancy",
    "rsi.imaging.io",
    "rsi.imaging.camera",
    "rsi.imaging.compensation",
    "rsi.imaging.bracket",
    "rsi.imaging.registration",
    "rsi.imaging.stereo",
    "rsi.detection.detect",
    "rsi.detection.flaw_models",
    "rsi.detection.roc",
    "rsi.detection.pair",
    "rsi.detection.nuisance",
    "rsi.detection.noise",
    "rsi.datasets.demo",
    "rsi.mission.settings",
    "rsi.mission.batch",
    "rsi.mission.batch_manifest",
    "rsi.mission.batch_cluster",
    "rsi.mission.batch_records",
    "rsi.archive.records",
    "rsi.archive.store",
    "rsi.sim.orbit",
    "rsi.sim.fields",
    "rsi.sim.solar_simulator",
    "rsi.sim.anomalies",
    "rsi.sim.capture",
    "rsi.sim.mockup",
    "rsi.datasets.synthetic",
    "rsi.datasets.deeppcb",
    "rsi.datasets.evaluate",
    "rsi.datasets.official",
    "rsi.datasets.pcb_classes",
    "rsi.datasets.pcb_features",
    "rsi.datasets.pcb_learn",
    "rsi.datasets.rendered",
    "rsi.mission.plan",
    "rsi.mission.score",
    "rsi.mission.tally",
    "rsi.units",
)
# Covered elsewhere, not here: each runs a whole simulation or cluster for seconds per call.
SLOW = {"rsi.datasets.demo.simulate_demo", "rsi.mission.batch.run_batch"}
# Result records that hold what rsi computed (built from checked values, never an entry point).
RECORDS = {"rsi.imaging.registration.Registration", "rsi.imaging.camera.Frame"}
EXAMPLES_PER_CALLABLE = 30
"""Calls with HOSTILE's generated arrays (milliseconds each to draw)."""
FAST_CASES = 1000
"""More calls from HOSTILE_FAST's kinds of value (hostile_values.fast_value), PER_EXAMPLE to an example."""
PER_EXAMPLE = 50
TIME_LIMIT_S = 10.0

_TEXTURE = np.random.default_rng(0).random((16, 16)) * 255.0
_PLAUSIBLE = st.one_of(
    st.floats(min_value=0.01, max_value=10.0),
    st.integers(min_value=1, max_value=9),
    st.sampled_from(
        [_TEXTURE, _TEXTURE.astype(np.float32), np.roll(_TEXTURE, 1, axis=1), np.ones(3), np.ones(6) * 0.1]
    ),
    st.sampled_from(["single", "both", "lrt", "translation", "odd", "avoidance", "A_door", "impact"]),
)


def _is_record(obj: object) -> bool:
    """A result dataclass with no checks of its own: built by rsi from checked values, not an entry point."""
    return dataclasses.is_dataclass(obj) and not hasattr(obj, "__post_init__")


def _public(module_name: str) -> Iterator[tuple[str, Callable[..., Any]]]:
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None) or [name for name in vars(module) if not name.startswith("_")]
    for name in names:
        obj = getattr(module, name)
        if getattr(obj, "__module__", None) != module_name or not callable(obj):
            continue
        if inspect.isclass(obj) and (
            issubclass(obj, BaseException) or _is_record(obj) or _is_protocol(obj) or is_typeddict(obj)
        ):
            continue
        if f"{module_name}.{name}" not in SLOW | RECORDS:
            yield f"{module_name}.{name}", obj


def _is_protocol(cls: type) -> bool:
    return bool(getattr(cls, "_is_protocol", False))


SURFACE = dict(item for module in MODULES for item in _public(module))


def _argument(parameter: inspect.Parameter) -> st.SearchStrategy[Any]:
    if parameter.name == "name":  # a validator's label for its messages, not data
        return st.sampled_from(["value", "distance_m"])
    if "bool" in str(parameter.annotation) and "|" not in str(parameter.annotation):
        return st.booleans()  # Python's own truthiness is the contract of a flag
    options = [HOSTILE, _PLAUSIBLE]
    if parameter.default is not inspect.Parameter.empty:
        options.append(st.just(parameter.default))
    return st.one_of(*options)


def _arguments(function: Callable[..., Any]) -> st.SearchStrategy[dict[str, Any]]:
    parameters = [
        parameter
        for parameter in inspect.signature(function).parameters.values()
        if parameter.kind not in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD, parameter.POSITIONAL_ONLY)
    ]
    return st.fixed_dictionaries({parameter.name: _argument(parameter) for parameter in parameters})


def test_the_suite_generates_at_least_a_thousand_cases_of_each_callable() -> None:
    assert EXAMPLES_PER_CALLABLE + FAST_CASES >= 1000
    front_doors = {
        "rsi.imaging.registration.register",
        "rsi.detection.detect.detect",
        "rsi.imaging.io.read_image",
        "rsi.detection.pair.inspect_pair",
        "rsi.mission.batch_manifest.read_manifest",
        "rsi.archive.store.Archive",
    }
    assert front_doors <= set(SURFACE)


# The report of a failing case may print a large array: hypothesis warns about the repr's size.
@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("qualified_name", sorted(SURFACE))
def test_a_public_callable_lets_only_named_errors_escape(
    qualified_name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # whatever a call writes (an archive, an image) lands here
    _fuzz(SURFACE[qualified_name], qualified_name)
    _fuzz_fast(SURFACE[qualified_name], qualified_name)


_PLAUSIBLE_VALUES = (
    0.01, 0.5, 1.0, 3.0, 10.0, 1, 2, 3, 9,
    _TEXTURE, _TEXTURE.astype(np.float32), np.roll(_TEXTURE, 1, axis=1), np.ones(3), np.ones(6) * 0.1,
    "single", "both", "lrt", "translation", "odd", "avoidance", "A_door", "impact",
)  # fmt: skip
"""_PLAUSIBLE's values, prebuilt for the fast calls."""


def _fast_arguments(function: Callable[..., Any], draw: random.Random) -> dict[str, Any]:
    """Each parameter hostile (two times in four), a plausible value, or its default, from `draw`."""
    arguments = {}
    for parameter in inspect.signature(function).parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD, parameter.POSITIONAL_ONLY):
            continue
        pick = draw.randrange(4)
        if pick == 3 and parameter.default is not inspect.Parameter.empty:
            arguments[parameter.name] = parameter.default
        elif pick == 2:
            arguments[parameter.name] = draw.choice(_PLAUSIBLE_VALUES)
        else:
            arguments[parameter.name] = fast_value(draw)
    return arguments


def _fuzz_fast(function: Any, label: str) -> None:
    """FAST_CASES generated calls of `function` from prebuilt values, each keeping the rule."""

    @settings(
        max_examples=FAST_CASES // PER_EXAMPLE,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.randoms(use_true_random=True))  # a seeded random.Random: microseconds a value
    def check(draw: random.Random) -> None:
        for _ in range(PER_EXAMPLE):
            arguments = _fast_arguments(function, draw)
            problem = call_keeps_the_rule(function, arguments, limit_s=TIME_LIMIT_S)
            assert not problem, f"{label}({_shown(arguments)}): {problem}"

    check()


def _shown(arguments: dict[str, Any]) -> str:
    return ", ".join(f"{name}={value!r}"[:120] for name, value in arguments.items())


def _fuzz(function: Any, label: str) -> None:
    """EXAMPLES_PER_CALLABLE generated calls of `function`, each keeping the rule (only named errors)."""

    @settings(
        max_examples=EXAMPLES_PER_CALLABLE,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(_arguments(function))
    def check(arguments: dict[str, Any]) -> None:
        problem = call_keeps_the_rule(function, arguments, limit_s=TIME_LIMIT_S)
        assert not problem, f"{label}({', '.join(arguments)}): {problem}"

    check()


# --------------------------------------------------------------------------------------- the archive

ARCHIVE_METHODS = (
    "open",  # the front door (a classmethod): hostile paths, URLs, flags and timeouts
    "add_vista",
    "vista",
    "store_image",
    "image",
    "store_reference",
    "reference",
    "reference_info",
    "start_run",
    "finish_run",
    "run",
    "runs",
    "findings",
    "finding",
    "history",
    "add_findings",
    "export_run",
)


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Archive]:
    with Archive.open(tmp_path_factory.mktemp("hostile") / "archive.db") as store:
        store.add_vista("A_door")
        run_id = store.start_run(seed=1)
        store.add_findings(run_id, [Finding("A_door", "impact", 0.5, bbox=(0, 0, 2, 2))])
        yield store


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("method", ARCHIVE_METHODS)
def test_an_archive_method_lets_only_named_errors_escape(
    archive: Archive, method: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)
    _fuzz(getattr(archive, method), f"Archive.{method}")
    _fuzz_fast(getattr(archive, method), f"Archive.{method}")
