"""The ``rsi`` command: parses arguments, calls :mod:`rsi.mission`, :mod:`rsi.report` and the core, prints.

Nothing here computes: every command is a thin shell over a library function. Heavy modules (numpy, OpenCV,
matplotlib) are imported inside the commands so that ``rsi --help`` stays fast.

Exit codes (also in every ``--help`` epilog): see :data:`EXIT_CODES`.
"""

from __future__ import annotations

import contextlib
import json
import math
import warnings
from collections.abc import Callable, Iterator, Mapping, Sequence
from enum import Enum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, NoReturn

import typer

from rsi.errors import FileError, InputError

if TYPE_CHECKING:
    from rich.console import Console

    from rsi.datasets.demo import DemoResult
    from rsi.detection.detect import Flaw
    from rsi.detection.pair import PairResult
    from rsi.detection.roc import RocCurve
    from rsi.mission import MissionResult, MissionScore
    from rsi.mission.proximity_records import Check
    from rsi.sim.anomalies import AnomalySettings

EXIT_OK = 0
MAX_SEED = 2**63 - 1  # the archive stores seeds as SQL integers (rsi.archive, run_mission): one rule for all
EXIT_USAGE = 2
EXIT_INVALID_VALUE = 3
EXIT_FILE = 4
EXIT_INTERNAL = 5
EXIT_CODES: Mapping[int, str] = {
    EXIT_OK: "success",
    EXIT_USAGE: "usage error: unknown command or option, bad choice, missing argument (typer)",
    EXIT_INVALID_VALUE: "invalid value (InputError): e.g. p-false-alarm outside (0, 0.5), even flaw size",
    EXIT_FILE: "missing, unreadable or corrupt file or folder, or --out a file (FileError, OS error)",
    EXIT_INTERNAL: "internal error: a bug; please report it with the command line",
}
_EPILOG = (
    "Exit codes: " + "; ".join(f"{code} {text.split(':')[0]}" for code, text in EXIT_CODES.items()) + "."
)
DEFAULT_OUT = Path("rsi-results")
"""Where ``rsi demo`` writes unless told otherwise."""
DEFAULT_PAIR_OUT = Path("rsi-pair-results")
"""Where ``rsi demo-pair`` writes unless told otherwise."""
_MAX_TABLE_ROWS = 20
_MAX_MISSION_ROWS = 40  # a mission reports ~10-30 findings: print them all
_ROC_TABLE_P_FALSE_ALARM = (1e-6, 1e-5, 1e-4, 1e-3)


class FlawModel(str, Enum):
    """Seed §2.4 flaw models selectable on the command line."""

    single = "single"
    uniform = "uniform"
    disc = "disc"
    peak = "peak"


class Polarity(str, Enum):
    """Which sign of change counts as a flaw."""

    both = "both"
    dark = "dark"
    bright = "bright"


class RegistrationModel(str, Enum):
    """Motion models of ``rsi.imaging.registration.REGISTRATION_MODELS`` (kept in step by a test)."""

    translation = "translation"
    euclidean = "euclidean"
    similarity = "similarity"
    affine = "affine"
    homography = "homography"
    local = "local"


class Method(str, Enum):
    """Likelihood-ratio test or its morphological-erosion approximation (seed §2.4)."""

    lrt = "lrt"
    erosion = "erosion"


class Repeatability(str, Enum):
    """Viewpoint repeatability of a vista visit (seed §2.3)."""

    lab = "lab"
    space = "space"


class AnomalyDraw(str, Enum):
    """Named anomaly draws of ``rsi.sim.anomalies.ANOMALY_PRESETS`` (kept in step by a test)."""

    wide = "wide"
    seed_mockup = "seed-mockup"


class Split(str, Enum):
    """DeepPCB splits."""

    trainval = "trainval"
    test = "test"


class ClassSource(str, Enum):
    """Who names DeepPCB defects (rsi.datasets.pcb_learn.CLASS_SOURCES)."""

    learned = "learned"
    rules = "rules"


# Detector options shared by `rsi inspect` and `rsi batch` (seed §2.3-2.4).
FlawModelOption = Annotated[FlawModel, typer.Option(help="Seed §2.4 flaw model.")]
SizeOption = Annotated[int, typer.Option(help="Flaw window side in pixels (odd).")]
PFalseAlarmOption = Annotated[float, typer.Option(help="Per-pixel false-alarm probability, in (0, 0.5).")]
PolarityOption = Annotated[Polarity, typer.Option(help="Which changes count as flaws.")]
RegistrationModelOption = Annotated[RegistrationModel, typer.Option(help="Registration motion model.")]
MethodOption = Annotated[Method, typer.Option(help="Likelihood-ratio test or erosion approximation.")]
# The world's anomaly draw, shared by `rsi demo` and `rsi sim render` (issue 13).
AnomaliesOption = Annotated[
    AnomalyDraw,
    typer.Option(
        "--anomalies",
        help="Anomaly draw: 'wide' (issue 13: 0-8 impacts, dark and bright, on every visible surface, "
        "0-2 swaps and leaks, 2-40 K, one run in ten without anomalies) or 'seed-mockup' (the paper's "
        "fixed selection).",
    ),
]
AnomaliesJsonOption = Annotated[
    Path | None,
    typer.Option(
        "--anomalies-json",
        help="JSON object of AnomalySettings fields overriding the --anomalies draw, "
        'e.g. {"impact_count_range": [2, 4], "impact_bright_probability": 0.5}.',
    ),
]


# `rsi demo` inspects under another sun than the reference's (issue 14): rsi.mission.run.SUN_OFFSET_S, kept
# in step by a test (importing it here would load numpy and the simulator on `rsi --help`).
DEMO_SUN_OFFSET_S = 300.0
SunOffsetOption = Annotated[
    float,
    typer.Option(
        "--sun-offset-s",
        help="Start the inspection pass this many seconds later in the orbit than one orbit after the "
        "reference's, under another sun: 300 s is about 19 deg on the 400 km orbit, 0 the reference's sun; "
        "about 1300-3400 s puts the pass in the Earth's shadow (lamp off).",
    ),
]


def _orbit_start_s(sun_offset_s: float) -> tuple[float, float]:
    """The passes' orbit times for ``--sun-offset-s``: the reference at ``ORBIT_START_S[0]``, the inspection
    one orbit later plus the offset (raises InputError for a negative or non-finite offset)."""
    if not math.isfinite(sun_offset_s) or sun_offset_s < 0.0:
        raise InputError(
            f"--sun-offset-s must be a finite number of seconds >= 0; got {sun_offset_s!r}. Pass e.g. "
            f"--sun-offset-s {DEMO_SUN_OFFSET_S:g} (about 19 deg of sun, the default) or 0 (the reference's "
            "sun)."
        )
    from rsi.mission.run import ORBIT_START_S

    return (ORBIT_START_S[0], ORBIT_START_S[1] + float(sun_offset_s))


ANOMALIES_JSON_MAX_BYTES = 2**20  # AnomalySettings' fields take a few hundred bytes


def _anomaly_settings(draw: AnomalyDraw, json_path: Path | None) -> AnomalySettings:
    """The draw named on the command line, with the fields of `json_path` (if any) overriding it."""
    from rsi._files import read_regular_file
    from rsi.sim.anomalies import AnomalySettings

    fields: dict[str, Any] = {}
    if json_path is not None:
        # a regular file of a few KiB: a FIFO or /dev/zero named .json is refused, never read without end
        try:
            data = read_regular_file(
                json_path, max_bytes=ANOMALIES_JSON_MAX_BYTES, too_big="not AnomalySettings"
            )
            fields = json.loads(data.decode("utf-8"))
        except FileError as error:
            raise FileError(f"--anomalies-json: {error}") from None
        except (UnicodeDecodeError, json.JSONDecodeError) as error:
            raise FileError(
                f"--anomalies-json {str(json_path)!r} is not a readable JSON file ({error}). "
                "Pass a file holding a JSON object of AnomalySettings fields."
            ) from error
        if not isinstance(fields, dict):
            raise InputError(
                f"--anomalies-json {str(json_path)!r} holds a {type(fields).__name__}, not a JSON object of "
                'AnomalySettings fields, e.g. {"impact_count_range": [2, 4]}.'
            )
    return AnomalySettings.from_dict({"preset": draw.value, **fields})


app = typer.Typer(
    name="rsi",
    help="Robotic surface inspection: compare reference and inspection images and find flaws "
    "(after Volpe & Balaram, JPL). Start with `rsi demo`.",
    epilog=_EPILOG,
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
eval_app = typer.Typer(help="Score rsi on public benchmark datasets.", epilog=_EPILOG, no_args_is_help=True)
app.add_typer(eval_app, name="eval")


def _fail(code: int, message: str) -> NoReturn:
    # One line on stderr, no traceback: the message already names the argument, the value and the fix.
    typer.echo(f"rsi: error: {' '.join(message.split())}", err=True)
    raise typer.Exit(code)


# Numerical chatter (overflow in a cast, a mean of an empty slice) is not for the user: the result or the
# error says what matters. Other warnings (rsi's own advice) are printed, one line each, after success.
_SILENT_WARNINGS = (
    RuntimeWarning,
    DeprecationWarning,
    PendingDeprecationWarning,
    FutureWarning,
    ResourceWarning,
)


@contextlib.contextmanager
def _errors() -> Iterator[None]:
    """Map library errors to the documented exit codes (file errors first: they are InputErrors too).

    stderr gets one clean line: warnings raised meanwhile are held back (and dropped on failure), so no
    RuntimeWarning or library chatter lands before the ``rsi: error:`` line.
    """
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            yield
        except (FileError, OSError) as error:
            _fail(EXIT_FILE, str(error) or type(error).__name__)
        except InputError as error:
            _fail(EXIT_INVALID_VALUE, str(error))
        except MemoryError as error:
            _fail(EXIT_INTERNAL, f"internal error: out of memory ({error}); please report the command line")
        except Exception as error:
            _fail(EXIT_INTERNAL, f"internal error ({type(error).__name__}): {error}")
    shown = dict.fromkeys(
        " ".join(str(warning.message).split())
        for warning in caught
        if not issubclass(warning.category, _SILENT_WARNINGS)
    )
    for message in shown:
        typer.echo(f"rsi: warning: {message}", err=True)


def _out_folder(out: Path) -> Path:
    """--out checked before any work: a folder, or a path where one can be created (FileError, exit 4)."""
    from rsi._files import writable_folder

    folder, _ = writable_folder(out, "--out")
    return folder


def _stdout() -> Console:
    from rich.console import Console

    return Console(highlight=False)


@contextlib.contextmanager
def _progress_bar(description: str) -> Iterator[Callable[[str, int, int], None]]:
    """A rich progress bar on stderr (stdout stays clean for --json), fed ``update(stage, done, total)``."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn())
    console = Console(stderr=True)
    # Only on a terminal: piped or captured stderr keeps its one clean line (a bar would leave a newline).
    with Progress(*columns, console=console, transient=True, disable=not console.is_terminal) as progress:
        task = progress.add_task(description, total=None)

        def update(stage: str, completed: int, total: int) -> None:
            progress.update(task, description=f"{description}: {stage}", completed=completed, total=total)

        yield update


def _print_json(record: Mapping[str, Any]) -> None:
    from rsi.report.writers import json_ready

    # One line, last on stdout: scripts read it with `tail -n 1`.
    typer.echo(json.dumps(json_ready(record), allow_nan=False))


def _flaw_table(flaws: Sequence[Flaw], *, is_true: Sequence[bool] | None = None, title: str) -> Any:
    from rich.table import Table

    table = Table(title=title)
    for column in ("#", "row", "col", "area px", "score", "polarity", *(("truth",) if is_true else ())):
        table.add_column(column, justify="right")
    for number, flaw in enumerate(flaws[:_MAX_TABLE_ROWS], start=1):
        verdict = (("flaw" if is_true[number - 1] else "FALSE ALARM"),) if is_true else ()
        table.add_row(
            str(number),
            f"{flaw.row:.1f}",
            f"{flaw.col:.1f}",
            str(flaw.area_px),
            f"{flaw.score:.1f}",
            flaw.polarity,
            *verdict,
        )
    if len(flaws) > _MAX_TABLE_ROWS:
        table.caption = f"... and {len(flaws) - _MAX_TABLE_ROWS} more (all in flaws.csv)"
    return table


@app.command(epilog=_EPILOG)
def demo(
    *,
    seed: Annotated[
        int,
        typer.Option(
            min=0, max=MAX_SEED, help="Seed of the world: anomalies, viewpoint errors, sensor noise."
        ),
    ] = 0,
    out: Annotated[
        Path, typer.Option("--out", help="Results folder (created if missing; earlier runs are kept).")
    ] = DEFAULT_OUT,
    anomalies: AnomaliesOption = AnomalyDraw.wide,
    anomalies_json: AnomaliesJsonOption = None,
    sun_offset_s: SunOffsetOption = DEMO_SUN_OFFSET_S,
    layout: Annotated[
        str,
        typer.Option(
            help="The mock-up's layout: 'truss' (seed §4) or 'truss-b' (issue 15); either flown with a plan "
            "generated from its CAD model."
        ),
    ] = "truss",
    vista: Annotated[
        list[str] | None,
        typer.Option(
            "--vista",
            help="Fly only the plan's points taken from this vista, repeated for several (a targeted "
            "re-inspection: --vista cad_03). Default: the whole plan.",
        ),
    ] = None,
) -> None:
    """The whole inspection mission over the simulated truss mock-up, scored, archived and reported.
    Reference pass, anomalies, inspection pass with active second looks under another sun (--sun-offset-s),
    pyrometer and gas surveys (seed §2-4); findings scored against the world's ground truth; everything
    stored in OUT/archive.db; the run's self-contained HTML report in OUT/report.html (a copy per run under
    OUT/runs/), with both passes' suns and the lamp settings that reproduced them.
    """
    with _errors():
        orbit_start_s = _orbit_start_s(sun_offset_s)
        _check_layout(layout)
        vistas = _checked_vistas(vista)
        _out_folder(out)
        settings = _anomaly_settings(anomalies, anomalies_json)
        import time

        from rsi.archive import Archive
        from rsi.mission import MissionSettings, run_mission, score_mission
        from rsi.report.mission import write_mission_report

        start_s = time.perf_counter()
        _results_folder(out)
        with Archive.open(out / "archive.db") as archive, _progress_bar("mission") as update:
            stages = _FinalStage(update, "report")
            result = run_mission(
                seed,
                archive=archive,
                progress=stages.update,
                anomalies=settings,
                orbit_start_s=orbit_start_s,
                layout=layout,
                settings=MissionSettings(vistas=vistas),
            )
            scoring_s = time.perf_counter()
            score = score_mission(result)
            scoring_s = time.perf_counter() - scoring_s
            run_folder = out / "runs" / (f"run-{result.run_id:04d}" if result.run_id is not None else "run")
            files = write_mission_report(run_folder, result, score, timings_s={"scoring": scoring_s})
            files = {name: _copy_atomically(path, out / name) for name, path in files.items()}
            stages.finish()
        _print_mission(result, score, files, run_folder, elapsed_s=time.perf_counter() - start_s)


def _results_folder(out: Path) -> None:
    _out_folder(out).mkdir(parents=True, exist_ok=True)


class _FinalStage:
    """Feeds a progress bar the mission's stages, then one more of its own (the report)."""

    def __init__(self, update: Callable[[str, int, int], None], name: str) -> None:
        self._update, self._name, self._done, self._total = update, name, 0, 1

    def update(self, stage: str, done: int, total: int) -> None:
        self._done, self._total = done, total + 1
        self._update(stage, done, total + 1)

    def finish(self) -> None:
        self._update(self._name, self._total, self._total)


def _copy_atomically(source: Path, target: Path) -> Path:
    from rsi._files import atomic_write_bytes

    return atomic_write_bytes(target, source.read_bytes())


def _print_mission(
    result: MissionResult,
    score: MissionScore,
    files: Mapping[str, Path],
    run_folder: Path,
    *,
    elapsed_s: float,
) -> None:
    from rich import box
    from rich.table import Table

    from rsi.report.mission import finding_records, sun_separation_deg

    console = _stdout()
    records = finding_records(result, score)
    table = Table(
        title=f"Findings of seed {result.seed} against ground truth",
        box=box.SIMPLE_HEAD,
        padding=(0, 1, 0, 0),
    )
    for column in ("#", "kind", "source", "position mm", "size mm"):
        table.add_column(column, justify="right" if column in ("#", "size mm") else "left", no_wrap=True)
    table.add_column("ground truth", overflow="fold")  # in 80 columns a long site folds, nothing is cut
    for record in records[:_MAX_MISSION_ROWS]:
        matched = record["truth_index"]
        truth = "FALSE" if matched is None else f"#{matched} {record['truth_site']}"
        position = ", ".join(f"{1000 * record[key]:.0f}" for key in ("x_m", "y_m", "z_m"))
        size = f"{1000 * record['size_m']:.1f}"
        table.add_row(str(record["number"]), record["kind"], record["source"], position, size, truth)
    if len(records) > _MAX_MISSION_ROWS:
        table.caption = (
            f"... and {len(records) - _MAX_MISSION_ROWS} more (all in findings.csv and the report)"
        )
    console.print(table)
    console.print(_score_table(score))
    if result.settings.vistas:
        flown = ", ".join(result.settings.vistas)
        console.print(f"Targeted run (--vista {flown}): scored on the anomalies its views see.")
    console.print(
        f"{len(records)} findings, {score.false_findings} false; mission {result.timings_s['total']:.1f} s, "
        f"all {elapsed_s:.1f} s. Run {result.run_id} in {files['report.html'].parent / 'archive.db'}."
    )
    separation = sun_separation_deg(result)
    if separation is not None:
        inspection = f"{separation[0]:.1f} deg from the reference's (--sun-offset-s sets it)"
        console.print(f"Suns: the inspection's is {inspection}.")
    console.print(f"Report: {files['report.html']} (this run's copy: {run_folder / 'report.html'})")


def _score_table(score: MissionScore) -> Any:
    from rich import box
    from rich.table import Table

    from rsi.report.mission import FALSE_FINDINGS_TARGET, RECALL_TARGET

    title = f"Score per type (targets: recall >= {RECALL_TARGET}, <= {FALSE_FINDINGS_TARGET} false per run)"
    table = Table(title=title, box=box.SIMPLE_HEAD)
    for column in ("type", "found/truth", "recall", "recall target", "false findings"):
        table.add_column(column, justify="left" if column == "type" else "right")
    for name, entry in score.per_type.items():
        met = "met" if entry.recall >= RECALL_TARGET else "NOT MET"
        row = (name, f"{entry.found}/{entry.truth}", f"{entry.recall:.2f}", met, str(entry.false_findings))
        table.add_row(*row)
    return table


@app.command("demo-pair", epilog=_EPILOG)
def demo_pair(
    *,
    seed: Annotated[
        int, typer.Option(min=0, max=MAX_SEED, help="Seed of the scene, flaw positions and sensor noise.")
    ] = 0,
    out: Annotated[
        Path, typer.Option("--out", help="Results folder (created if missing).")
    ] = DEFAULT_PAIR_OUT,
) -> None:
    """One synthetic reference/inspection pair with seeded ~1 mm flaws: found, pictured and scored."""
    with _errors():
        _out_folder(out)
        from rsi.datasets.demo import simulate_demo
        from rsi.report.writers import write_demo_report

        with _progress_bar("demo") as update:
            result = simulate_demo(seed=seed, progress=update)
            files = write_demo_report(out, result)
        _print_demo(result, files, out)


def _print_demo(result: DemoResult, files: Mapping[str, Path], out: Path) -> None:
    console = _stdout()
    score, detection = result.score, result.pair.detection
    console.print(_flaw_table(detection.flaws, is_true=score.is_true, title="Flaws found (strongest first)"))
    console.print(
        f"Recall: {score.found_count}/{score.truth_count} seeded flaws found ({score.recall:.0%}); "
        f"false alarms: {score.false_alarms}; "
        f"{detection.flaw_model} model at P_F = {detection.p_false_alarm:g} per pixel."
    )
    if detection.registration is not None:
        found_x, found_y = detection.registration.translation_xy
        true_x, true_y = result.shift_xy
        console.print(
            f"Registration: shift ({found_x:.2f}, {found_y:.2f}) px; true ({true_x:.2f}, {true_y:.2f}) px."
        )
    console.print(f"Simulated in {result.elapsed_s:.1f} s. Results in {out}/: {', '.join(sorted(files))}")


@app.command("inspect", epilog=_EPILOG)
def inspect_command(
    *,
    reference: Annotated[Path, typer.Argument(help="Reference image (PNG, TIFF or JPEG; 8 or 16 bit).")],
    inspection: Annotated[Path, typer.Argument(help="Inspection image of the same surface.")],
    out: Annotated[Path, typer.Option("--out", help="Results folder (created if missing).")],
    flaw_model: FlawModelOption = FlawModel.single,
    size: SizeOption = 3,
    p_false_alarm: PFalseAlarmOption = 1e-5,
    polarity: PolarityOption = Polarity.both,
    model: RegistrationModelOption = RegistrationModel.translation,
    method: MethodOption = Method.lrt,
    noise_sigma: Annotated[
        float | None,
        typer.Option(help="Noise std of one image in its own units; estimated from the data if omitted."),
    ] = None,
    misregistration_std_px: Annotated[
        float, typer.Option(help="Floor on the residual shift std (px): local distortion becomes edge noise.")
    ] = 0.0,
    as_json: Annotated[bool, typer.Option("--json", help="Print one JSON object instead of tables.")] = False,
) -> None:
    """Register REFERENCE to INSPECTION, detect flaws, write flaws.json/.csv and PNG pictures to --out."""
    with _errors():
        _out_folder(out)
        from rsi.detection.pair import inspect_pair
        from rsi.imaging.io import read_image
        from rsi.report.writers import write_pair_report

        result = inspect_pair(
            read_image(reference),
            read_image(inspection),
            flaw_model=flaw_model.value,
            size=size,
            p_false_alarm=p_false_alarm,
            polarity=polarity.value,
            registration_model=model.value,
            method=method.value,
            noise_sigma=noise_sigma,
            misregistration_std_px=misregistration_std_px,
        )
        files = write_pair_report(out, result)
        _print_inspection(result, out, files, as_json=as_json)


def _print_inspection(result: PairResult, out: Path, files: Mapping[str, Path], *, as_json: bool) -> None:
    from rsi.report.writers import flaw_records, pair_summary

    if as_json:
        _print_json({**pair_summary(result), "flaws": flaw_records(result.flaws), "files": files})
        return
    console = _stdout()
    console.print(_flaw_table(result.flaws, title="Flaws found (strongest first)"))
    detection = result.detection
    console.print(
        f"{len(result.flaws)} flaw(s) at P_F = {detection.p_false_alarm:g} per pixel "
        f"(threshold {detection.threshold:.2f}); results in {out}/"
    )


@app.command(epilog=_EPILOG)
def register(
    *,
    reference: Annotated[Path, typer.Argument(help="Reference image.")],
    inspection: Annotated[Path, typer.Argument(help="Inspection image.")],
    model: Annotated[RegistrationModel, typer.Option(help="Motion model.")] = RegistrationModel.translation,
    as_json: Annotated[
        bool, typer.Option("--json", help="Print one JSON object instead of a table.")
    ] = False,
) -> None:
    """Register REFERENCE to INSPECTION (seed §2.3 Gauss-Newton) and print the motion and photometry."""
    with _errors():
        from rsi.imaging.io import read_image
        from rsi.imaging.registration import register as register_images
        from rsi.report.writers import registration_record

        registration = register_images(read_image(reference), read_image(inspection), model=model.value)
        record = registration_record(registration) or {}
        if as_json:
            _print_json(record)
            return
        _print_record(record, title=f"Registration ({model.value})")


def _print_record(record: Mapping[str, Any], *, title: str) -> None:
    from rich.table import Table

    from rsi.report.writers import json_ready

    table = Table(title=title, show_header=False)
    table.add_column("field")
    table.add_column("value")
    for key, value in json_ready(record).items():
        table.add_row(key, _readable(value))
    _stdout().print(table)


def _readable(value: Any) -> str:
    """Four significant digits for floats (the JSON output keeps full precision), lists in brackets."""
    if isinstance(value, list):
        return "[" + ", ".join(_readable(item) for item in value) + "]"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


@app.command(epilog=_EPILOG)
def roc(
    *,
    strength: Annotated[float, typer.Option(help="Flaw strength in noise sigmas (strongest pixel).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for roc.png and roc.csv.")],
    flaw_model: Annotated[FlawModel | None, typer.Option(help="One flaw model; default: all four.")] = None,
    size: Annotated[int, typer.Option(help="Flaw window side in pixels (odd).")] = 3,
) -> None:
    """Theoretical ROC curves (seed §2.4: P_D against P_F) as roc.png and roc.csv."""
    with _errors():
        _out_folder(out)
        import numpy as np

        from rsi.detection.roc import theoretical_roc
        from rsi.report.writers import write_roc_report

        models = [flaw_model] if flaw_model is not None else list(FlawModel)
        curves = [theoretical_roc(m.value, strength_sigma=strength, size=size) for m in models]
        files = write_roc_report(out, curves, title=f"Theoretical ROC, flaw strength {strength:g} sigma")
        table_points = np.asarray(_ROC_TABLE_P_FALSE_ALARM)
        points = [
            theoretical_roc(m.value, strength_sigma=strength, size=size, p_false_alarm=table_points)
            for m in models
        ]
        _print_roc(points, files)


def _print_roc(points: Sequence[RocCurve], files: Mapping[str, Path]) -> None:
    from rich.table import Table

    table = Table(title="P_D at selected P_F (per pixel)")
    table.add_column("curve")
    for p_false_alarm in _ROC_TABLE_P_FALSE_ALARM:
        table.add_column(f"P_F={p_false_alarm:g}", justify="right")
    for curve in points:
        table.add_row(curve.label, *(f"{p:.3f}" for p in curve.p_detection))
    console = _stdout()
    console.print(table)
    console.print(f"Wrote {', '.join(str(path) for path in files.values())}")


@eval_app.command("deeppcb", epilog=_EPILOG)
def eval_deeppcb(
    *,
    root: Annotated[Path, typer.Argument(help="DeepPCB checkout (the folder holding PCBData/).")],
    split: Annotated[Split, typer.Option(help="Which list of pairs to score.")] = Split.test,
    classes: Annotated[
        ClassSource,
        typer.Option(
            help="Who names the defects: a classifier never fitted on the pairs it names (test: fitted on "
            "trainval first; trainval: each board group by one fitted on the others), or the topology rules."
        ),
    ] = ClassSource.learned,
    as_json: Annotated[
        bool, typer.Option("--json", help="End with one JSON object on the last stdout line.")
    ] = False,
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Also write deeppcb.json, per_class.csv, per_class.png and confusion.png to this folder "
            "(created if missing).",
        ),
    ] = None,
) -> None:
    """Score rsi on DeepPCB template/tested pairs: recall, precision, F1, false alarms per image."""
    with _errors():
        if out is not None:
            _out_folder(out)
        from rsi.datasets.pcb_learn import evaluate_deeppcb

        with _progress_bar(f"DeepPCB {split.value}") as update:
            evaluation = evaluate_deeppcb(root, split=split.value, progress=update, classes=classes.value)
        record = evaluation.to_dict()
        written = _deeppcb_files(out, record)
        if as_json:
            _print_json(record)
            return
        per_class, confusion = record.pop("per_class"), record.pop("confusion")
        _print_record(record, title=f"DeepPCB {split.value}")
        _print_classes(per_class, confusion)
        if written:
            _stdout().print(f"Wrote {', '.join(str(path) for path in written.values())}")


def _deeppcb_files(out: Path | None, record: dict[str, Any]) -> dict[str, Path]:
    """The evaluation's results folder (:func:`rsi.report.deeppcb.write_deeppcb_report`), if asked for."""
    if out is None:
        return {}
    from rsi.report.deeppcb import write_deeppcb_report

    return write_deeppcb_report(out, record)


def _print_classes(per_class: Mapping[str, Mapping[str, float]], confusion: Sequence[Sequence[int]]) -> None:
    """The official rule per class, and the confusion of paired boxes (rows true, columns detected)."""
    from rich.table import Table

    table = Table(title="Per class (IoU > 0.33, same class)")
    for column in ("class", "boxes", "detections", "precision", "recall", "AP"):
        table.add_column(column)
    for name, row in per_class.items():
        table.add_row(
            name, *(_readable(row[key]) for key in ("boxes", "detections", "precision", "recall", "ap"))
        )
    _stdout().print(table)
    names = ["none", *per_class]
    matrix = Table(title="Confusion (rows: true class, columns: detected; none = missed / false alarm)")
    matrix.add_column("true \\ detected")
    for name in names:
        matrix.add_column(name)
    for name, counts in zip(names, confusion, strict=True):
        matrix.add_row(name, *(str(value) for value in counts))
    _stdout().print(matrix)


sim_app = typer.Typer(
    help="The orbital-environment simulator (seed §4): truss mock-up, anomalies, solar simulator.",
    epilog=_EPILOG,
    no_args_is_help=True,
)
app.add_typer(sim_app, name="sim")


def _pick_vista(names: Sequence[str], vista: str) -> str:
    """A vista by name or by its index in the world's list (the issue's `--vista N`)."""
    if vista.isdigit() and int(vista) < len(names):
        return names[int(vista)]
    if vista in names:
        return vista
    raise InputError(
        f"vista={vista!r} is not known. Choose an index 0-{len(names) - 1} or one of {', '.join(names)}."
    )


def _checked_vistas(vistas: list[str] | None) -> tuple[str, ...]:
    """--vista checked before any work: names, each given once (the plan, once generated, checks that it
    visits them)."""
    names = tuple(vistas or ())
    for name in names:
        if not name.strip() or len(name) > _MAX_VISTA_NAME:
            raise InputError(
                f"--vista={name[:40]!r} is not a vista name: give one of the plan's vistas (the report's "
                "plan table lists them), e.g. --vista cad_03."
            )
    return tuple(dict.fromkeys(names))


_MAX_VISTA_NAME = 64  # the mock-ups' and the generated plans' names are under 20 characters


def _check_layout(layout: str) -> None:
    """--layout checked before any work: one of the mock-up's layouts (rsi.sim.LAYOUTS)."""
    from rsi.sim import LAYOUTS

    if layout not in LAYOUTS:
        raise InputError(f"--layout={layout!r} is not known. Choose one of {', '.join(LAYOUTS)}.")


@sim_app.command("render", epilog=_EPILOG)
def sim_render(
    *,
    seed: Annotated[
        int, typer.Option(min=0, max=MAX_SEED, help="Seed of the world: anomalies, pose errors, noise.")
    ] = 0,
    vista: Annotated[str, typer.Option(help="Vista point: index or name (see the table printed).")] = "0",
    out: Annotated[Path, typer.Option("--out", help="Folder for frames, depth and truth.")] = Path("rsi-sim"),
    rows: Annotated[int, typer.Option(min=16, max=2048, help="Frame rows (the renderer's buffer).")] = 480,
    cols: Annotated[int, typer.Option(min=16, max=2048, help="Frame columns.")] = 640,
    repeatability: Annotated[
        Repeatability, typer.Option(help="Viewpoint repeatability of each visit (seed §2.3).")
    ] = Repeatability.lab,
    anomalies: AnomaliesOption = AnomalyDraw.wide,
    anomalies_json: AnomaliesJsonOption = None,
    layout: Annotated[
        str, typer.Option(help="The mock-up's layout: 'truss' (seed §4) or 'truss-b' (issue 15).")
    ] = "truss",
) -> None:
    """Visit a vista twice (reference, then inspection with anomalies) and write what the camera saw."""
    with _errors():
        _check_layout(layout)
        _out_folder(out)
        settings = _anomaly_settings(anomalies, anomalies_json)
        from rich.table import Table

        import rsi.sim
        from rsi.datasets.rendered import render_vista_to_folder
        from rsi.report.sim import write_overview

        world = rsi.sim.load(layout, seed=seed, repeatability=repeatability.value, settings=settings)
        name = _pick_vista(world.vistas, vista)
        files: dict[str, Path] = {}
        with _progress_bar("render") as update:
            for step, state in enumerate(("reference", "inspection"), start=1):
                written = render_vista_to_folder(world, name, out, size=(rows, cols), state=state)
                files.update({f"{state} {key}": path for key, path in written.items()})
                update(state, step, 3)
            files.update(write_overview(out, world.overview_picture()))
            update("overview", 3, 3)
        table = Table(title=f"World seed {seed} ({layout}): anomalies (ground truth)")
        for column in ("#", "kind", "subtype", "surface", "site", "x m", "y m", "z m", "size mm"):
            table.add_column(column)
        for number, anomaly in enumerate(world.anomalies.anomalies):
            x, y, z = anomaly.position_m
            table.add_row(
                str(number), anomaly.kind, anomaly.subtype, anomaly.surface, anomaly.site,
                f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", f"{1000 * anomaly.size_m:.1f}",
            )  # fmt: skip
        if not world.anomalies.anomalies:
            table.caption = "no anomalies this run (the wide draw leaves about one run in ten clean)"
        console = _stdout()
        console.print(table)
        console.print(f"Vista {name!r} ({', '.join(world.vistas)}). Wrote {len(files)} files to {out}/.")


@sim_app.command("sun", epilog=_EPILOG)
def sim_sun(
    *,
    altitude_km: Annotated[float, typer.Option(help="Circular orbit altitude.")] = 400.0,
    beta_deg: Annotated[
        float, typer.Option(help="Sun beta angle (sun elevation over the orbit plane).")
    ] = 0.0,
    orbits: Annotated[
        float, typer.Option(min=0.01, max=20.0, help="How many orbital periods to sample.")
    ] = 1.0,
    step_s: Annotated[float, typer.Option(min=0.1, max=600.0, help="Sample spacing.")] = 10.0,
    vista: Annotated[str, typer.Option(help="Vista point whose target the lamp lights.")] = "0",
    out: Annotated[Path, typer.Option("--out", help="Folder for sun_path.csv/.png/.json.")] = Path("rsi-sun"),
    layout: Annotated[
        str, typer.Option(help="The mock-up's layout: 'truss' (seed §4) or 'truss-b' (issue 15).")
    ] = "truss",
) -> None:
    """Sun direction along a low Earth orbit and the lamp trajectory that reproduces it (seed §4.1)."""
    with _errors():
        _check_layout(layout)
        _out_folder(out)
        import math

        import numpy as np

        from rsi.report.sim import write_sun_report
        from rsi.sim.mockup import mockup as build_mockup
        from rsi.sim.orbit import Orbit, eclipse, orbital_period_s, sun_path
        from rsi.sim.solar_simulator import LAMBDA_RANGE_M, LampMount

        orbit = Orbit(altitude_m=altitude_km * 1000.0, beta_rad=math.radians(beta_deg))
        mockup = build_mockup(layout)
        name = _pick_vista(tuple(mockup.vistas), vista)
        times = np.arange(0.0, orbits * orbital_period_s(orbit), step_s)
        spot_x, _, spot_z = mockup.vistas[name].target_m
        # The lab sets the rail level with the lit spot and centred on it: at beta 0 the sun sweeps the plane
        # through the spot that holds the rail, so every direction the rail's length allows is reproduced.
        mount = LampMount(rail_origin_world_m=(spot_x - 0.5 * LAMBDA_RANGE_M[1], -2.0, spot_z))
        path = sun_path(orbit, times, spot_world_m=mockup.vistas[name].target_m, mount=mount)
        title = f"{altitude_km:g} km, beta {beta_deg:g} deg, spot at vista {name}"
        files = write_sun_report(out, path, title=title)
        shadow = eclipse(orbit)
        console = _stdout()
        reproduced = float(np.mean(~path.clipped[path.sunlit])) if path.sunlit.any() else 0.0
        console.print(
            f"Period {orbital_period_s(orbit) / 60:.1f} min; "
            f"eclipse {100 * shadow.fraction:.1f}% of the orbit; "
            f"lamp at {path.target_intensity_lux:.0f} lux, "
            f"lab shutter {path.exposure.lab_exposure_s * 1e3:.2f} ms; "
            f"the lab reproduces {100 * reproduced:.0f}% of the sunlit samples."
        )
        console.print(f"Wrote {', '.join(str(path) for path in files.values())}")


isee_app = typer.Typer(
    help="The Integrated Sensor End-Effector (seed §3): proximity loop, sensors and lamps on the arm.",
    epilog=_EPILOG,
    no_args_is_help=True,
)
app.add_typer(isee_app, name="isee")


@isee_app.command("proximity-demo", epilog=_EPILOG)
def isee_proximity_demo(
    *,
    seed: Annotated[
        int, typer.Option(min=0, max=MAX_SEED, help="Seed of every noise source (sensors, lamp supply).")
    ] = 0,
    out: Annotated[
        Path, typer.Option("--out", help="Folder for the plots, figures.json and scenarios.json.")
    ] = Path("rsi-proximity"),
    as_json: Annotated[
        bool, typer.Option("--json", help="End with one JSON object of the figures on the last stdout line.")
    ] = False,
) -> None:
    """Close the 44 Hz proximity loop on the arm (seed §3.1) and draw Figs 3, 6, 7 and time plots."""
    with _errors():
        _out_folder(out)
        from rsi.mission.proximity_demo import acceptance, simulate_proximity_demo
        from rsi.report.isee import write_proximity_report

        with _progress_bar("proximity demo") as update:
            result = simulate_proximity_demo(seed=seed, progress=update)
            files = write_proximity_report(out, result)
        if as_json:
            _print_json(result.figures.to_dict())
            return
        _print_acceptance(result.figures.to_dict(), acceptance(result.figures), files, out)


def _print_acceptance(
    figures: Mapping[str, float], checks: Sequence[Check], files: Mapping[str, Path], out: Path
) -> None:
    from rich.table import Table

    by_figure = {check.figure: check for check in checks}
    table = Table(title="Proximity demo: issue 4 acceptance figures")
    for column in ("figure", "value", "acceptance", "result"):
        table.add_column(column, justify="right" if column == "value" else "left")
    for name, value in figures.items():
        check = by_figure.get(name)
        limit = f"{check.relation} {check.limit:.4g}" if check else ""
        verdict = ("pass" if check.passed else "FAIL") if check else ""
        table.add_row(name, _readable(value), limit, verdict)
    console = _stdout()
    console.print(table)
    passed = sum(check.passed for check in checks)
    console.print(f"{passed}/{len(checks)} acceptance checks pass. Wrote {len(files)} files to {out}/.")


archive_app = typer.Typer(
    help="The inspection archive: runs, findings and flaw history.", epilog=_EPILOG, no_args_is_help=True
)
app.add_typer(archive_app, name="archive")
ArchiveOption = Annotated[
    str, typer.Option("--archive", help="SQLite file or SQLAlchemy URL of the archive (it must exist).")
]
DEFAULT_ARCHIVE = "rsi-archive.db"
ImagesDirOption = Annotated[
    Path | None,
    typer.Option(
        "--images-dir",
        help="Folder of the archive's image files; default <archive file>.images; needed for other URLs.",
    ),
]


@archive_app.command("list", epilog=_EPILOG)
def archive_list(*, archive: ArchiveOption = DEFAULT_ARCHIVE, images_dir: ImagesDirOption = None) -> None:
    """List the inspection runs, newest last (the archive is opened read-only)."""
    with _errors():
        from rich.table import Table

        from rsi.archive import Archive

        with Archive.open(archive, read_only=True, images_dir=images_dir) as store:
            runs = store.runs()
        table = Table(title=f"Runs in {archive}")
        for column in ("run", "label", "status", "seed", "started", "findings"):
            table.add_column(column)
        for run in runs:
            seed = "" if run.seed is None else str(run.seed)
            table.add_row(str(run.run_id), run.label, run.status, seed, f"{run.started_at:%Y-%m-%d %H:%M:%S}",
                          str(run.finding_count))  # fmt: skip
        _stdout().print(table)


@archive_app.command("show", epilog=_EPILOG)
def archive_show(
    *,
    run: Annotated[int, typer.Argument(help="Run number (see `rsi archive list`).")],
    archive: ArchiveOption = DEFAULT_ARCHIVE,
    images_dir: ImagesDirOption = None,
) -> None:
    """Show one run's findings, each with its earlier sighting when it was seen before (read-only)."""
    with _errors():
        from rich.table import Table

        from rsi.archive import Archive

        with Archive.open(archive, read_only=True, images_dir=images_dir) as store:
            record, findings = store.run(run), store.findings(run)
        table = Table(
            title=f"Run {record.run_id} ({record.label}, {record.status}): {len(findings)} findings"
        )
        for column in ("finding", "vista", "kind", "confidence", "size mm", "seen before as"):
            table.add_column(column)
        for finding in findings:
            size = "" if finding.size_m is None else f"{1000 * finding.size_m:.2f}"
            before = "" if finding.previous_id is None else str(finding.previous_id)
            confidence = f"{finding.confidence:.2f}"
            table.add_row(str(finding.finding_id), finding.vista, finding.kind, confidence, size, before)
        _stdout().print(table)


@archive_app.command("export", epilog=_EPILOG)
def archive_export(
    *,
    run: Annotated[int, typer.Argument(help="Run number (see `rsi archive list`).")],
    out: Annotated[Path, typer.Option("--out", help="Folder for the run's JSON and its images.")],
    archive: ArchiveOption = DEFAULT_ARCHIVE,
    images_dir: ImagesDirOption = None,
) -> None:
    """Export one run (JSON with its findings and history links, plus the referenced images; read-only)."""
    with _errors():
        _out_folder(out)
        from rsi.archive import Archive

        with Archive.open(archive, read_only=True, images_dir=images_dir) as store:
            path = store.export_run(run, out)
        _stdout().print(f"Wrote {path}")


@app.command("batch", epilog=_EPILOG)
def batch(
    *,
    manifest: Annotated[
        Path,
        typer.Argument(help="CSV with a header 'reference,inspection' (optional: id, per-pair settings)."),
    ],
    out: Annotated[Path, typer.Option("--out", help="Folder for pairs.csv, flaws.csv and batch.json.")],
    archive: Annotated[
        str,
        typer.Option("--archive", help="SQLite file or SQLAlchemy URL of the archive (created if missing)."),
    ] = DEFAULT_ARCHIVE,
    images_dir: ImagesDirOption = None,
    scheduler: Annotated[
        str | None,
        typer.Option(help="Address of a running dask scheduler (tcp://host:8786); default: local processes."),
    ] = None,
    workers: Annotated[
        int | None,
        typer.Option(
            min=1, help="Local worker processes (default: CPU count); with --scheduler, wait for this many."
        ),
    ] = None,
    flaw_model: FlawModelOption = FlawModel.single,
    size: SizeOption = 3,
    p_false_alarm: PFalseAlarmOption = 1e-5,
    polarity: PolarityOption = Polarity.both,
    model: RegistrationModelOption = RegistrationModel.translation,
    method: MethodOption = Method.lrt,
    as_json: Annotated[
        bool, typer.Option("--json", help="End with one JSON object on the last stdout line.")
    ] = False,
) -> None:
    """Inspect every pair of MANIFEST in parallel (dask); store results and failures in the archive.

    A pair that cannot be read or inspected is reported and skipped; the batch goes on and exits 0. A
    malformed manifest row stops it before anything runs (exit 4, every bad line named). Manifest columns
    named like the options below override them for their row.
    """
    with _errors():
        _out_folder(out)
        from rsi.archive import Archive
        from rsi.mission.batch import PairSettings, read_manifest, run_batch
        from rsi.report.batch import write_batch_report

        settings = PairSettings(
            flaw_model=flaw_model.value,
            size=size,
            p_false_alarm=p_false_alarm,
            polarity=polarity.value,
            registration_model=model.value,
            method=method.value,
        )
        items = read_manifest(manifest)
        with Archive.open(archive, images_dir=images_dir) as store, _progress_bar("batch") as update:
            result = run_batch(
                items, archive=store, scheduler=scheduler, workers=workers, settings=settings,
                label=f"batch {manifest.name}", progress=update,
            )  # fmt: skip
        files = write_batch_report(out, result, items)
        record = {**result.summary(), "archive": archive, "files": files}
        if as_json:
            _print_json(record)
            return
        _print_batch(record, out)


def _print_batch(record: Mapping[str, Any], out: Path) -> None:
    from rich.table import Table

    console = _stdout()
    failed = record["failed"]
    if failed:
        table = Table(title=f"{len(failed)} pair(s) skipped")
        for column in ("pair", "stage", "error"):
            table.add_column(column)
        for failure in failed[:_MAX_TABLE_ROWS]:
            table.add_row(failure["pair_id"], failure["stage"], failure["error"])
        if len(failed) > _MAX_TABLE_ROWS:
            table.caption = f"... and {len(failed) - _MAX_TABLE_ROWS} more (all in pairs.csv)"
        console.print(table)
    console.print(
        f"{record['pairs']} pairs done: {record['inspected']} inspected, {record['failures']} failed, "
        f"{record['flaws']} flaws; {record['pairs_per_s']:.1f} pairs/s on {record['workers']} worker(s) "
        f"({record['elapsed_s']:.1f} s). Run {record['run_id']} in {record['archive']}; results in {out}/"
    )


@app.command(epilog=_EPILOG)
def console(
    *,
    host: Annotated[str, typer.Option(help="Address to listen on; 0.0.0.0 reaches beyond this machine.")] = (
        "127.0.0.1"
    ),
    port: Annotated[int, typer.Option(help="TCP port.")] = 8765,
    archive: Annotated[
        Path | None, typer.Option(help="SQLite archive missions write to (default: a new one in a temp dir).")
    ] = None,
    seed: Annotated[
        int, typer.Option(min=0, max=MAX_SEED, help="Seed of the live world's anomalies and noise.")
    ] = 0,
    layout: Annotated[str, typer.Option(help="The mock-up.")] = "truss",
    token: Annotated[
        str | None, typer.Option(help="Access token (default: a random one, printed in the start URL).")
    ] = None,
) -> None:
    """Operator console: watch, drive and review the inspection robot in a browser (docs/console.md)."""
    import warnings

    from rsi.web.server import check_archive, console_settings, serve

    with _errors():
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            settings = console_settings(
                host=host, port=port, archive=archive, seed=seed, layout=layout, token=token
            )
        for warning in caught:
            typer.echo(f"rsi: warning: {warning.message}", err=True)
        check_archive(settings.archive)  # a damaged archive: exit 4 before the start URL is printed
        typer.echo(f"rsi console: open {settings.url}  (archive {settings.archive}; Ctrl-C stops)")
        serve(settings)
