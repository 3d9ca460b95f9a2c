"""The report writers and the scene, dent, clearance and proximity-loop builders under hostile arguments
(issue 17): generated calls of every public function of ``rsi.report.*`` and of ``rsi.sim.dent``,
``rsi.sim.clearance``, ``rsi.sim.proximity_loop`` and ``rsi.sim.scene``.

Each argument is drawn from :data:`hostile_values.HOSTILE_FAST` or, less often, its default, so nearly every
call must be refused, fast, by the rule of :func:`hostile_values.call_keeps_the_rule`. Every function gets
:data:`CASES` calls, drawn :data:`PER_EXAMPLE` to a hypothesis example: hypothesis costs about 1 ms an
example however cheap the refusal, and one call to an example would take the 52 functions over a minute.
"""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import os
import stat
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hostile_values import HOSTILE_FAST, call_keeps_the_rule
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rsi.errors import FileError, InputError
from rsi.report import batch as report_batch
from rsi.report import figures, writers
from rsi.report import isee as report_isee
from rsi.report import mission as report_mission
from rsi.report import sim as report_sim
from rsi.sim import clearance, dent, proximity_loop, scene

MODULES = (
    "rsi.report",
    "rsi.report.mission",
    "rsi.report.figures",
    "rsi.report.writers",
    "rsi.report.sim",
    "rsi.report.batch",
    "rsi.report.deeppcb",
    "rsi.report.isee",
    "rsi.sim.dent",
    "rsi.sim.clearance",
    "rsi.sim.proximity_loop",
    "rsi.sim.scene",
)
CASES = 1000
PER_EXAMPLE = 10
"""Calls drawn in one hypothesis example (a failing batch still shrinks, to the one call that broke)."""
TIME_LIMIT_S = 10.0


def _public(module_name: str) -> Iterator[tuple[str, Callable[..., Any]]]:
    """The module's public functions and classes (``__all__``, else its non-underscore names), each once."""
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None) or [name for name in vars(module) if not name.startswith("_")]
    for name in names:
        obj = getattr(module, name)
        home = getattr(obj, "__module__", None)
        if not callable(obj) or not (home or "").startswith(module_name):
            continue
        if inspect.isclass(obj) and getattr(obj, "_is_protocol", False):
            continue  # a Protocol describes what a caller passes; it is never called
        if dataclasses.is_dataclass(obj) and not hasattr(obj, "__post_init__"):
            continue  # a record rsi builds from checked values (as test_hostile_api.py), no entry point
        yield f"{home}.{obj.__qualname__}", obj


SURFACE = dict(item for module in MODULES for item in _public(module))


def _kept_inside(value: object) -> object:
    """A path drawn as text or Path, made relative (so under the test's folder) unless it is /dev/zero.

    The writers create what they are given and the suite may run as root: ``/nonexistent/x`` or a drawn
    ``"/a"`` would be written at the root of the machine. /dev/zero stays, and must be refused: replacing it
    once turned the device into a 4-byte file (``rsi._files.atomic_write_bytes`` now refuses).
    """
    if isinstance(value, (str, Path)) and str(value) != "/dev/zero":
        text = str(value).lstrip("/").replace("..", "__")
        return Path(text) if isinstance(value, Path) else text
    return value


_HOSTILE = HOSTILE_FAST.map(_kept_inside)


def _arguments(function: Callable[..., Any]) -> st.SearchStrategy[dict[str, Any]]:
    """Each parameter hostile, or one time in three its default."""
    drawn = {}
    for parameter in inspect.signature(function).parameters.values():
        if parameter.kind in (parameter.VAR_POSITIONAL, parameter.VAR_KEYWORD):
            continue
        options = [_HOSTILE, _HOSTILE]
        if parameter.default is not inspect.Parameter.empty:
            options.append(st.just(parameter.default))
        drawn[parameter.name] = st.one_of(*options)
    return st.fixed_dictionaries(drawn)


def test_every_listed_function_is_fuzzed() -> None:
    front_doors = {
        "rsi.report.mission.write_mission_report",
        "rsi.report.batch.write_batch_report",
        "rsi.report.writers.write_pair_report",
        "rsi.sim.dent.box_mesh",
        "rsi.sim.scene.build_model",
        "rsi.sim.proximity_loop.run_closed_loop",
        "rsi.sim.clearance.ArmClearance",
    }
    assert front_doors <= set(SURFACE)
    assert len(SURFACE) * CASES >= 50_000


@pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")
@pytest.mark.parametrize("qualified_name", sorted(SURFACE))
def test_a_report_or_scene_function_lets_only_named_errors_escape(
    qualified_name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # whatever a call writes (a report folder) lands here
    function = SURFACE[qualified_name]

    @settings(
        max_examples=CASES // PER_EXAMPLE,
        deadline=None,
        database=None,
        suppress_health_check=list(HealthCheck),
    )
    @given(st.lists(_arguments(function), min_size=PER_EXAMPLE, max_size=PER_EXAMPLE))
    def check(calls: list[dict[str, Any]]) -> None:
        for arguments in calls:
            problem = call_keeps_the_rule(function, arguments, limit_s=TIME_LIMIT_S)
            assert not problem, f"{qualified_name}({', '.join(arguments)}): {problem}"

    check()


# ------------------------------------------------------------------ each refusal added for issue 17, directly

_FIGURE = np.zeros((4, 4), dtype=np.uint8)


def _refusals(tmp: Path) -> list[tuple[Callable[..., Any], dict[str, Any], str]]:
    """(function, arguments, what the message must say): one per check the hostile suite above made."""
    return [
        (writers.write_pair_report, {"out_dir": tmp, "result": 3}, "result must be a PairResult; got int"),
        (writers.write_roc_report, {"out_dir": tmp, "curves": (1,)}, r"curves\[0\] must be a RocCurve"),
        (writers.write_roc_report, {"out_dir": tmp, "curves": 5}, "curves must be a list of RocCurve"),
        (writers.write_files, {"out_dir": None, "contents": {}}, "out_dir must be a folder path"),
        (writers.write_files, {"out_dir": tmp, "contents": {"a": "text"}}, "contents must map file names"),
        (writers.write_files, {"out_dir": tmp, "contents": {"x" * 300: b""}}, "contents=.* at most 239"),
        (writers.write_files, {"out_dir": tmp / ("y" * 300), "contents": {}}, "out_dir=.* at most 239"),
        (writers.atomic_write_text, {"path": "a\x00b", "text": ""}, "path=.* holds a NUL"),
        (writers.atomic_write_text, {"path": 7, "text": ""}, "path must be a file path"),
        (writers.atomic_write_text, {"path": tmp, "text": ""}, "is not a regular file"),
        (writers.atomic_write_text, {"path": tmp / "a.txt", "text": b"x"}, "text must be a str; got bytes"),
        (writers.to_json, {"record": [1]}, "record must be a mapping"),
        (writers.csv_text, {"columns": "ab", "rows": []}, "columns must be a list of str"),
        (writers.csv_text, {"columns": ["a"], "rows": [1]}, "rows must be a list of dicts"),
        (writers.flaw_records, {"flaws": [], "is_true": [True]}, "is_true must be None or 0 bools"),
        (writers.registration_record, {"registration": "r"}, "registration must be a Registration"),
        (figures.encode_png, {"image": np.zeros((4, 4))}, "image must be a uint8 array"),
        (figures.figure_png, {"figure": None}, "figure must be a Figure"),
        (figures.roc_png, {"curves": [], "title": 1}, "title must be a str"),
        (figures.roc_png, {"curves": [], "measured": 1}, "measured must be a list of bools"),
        (figures.overlay_png, {"image": _FIGURE, "flaws": None}, "flaws must be a list of Flaw"),
        (figures.colour_png, {"image": _FIGURE, "limit": ""}, "limit must be a number"),
        (figures.mapped_png, {"image": _FIGURE, "low": None, "high": 1.0}, "low must be a number"),
        (figures.mapped_png, {"image": _FIGURE, "low": 0, "high": 1, "scale_rc": None}, "scale_rc must hold"),
        (
            figures.mapped_png,
            {"image": _FIGURE, "low": 0, "high": 1, "scale_rc": (1, 10**7)},
            "under 67108864",
        ),
        (report_sim.write_overview, {"out_dir": tmp, "picture_rgb": _FIGURE}, "picture_rgb must be a uint8"),
        (report_sim.sun_path_png, {"path": 0, "title": "t"}, "path must be a SunPath"),
        (report_batch.pair_rows, {"result": None, "items": []}, "result must be a BatchResult"),
        (report_isee.scenario_details, {"result": 1.5}, "result must be a ProximityDemoResult"),
        (report_mission.crop_window, {"bbox": (0, 0, 4), "shape": (8, 8)}, "bbox must be 4 integers"),
        (report_mission.crop_window, {"bbox": (0, 0, 4, 4), "shape": (8, -8)}, r"shape\[1\] must be"),
        (report_mission.crop_window, {"bbox": (0, 0, 4, 4), "shape": (8, 8), "row_step": 99}, "row_step"),
        (report_mission.sun_png, {"result": {}}, "result must be a MissionResult"),
        (dent.local_rotation, {"zaxis": (0.0, 0.0, 0.0)}, "zaxis must be a non-zero direction"),
        (dent.box_mesh, {"size": (1.0, 1.0, 1e9), "repeat_per_m": 1.0}, r"size must be half sizes <= 5.0 m"),
        (dent.box_mesh, {"size": (1.0, 0.0, 1.0), "repeat_per_m": 1.0}, "size must be three half sizes > 0"),
        (
            dent.box_mesh,
            {"size": (1.0, 1.0, 1.0), "repeat_per_m": 1.0, "crater": 1},
            "crater must be a Crater",
        ),
        (
            dent.skin_mesh,
            {"radius": 0.1, "half_length": 0.2, "capsule": "yes", "repeat_per_m": 1.0},
            "capsule",
        ),
        (dent.skin_mesh, {"radius": 0.0, "half_length": 0.2, "capsule": True, "repeat_per_m": 1.0}, "radius"),
        (
            dent.skin_surface,
            {"dent": None, "radius": 1, "pos": (0, 0, 0), "zaxis": (0, 0, 1), "point_m": (0, 0, 0)},
            "dent must be a SkinDent",
        ),
        (clearance.ArmClearance, {"world": "w"}, "world must be a World"),
        (clearance.is_arm_geom, {"model": None, "geom": 0, "prefix": "a"}, "model must be a MjModel"),
        (proximity_loop.ProximityLoop, {"rig": 1}, "rig must be an arm .* lacks rangefinder_distances_m"),
        (scene.scene_mjcf, {"mockup": None, "anomalies": None}, "mockup must be a Mockup"),
    ]


def test_each_added_refusal_names_the_argument_and_the_fix(tmp_path: Path) -> None:
    for function, arguments, message in _refusals(tmp_path):
        with pytest.raises(InputError, match=message):
            function(**arguments)
    assert not any(tmp_path.iterdir()), "a refused call wrote something"


def test_a_device_is_never_replaced_by_a_written_file(tmp_path: Path) -> None:
    fifo = tmp_path / "pipe.txt"
    os.mkfifo(fifo)
    with pytest.raises(FileError, match="is not a regular file"):
        writers.atomic_write_text(fifo, "x")
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    assert sorted(tmp_path.iterdir()) == [fifo]  # no temporary left behind


def test_the_arm_geom_check_refuses_a_geom_outside_the_model() -> None:
    mujoco = pytest.importorskip("mujoco")
    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody><geom size='1'/></worldbody></mujoco>")
    with pytest.raises(InputError, match=r"geom must be an integer in \[0, 0\]"):
        clearance.is_arm_geom(model, 1, "arm")
    with pytest.raises(InputError, match="prefix must be a str"):
        clearance.is_arm_geom(model, 0, None)
    assert clearance.is_arm_geom(model, 0, "") is True


def test_build_model_checks_the_arm_position_before_building_the_scene() -> None:
    with pytest.raises(InputError, match="arm_home_tool_tip_m must be a number or an array"):
        scene.build_model(None, None, arm_home_tool_tip_m="x")  # type: ignore[arg-type]
