"""Every ``rsi`` command run in-process with hostile arguments and files (issue 17).

What must hold for each invocation: the exit code is a documented one (0, 2 usage, 3 value, 4 file), never
5 (a bug) or an uncaught exception; a failure (3 or 4) prints exactly one line on stderr, ``rsi: error:
...``, with no library chatter or warning before it; a success prints nothing on stderr but ``rsi:
warning:`` lines; and every corrupt archive the command was pointed at is byte for byte as it was.
"""

from __future__ import annotations

import os
import shutil
import sqlite3
import struct
import zlib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
import typer
import typer.main
import typer.testing
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

from rsi.archive import Archive, Finding
from rsi.cli import EXIT_FILE, EXIT_INVALID_VALUE, EXIT_OK, EXIT_USAGE, app

pytestmark = pytest.mark.filterwarnings("ignore::hypothesis.errors.HypothesisWarning")

CASES = {
    "inspect": 200,
    "register": 120,
    "roc": 60,
    "batch": 150,
    "archive": 270,
    "quick_fail": 200,
    "sun": 30,
    "console": 120,
}


def _png_claiming(cols: int, rows: int) -> bytes:
    """A small, valid-looking grey PNG whose header claims cols x rows (a decompression bomb's shape)."""

    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    header = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    pixels = zlib.compress(b"\x00" * (cols + 1) * 8)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", pixels) + chunk(b"IEND", b"")


@dataclass(frozen=True)
class Files:
    root: Path
    images: tuple[str, ...]
    manifests: tuple[str, ...]
    archives: tuple[str, ...]
    corrupt: dict[str, bytes]


def _write_archives(root: Path) -> tuple[list[str], dict[str, bytes]]:
    good = root / "good.db"
    with Archive.open(good) as archive:
        archive.add_vista("A_door")
        run_id = archive.start_run(seed=1)
        findings = [Finding("A_door", "impact", 0.5, bbox=(i, i, i + 2, i + 2)) for i in range(300)]
        archive.add_findings(run_id, findings)
        archive.finish_run(run_id)
    tampers = {
        "settings.db": "UPDATE runs SET settings_json = '{bad'",
        "started.db": "UPDATE runs SET started_at = 'yesterday'",
        "version_gone.db": "DELETE FROM rsi_archive",
        "version_text.db": "UPDATE rsi_archive SET schema_version = 'one'",
        "dropped.db": "DROP TABLE findings",
        "extras.db": "UPDATE findings SET extras_json = '[1]' WHERE id = 7",
        "huge_id.db": "UPDATE runs SET id = 9223372036854775807",
    }
    corrupt: dict[str, bytes] = {}
    for name, statement in tampers.items():
        shutil.copy(good, root / name)
        connection = sqlite3.connect(root / name)
        connection.execute("PRAGMA journal_mode=DELETE")
        connection.execute("PRAGMA foreign_keys=OFF")
        connection.execute(statement)
        connection.commit()
        connection.close()
    data = bytearray(good.read_bytes())
    data[2 * 4096 : len(data) - 4096] = b"\xa5" * (len(data) - 3 * 4096)  # malformed pages, header kept
    (root / "pages.db").write_bytes(bytes(data))
    (root / "garbage.db").write_bytes(np.random.default_rng(2).bytes(20000))
    for name in (*tampers, "pages.db", "garbage.db"):
        corrupt[name] = (root / name).read_bytes()
    return ["good.db", *corrupt, "missing.db", "folder"], corrupt


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Files:
    root = tmp_path_factory.mktemp("cli")
    texture = (np.random.default_rng(0).random((32, 32)) * 255).astype(np.uint8)
    cv2.imwrite(str(root / "good.png"), texture)
    cv2.imwrite(str(root / "shifted.png"), np.roll(texture, 2, axis=1))
    cv2.imwrite(str(root / "black.png"), np.zeros((32, 32), np.uint8))
    cv2.imwrite(str(root / "white.png"), np.full((32, 32), 255, np.uint8))
    cv2.imwrite(str(root / "tiny.png"), np.zeros((1, 1), np.uint8))
    (root / "bomb.png").write_bytes(_png_claiming(20000, 20000))
    (root / "huge.png").write_bytes(_png_claiming(100000, 100000))
    good = (root / "good.png").read_bytes()
    (root / "truncated.png").write_bytes(good[: len(good) // 2])
    (root / "bmp.png").write_bytes(cv2.imencode(".bmp", texture)[1].tobytes())
    (root / "empty.png").write_bytes(b"")
    os.symlink("/dev/zero", root / "zero.png")
    os.mkfifo(root / "fifo.png")
    (root / "folder.png").mkdir()
    (root / "folder").mkdir()
    (root / "file").write_text("not a folder")
    images = ("good.png", "shifted.png", "black.png", "white.png", "tiny.png", "bomb.png", "huge.png",
              "truncated.png", "bmp.png", "empty.png", "zero.png", "fifo.png", "folder.png", "missing.png",
              "good.tif", "file")  # fmt: skip
    manifests = {
        "pairs.csv": "reference,inspection\ngood.png,shifted.png\ngood.png,black.png\n",
        "long_field.csv": "reference,inspection\n" + "x" * 200_000 + ",good.png\n",
        "long_cell.csv": "reference,inspection\n" + "y" * 5000 + ",good.png\n",
        "bad_rows.csv": "reference,inspection,p_false_alarm\ngood.png,good.png,often\n,good.png,\n",
        "no_header.csv": "\n\n",
        "binary.csv": "\x00\xff\xfe",
    }
    for name, text in manifests.items():
        (root / name).write_bytes(
            text.encode("utf-8", "surrogateescape") if name != "binary.csv" else b"\xff\xfe\x00"
        )
    archives, corrupt = _write_archives(root)
    return Files(
        root, images, (*manifests, "fifo.png", "zero.png", "folder", "missing.csv"), tuple(archives), corrupt
    )


runner = CliRunner()
COMMAND = typer.main.get_command(app)


@pytest.fixture(scope="module", autouse=True)
def _command_built_once() -> Iterator[None]:
    """typer's CliRunner rebuilds the whole command tree at every invoke (15-25 ms, most of a refused
    case's cost): here it is built once and reused, so every command can take 1,000 cases."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(typer.testing, "_get_command", lambda _app: COMMAND)
        yield


def _invoke(files: Files, arguments: Sequence[str]) -> int:
    """Run one command in `files.root`, check every promise of the module docstring; its exit code."""
    previous = Path.cwd()
    os.chdir(files.root)
    try:
        result = runner.invoke(app, list(arguments))
    finally:
        os.chdir(previous)
    shown = f"rsi {' '.join(arguments)[:300]} -> exit {result.exit_code}; stderr {result.stderr[-600:]!r}"
    assert result.exit_code in (EXIT_OK, EXIT_USAGE, EXIT_INVALID_VALUE, EXIT_FILE), shown
    assert result.exception is None or isinstance(result.exception, SystemExit), shown
    lines = result.stderr.splitlines()
    if result.exit_code in (EXIT_INVALID_VALUE, EXIT_FILE):
        assert len(lines) == 1 and lines[0].startswith("rsi: error: "), shown
    if result.exit_code == EXIT_OK:
        assert all(line.startswith("rsi: warning: ") for line in lines if line.strip()), shown
    for name, data in files.corrupt.items():
        assert (files.root / name).read_bytes() == data, f"{name} changed by: {shown}"
    return int(result.exit_code)


def _cli_settings(cases: int) -> settings:
    return settings(max_examples=cases, deadline=None, database=None, suppress_health_check=list(HealthCheck))


NUMBERS = st.sampled_from(
    ["3", "1", "0", "-1", "2", "255", "256", "99999", "1e-5", "0.5", "nan", "inf", "-inf", "1e200", "1e-400",
     "1e400", "abc", "", "9223372036854775808", "0x10"]
)  # fmt: skip
OUTS = st.sampled_from(["out", "file", "file/below", "folder", "out/deeper"])


def _options(pairs: dict[str, st.SearchStrategy[str]]) -> st.SearchStrategy[list[str]]:
    """Any subset of the options, each with a drawn value."""
    chosen = st.lists(st.sampled_from(sorted(pairs)), unique=True, max_size=len(pairs))
    return chosen.flatmap(lambda names: st.tuples(*(pairs[name].map(lambda value, n=name: [n, value]) for name in names)).map(lambda items: [part for item in items for part in item]))  # noqa: E501  # fmt: skip


DETECTOR = {
    "--size": NUMBERS,
    "--p-false-alarm": NUMBERS,
    "--flaw-model": st.sampled_from(["single", "uniform", "peak", "kernel", "x"]),
    "--polarity": st.sampled_from(["both", "dark", "bright", "none"]),
    "--model": st.sampled_from(["translation", "affine", "homography", "zoom"]),
    "--method": st.sampled_from(["lrt", "erosion", "x"]),
}


def test_the_cli_suite_generates_at_least_a_thousand_cases() -> None:
    assert sum(CASES.values()) >= 1000


def test_inspect(files: Files) -> None:
    extra = {**DETECTOR, "--noise-sigma": NUMBERS, "--misregistration-std-px": NUMBERS}

    @_cli_settings(CASES["inspect"])
    @given(st.sampled_from(files.images), st.sampled_from(files.images), OUTS, _options(extra), st.booleans())
    def run(reference: str, inspection: str, out: str, options: list[str], as_json: bool) -> None:
        _invoke(
            files,
            ["inspect", reference, inspection, "--out", out, *options, *(["--json"] if as_json else [])],
        )

    run()


def test_register(files: Files) -> None:
    @_cli_settings(CASES["register"])
    @given(
        st.sampled_from(files.images),
        st.sampled_from(files.images),
        st.sampled_from(["translation", "affine", "x"]),
    )
    def run(reference: str, inspection: str, model: str) -> None:
        _invoke(files, ["register", reference, inspection, "--model", model, "--json"])

    run()


def test_roc(files: Files) -> None:
    strengths = st.sampled_from(["3", "nan", "inf", "-1", "0", "1e300", "abc", "1e-300"])

    @_cli_settings(CASES["roc"])
    @given(strengths, OUTS, _options({"--size": NUMBERS, "--flaw-model": DETECTOR["--flaw-model"]}))
    def run(strength: str, out: str, options: list[str]) -> None:
        _invoke(files, ["roc", "--strength", strength, "--out", out, *options])

    run()


def test_batch(files: Files) -> None:
    # The scheduler refuses the connection: every case stops before a cluster would start, after the manifest,
    # the archive and every option were checked.
    options = {**DETECTOR, "--workers": NUMBERS, "--archive": st.sampled_from(files.archives)}

    @_cli_settings(CASES["batch"])
    @given(st.sampled_from(files.manifests), OUTS, _options(options))
    def run(manifest: str, out: str, options: list[str]) -> None:
        _invoke(files, ["batch", manifest, "--out", out, "--scheduler", "tcp://127.0.0.1:1", *options])

    run()


def test_archive_commands(files: Files) -> None:
    archives = st.sampled_from(
        [*files.archives, "postgresql://user:secret@127.0.0.1:1/rsi", "sqlite:///good.db"]
    )
    runs = st.sampled_from(["1", "0", "-1", "2", "9223372036854775807", "9223372036854775808", "abc", "1e3"])
    command = st.one_of(
        st.tuples(st.just(["archive", "list"])),
        st.tuples(st.just(["archive", "show"]), runs.map(lambda run: [run])),
        st.tuples(
            st.just(["archive", "export"]), runs.map(lambda run: [run]), OUTS.map(lambda out: ["--out", out])
        ),
    ).map(lambda parts: [word for part in parts for word in part])

    @_cli_settings(CASES["archive"])
    @given(command, archives, st.sampled_from([None, "images", "file"]))
    def run(words: list[str], archive: str, images_dir: str | None) -> None:
        _invoke(files, [*words, "--archive", archive, *(["--images-dir", images_dir] if images_dir else [])])

    run()


def test_commands_that_must_fail_before_any_simulation(files: Files) -> None:
    # demo, demo-pair, the proximity demo, sim render and eval run for seconds when they succeed: here each
    # gets at least one bad value, which must be refused up front, with the documented exit code.
    bad_seed = st.sampled_from(["-1", "abc", "1.5", "", "99999999999999999999999"])
    bad_out = st.sampled_from(["file", "file/below"])
    bad = st.one_of(bad_seed.map(lambda s: ["--seed", s]), bad_out.map(lambda o: ["--out", o]))
    eval_roots = st.sampled_from(["missing", "file", "folder", "fifo.png", "zero.png"])
    commands = st.one_of(
        st.tuples(st.sampled_from([["demo"], ["demo-pair"], ["isee", "proximity-demo"]]), bad),
        st.tuples(
            st.just(["sim", "render"]),
            st.one_of(
                st.sampled_from(["15", "2049", "4096", "abc", "-5"]).map(lambda r: ["--rows", r]),
                st.sampled_from(["15", "2049", "abc"]).map(lambda c: ["--cols", c]),
                bad_seed.map(lambda s: ["--seed", s]),
                bad_out.map(lambda o: ["--out", o]),
            ),
        ),
        st.tuples(st.just(["eval", "deeppcb"]), eval_roots.map(lambda root: [root])),
        st.tuples(st.sampled_from([["nope"], ["archive", "nope"], ["sim"], ["inspect"]]), st.just([])),
    ).map(lambda parts: [word for part in parts for word in part])  # fmt: skip

    @_cli_settings(CASES["quick_fail"])
    @given(commands)
    def run(words: list[str]) -> None:
        _invoke(files, words)

    run()


def test_sim_sun(files: Files) -> None:
    options = {
        "--altitude-km": st.sampled_from(["400", "-1", "0", "1e300", "nan", "abc"]),
        "--beta-deg": st.sampled_from(["0", "90", "1e300", "nan", "-inf"]),
        "--orbits": st.sampled_from(["0.05", "0", "21", "nan", "abc"]),
        "--step-s": st.sampled_from(["60", "0.05", "601", "nan"]),
        "--vista": st.sampled_from(["0", "99", "-1", "A_door", "", "x" * 300]),
    }

    @_cli_settings(CASES["sun"])
    @given(OUTS, _options(options))
    def run(out: str, options: list[str]) -> None:
        # Hostile values first: a valid run (seconds) only when the draw happens to be all good.
        _invoke(files, ["sim", "sun", "--out", out, "--orbits", "0.05", "--step-s", "60", *options])

    run()


def test_console(files: Files) -> None:
    # A valid invocation serves until interrupted: every case has one option the console must refuse (a
    # damaged archive among them, which must be left as it was), the others drawn good or bad.
    # huge_id.db is not damaged: its one run holds the largest id an archive takes, and it opens.
    damaged = sorted(name for name in files.corrupt if name != "huge_id.db")
    bad = {
        "--host": st.sampled_from(["localhost", "", "999.1.1.1", "x" * 300]),
        "--port": st.sampled_from(["-1", "65536", "abc", "1e3", "99999999999999999999"]),
        "--seed": st.sampled_from(["-1", "abc", "1.5", ""]),
        "--layout": st.sampled_from(["station", "", "TRUSS"]),
        "--token": st.sampled_from(["", "short", "x" * 15, "not a token with spaces!!"]),
        "--archive": st.sampled_from([*damaged, "folder", "fifo.png", "zero.png", "file"]),
    }
    good = {
        "--host": st.just("127.0.0.1"),
        "--port": st.just("0"),
        "--seed": st.just("3"),
        "--layout": st.sampled_from(["truss", "truss-b"]),
        "--token": st.just("a" * 24),
    }
    others = {name: st.one_of(bad[name], good[name]) for name in good}

    @_cli_settings(CASES["console"])
    @given(
        st.sampled_from(sorted(bad)).flatmap(lambda name: st.tuples(st.just(name), bad[name])),
        _options(others),
    )
    def run(refused: tuple[str, str], options: list[str]) -> None:
        chosen = {**dict(zip(options[::2], options[1::2], strict=True)), refused[0]: refused[1]}
        code = _invoke(files, ["console", *[word for item in chosen.items() for word in item]])
        assert code != EXIT_OK, f"rsi console started with {refused[0]} {refused[1]!r}"

    run()


# ------------------------------------------------------------------------- 1,000 cases of every command

PER_COMMAND = 1000
BAD_SEEDS = st.sampled_from(["-1", "abc", "1.5", "", "99999999999999999999999"])
BAD_OUTS = st.sampled_from(["file", "file/below"])
CHOICES = st.sampled_from(["", "x", "x" * 300, "nan"])


def _any_values(files: Files) -> dict[str, st.SearchStrategy[str]]:
    """A hostile-or-good value for every option any command takes."""
    archives = st.sampled_from([*files.archives, "postgresql://user:secret@127.0.0.1:1/rsi"])
    return {
        **DETECTOR,
        "--seed": st.one_of(BAD_SEEDS, st.just("3")),
        "--out": OUTS,
        "--anomalies": st.sampled_from(["wide", "seed-mockup", *["", "x"]]),
        "--anomalies-json": st.sampled_from(["file", "missing.json", "pairs.csv", "zero.png", "fifo.png"]),
        "--sun-offset-s": NUMBERS,
        "--layout": st.sampled_from(["truss", "truss-b", "station", ""]),
        "--noise-sigma": NUMBERS,
        "--misregistration-std-px": NUMBERS,
        "--strength": NUMBERS,
        "--archive": archives,
        "--images-dir": st.sampled_from(["images", "file", "folder"]),
        "--workers": NUMBERS,
        "--split": st.sampled_from(["trainval", "test", "x"]),
        "--vista": st.sampled_from(["0", "99", "-1", "A_door", "", "x" * 300]),
        "--rows": NUMBERS,
        "--cols": NUMBERS,
        "--repeatability": st.sampled_from(["lab", "space", "x"]),
        "--host": st.sampled_from(["127.0.0.1", "localhost", ""]),
        "--port": st.sampled_from(["0", "-1", "abc"]),
        "--token": st.sampled_from(["a" * 24, "", "short"]),
        "--altitude-km": NUMBERS,
        "--beta-deg": NUMBERS,
        "--orbits": NUMBERS,
        "--step-s": NUMBERS,
    }


DETECTOR_OPTIONS = ("--flaw-model", "--size", "--p-false-alarm", "--polarity", "--model", "--method")
Row = tuple[list[str], tuple[str, ...], tuple[str, ...], dict[str, st.SearchStrategy[str]]]
COMMANDS: dict[str, Row] = {
    "demo": (
        ["demo"],
        (),
        ("--seed", "--out", "--anomalies", "--anomalies-json", "--sun-offset-s", "--layout", "--vista"),
        {
            "--seed": BAD_SEEDS,
            "--out": BAD_OUTS,
            "--layout": st.just("station"),
            "--vista": st.sampled_from(["", " ", "x" * 300]),
        },
    ),
    "demo-pair": (["demo-pair"], (), ("--seed", "--out"), {"--seed": BAD_SEEDS, "--out": BAD_OUTS}),
    "isee proximity-demo": (
        ["isee", "proximity-demo"],
        (),
        ("--seed", "--out", "--json"),
        {"--seed": BAD_SEEDS, "--out": BAD_OUTS},
    ),
    "sim render": (
        ["sim", "render"],
        (),
        ("--seed", "--vista", "--out", "--rows", "--cols", "--repeatability", "--anomalies", "--layout"),
        {
            "--rows": st.sampled_from(["15", "2049", "abc"]),
            "--cols": st.sampled_from(["15", "abc"]),
            "--seed": BAD_SEEDS,
            "--out": BAD_OUTS,
        },
    ),
    "sim sun": (
        ["sim", "sun"],
        (),
        ("--altitude-km", "--beta-deg", "--orbits", "--step-s", "--vista", "--out", "--layout"),
        {
            "--orbits": st.sampled_from(["0", "21", "nan", "abc"]),
            "--step-s": st.sampled_from(["0.05", "601", "nan"]),
            "--altitude-km": st.sampled_from(["-1", "nan", "abc"]),
        },
    ),
    "eval deeppcb": (["eval", "deeppcb"], ("root",), ("--split", "--json"), {}),
    "roc": (
        ["roc"],
        (),
        ("--strength", "--out", "--flaw-model", "--size"),
        {
            "--strength": st.sampled_from(["nan", "abc", "-1", "inf"]),
            "--size": st.sampled_from(["0", "2", "256", "abc"]),
            "--out": BAD_OUTS,
        },
    ),
    "inspect": (
        ["inspect"],
        ("image", "image"),
        ("--out", *DETECTOR_OPTIONS, "--noise-sigma", "--misregistration-std-px", "--json"),
        {},
    ),
    "register": (["register"], ("image", "image"), ("--model", "--json"), {}),
    "batch": (
        ["batch", "--scheduler", "tcp://127.0.0.1:1"],
        ("manifest",),
        ("--out", "--archive", "--images-dir", "--workers", *DETECTOR_OPTIONS, "--json"),
        {},
    ),
    "archive list": (["archive", "list"], (), ("--archive", "--images-dir"), {}),
    "archive show": (["archive", "show"], ("run",), ("--archive", "--images-dir"), {}),
    "archive export": (["archive", "export"], ("run",), ("--out", "--archive", "--images-dir"), {}),
    "console": (
        ["console"],
        (),
        ("--host", "--port", "--archive", "--seed", "--layout", "--token"),
        {
            "--port": st.sampled_from(["-1", "65536", "abc"]),
            "--seed": BAD_SEEDS,
            "--layout": st.sampled_from(["station", ""]),
            "--token": st.sampled_from(["", "short"]),
        },
    ),
}
"""Each command: its words, its positional arguments, its options, and the options one of which is always
given a value it must refuse before any long work (a valid demo, render, sun path, ROC figure, DeepPCB
evaluation or console runs for seconds or until interrupted). Commands whose valid runs take milliseconds
(inspect, register, the archive's) or stop at the refused scheduler (batch) draw every option freely."""
FLAGS = {"--json"}
# --help asked one case in this many: typer draws it with rich (~70 ms, against ~2 ms for a refusal); drawn
# as freely as the flags it took 40 % of a command's cases and 85 % of their time
HELP_ONE_IN = 20


def _positional(files: Files, kind: str) -> st.SearchStrategy[str]:
    return {
        "image": st.sampled_from(files.images),
        "manifest": st.sampled_from(files.manifests),
        "root": st.sampled_from(["missing", "file", "folder", "fifo.png", "zero.png"]),
        "run": st.sampled_from(["1", "0", "-1", "2", "9223372036854775808", "abc"]),
    }[kind]


def _command_line(files: Files, command: str) -> st.SearchStrategy[list[str]]:
    words, positional, names, refusals = COMMANDS[command]
    values = _any_values(files)
    options = {name: values[name] for name in names if name not in FLAGS}
    flags = (
        st.lists(st.sampled_from(sorted(FLAGS & set(names))), unique=True, max_size=1)
        if FLAGS & set(names)
        else st.sampled_from([()] * (HELP_ONE_IN - 1) + [("--help",)]).map(list)
    )
    forced = (
        st.sampled_from(sorted(refusals)).flatmap(lambda name: st.tuples(st.just(name), refusals[name]))
        if refusals
        else st.none()
    )

    def line(drawn: tuple[list[str], list[str], list[str], tuple[str, str] | None]) -> list[str]:
        arguments, chosen, flag, refused = drawn
        pairs = dict(zip(chosen[::2], chosen[1::2], strict=True))
        if refused is not None:
            pairs[refused[0]] = refused[1]
        flag = [word for word in flag if word != "--help" or refusals]  # --help only where nothing runs
        return [*words, *arguments, *[word for item in pairs.items() for word in item], *flag]

    arguments = st.tuples(*(_positional(files, kind) for kind in positional)).map(list)
    return st.tuples(arguments, _options(options), flags, forced).map(line)


def test_every_command_is_in_the_table() -> None:
    listed = {" ".join(words[:2]) if words[0] in ("isee", "sim", "eval", "archive") else words[0]
              for words, *_ in COMMANDS.values()}  # fmt: skip
    groups = {name: getattr(COMMAND, "commands", {}).get(name) for name in getattr(COMMAND, "commands", {})}
    leaves = set()
    for name, group in groups.items():
        inner = getattr(group, "commands", None)
        leaves |= {f"{name} {sub}" for sub in inner} if inner else {name}
    assert listed == leaves


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_a_command_keeps_its_promises_over_a_thousand_cases(files: Files, command: str) -> None:
    refusals = COMMANDS[command][3]

    @_cli_settings(PER_COMMAND)
    @given(_command_line(files, command))
    def run(words: list[str]) -> None:
        code = _invoke(files, words)
        assert not (refusals and code == EXIT_OK and "--help" not in words), f"rsi {words} ran"

    run()


@pytest.fixture(autouse=True)
def _no_stray_fifo_writers() -> Iterator[None]:
    yield
