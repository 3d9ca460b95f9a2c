"""Direct tests of the checks added for the hostile suite whose messages the generated cases may not reach
(issue 17): each asserts the argument, the value or the fix is named."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from rsi import _validate as v
from rsi.datasets.deeppcb import DeepPcbPair, read_annotation
from rsi.datasets.evaluate import (
    MatchCounts,
    PcbDetections,
    count_pairs,
    detect_defects,
    leave_one_group_out,
    match_counts,
)
from rsi.datasets.official import average_precision, pair_official
from rsi.datasets.pcb_classes import classify_defects, classify_window
from rsi.datasets.synthetic import synthetic_pair
from rsi.detection.noise import (
    affine_variance,
    fit_sensor_variance,
    interpolation_factor,
    mean_interpolation_factor,
    systematic_errors,
)
from rsi.errors import DatasetError, InputError
from rsi.mission.score import run_roc
from rsi.mission.settings import MissionSettings
from rsi.sim.mockup import vista
from rsi.sim.solar_simulator import LampOptics


def test_a_vista_needs_a_name() -> None:
    with pytest.raises(InputError, match="name must be a non-empty string; got ''"):
        vista("", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), 0.5)


def test_a_vista_refuses_an_up_along_its_normal() -> None:
    with pytest.raises(InputError, match=r"up=\(0, 0, 2\) is parallel to normal=\(0, 0, 1\)"):
        vista("A_door", (0.0, 0.0, 0.0), (0, 0, 1), (0, 0, 2), 0.5)


def test_a_vista_is_built_from_checked_vectors() -> None:
    view = vista("A_door", (1, 2, 3), (0, 0, 2), (0, 1, 0), 0.5)
    assert view.position_m == (1.0, 2.0, 3.5)
    assert view.forward == (0.0, 0.0, -1.0)


# ------------------------------------------------------------------------------------------ rsi._validate


def test_a_vector_is_three_finite_numbers() -> None:
    assert v.vector3([1, 2, 3], "position_m") == (1.0, 2.0, 3.0)
    for bad in ((1.0, 2.0), (1.0, 2.0, math.nan), "xyz"):
        with pytest.raises(InputError, match="position_m must be"):
            v.vector3(bad, "position_m")


def test_a_direction_is_normalised_and_never_zero() -> None:
    assert np.allclose(v.direction3((0, 0, 2), "normal"), (0.0, 0.0, 1.0))
    with pytest.raises(InputError, match=r"normal must be a non-zero direction; got \(0, 0, 0\)"):
        v.direction3((0, 0, 0), "normal")
    assert np.allclose(v.direction3((1e308, 1e308, 0.0), "normal"), (2**-0.5, 2**-0.5, 0.0))  # no overflow


def test_an_optional_settings_object_defaults_or_is_checked() -> None:
    assert v.instance_or_default(None, "optics", LampOptics) == LampOptics()
    optics = LampOptics(beam_flux_lm=100.0)
    assert v.instance_or_default(optics, "optics", LampOptics) is optics
    with pytest.raises(InputError, match="optics must be a LampOptics"):
        v.instance_or_default(1.5, "optics", LampOptics)


# --------------------------------------------------------------------------------------- rsi.datasets


def _pair(tmp_path: Path) -> DeepPcbPair:
    boxes = np.array([[1, 1, 4, 4]], dtype=np.int64)
    return DeepPcbPair(
        "group1/1/1", tmp_path / "a.jpg", tmp_path / "b.jpg", tmp_path / "a.txt", boxes, boxes[:, 0]
    )


def test_an_annotation_must_be_utf8_text_of_bounded_size(tmp_path: Path) -> None:
    binary = tmp_path / "binary.txt"
    binary.write_bytes(b"\xff\xfe 1 2 3 4 1")
    with pytest.raises(DatasetError, match=r"binary\.txt' is not UTF-8 text"):
        read_annotation(binary)
    huge = tmp_path / "huge.txt"
    huge.write_bytes(b"0 0 1 1 1\n" * 200_000)
    with pytest.raises(DatasetError, match=r"huge\.txt' is 2000000 bytes, over 1048576: not a DeepPCB"):
        read_annotation(huge)


def test_match_counts_checks_the_detections_and_the_time(tmp_path: Path) -> None:
    found = PcbDetections(np.array([[2.0, 2.0]]), np.array([[1, 1, 4, 4]]))
    assert match_counts(_pair(tmp_path), found, 0.5).found == 1
    with pytest.raises(InputError, match="found must be a PcbDetections; got ndarray"):
        match_counts(_pair(tmp_path), np.zeros((1, 2)))
    with pytest.raises(InputError, match=r"seconds must be in \[0.0, inf\]; got -1.0"):
        match_counts(_pair(tmp_path), found, -1.0)


def test_count_pairs_checks_its_detector_progress_and_tally(tmp_path: Path) -> None:
    pairs = (_pair(tmp_path),)
    with pytest.raises(InputError, match=r"pairs\[1\] must be a DeepPcbPair"):
        count_pairs((pairs[0], "b"), detect_defects)
    with pytest.raises(InputError, match=r"detector must be a function called as detector\(reference"):
        count_pairs(pairs, "detect")  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"progress must be a function called as progress\(pair_id"):
        count_pairs(pairs, detect_defects, progress=3)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="tally must be a OfficialTally"):
        count_pairs(pairs, detect_defects, tally={})  # type: ignore[arg-type]


def test_leave_one_group_out_names_a_count_that_is_not_one() -> None:
    with pytest.raises(InputError, match=r"counts\['loose'\]\['a'\] must be a MatchCounts"):
        leave_one_group_out({"loose": {"a": 3, "b": MatchCounts()}})  # type: ignore[dict-item]
    with pytest.raises(InputError, match=r"counts\['loose'\] must be a dict of group -> MatchCounts"):
        leave_one_group_out({"loose": 3})  # type: ignore[dict-item]


def test_the_official_rule_checks_classes_and_flags() -> None:
    box = np.array([[0, 0, 4, 4]])
    found, correct = pair_official(box, [1], box, [1])
    assert found.tolist() == correct.tolist() == [True]
    with pytest.raises(InputError, match="detected_classes must hold 1 whole-number classes"):
        pair_official(box, [1], box, [1.5])
    with pytest.raises(InputError, match="truth_classes must hold 1 whole-number classes"):
        pair_official(box, [1, 2], box, [1])
    assert average_precision([0.9, 0.1], [True, False], 1) == 1.0
    with pytest.raises(InputError, match="correct must hold 2 booleans"):
        average_precision([0.9, 0.1], [True], 1)
    with pytest.raises(InputError, match="confidences contain NaN"):
        average_precision([math.nan], [True], 1)
    with pytest.raises(InputError, match=r"boxes must be an integer in \[0, 9007199254740992\]; got -1"):
        average_precision([0.9], [True], -1)


def test_classifying_defects_needs_matching_images_and_boxes_inside_them() -> None:
    board = np.full((8, 8), 255.0)
    classes, confidences = classify_defects(board, board, np.array([[0, 0, 7, 7]]))
    assert classes.shape == confidences.shape == (1,)
    with pytest.raises(InputError, match="template and test must have the same shape"):
        classify_window(board, board[:4])
    with pytest.raises(InputError, match="template and test must have the same shape"):
        classify_defects(board, board[:4], np.empty((0, 4)))
    with pytest.raises(InputError, match=r"boxes_xyxy must be whole-pixel boxes .* 0 <= x1 <= x2 < 8"):
        classify_defects(board, board, np.array([[0, 0, 8, 3]]))
    with pytest.raises(InputError, match="boxes_xyxy must be whole-pixel boxes"):
        classify_defects(board, board, np.array([[0.5, 0, 3, 3]]))


def test_a_synthetic_shift_must_leave_the_pair_overlapping() -> None:
    with pytest.raises(
        InputError, match=r"shift_xy=\(64, 0\) moves the image off itself \(shape \(32, 64\)\)"
    ):
        synthetic_pair((32, 64), shift_xy=(64, 0), rng=0)
    with pytest.raises(InputError, match="shift_xy must be a"):
        synthetic_pair((32, 64), shift_xy=1.0, rng=0)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------------------- rsi.mission


def test_run_roc_checks_its_settings() -> None:
    assert run_roc((), MissionSettings()) == ()
    with pytest.raises(InputError, match="settings must be a MissionSettings"):
        run_roc((), {})  # type: ignore[arg-type]


# ------------------------------------------------------------------------------- rsi.detection.noise


def test_the_sensor_variance_fit_checks_its_images_and_numbers() -> None:
    rng = np.random.default_rng(0)
    predicted = rng.uniform(10.0, 200.0, (64, 64)).astype(np.float32)
    difference = rng.normal(0.0, 2.0, (64, 64)).astype(np.float32)
    valid = np.ones((64, 64), dtype=bool)
    a, b = fit_sensor_variance(difference, predicted, valid, gain=1.0, bias=0.0, factor=1.0)
    assert a >= 0.0 and b >= 0.0
    with pytest.raises(InputError, match="gain must be non-zero"):
        fit_sensor_variance(difference, predicted, valid, gain=0.0, bias=0.0, factor=1.0)
    with pytest.raises(InputError, match="bias must be finite"):
        fit_sensor_variance(difference, predicted, valid, gain=1.0, bias=math.nan, factor=1.0)
    with pytest.raises(InputError, match=r"factor must be in \[0.0, inf\]"):
        fit_sensor_variance(difference, predicted, valid, gain=1.0, bias=0.0, factor=-1.0)
    with pytest.raises(InputError, match="difference and predicted must have the same shape"):
        fit_sensor_variance(difference[:8], predicted, valid, gain=1.0, bias=0.0, factor=1.0)
    with pytest.raises(InputError, match=r"valid must have shape \(64, 64\)"):
        fit_sensor_variance(difference, predicted, valid[:8], gain=1.0, bias=0.0, factor=1.0)


def test_the_variance_model_and_error_maps_check_their_parameters() -> None:
    assert affine_variance(np.array([1.0, -10.0]), (1.0, 0.5)).tolist() == [1.5, 0.0]
    with pytest.raises(InputError, match="intensity must be an array of numbers; got dtype=complex128"):
        affine_variance(np.ones(2, dtype=complex), (1.0, 0.5))
    with pytest.raises(InputError, match=r"coefficients must be \(a, b\)"):
        affine_variance(np.ones(2), (1.0, 1e300))
    plane = np.zeros((8, 8), dtype=np.float32)
    assert systematic_errors(plane, None, (math.inf, math.nan))[0].shape == (8, 8)  # unknown is allowed
    with pytest.raises(InputError, match=r"shift_std_px must be two numbers \(x, y\) in \[0, inf\] or NaN"):
        systematic_errors(plane, None, (-1.0, 0.0))
    with pytest.raises(InputError, match=r"fraction_xy must be two numbers \(x, y\) in \[0, 1\]"):
        systematic_errors(plane, (0.5, 1.5), (0.1, 0.1))


def test_the_interpolation_factor_needs_a_flaw_model_and_is_scale_free() -> None:
    model = np.ones((3, 3))
    assert interpolation_factor(model * 1e300, (0.5, 0.5)) == pytest.approx(
        interpolation_factor(model, (0.5, 0.5))
    )
    with pytest.raises(InputError, match="weights must be a finite, non-zero 2-D flaw model"):
        mean_interpolation_factor(np.zeros((3, 3)))


def test_mission_settings_refuse_an_integer_beyond_the_float_range() -> None:
    with pytest.raises(
        InputError, match="p_false_alarm must be a finite number; got an integer of 1329 bits"
    ):
        MissionSettings(p_false_alarm=10**400)


# ------------------------------------------------------- found by the 1,000-case runs of test_hostile_api


def test_a_deeppcb_root_must_be_a_path() -> None:
    from rsi.datasets.deeppcb import load_split

    with pytest.raises(InputError, match="root must be a folder path"):
        load_split(None)  # type: ignore[arg-type]


def test_a_defect_mask_must_be_a_number_array() -> None:
    from rsi.datasets.evaluate import group_defects

    with pytest.raises(InputError, match="mask must be a numpy bool or number array"):
        group_defects(None)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="mask must be a numpy bool or number array"):
        group_defects(np.array([["a"]]))


def test_mission_settings_name_an_array_given_for_a_choice() -> None:
    with pytest.raises(InputError, match="plan must be one of"):
        MissionSettings(plan=np.zeros(3))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="flaw_model must be 'single', 'uniform', 'disc' or 'peak'"):
        MissionSettings(flaw_model=np.zeros(3))  # type: ignore[arg-type]


def test_the_distance_check_takes_a_bool_for_inf() -> None:
    from rsi.sensors.proximity import as_distances_m

    with pytest.raises(InputError, match="allow_inf must be True or False"):
        as_distances_m([0.5], "distance_m", allow_inf=np.ones(2))  # type: ignore[arg-type]


def test_a_deeppcb_root_too_long_for_the_file_system_is_named() -> None:
    from rsi.datasets.deeppcb import load_split

    with pytest.raises(DatasetError, match="cannot be read: File name too long"):
        load_split("x" * 300)


def test_a_file_name_with_a_nul_is_refused_by_the_readers() -> None:
    from rsi.mission.batch_manifest import read_manifest

    with pytest.raises(DatasetError, match="holds a NUL character"):
        read_annotation("aaa\x00")
    with pytest.raises(DatasetError, match="holds a NUL character"):
        read_manifest("pairs\x00.csv")


def test_a_ragged_flaw_footprint_is_named() -> None:
    from rsi.detection.roc import footprint_size

    with pytest.raises(InputError, match="weights must be a number or an array of numbers"):
        footprint_size([[1.0, 2.0], [3.0]])  # type: ignore[arg-type]


def test_counts_beyond_exact_floats_are_refused_by_the_rate_interval() -> None:
    from rsi.mission.tally import poisson_rate_interval

    with pytest.raises(InputError, match=r"events must be an integer in \[0, 9007199254740992\]"):
        poisson_rate_interval(10**110, 1)


def test_a_butterworth_order_is_bounded() -> None:
    from rsi.sensors.proximity import MAX_ORDER, LowPassFilter

    with pytest.raises(InputError, match=rf"order must be an integer in \[1, {MAX_ORDER}\]"):
        LowPassFilter(3.0, 44.0, order=78699)


def test_a_damping_whose_square_overflows_is_refused() -> None:
    from rsi.control.redundancy import damped_least_squares, damped_pseudo_inverse

    with pytest.raises(InputError, match=r"damping must be in \[0.0, 1e\+150\]"):
        damped_pseudo_inverse(np.eye(3), damping=1e300)
    with pytest.raises(InputError, match=r"damping must be in \[0.0, 1e\+150\]"):
        damped_least_squares(np.eye(3), np.ones(3), damping=1e300)


def test_an_archive_path_too_long_for_the_file_system_is_named(tmp_path: Path) -> None:
    from rsi.archive import Archive, ArchiveFileError

    with pytest.raises(ArchiveFileError, match="cannot be used: File name too long"):
        Archive.open(tmp_path / ("x" * 300))
    assert not any(tmp_path.iterdir())


def test_a_float64_prediction_gets_its_error_maps() -> None:
    plane = np.random.default_rng(0).random((16, 16)) * 255.0
    maps = systematic_errors(plane, None, (0.0, 0.0))
    assert all(each.dtype == np.float32 and each.shape == (16, 16) for each in maps)
    assert maps[2].any()  # the curvature of a textured plane


def test_commands_of_different_samples_are_named() -> None:
    from rsi.control.blending import blend_commands

    with pytest.raises(InputError, match="must describe the same samples"):
        blend_commands([], np.ones(3), np.full((3, 2), 0.5))


def test_an_average_precision_over_more_boxes_than_floats_count_is_refused() -> None:
    with pytest.raises(InputError, match=r"boxes must be an integer in \[0, 9007199254740992\]"):
        average_precision([0.5], [True], 10**110)


def test_an_archive_path_with_a_nul_is_named() -> None:
    from rsi.archive import Archive

    with pytest.raises(InputError, match="holds a NUL character"):
        Archive.open("archive\x00.db")
