"""The mission's HTML report: self-contained, every picture a valid PNG, the numbers of the record, escaped
text, and a real browser that shows every picture (headless Debian chromium through selenium)."""

from __future__ import annotations

import base64
import csv
import dataclasses
import json
import math
import os
import re
import types
from dataclasses import dataclass
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.errors import InputError
from rsi.mission import (
    ORBIT_START_S,
    SUN_OFFSET_S,
    MissionResult,
    MissionScore,
    MissionSettings,
    run_mission,
    score_mission,
)
from rsi.mission.sun import sun_setting
from rsi.report import figures
from rsi.report.mission import (
    FINDING_COLUMNS,
    REPORT_FILE,
    crop_window,
    header_section,
    mission_html,
    proximity_section,
    roc_section,
    sun_png,
    sun_separation_deg,
    suns_section,
    write_mission_report,
)
from rsi.sim.anomalies import AnomalySet
from rsi.sim.mockup import A_FACE_Y_M, BAY_M, TRUSS_Z0_M
from rsi.sim.orbit import orbital_period_s

SEED = 0
SMALL = (240, 320)
# the views the arm flies to (transits, frames behind the jaws; seed 0 has impacts, a swap and screws there):
# every section of the report is drawn, in a third of the whole plan's time
ARM_VIEWS = MissionSettings(plan="hand", vistas=("A_door", "A_kapton", "B_tank", "D_tubing"))
DATA_URI = "data:image/png;base64,"
CHROMIUM, CHROMEDRIVER = Path("/usr/bin/chromium"), Path("/usr/bin/chromedriver")


@dataclass(frozen=True)
class Report:
    result: MissionResult
    score: MissionScore
    files: dict[str, Path]
    page: str


@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Report:
    result = run_mission(SEED, size=SMALL, settings=ARM_VIEWS)
    score = score_mission(result)
    files = write_mission_report(tmp_path_factory.mktemp("mission") / "out", result, score)
    return Report(result, score, files, files[REPORT_FILE].read_text(encoding="utf-8"))


class _Tags(HTMLParser):
    """Every start tag with its attributes, in order."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))


def _tags(page: str) -> list[tuple[str, dict[str, str | None]]]:
    parser = _Tags()
    parser.feed(page)
    return parser.tags


def _images(page: str) -> list[str]:
    return [attrs["src"] or "" for tag, attrs in _tags(page) if tag == "img"]


def test_page_is_self_contained(report: Report) -> None:
    page = report.page
    assert "://" not in page  # no http(s), file or any other address (base64 has no ':')
    for tag, attrs in _tags(page):
        assert tag not in ("script", "link", "iframe", "object", "embed"), tag
        for name in ("src", "href"):
            if name in attrs:
                assert (attrs[name] or "").startswith(DATA_URI), (tag, name, (attrs[name] or "")[:40])
    assert "url(" not in page


def test_every_image_is_a_png_that_decodes(report: Report) -> None:
    sources = _images(report.page)
    # the overview, one row of four crops per boxed visual finding, pyrometer, gas, proximity and ROC plots
    boxed = sum(finding.bbox is not None for finding in report.result.findings)
    assert boxed > 0
    plots = 2 + (1 if report.result.transits else 0) + (1 if report.result.roc else 0)
    plots += 1 if report.result.suns else 0  # the passes' suns (issue 14)
    plots += 1 if report.result.plan_coverage is not None else 0  # the plan's coverage map (issue 15)
    assert len(sources) == 1 + 4 * boxed + plots
    for source in sources:
        data = base64.b64decode(source.removeprefix(DATA_URI), validate=True)
        image = cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_UNCHANGED)
        assert image is not None and image.size > 0 and min(image.shape[:2]) >= 16


def test_page_counts_every_finding_and_marks_the_false_ones(report: Report) -> None:
    result, score, page = report.result, report.score, report.page
    rows = re.findall(r'<tr class="finding (false|found)">', page)
    assert len(rows) == len(result.findings) > 0
    assert rows.count("false") == score.false_findings
    assert f"<strong>{len(result.findings)} findings</strong>" in page
    assert page.count("MISSED: ") == len(score.misses)


def test_findings_files_agree_with_the_record(report: Report) -> None:
    result, score = report.result, report.score
    document = json.loads(report.files["findings.json"].read_text())
    assert document["count"] == len(result.findings)
    with report.files["findings.csv"].open() as stream:
        rows = list(csv.DictReader(stream))
    assert tuple(rows[0]) == FINDING_COLUMNS
    for index, (row, finding) in enumerate(zip(rows, result.findings, strict=True)):
        assert row["kind"] == finding.kind and int(row["number"]) == index + 1
        assert float(row["x_m"]) == pytest.approx(finding.position_m[0])
        assert (row["verdict"] == "FALSE") == (index not in score.matches)


def test_targets_are_marked_honestly(report: Report) -> None:
    page, score = report.page, report.score
    section = page[page.index("Score against the targets") : page.index("<h2>Timings")]
    met = section.count('class="met"')
    unmet = section.count('class="unmet"')
    recall_met = sum(entry.recall >= 0.95 for entry in score.per_type.values())
    assert met == recall_met + (score.false_findings <= 1)
    assert met + unmet == len(score.per_type) + 1


def test_text_from_the_record_is_escaped(report: Report) -> None:
    hostile = "<script>alert('x')</script>"
    first = dataclasses.replace(report.result.findings[0], source=hostile)
    result = dataclasses.replace(report.result, findings=(first, *report.result.findings[1:]))
    page = mission_html(result, score_mission(result))
    assert "<script" not in page
    assert "&lt;script&gt;alert(&#x27;x&#x27;)&lt;/script&gt;" in page


@dataclass(frozen=True)
class _Transit:
    name: str
    time_s: Any
    distances_m: Any


class _WithTransits:
    """A mission result with the arm's transits (MissionResult gets them on another branch)."""

    def __init__(self, result: MissionResult, transits: tuple[_Transit, ...]) -> None:
        self._result, self.transits = result, transits

    def __getattr__(self, name: str) -> Any:
        return getattr(self._result, name)


def test_proximity_section_draws_transits_when_present(report: Report) -> None:
    without = dataclasses.replace(report.result, transits=())
    assert "No arm transits in this run." in proximity_section(without)
    # the mission's own transits (the arm moved the ISEE to every reachable plan point)
    assert report.result.transits and len(_images(proximity_section(report.result))) == 1
    time_s = np.linspace(0.0, 2.0, 50)
    distances = np.column_stack([0.30 - 0.1 * time_s, np.full(50, np.nan)])  # right sensor out of range
    transit = _Transit("A_door -> A_kapton", time_s, distances)
    section = proximity_section(_WithTransits(report.result, (transit,)))  # type: ignore[arg-type]
    assert "No arm transits" not in section
    assert len(_images(section)) == 1
    assert "A_door -&gt; A_kapton" in section
    assert "<td>100.0</td>" in section  # closest left reading: 0.30 - 0.2 m


def test_proximity_section_names_a_transit_of_the_wrong_shape(report: Report) -> None:
    transit = _Transit("bad", np.arange(5.0), np.zeros((5, 3)))
    with pytest.raises(InputError, match=r"transit 'bad'.*\(T, 2\)"):
        proximity_section(_WithTransits(report.result, (transit,)))  # type: ignore[arg-type]


def test_roc_section_says_when_the_run_has_no_roc(report: Report) -> None:
    assert report.result.roc, "seed 0 sees counted impacts: its run has an ROC"
    assert len(_images(roc_section(report.result))) == 1
    empty = dataclasses.replace(report.result, roc=())
    section = roc_section(empty)
    assert not _images(section) and "no empirical ROC" in section


# ---------------------------------------------------------------------------------- the passes' suns

PERIOD_S = orbital_period_s()
SPOT_A_M = (0.0, A_FACE_Y_M, TRUSS_Z0_M + BAY_M / 2)  # ORU A's face: the lamp gives a beta = 0 sun exactly
VISITS = 6


def _sun_result(inspection_start_s: float, *, visits: int = VISITS) -> MissionResult:
    """A mission's record of its suns alone: the same plan points 6 s apart on both passes (no rendering)."""
    suns = [
        sun_setting(SPOT_A_M, start_s + 6.0 * number, label=f"P{number}", stage=stage)
        for stage, start_s in (("reference", ORBIT_START_S[0]), ("inspection", inspection_start_s))
        for number in range(visits)
    ]
    empty = np.zeros((0, 3))
    return MissionResult(0, "lab", True, SMALL, (), (), (), AnomalySet(), {}, np.zeros(0), empty, None,
                         suns=tuple(suns))  # fmt: skip


def _cells(section: str, table: int) -> list[list[str]]:
    body = section.split("<tbody>")[table + 1].split("</tbody>", maxsplit=1)[0]
    return [re.findall(r"<td[^>]*>(.*?)</td>", row) for row in body.split("</tr>") if "<td" in row]


@pytest.mark.parametrize("offset_s", [0.0, SUN_OFFSET_S, 900.0])
def test_suns_section_states_the_angle_the_orbit_turned_between_the_passes(offset_s: float) -> None:
    # beta = 0: the sun stays in the orbit plane, so at the same point of each pass the suns are the orbit's
    # turn apart, 360 deg x offset / period (19.4 deg at 300 s, 58.3 deg at 900 s)
    result = _sun_result(ORBIT_START_S[1] + offset_s)
    expected_deg = 360.0 * offset_s / PERIOD_S
    median, least, most = sun_separation_deg(result) or (math.nan,) * 3
    assert median == pytest.approx(expected_deg, abs=1e-6)
    assert least == pytest.approx(most, abs=1e-6)
    section = suns_section(result)
    assert "<h2>The sun on each pass</h2>" in section
    words = f"the inspection&#x27;s sun is {expected_deg:.1f} deg from the reference&#x27;s"
    assert words in section
    assert ("(the same sun)" in section) == (offset_s == 0.0)
    passes = _cells(section, 0)
    assert [row[0] for row in passes] == ["reference", "inspection"]
    noon_deg = [
        math.degrees(2 * math.pi * (start % PERIOD_S) / PERIOD_S) for start in (400.0, 400.0 + offset_s)
    ]
    for row, start_deg, stage in zip(passes, noon_deg, ("reference", "inspection"), strict=True):
        assert row[3].startswith(f"{start_deg:.1f} to ")
        exact = sum(setting.reachable for setting in result.suns if setting.stage == stage)
        assert row[5] == "sunlit" and row[6].startswith(f"{exact}/{VISITS} sunlit visits")
        # seed §4.1: the rail gives ORU A the sun from noon to about 71 deg past it; at 84 deg it cannot
        assert exact == (VISITS if start_deg < 71.0 else 0)


def test_suns_section_lists_each_visits_lamp_setting() -> None:
    result = _sun_result(ORBIT_START_S[1] + SUN_OFFSET_S)
    rows = _cells(suns_section(result), 1)
    assert len(rows) == len(result.suns) == 2 * VISITS
    for row, setting in zip(rows, result.suns, strict=True):
        lamp = setting.lamp
        assert row[:2] == [setting.stage, setting.label]
        assert float(row[5]) == pytest.approx(math.degrees(lamp.theta_rad), abs=0.05)
        assert float(row[6]) == pytest.approx(math.degrees(lamp.phi_rad), abs=0.05)
        assert float(row[7]) == pytest.approx(lamp.lambda_m, abs=5e-4)
        assert float(row[8]) == pytest.approx(1000.0 * lamp.gamma_m, abs=0.05)
        # seed §4.1: the lamp holds the lab's 1.5 % of sunlight at the spot, and gives ORU A's sun exactly
        assert row[9] == "1950" and float(row[10]) == 0.0 and row[11] == "yes"


def test_suns_section_says_when_the_inspection_is_in_the_earths_shadow() -> None:
    midnight_s = ORBIT_START_S[1] - 400.0 + PERIOD_S / 2  # orbit midnight, the eclipse's centre
    result = _sun_result(midnight_s)
    section = suns_section(result)
    passes = _cells(section, 0)
    assert passes[1][5] == "in the Earth&#x27;s shadow (lamp off)" and passes[1][6] == "lamp off"
    shadow = _cells(section, 1)[VISITS:]
    assert all(row[4] == "shadow: lamp off" and row[9] == "0" and row[11] == "lamp off" for row in shadow)
    assert section.count('<tr class="shadow">') == VISITS
    assert "the strobe alone lights its frames" in section
    assert (sun_separation_deg(result) or (0.0,))[0] == pytest.approx(
        180.0 - 360.0 * 400.0 / PERIOD_S, abs=1e-6
    )


def test_suns_section_draws_one_plot_and_the_header_names_the_angle() -> None:
    result = _sun_result(ORBIT_START_S[1] + SUN_OFFSET_S)
    sources = _images(suns_section(result))
    assert len(sources) == 1
    decoded = cv2.imdecode(np.frombuffer(sun_png(result), np.uint8), cv2.IMREAD_UNCHANGED)
    assert decoded is not None and min(decoded.shape[:2]) >= 200
    header = header_section(result, score_mission(result))
    assert f"{360.0 * SUN_OFFSET_S / PERIOD_S:.1f} deg apart" in header


def test_suns_section_without_the_orbit_or_a_common_plan_point() -> None:
    without = dataclasses.replace(_sun_result(ORBIT_START_S[1]), suns=())
    assert "No sun in this run" in suns_section(without) and not _images(suns_section(without))
    assert sun_separation_deg(without) is None
    reference_only = _sun_result(ORBIT_START_S[1])
    reference_only = dataclasses.replace(reference_only, suns=reference_only.suns[:VISITS])
    section = suns_section(reference_only)
    assert "no angle between their suns" in section and len(_cells(section, 0)) == 1


def test_pass_start_is_the_first_transits_clock_when_the_arm_moved() -> None:
    result = _sun_result(ORBIT_START_S[1])
    transits = (types.SimpleNamespace(stage="reference", start_clock_s=400.0),
                types.SimpleNamespace(stage="inspection", start_clock_s=ORBIT_START_S[1]))  # fmt: skip
    passes = _cells(suns_section(dataclasses.replace(result, transits=transits)), 0)
    assert [row[1] for row in passes] == ["400.0", f"{ORBIT_START_S[1]:.1f}"]
    assert _cells(suns_section(result), 0)[0][1] == "400.0 (first visit)"


@pytest.mark.parametrize(
    ("bbox", "shape"),
    [((50, 70, 53, 74), (120, 320)), ((0, 0, 2, 2), (120, 320)), ((29, 95, 92, 118), (120, 320)),
     ((110, 300, 119, 319), (120, 320)), ((5, 5, 8, 9), (16, 30))],
)  # fmt: skip
def test_crop_window_holds_the_box_inside_the_image(
    bbox: tuple[int, int, int, int], shape: tuple[int, int]
) -> None:
    for row_step in (1, 2):
        rows, cols = crop_window(bbox, shape, row_step=row_step)
        assert 0 <= rows.start <= bbox[0] and bbox[2] <= rows.stop <= shape[0]
        assert 0 <= cols.start <= bbox[1] and bbox[3] <= cols.stop <= shape[1]
        height, width = rows.stop - rows.start, cols.stop - cols.start
        if shape[0] >= 2 * height and shape[1] >= 2 * width:
            # square on screen (a field row is drawn twice, seed §2.2), at least 48 x 48 frame pixels
            assert width == row_step * height and height * row_step >= 48


def test_mapped_png_uses_the_given_limits_and_scales() -> None:
    image = np.array([[0.0, 5.0], [10.0, np.nan]])
    png = figures.mapped_png(image, low=0.0, high=10.0, scale_rc=(4, 2))
    decoded = cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_UNCHANGED)
    assert decoded.shape == (8, 4, 3)
    assert tuple(decoded[0, 0]) == (0, 0, 0) and tuple(decoded[4, 0]) == (255, 255, 255)
    assert tuple(decoded[4, 2]) == (96, 96, 96)  # NaN carries no data: mid grey


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"low": 1.0, "high": 1.0}, "high must exceed low"),
        ({"low": 0.0, "high": 1.0, "scale_rc": (0, 1)}, "scale_rc"),
    ],
)
def test_mapped_png_bad_input(kwargs: dict[str, Any], message: str) -> None:
    with pytest.raises(InputError, match=message):
        figures.mapped_png(np.zeros((4, 4)), **kwargs)


def test_roc_png_needs_one_measured_flag_per_curve(report: Report) -> None:
    with pytest.raises(InputError, match="one flag per curve"):
        figures.roc_png(report.result.roc, measured=[True])


# ------------------------------------------------------------------------------------ a real browser


def _browser() -> Any:
    """Headless Debian chromium through its chromedriver; skipped (failed in CI) when either is absent."""
    missing = [str(path) for path in (CHROMIUM, CHROMEDRIVER) if not path.exists()]
    fixes = ["apt-get install chromium chromium-driver"] if missing else []
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        missing.append("the selenium package")
        fixes.append("pip install -e '.[test]'")
    if missing:
        message = f"no real browser: {', '.join(missing)} missing; {' and '.join(fixes)}"
        if os.environ.get("RSI_REQUIRE_BROWSER"):
            pytest.fail(message)
        pytest.skip(message)
    options = webdriver.ChromeOptions()
    options.binary_location = str(CHROMIUM)
    for flag in ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1280,2400"):  # fmt: skip
        options.add_argument(flag)
    return webdriver.Chrome(options=options, service=Service(executable_path=str(CHROMEDRIVER)))


_LOADED = 'return document.readyState === "complete" && Array.from(document.images).every(i => i.complete);'


def test_report_renders_in_a_real_browser_with_every_image(report: Report, tmp_path: Path) -> None:
    browser = _browser()
    from selenium.webdriver.support.wait import WebDriverWait  # present: _browser skipped otherwise

    try:
        browser.get(report.files[REPORT_FILE].resolve().as_uri())
        # chromedriver can hand back a large page while its parser still runs (a CI run saw 15 of 19
        # images): wait for the parse and every image to finish, bounded, before counting
        WebDriverWait(browser, 60).until(lambda page: page.execute_script(_LOADED))
        state = browser.execute_script(
            "return Array.from(document.images).map(i => [i.complete, i.naturalWidth, i.naturalHeight]);"
        )
        screenshot = browser.get_screenshot_as_png()
    finally:
        browser.quit()
    assert len(state) == len(_images(report.page)) > 0
    assert all(complete and width > 0 and height > 0 for complete, width, height in state), state
    shot = cv2.imdecode(np.frombuffer(screenshot, np.uint8), cv2.IMREAD_GRAYSCALE)
    (tmp_path / "report.png").write_bytes(screenshot)
    # not blank: the page draws text, tables and the dark overview picture on white
    assert shot.shape[0] >= 1000 and shot.shape[1] >= 1000
    assert float(shot.std()) > 20.0
    assert np.mean(shot < 64) > 0.02 and np.mean(shot > 240) > 0.3


def test_browser_check_skips_with_a_clear_message_without_chromium(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("RSI_REQUIRE_BROWSER", raising=False)
    monkeypatch.setattr(f"{__name__}.CHROMIUM", Path("/nonexistent/chromium"))
    with pytest.raises(pytest.skip.Exception, match="apt-get install chromium chromium-driver"):
        _browser()


def test_plan_table_says_where_the_jaws_stood_and_which_frames_look_behind_them(report: Report) -> None:
    from rsi.report.plan import plan_rows

    rows = {row[0]: row for row in plan_rows(report.result)}
    behind = [p for p in report.result.plan if p.behind_jaws_at_m is not None]
    assert behind  # the arm's frames lose what the jaws hide; the plan looks behind them
    for point in behind:
        assert (
            rows[point.name][3]
            == f"{point.jaw_opening_m * 1e3:.0f} (behind {point.behind_jaws_at_m * 1e3:.0f})"
        )
    assert "<th>jaws mm</th>" in report.page
