"""The proximity-demo report: every plot a valid PNG, and the JSON files agree with the result record."""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import cv2
import numpy as np
import pytest

from rsi.mission.proximity_records import ProximityDemoResult
from rsi.report.isee import PICTURES, lamp_png, law_png, write_proximity_report

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def report(proximity_demo: ProximityDemoResult, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    return write_proximity_report(tmp_path_factory.mktemp("proximity") / "results", proximity_demo)


def test_every_plot_is_a_valid_png(report: dict[str, Path]) -> None:
    assert set(report) == {*PICTURES, "figures.json", "scenarios.json"}
    for name in PICTURES:
        data = report[name].read_bytes()
        assert data.startswith(PNG_SIGNATURE), name
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert image is not None and min(image.shape[:2]) > 200, name
        assert image.std() > 10.0, name  # something is drawn, not a blank canvas
    # no temporary files left behind by the atomic writes
    assert sorted(path.name for path in report["f_lamp.png"].parent.iterdir()) == sorted(report)


def test_json_agrees_with_the_record(report: dict[str, Path], proximity_demo: ProximityDemoResult) -> None:
    assert json.loads(report["figures.json"].read_text()) == proximity_demo.figures.to_dict()
    details = json.loads(report["scenarios.json"].read_text())
    law = proximity_demo.law
    assert details["seed"] == proximity_demo.seed == 0
    derived = {"standoff_m": law.standoff_m, "peak_distance_m": law.peak_distance_m}
    assert details["law"] == asdict(law) | derived
    assert details["surfaces"] == {name: asdict(each) for name, each in proximity_demo.surfaces.items()}
    assert details["additional_task_error_deg"] == proximity_demo.additional_task_error_deg
    assert details["filter_delay_s"] == proximity_demo.filter_delay_s
    assert details["arm_path"] == proximity_demo.arm_path
    assert details["recovery_s"] == proximity_demo.recovery_s


def test_the_plots_are_drawn_from_the_record_alone(
    report: dict[str, Path], proximity_demo: ProximityDemoResult
) -> None:
    # a view: the same record draws the same bytes (no simulation, no randomness in the drawing)
    assert law_png(proximity_demo.servo_response) == report["fig7_servo_velocity.png"].read_bytes()
    assert lamp_png(proximity_demo) == report["f_lamp.png"].read_bytes()
