"""The 44 Hz proximity loop on the arm (seed §3.1): issue 4's acceptance figures, metrics and bad input."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sensors.proximity import ProximitySensor
from rsi.sim import isee_demo as demo
from rsi.sim.arm import Arm, Wall

LAW = demo.DEMO_LAW


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[demo.DemoFigures, Path]:
    out = tmp_path_factory.mktemp("proximity_demo")
    messages: list[str] = []
    figures = demo.run_proximity_demo(out, seed=0, progress=messages.append)
    assert len(messages) >= 6
    return figures, out


def test_full_push_stops_in_region_c_without_oscillation(demo_run: tuple[demo.DemoFigures, Path]) -> None:
    figures, _ = demo_run
    assert figures.avoidance_near_edge_m == LAW.avoidance_start_m
    assert figures.min_distance_full_push_m >= figures.avoidance_near_edge_m - 0.010
    assert figures.push_oscillation_m <= 0.002  # sensor noise only, no limit cycle


def test_servo_from_0_6_m_settles(demo_run: tuple[demo.DemoFigures, Path]) -> None:
    figures, _ = demo_run
    assert figures.servo_settle_error_m <= 0.005
    assert figures.servo_settle_time_s <= 2.0
    assert figures.servo_overshoot_m <= 0.010


def test_following_contour_arm_and_lamp(demo_run: tuple[demo.DemoFigures, Path]) -> None:
    figures, out = demo_run
    assert figures.following_error_m <= 0.015
    assert figures.contour_rms_error_m <= 0.005
    assert figures.arm_tracking_error_m <= 0.001
    assert figures.lamp_illumination_error <= 0.01
    details = json.loads((out / "scenarios.json").read_text())
    assert details["additional_task_error_deg"] <= 1.0
    for surface in details["surfaces"].values():
        # region B/C keep a protrusion coming into view from pushing the arm toward the wall
        assert surface["closest_m"] >= LAW.avoidance_start_m


def test_files_written(demo_run: tuple[demo.DemoFigures, Path]) -> None:
    figures, out = demo_run
    assert json.loads((out / "figures.json").read_text()) == figures.to_dict()
    for name in (
        "fig3_readings_vs_position",
        "fig6_avoidance_velocity",
        "fig7_servo_velocity",
        "a_full_push",
        "b_servo",
        "c_follow_stepped",
        "c_follow_curved",
        "d_contour",
        "f_lamp",
    ):
        assert (out / f"{name}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_same_seed_same_figures(demo_run: tuple[demo.DemoFigures, Path], tmp_path: Path) -> None:
    figures, _ = demo_run
    assert demo.run_proximity_demo(tmp_path, seed=0) == figures


def test_seed_changes_the_noise() -> None:
    first = demo.servo_approach(rng=1).trace
    again = demo.servo_approach(rng=1).trace
    other = demo.servo_approach(rng=2).trace
    np.testing.assert_array_equal(first.reading_m, again.reading_m)
    np.testing.assert_array_equal(first.true_m, again.true_m)
    assert not np.array_equal(first.reading_m, other.reading_m)


def test_figs_6_7_sweep_is_open_loop() -> None:
    trace = demo.reading_sweep(rng=0).trace
    # seed §3.1: for Figs 6-7 x_ps was computed but not added; the arm follows the trajectory alone
    np.testing.assert_allclose(trace.command_m_s, -demo.SWEEP_SPEED_M_S)
    assert trace.proximity_m_s.min() < -LAW.joystick_speed_m_s
    assert trace.out_of_range[-1].all()


def test_settle_figures_on_a_known_response() -> None:
    time_s = np.arange(200) / 44.0
    distance = 0.39 + 0.2 * np.exp(-time_s / 0.1)
    distance[60] = 0.39 - 0.008  # one sample past the standoff
    error, settle, overshoot = demo.settle_figures(time_s, distance, 0.39)
    assert error < 1e-6
    assert settle == pytest.approx(61 / 44.0)
    assert overshoot == pytest.approx(0.008)
    _, never, _ = demo.settle_figures(time_s, np.full(200, 0.5), 0.39)
    assert never == np.inf


def test_following_error_leaves_out_the_recovery_window() -> None:
    error = np.zeros(100)
    error[50:55] = [0.05, 0.03, 0.01, 0.004, 0.001]
    error[90] = 0.006
    jumps = np.zeros(100, dtype=bool)
    jumps[50] = True
    steady, transient = demo.following_error_m(error, jumps, samples_to_recover=10)
    assert (steady, transient) == (0.006, 0.05)


def test_contour_pairs_readings_with_delayed_poses() -> None:
    # the tool moves toward a wall at 1 m; a reading that lags by 0.1 s matches the pose 0.1 s earlier
    time_s = np.arange(50) / 44.0
    position = 1.0 - 0.1 * time_s
    reading = np.interp(time_s - 0.1, time_s, position, left=position[0])
    origin = np.zeros((50, 2, 3))
    origin[:, :, 2] = -position[:, None] + 1.0
    trace = demo.LoopTrace(
        time_s=time_s,
        true_m=np.stack([position] * 2, 1),
        reading_m=np.stack([reading] * 2, 1),
        out_of_range=np.zeros((50, 2), bool),
        command_m_s=np.zeros(50),
        proximity_m_s=np.zeros(50),
        origin_m=origin,
        axis=np.tile([0.0, 0.0, 1.0], (50, 1)),
    )
    points, at_s = demo.reconstruct_contour(trace, delay_s=0.1)
    np.testing.assert_allclose(points[:, 2], 1.0, atol=1e-3)
    assert at_s.min() >= 0.0
    lagging, _ = demo.reconstruct_contour(trace, delay_s=0.0)
    assert np.abs(lagging[:, 2] - 1.0).max() > 5e-3


def test_bad_input_names_the_argument(tmp_path: Path) -> None:
    arm = Arm([Wall(0.4)])
    with pytest.raises(InputError, match="duration_s"):
        demo.run_closed_loop(arm, duration_s=0.0)
    with pytest.raises(InputError, match="mode"):
        demo.run_closed_loop(arm, duration_s=0.1, mode="hover")
    with pytest.raises(InputError, match="sample_rate_hz"):
        demo.run_closed_loop(arm, duration_s=0.1, sensor=ProximitySensor(sample_rate_hz=100.0))
    with pytest.raises(InputError, match="tangential_m_s"):
        demo.run_closed_loop(arm, duration_s=0.1, tangential_m_s=float("nan"))
    with pytest.raises(InputError, match="surface"):
        demo.follow_surface("wavy")
    with pytest.raises(InputError, match="speed_m_s"):
        demo.follow_surface("curved", speed_m_s=0.0)
    with pytest.raises(InputError, match="seed"):
        demo.run_proximity_demo(tmp_path, seed=-1)
    with pytest.raises(InputError, match="delay_s"):
        demo.reconstruct_contour(demo.servo_approach(rng=0).trace, delay_s=-0.1)
