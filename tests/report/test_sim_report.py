"""The sun-path report: a CSV row per sample, a plot, and a summary that agrees with the record."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from rsi.report.sim import SUN_PATH_COLUMNS, write_sun_report
from rsi.sim.orbit import Orbit, orbital_period_s, sun_path

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def path() -> object:
    orbit = Orbit()
    times = np.arange(0.0, orbital_period_s(orbit), 30.0)
    return sun_path(orbit, times, spot_world_m=(0.9, 0.0, 0.3))


def test_sun_report_files_agree_with_the_record(tmp_path: Path, path: object) -> None:
    files = write_sun_report(tmp_path, path, title="400 km, beta 0")  # type: ignore[arg-type]
    assert set(files) == {"sun_path.csv", "sun_path.png", "sun_path.json"}
    assert files["sun_path.png"].read_bytes().startswith(PNG_SIGNATURE)
    with files["sun_path.csv"].open() as stream:
        rows = list(csv.DictReader(stream))
    assert list(rows[0]) == list(SUN_PATH_COLUMNS)
    assert len(rows) == len(path.time_s)  # type: ignore[attr-defined]
    eclipsed = [row for row in rows if row["sunlit"] == "False"]
    assert eclipsed and all(float(row["intensity_lux"]) == 0.0 for row in eclipsed)
    summary = json.loads(files["sun_path.json"].read_text())
    # seed §4.1 / §2.1: 1.5 % of the sun needs a ~67x longer shutter than 1/10000 s for the same ratio
    assert summary["target_intensity_lux"] == pytest.approx(0.015 * 130_000)
    assert summary["lab_exposure_s"] == pytest.approx(1e-4 / 0.015)
    assert summary["sunlit_fraction"] == pytest.approx(1.0 - len(eclipsed) / len(rows))
