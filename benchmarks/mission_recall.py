"""Recall per anomaly type and per stratum with 95 % Wilson intervals, false findings per run by kind, and the
runs with no anomaly scored on their own, over a range of seeded missions (issue 13 item 3).

Each seed runs :func:`rsi.mission.run_mission` (reference pass, inspection pass, pyrometer, gas) and is scored
by :func:`rsi.mission.score_mission`; :class:`rsi.mission.Tally` adds the runs up. Printed at the end, as
markdown: recall per type (impacts >= 1 mm), per stratum (type x subtype x surface x impact size band), false
findings per run by finding kind, and the anomaly-free runs (no anomaly that counts: every finding is a false
alarm). See docs/mission.md, "The recall benchmark".

Seeds 0-99 are DEVELOPMENT seeds: settings were chosen on them. A generalisation figure needs a range nobody
tuned on (a held-out range, reported next to the development one).

``--sun-offset-s S`` starts the inspection pass S seconds later in the orbit than the default (one orbit after
the reference, the same sun): the reference keeps its sun and the inspection sees another (S between 1300 and
3460 puts the inspection pass's start in the Earth's shadow, lit by the strobe alone).

``--json PATH`` keeps every seed's result as it finishes; the same command again resumes where it stopped (and
a file of other settings is refused). ``--compare`` runs active and passive inspection on the same seeds (the
issue 5 comparison).

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/mission_recall.py --first-seed 0 --seeds 20
[--sun-offset-s 0] [--repeatability lab] [--layout truss] [--plan auto] [--no-active | --compare]
[--size 480 640] [--json PATH]``
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

for _variable in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_variable, "1")
os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.mission import ORBIT_START_S, MissionSettings, Tally, run_mission, score_mission, tally_run
from rsi.mission.settings import PLANS
from rsi.mission.tally import Rate, Recall
from rsi.sim import LAYOUTS

DEVELOPMENT_SEEDS = range(100)
_FORMAT = "rsi-bench-mission-recall/1"


def _arguments() -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--first-seed", type=int, default=0, help="first seed (0-99 are development)")
    parser.add_argument("--seeds", type=int, default=20, help="number of seeds from --first-seed")
    parser.add_argument("--sun-offset-s", type=float, default=0.0, help="inspection pass later by S s")
    parser.add_argument("--repeatability", default="lab", choices=("lab", "space"))
    parser.add_argument("--layout", default="truss", choices=LAYOUTS, help="the mock-up (docs/simulator.md)")
    parser.add_argument(
        "--plan", default="auto", choices=PLANS, help="vista points: hand, cad, or auto (hand on truss only)"
    )
    parser.add_argument(
        "--active", action=argparse.BooleanOptionalAction, default=True, help="active inspection (seed §2.5)"
    )
    parser.add_argument("--compare", action="store_true", help="run active and passive on the same seeds")
    parser.add_argument("--size", type=int, nargs=2, default=(480, 640), metavar=("ROWS", "COLS"))
    parser.add_argument("--json", type=Path, default=None, help="per-seed results, written as they finish")
    args = parser.parse_args()
    if args.first_seed < 0 or args.seeds < 1:
        parser.error(f"--first-seed must be >= 0 and --seeds >= 1; got {args.first_seed}, {args.seeds}.")
    inspection_s = ORBIT_START_S[1] + args.sun_offset_s
    if not math.isfinite(inspection_s) or inspection_s < 0:
        parser.error(
            f"--sun-offset-s must be finite and >= {-ORBIT_START_S[1]:.1f} (the inspection pass cannot start "
            f"before the orbit's noon at t = 0); got {args.sun_offset_s}."
        )
    return args


def _settings(args: argparse.Namespace) -> dict[str, object]:
    """What a stored result depends on besides its seed (a file of other settings cannot be resumed)."""
    return {
        "size": list(args.size),
        "repeatability": args.repeatability,
        "orbit_start_s": [ORBIT_START_S[0], ORBIT_START_S[1] + args.sun_offset_s],
        "anomalies": "default",
        **({} if args.layout == "truss" else {"layout": args.layout}),
        **({} if args.plan == "auto" else {"plan": args.plan}),
    }


def _load(path: Path | None, settings: dict[str, object]) -> dict[str, Tally]:
    if path is None or not path.exists():
        return {}
    stored = json.loads(path.read_text())
    if stored.get("format") != _FORMAT or stored.get("settings") != settings:
        sys.exit(
            f"{path} holds results of other settings ({stored.get('settings')}); this run's are {settings}. "
            "Give another --json path."
        )
    return {mode: Tally.from_dict(data) for mode, data in stored["modes"].items()}


def _save(path: Path | None, settings: dict[str, object], tallies: dict[str, Tally]) -> None:
    if path is None:
        return
    text = json.dumps(
        {"format": _FORMAT, "settings": settings, "modes": {m: t.to_dict() for m, t in tallies.items()}},
        indent=1,
    )
    partial = path.with_name(path.name + ".partial")
    partial.write_text(text)
    partial.replace(path)  # atomic: an interrupted write leaves the last complete file


def _run(args: argparse.Namespace, modes: list[str], seeds: range) -> dict[str, Tally]:
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    settings = _settings(args)
    tallies = _load(args.json, settings)
    orbit_start = (ORBIT_START_S[0], ORBIT_START_S[1] + args.sun_offset_s)
    todo = [(mode, seed) for mode in modes for seed in seeds if seed not in tallies.get(mode, Tally()).seeds]
    columns = (TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, transient=True) as progress:
        task = progress.add_task("missions", total=len(todo))
        for mode, seed in todo:
            progress.update(task, description=f"{mode} seed {seed}")
            start = time.perf_counter()
            result = run_mission(
                seed,
                size=(args.size[0], args.size[1]),
                active=mode == "active",
                repeatability=args.repeatability,
                orbit_start_s=orbit_start,
                layout=args.layout,
                settings=MissionSettings(plan=args.plan),
            )
            run = tally_run(result, score_mission(result), mission_s=time.perf_counter() - start)
            tallies[mode] = tallies.get(mode, Tally()).merge(Tally((run,)))
            _save(args.json, settings, tallies)
            progress.advance(task)
    return {mode: Tally(tuple(r for r in tallies[mode].runs if r.seed in seeds)) for mode in modes}


def _interval(entry: Recall | Rate) -> str:
    return f"{entry.low:.3f}-{entry.high:.3f}"


def _recall(entry: Recall) -> str:
    return "-" if entry.truth == 0 else f"{entry.recall:.3f}"


def _print_tables(tally: Tally) -> None:
    errors = tally.localisation_error_m()
    print("\n| type | found/truth | recall | 95 % interval | localisation error mm |")
    print("| --- | --- | --- | --- | --- |")
    for name, entry in tally.per_type().items():
        error = "-" if math.isnan(errors[name]) else f"{1e3 * errors[name]:.1f}"
        label = "impact (>= 1 mm)" if name == "impact" else name
        print(f"| {label} | {entry.found}/{entry.truth} | {_recall(entry)} | {_interval(entry)} | {error} |")
    print("\n| type | subtype | surface | size | found/truth | recall | 95 % interval |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for key, entry in tally.per_stratum().items():
        note = " (does not count)" if key.size_band == "<1 mm" else ""
        print(
            f"| {key.type} | {key.subtype} | {key.surface} | {key.size_band}{note} | {entry.found}/"
            f"{entry.truth} | {_recall(entry)} | {_interval(entry)} |"
        )
    print("\n| finding kind | false findings | per run | 95 % interval |")
    print("| --- | --- | --- | --- |")
    for kind, rate in tally.false_by_kind().items():
        print(f"| {kind} | {rate.events} | {rate.per_run:.2f} | {rate.low:.2f}-{rate.high:.2f} |")
    free = tally.anomaly_free()
    print(
        "\n| anomaly-free runs | false findings | per run | 95 % interval | runs with a false finding | "
        "share | 95 % interval |"
    )
    print("| --- | --- | --- | --- | --- | --- | --- |")
    if free.runs == 0:
        print("| 0 | - | - | - | - | - | - |")
        return
    rate, alarmed = free.false_findings, free.runs_with_false
    print(
        f"| {free.runs} | {rate.events} | {rate.per_run:.2f} | {rate.low:.2f}-{rate.high:.2f} | "
        f"{alarmed.found}/{alarmed.truth} | {alarmed.recall:.3f} | {_interval(alarmed)} |"
    )


def _heading(args: argparse.Namespace, mode: str, tally: Tally, seeds: range) -> str:
    from rsi.sim.orbit import in_sunlight

    inspection_s = ORBIT_START_S[1] + args.sun_offset_s
    sun = "sunlit" if bool(in_sunlight(None, inspection_s)) else "in eclipse"
    development = set(seeds) & set(DEVELOPMENT_SEEDS)
    kind = "DEVELOPMENT seeds" if development == set(seeds) else "held out" if not development else "mixed"
    seconds = [run.mission_s for run in tally.runs]
    timing = f"mission {sum(seconds) / len(seconds):.1f} s mean, {max(seconds):.1f} s max" if seconds else ""
    return (
        f"\n### {mode}: seeds {seeds.start}..{seeds.stop - 1} ({kind}), {len(tally.runs)} runs, size "
        f"{args.size[0]}x{args.size[1]}, {args.repeatability}, sun offset {args.sun_offset_s:g} s "
        f"(inspection starts {inspection_s:.0f} s after orbit noon, {sun}); {timing}"
    )


def main() -> None:
    args = _arguments()
    modes = ["active", "passive"] if args.compare else ["active" if args.active else "passive"]
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    tallies = _run(args, modes, seeds)
    for mode in modes:
        print(_heading(args, mode, tallies[mode], seeds))
        _print_tables(tallies[mode])


if __name__ == "__main__":
    main()
