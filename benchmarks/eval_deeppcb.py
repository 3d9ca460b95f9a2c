"""DeepPCB: rsi's detector against a plain difference with a 5x5 opening, on a whole split.

Run from the repository root (the data are read in place, never copied)::

    .venv/bin/python benchmarks/eval_deeppcb.py                      # full trainval, 1-3 min on 2 cores
    .venv/bin/python benchmarks/eval_deeppcb.py --every 10           # every 10th pair, quick look
    .venv/bin/python benchmarks/eval_deeppcb.py --misregistration-std-px 1,2,3   # sensitivity sweep
    .venv/bin/python benchmarks/eval_deeppcb.py --logo                # leave-one-group-out
    .venv/bin/python benchmarks/eval_deeppcb.py --logo --out logo/    # + the pooled figures' pictures

``--logo`` scores every setting of ``--grid`` (registration model and mis-registration floor) on every
board group, then, for each group in turn, picks the setting with the best F1 on the other six and scores
it on that one: per group, pooled, and beside each setting's whole-trainval figure. The group named by
``--final-group`` (default group50600) is also the final held-out check: its row is the setting chosen on
the six others, looked at once, at the end.

The baseline is what a user would write first: threshold |inspection - reference| at mid-grey (the images
are binarised), open with a 5x5 square, report each connected component (no registration). Both detectors'
boxes get DeepPCB's 10 px padding so that the IoU columns compare detections, not box conventions.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
import zlib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import cast

import cv2
import numpy as np
from numpy.typing import NDArray

from rsi.datasets.deeppcb import DeepPcbPair, load_split, read_pair
from rsi.datasets.evaluate import (
    DeepPcbSettings,
    EvaluationResult,
    MatchCounts,
    PcbDetections,
    detect_defects,
    evaluate_pairs,
    group_defects,
    group_detection,
    group_of,
    leave_one_group_out,
    match_counts,
    name_detection,
    register_pair,
    registration_options,
    sparse_above,
)
from rsi.datasets.official import OfficialTally
from rsi.datasets.pcb_features import DefectClassifier, fit_classifier
from rsi.datasets.pcb_learn import training_labels
from rsi.detection.detect import detect
from rsi.report.deeppcb import write_deeppcb_report

DEFAULT_ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "deeppcb"
MID_GREY_DN = 127.5
OPENING = np.ones((5, 5), np.uint8)
PADDING_PX = DeepPcbSettings().box_padding_px


def baseline(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> PcbDetections:
    """Plain difference, thresholded at mid-grey, opened with a 5x5 square; one defect per component."""
    changed = (np.abs(inspection - reference) > MID_GREY_DN).astype(np.uint8)
    opened = cv2.morphologyEx(changed, cv2.MORPH_OPEN, OPENING)
    return group_defects(opened.astype(bool), grow_px=PADDING_PX)


Detector = Callable[[NDArray[np.float32], NDArray[np.float32]], PcbDetections]
# The distorted boards' field: three plane waves per axis of 0.3-1.5 periods across the board, scaled so
# that the largest displacement is the amplitude asked for (issue 12: 1-3 px that vary across the board
# on pairs outside trainval).
DISTORTION_WAVES = 3
DISTORTION_PERIODS = (0.3, 1.5)


def smooth_distortion(shape: tuple[int, int], amplitude_px: float, seed: int) -> NDArray[np.float32]:
    """A smooth displacement field (2, rows, cols) whose largest component is `amplitude_px`."""
    rng = np.random.default_rng(seed)
    rows, cols = np.mgrid[0 : shape[0], 0 : shape[1]].astype(np.float32)
    field = np.zeros((2, *shape), np.float32)
    for axis in range(2):
        for _ in range(DISTORTION_WAVES):
            kx, ky = rng.uniform(*DISTORTION_PERIODS, 2) * 2 * np.pi / np.array(shape[::-1])
            field[axis] += np.sin(kx * cols + ky * rows + rng.uniform(0, 2 * np.pi)).astype(np.float32)
        field[axis] *= amplitude_px / max(float(np.abs(field[axis]).max()), 1e-9)
    return field


def distorted(detector: Detector, amplitude_px: float) -> Detector:
    """`detector` run on the tested board warped by a smooth field (the same for a pair in every run: seeded
    by the image's CRC) and binarised again; its detections are carried back to the board's own frame, so
    the pair's boxes score them. A held-out stand-in for boards whose distortion trainval does not show."""

    def run(reference: NDArray[np.float32], inspection: NDArray[np.float32]) -> PcbDetections:
        field = smooth_distortion(inspection.shape, amplitude_px, zlib.crc32(inspection.tobytes()))
        rows, cols = np.mgrid[0 : inspection.shape[0], 0 : inspection.shape[1]].astype(np.float32)
        moved = cv2.remap(
            inspection, cols + field[0], rows + field[1], cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT
        )
        found = detector(reference, np.where(moved > MID_GREY_DN, 255.0, 0.0).astype(np.float32))
        if not len(found.centres_xy):
            return found
        # Test pixel q shows the board at q + u(q): so does each detection.
        at = np.round(found.centres_xy).astype(np.intp)
        at = np.clip(at, 0, [inspection.shape[1] - 1, inspection.shape[0] - 1])
        shift = field[:, at[:, 1], at[:, 0]].T.astype(np.float64)
        return dataclasses.replace(
            found,
            centres_xy=found.centres_xy + shift,
            boxes_xyxy=found.boxes_xyxy + np.round(np.hstack([shift, shift])).astype(np.int64),
        )

    return run


COLUMNS = (
    "recall",
    "precision",
    "f1",
    "false_alarms_per_image",
    "iou_recall",
    "iou_precision",
    "seconds_per_pair",
    "official_precision",
    "official_recall",
    "official_f",
    "map",
)


def _row(name: str, result: EvaluationResult) -> str:
    figures = result.to_dict()
    cells = [f"{figures[key]:.3f}" for key in COLUMNS]
    return f"| {name} | {result.pairs} | {result.defects} | " + " | ".join(cells) + " |"


def _class_table(result: EvaluationResult) -> None:
    print("\n| class | boxes | detections | precision | recall | AP |")
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    for name, row in result.per_class.items():
        print(
            f"| {name} | {row['boxes']:.0f} | {row['detections']:.0f} | {row['precision']:.3f} "
            f"| {row['recall']:.3f} | {row['ap']:.3f} |"
        )
    names = ["none", *result.per_class]
    print("\nconfusion (rows: true class, columns: detected class; IoU > 0.33, class-agnostic pairing)\n")
    print("| true \\ detected | " + " | ".join(names) + " |")
    print("| --- |" + " ---: |" * len(names))
    for name, row in zip(names, result.confusion, strict=True):
        print(f"| {name} | " + " | ".join(str(value) for value in row) + " |")


def _settings(spec: str, base: DeepPcbSettings | None = None) -> DeepPcbSettings:
    """ "affine:3" -> `base` (default DeepPcbSettings()) with registration_model="affine" and a 3 px floor;
    "local:3:10" also merges pieces within 10 px (merge_gap_px), "local:3:10:disc" also tests with the
    disc flaw model (flaw_model)."""
    model, floor, *rest = spec.split(":")
    chosen = dataclasses.replace(
        base or DeepPcbSettings(), registration_model=model, misregistration_std_px=float(floor)
    )
    if rest:
        chosen = dataclasses.replace(chosen, merge_gap_px=int(rest[0]))
    return dataclasses.replace(chosen, flaw_model=rest[1]) if len(rest) > 1 else chosen


Found = list[tuple[DeepPcbPair, PcbDetections, float]]


def _run(pairs: Sequence[DeepPcbPair], settings: DeepPcbSettings) -> Found:
    """Each pair's detections (topology-rule classes) and wall seconds, reading the JPEGs included."""
    found = []
    for pair in pairs:
        start = time.perf_counter()
        detections = detect_defects(*read_pair(pair), settings=settings)
        found.append((pair, detections, time.perf_counter() - start))
    return found


def _tally(found: Found, classifier: DefectClassifier | None = None) -> OfficialTally:
    tally = OfficialTally()
    for pair, detections, _ in found:
        classes, confidences = detections.classes, detections.confidences
        if classifier is not None:
            classes, confidences = classifier.predict(detections.features)
        tally.add(pair.boxes_xyxy, pair.defect_types, detections.boxes_xyxy, classes, confidences)
    return tally


def _fit(found: Found) -> DefectClassifier:
    features = np.concatenate([cast(np.ndarray, detections.features) for _, detections, _ in found])
    labels = np.concatenate([training_labels(pair, detections) for pair, detections, _ in found])
    return fit_classifier(features, labels)


def logo(
    pairs: Sequence[DeepPcbPair], grid: list[str], final_group: str, base: DeepPcbSettings | None = None
) -> EvaluationResult:
    """Leave-one-group-out over the board groups (see the module docstring); returns the pooled figures
    with the learned classes."""
    groups = sorted({group_of(pair) for pair in pairs})
    runs: dict[str, dict[str, Found]] = {}
    counts: dict[str, dict[str, MatchCounts]] = {}
    for spec in grid:
        found = _run(pairs, _settings(spec, base))
        runs[spec] = {group: [item for item in found if group_of(item[0]) == group] for group in groups}
        counts[spec] = {
            group: sum((match_counts(*item) for item in runs[spec][group]), MatchCounts()) for group in groups
        }
        rules = {group: _tally(runs[spec][group]) for group in groups}
        print(_row(f"whole set, {spec}, rules (tuned on it)", _official(counts[spec], rules)), flush=True)
    result = leave_one_group_out(counts)
    rules, learned = {}, {}
    for group in groups:
        spec = result.chosen[group]
        # The classifier of this fold sees the six other groups only, under the setting chosen on them.
        training = [item for other in groups if other != group for item in runs[spec][other]]
        rules[group] = _tally(runs[spec][group])
        learned[group] = _tally(runs[spec][group], _fit(training))
    for group in groups:
        label = "final held-out check" if group == final_group else "left out"
        figures = _official({group: result.held_out[group]}, {group: learned[group]})
        print(_row(f"{group} ({label}; chosen on the others: {result.chosen[group]}), learned", figures))
    print(_row("pooled, leave-one-group-out, rules", _official(result.held_out, rules)))
    pooled = _official(result.held_out, learned)
    print(_row("**pooled, leave-one-group-out, learned**", pooled), flush=True)
    _class_table(pooled)
    return pooled


def _official(counts: dict[str, MatchCounts], tallies: dict[str, OfficialTally]) -> EvaluationResult:
    """Class-agnostic figures of the summed counts with the official ones of the summed tallies."""
    total = sum(counts.values(), MatchCounts()).result()
    return dataclasses.replace(total, **sum(tallies.values(), OfficialTally()).figures())


def profile(pairs: Sequence[DeepPcbPair], settings: DeepPcbSettings) -> None:
    """CPU time of each stage of detect_defects per pair, one thread, reading the JPEGs included."""
    cv2.setNumThreads(1)
    stages: dict[str, list[float]] = {
        name: [] for name in ("read", "register", "detect", "group", "name", "total")
    }
    for pair in pairs:
        clock = [time.thread_time()]

        def lap(name: str, clock: list[float] = clock) -> None:
            now = time.thread_time()
            stages[name].append(now - clock[0])
            clock[0] = now

        start = clock[0]
        reference, inspection = read_pair(pair)
        lap("read")
        fit = register_pair(reference, inspection, **registration_options(settings))
        lap("register")
        detection = detect(
            reference,
            inspection,
            flaw_model=settings.flaw_model,
            size=settings.size,
            method=settings.method,
            p_false_alarm=settings.p_false_alarm,
            noise_sigma=settings.noise_sigma,
            registration=fit,
            misregistration_std_px=settings.misregistration_std_px,
            sparse_above=sparse_above(settings),
        )
        lap("detect")
        found = group_detection(detection, settings)
        lap("group")
        name_detection(found, detection, inspection)
        lap("name")
        stages["total"].append(time.thread_time() - start)
    _speed_table(stages, settings, len(pairs))


# Issue 12's speed target: the deep model of Tang et al. 2019 (arXiv:1902.06197) runs at 62 pairs/s, as its
# paper reports, on a GPU; rsi is held to the same rate on one CPU thread.
DEEP_MODEL_PAIRS_PER_S = 62.0
TARGET_MS = 1e3 / DEEP_MODEL_PAIRS_PER_S


def _speed_table(stages: dict[str, list[float]], settings: DeepPcbSettings, pairs: int) -> None:
    """Per-stage CPU ms (median, mean), the total as pairs/s, and the deep model's rate beside it."""
    print(
        f"\nstage CPU ms per pair, one thread, {pairs} pairs ({settings.registration_model}, "
        f"mis-registration floor {settings.misregistration_std_px:g} px), reading both JPEGs included\n"
    )
    print("| stage | median ms | mean ms |")
    print("| --- | ---: | ---: |")
    for name, seconds in stages.items():
        print(f"| {name} | {1e3 * float(np.median(seconds)):.1f} | {1e3 * float(np.mean(seconds)):.1f} |")
    total_ms = 1e3 * float(np.median(stages["total"]))
    print("\n| detector | hardware | ms per pair | pairs/s |")
    print("| --- | --- | ---: | ---: |")
    print(f"| rsi (this run, median) | one CPU thread | {total_ms:.1f} | {1e3 / total_ms:.1f} |")
    print(
        f"| deep model (Tang et al. 2019, as reported; not run here) | a GPU | {TARGET_MS:.1f} "
        f"| {DEEP_MODEL_PAIRS_PER_S:.0f} |"
    )
    verdict = "met" if total_ms <= TARGET_MS else "not met"
    print(f"\nissue 12's target, <= {TARGET_MS:.1f} ms per pair on one thread: {verdict}")


def _chosen_settings(args: argparse.Namespace) -> DeepPcbSettings:
    """DeepPcbSettings() with the registration and sparse options of the command line, replaced at once (the
    finest and coarsest levels are checked against each other)."""
    changes: dict[str, object] = {}
    if args.model is not None:
        changes["registration_model"] = args.model
    if args.finest_level is not None:
        changes["registration_finest_level"] = args.finest_level
    if args.coarsest_level is not None:
        coarsest = None if args.coarsest_level == "all" else int(args.coarsest_level)
        changes["registration_coarsest_level"] = coarsest
    if args.row_step is not None:
        changes["registration_row_step"] = None if args.row_step == "auto" else int(args.row_step)
    if args.photometric:
        changes["registration_photometric"] = True
    if args.presmooth:
        changes["registration_presmooth"] = True
    if args.whole_frame:
        changes["sparse"] = False
    if args.field_tolerance_px is not None:
        changes["registration_field_tolerance_px"] = args.field_tolerance_px
    return dataclasses.replace(DeepPcbSettings(), **changes)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--root", type=Path, default=DEFAULT_ROOT, help="DeepPCB folder (holds PCBData/)")
    parser.add_argument("--split", default="trainval", choices=("trainval", "test"))
    parser.add_argument("--every", type=int, default=1, help="use every n-th pair (1: all)")
    parser.add_argument("--offset", type=int, default=0, help="... starting from this pair (0: the first)")
    parser.add_argument(
        "--misregistration-std-px",
        default=None,
        help="comma-separated values to sweep (default: DeepPcbSettings())",
    )
    parser.add_argument("--no-baseline", action="store_true")
    parser.add_argument("--logo", action="store_true", help="leave-one-group-out over the board groups")
    parser.add_argument(
        "--grid",
        default="affine:2,affine:3,affine:4",
        help="settings for --logo: model:floor_px[:merge_gap_px[:flaw_model]], ...",
    )
    parser.add_argument("--final-group", default="group50600", help="the final held-out check of --logo")
    parser.add_argument(
        "--profile", default=None, help="model:floor_px: CPU time of each stage, one thread (no scoring)"
    )
    parser.add_argument(
        "--finest-level",
        type=int,
        default=None,
        help="registration_finest_level (default: DeepPcbSettings()'s); 0 refines at full resolution",
    )
    parser.add_argument(
        "--coarsest-level",
        default=None,
        help="registration_coarsest_level (default: DeepPcbSettings()'s); 'all' for the whole pyramid",
    )
    parser.add_argument(
        "--row-step",
        default=None,
        help="registration_row_step (default: DeepPcbSettings()'s); 'auto' for rsi.register's default",
    )
    parser.add_argument(
        "--photometric",
        action="store_true",
        help="registration_photometric=True: fit a gain and bias (the code before the third step)",
    )
    parser.add_argument(
        "--presmooth",
        action="store_true",
        help="registration_presmooth=True: smooth the full-resolution images first (before the third step)",
    )
    parser.add_argument(
        "--whole-frame", action="store_true", help="sparse=False: the detector's maps on the whole frame"
    )
    parser.add_argument(
        "--model", default=None, help="registration_model (default: DeepPcbSettings()'s), e.g. local"
    )
    parser.add_argument(
        "--field-tolerance-px",
        type=float,
        default=None,
        help="registration_field_tolerance_px (default: DeepPcbSettings()'s): the local field's tolerance",
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="write the last run's record, per-class table and pictures here (--logo: the pooled figures)",
    )
    parser.add_argument(
        "--distort-px",
        type=float,
        default=None,
        help="warp each tested board by a smooth field of this amplitude first (a held-out stand-in)",
    )
    args = parser.parse_args(argv)
    default = _chosen_settings(args)
    if not (args.root / "PCBData").is_dir():
        print(f"DeepPCB not found at {args.root}; pass --root (see ../shared/data/deeppcb/README.md).")
        return 1
    pairs = load_split(args.root, args.split)[args.offset :: args.every]
    if args.profile:
        profile(pairs, _settings(args.profile, default))
        return 0
    print(
        f"DeepPCB {args.split}: {len(pairs)} pairs; centre-in-box rule for recall/precision/F1/FA, "
        "class-agnostic IoU > 0.33 for the IoU columns\n"
    )
    print(
        "| detector | pairs | defects | recall | precision | F1 | FA/image | IoU recall | IoU precision "
        "| s/pair | official P | official R | official F | mAP |"
    )
    print("| --- |" + " ---: |" * 13)
    if args.logo:
        _written(args.out, logo(pairs, args.grid.split(","), args.final_group, default))
        return 0
    stds = (
        [default.misregistration_std_px]
        if args.misregistration_std_px is None
        else [float(value) for value in args.misregistration_std_px.split(",")]
    )
    last = None

    def chosen(detector: Detector) -> Detector:
        return detector if args.distort_px is None else distorted(detector, args.distort_px)

    suffix = "" if args.distort_px is None else f", boards distorted by {args.distort_px:g} px"
    for std_px in stds:
        settings = dataclasses.replace(default, misregistration_std_px=std_px)

        def rsi(reference: NDArray[np.float32], inspection: NDArray[np.float32], s=settings) -> PcbDetections:
            return detect_defects(reference, inspection, settings=s)

        result = evaluate_pairs(pairs, chosen(rsi))
        label = f"rsi ({settings.registration_model}, sigma_s={std_px:g} px{suffix})"
        print(_row(label, result), flush=True)
        last = result
    if not args.no_baseline:
        print(_row(f"difference + 5x5 opening{suffix}", evaluate_pairs(pairs, chosen(baseline))), flush=True)
    if last is not None:
        _class_table(last)
        _written(args.out, last)
    return 0


def _written(out: Path | None, result: EvaluationResult) -> None:
    """The result's folder (rsi.report.deeppcb: deeppcb.json, per_class.csv, per_class.png, confusion.png)."""
    if out is not None:
        files = write_deeppcb_report(out, result.to_dict())
        print(f"\nwrote {', '.join(str(path) for path in files.values())}")


if __name__ == "__main__":
    sys.exit(main())
