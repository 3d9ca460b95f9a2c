"""Temperature, emissivity and ammonia fields of the mock-up (seed §4): truths, invariants, every raise."""

from __future__ import annotations

import doctest
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import rsi.sim.fields as fields_module
from rsi.errors import InputError
from rsi.sensors.pyrometer import Pyrometer, read_pyrometer
from rsi.sim.anomalies import AnomalySettings, Candidates, GasLeak, Site, ThermalSpot, seed_anomalies
from rsi.sim.fields import (
    AMBIENT_K,
    EMISSIVITY,
    RoundJet,
    emissivity,
    gas_concentration_ppm,
    surface_temperature_k,
)

RADIUS_M = 0.025
HOT = ThermalSpot("peltier_0", (0.0, 0.0, 0.0), (0, 0, 1), 2 * RADIUS_M, "kapton", delta_k=30.0)
COLD = ThermalSpot("peltier_1", (1.0, 0.0, 0.0), (0, 0, 1), 2 * RADIUS_M, "kapton", delta_k=-30.0)
DIAMETER_M = 1e-3
LEAK = GasLeak(
    "leak_0",
    (0.2, -0.1, 0.3),
    (1.0, 1.0, 1.0),
    DIAMETER_M,
    "aluminium",
    start_time_s=5.0,
    exit_velocity_m_s=10.0,
    exit_ppm=5000.0,
    turn_on_time_s=1.0,
)
AXIS = np.asarray(LEAK.normal)
HOLE_M = np.asarray(LEAK.position_m)
STEADY_S = 1e4  # long after every front has arrived and the source has built up
JET = RoundJet()


def _on_axis(distances_m: np.ndarray) -> np.ndarray:
    return np.asarray(HOLE_M + distances_m[:, None] * AXIS, dtype=np.float64)


def _perpendicular() -> np.ndarray:
    side = np.cross(AXIS, [1.0, 0.0, 0.0])
    return np.asarray(side / np.linalg.norm(side), dtype=np.float64)


# ------------------------------------------------------------------------------------------ temperature


def test_spot_centres_are_ambient_plus_minus_delta() -> None:
    temperature = surface_temperature_k([HOT.position_m, COLD.position_m], [HOT, COLD])
    # The other spot is 40 radii away: its contribution, 30 exp(-1600) K, is zero in float64.
    np.testing.assert_allclose(temperature, [AMBIENT_K + 30.0, AMBIENT_K - 30.0], rtol=0, atol=1e-12)


def test_fall_off_is_gaussian_with_the_stated_radius() -> None:
    temperature = surface_temperature_k([[RADIUS_M, 0.0, 0.0], [0.0, 2 * RADIUS_M, 0.0]], [HOT])
    np.testing.assert_allclose(temperature - AMBIENT_K, [30.0 / math.e, 30.0 * math.exp(-4.0)], rtol=1e-12)


@pytest.mark.parametrize("direction", [(1, 0, 0), (0, 1, 0), (1, 1, 0), (0, 0, 1), (-1, 2, 3)])
@pytest.mark.parametrize("spot", [HOT, COLD])
def test_fall_off_is_monotone_and_reaches_ambient(direction: tuple[int, ...], spot: ThermalSpot) -> None:
    unit = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    distances_m = np.linspace(0.0, 0.5, 501)
    points = np.asarray(spot.position_m) + distances_m[:, None] * unit
    excess_k = np.abs(surface_temperature_k(points, [spot]) - AMBIENT_K)
    assert (np.diff(excess_k) <= 0).all()
    assert (np.diff(excess_k)[excess_k[1:] > 1e-12] < 0).all()
    assert excess_k[0] == pytest.approx(30.0)
    assert excess_k[-1] < 1e-12  # 20 radii away: ambient


def test_overlapping_spots_add() -> None:
    near = ThermalSpot("peltier_2", (0.02, 0.0, 0.0), (0, 0, 1), 0.05, "kapton", delta_k=10.0)
    points = np.random.default_rng(0).uniform(-0.05, 0.05, (50, 3))
    both = surface_temperature_k(points, [HOT, near])
    alone = surface_temperature_k(points, [HOT]) + surface_temperature_k(points, [near]) - AMBIENT_K
    np.testing.assert_allclose(both, alone, rtol=1e-14)


def test_no_spots_and_an_anomaly_set_are_accepted() -> None:
    points = np.zeros((4, 3))
    np.testing.assert_array_equal(surface_temperature_k(points, [], ambient_k=250.0), np.full(4, 250.0))
    sites = tuple(Site(f"p{k}", (k, 0.0, 0.0), (0, 0, 1), "kapton") for k in range(4))
    world = seed_anomalies(
        Candidates(peltier_sites=sites),
        rng=0,
        settings=AnomalySettings(
            anomaly_free_probability=0.0,
            active_leak_count_range=(0, 0),
            impact_count_range=(0, 0),
            swapped_component_count_range=(0, 0),
        ),
    )
    centres = [spot.position_m for spot in world.thermal_spots]
    expected = [AMBIENT_K + spot.delta_k for spot in world.thermal_spots]
    np.testing.assert_allclose(surface_temperature_k(centres, world), expected, atol=1e-9)
    assert surface_temperature_k(np.empty((0, 3)), world).shape == (0,)


def test_pyrometer_reads_the_spot_on_kapton_not_on_aluminium() -> None:
    # seed §4: the Kapton circle is what lets the pyrometer read the Peltier spot correctly.
    centre = np.array([HOT.position_m])
    temperature = surface_temperature_k(centre, [HOT])
    on_kapton = emissivity(centre, "aluminium", kapton_sites=[Site("peltier_0", (0, 0, 0), (0, 0, 1))])
    bare = emissivity(centre, "aluminium")
    quiet = Pyrometer(noise_std_k=0.0)  # emissivity setting 0.95: set for Kapton
    assert read_pyrometer(temperature, on_kapton, quiet).temperature_k[0] == pytest.approx(
        AMBIENT_K + 30.0, abs=1e-6
    )
    assert abs(read_pyrometer(temperature, bare, quiet).temperature_k[0] - (AMBIENT_K + 30.0)) > 20.0


# ------------------------------------------------------------------------------------------ emissivity


def test_emissivity_follows_the_table_and_the_kapton_circles() -> None:
    points = np.array([[0.0, 0.0, 0.0], [0.02, 0.0, 0.0], [0.03, 0.0, 0.0], [1.0, 0.0, 0.0]])
    kapton = [Site("peltier_0", (0.0, 0.0, 0.0), (0, 0, 1))]
    got = emissivity(points, ["aluminium", "aluminium", "aluminium", "solar_cell"], kapton_sites=kapton)
    np.testing.assert_array_equal(got, [0.95, 0.95, 0.05, 0.85])
    assert EMISSIVITY["aluminium"] <= 0.1 < EMISSIVITY["solar_cell"] < EMISSIVITY["kapton"]
    painted = emissivity(points[:1], "white_paint", table={"white_paint": 0.9})
    np.testing.assert_array_equal(painted, [0.9])


# ------------------------------------------------------------------------------------------------ gas


def test_gas_is_zero_before_the_start_and_at_it() -> None:
    points = np.vstack([_on_axis(np.linspace(0.0, 1.0, 11)), HOLE_M + 0.01 * _perpendicular()])
    for time_s in (0.0, 2.5, LEAK.start_time_s):
        np.testing.assert_array_equal(gas_concentration_ppm(points, time_s, [LEAK]), 0.0)


def test_gas_is_zero_upstream_of_the_hole() -> None:
    rng = np.random.default_rng(1)
    offsets = rng.normal(size=(200, 3))
    behind = HOLE_M + offsets - np.maximum(offsets @ AXIS, 0.0)[:, None] * AXIS - 1e-6 * AXIS
    assert ((behind - HOLE_M) @ AXIS < 0).all()
    np.testing.assert_array_equal(gas_concentration_ppm(behind, STEADY_S, [LEAK]), 0.0)
    far_upstream = _on_axis(np.array([-0.01, -1.0, -100.0]))
    np.testing.assert_array_equal(gas_concentration_ppm(far_upstream, STEADY_S, [LEAK]), 0.0)


def test_gas_is_largest_at_the_hole_and_falls_along_the_axis() -> None:
    distances_m = np.linspace(0.0, 2.0, 2001)
    axis_ppm = gas_concentration_ppm(_on_axis(distances_m), STEADY_S, [LEAK])
    assert axis_ppm[0] == pytest.approx(LEAK.exit_ppm)
    assert (np.diff(axis_ppm) <= 0).all()
    core_end_m = JET.concentration_decay * DIAMETER_M - DIAMETER_M / (2 * JET.half_width_rate)
    assert (np.diff(axis_ppm)[distances_m[:-1] >= core_end_m] < 0).all()
    rng = np.random.default_rng(2)
    anywhere = HOLE_M + rng.uniform(-0.5, 0.5, (2000, 3))
    assert gas_concentration_ppm(anywhere, STEADY_S, [LEAK]).max() <= axis_ppm[0]


def test_far_field_is_the_round_jet_solution() -> None:
    # Pope (2000) §5.1, Chen & Rodi (1980): axis value ~ 1/x, half value at r = S_c (x + x0).
    x0_m = DIAMETER_M / (2 * JET.half_width_rate)
    for x_m in (0.1, 0.3, 1.0):
        axis = gas_concentration_ppm(_on_axis(np.array([x_m])), STEADY_S, [LEAK])[0]
        assert axis == pytest.approx(LEAK.exit_ppm * JET.concentration_decay * DIAMETER_M / (x_m + x0_m))
        half_width_m = JET.half_width_rate * (x_m + x0_m)
        edge = HOLE_M + x_m * AXIS + half_width_m * _perpendicular()
        assert gas_concentration_ppm(edge[None], STEADY_S, [LEAK])[0] == pytest.approx(axis / 2)
    assert JET.half_angle_rad == pytest.approx(math.radians(6.28), abs=1e-3)


@settings(max_examples=40, deadline=None)
@given(
    distance_m=st.floats(0.0, 1.5),
    radius_m=st.floats(0.0, 0.2),
    angle_rad=st.floats(0.0, 2 * math.pi),
    time_s=st.floats(0.0, 60.0),
)
def test_gas_is_symmetric_about_the_axis(
    distance_m: float, radius_m: float, angle_rad: float, time_s: float
) -> None:
    point = HOLE_M + distance_m * AXIS + radius_m * _perpendicular()
    turned = HOLE_M + Rotation.from_rotvec(angle_rad * AXIS).apply(point - HOLE_M)
    values = gas_concentration_ppm(np.array([point, turned]), time_s, [LEAK])
    assert values[1] == pytest.approx(values[0], rel=1e-9, abs=1e-12)


def test_gas_turns_on_with_a_travelling_front() -> None:
    x_m = 0.5
    point = _on_axis(np.array([x_m]))
    front_speed_m2_s = JET.front_speed_fraction * JET.velocity_decay * DIAMETER_M * LEAK.exit_velocity_m_s
    arrival_s = LEAK.start_time_s + x_m**2 / (2 * front_speed_m2_s)
    times_s = np.linspace(0.0, arrival_s + 20.0, 400)
    series = gas_concentration_ppm(np.repeat(point, times_s.size, axis=0), times_s, [LEAK])
    assert (series[times_s <= arrival_s] == 0).all()
    assert (series[times_s > arrival_s] > 0).all()
    assert (np.diff(series) >= 0).all()
    steady = gas_concentration_ppm(point, STEADY_S, [LEAK])[0]
    one_tau = gas_concentration_ppm(point, arrival_s + LEAK.turn_on_time_s, [LEAK])[0]
    assert one_tau == pytest.approx(steady * (1 - math.exp(-1)))


def test_leaks_add_and_an_anomaly_set_is_accepted() -> None:
    other = GasLeak("leak_1", (0.0, 0.0, 0.0), (0, 0, 1), DIAMETER_M, "aluminium", start_time_s=0.0)
    points = np.random.default_rng(3).uniform(-0.2, 0.6, (100, 3))
    both = gas_concentration_ppm(points, 30.0, [LEAK, other])
    summed = gas_concentration_ppm(points, 30.0, [LEAK]) + gas_concentration_ppm(points, 30.0, [other])
    np.testing.assert_allclose(both, summed, rtol=1e-14)
    leaks = tuple(Site(f"leak_{k}", (0.0, k, 0.0), (1, 0, 0)) for k in range(3))
    world = seed_anomalies(
        Candidates(leak_sites=leaks),
        rng=0,
        settings=AnomalySettings(
            active_peltier_count=0,
            active_leak_count_range=(1, 1),
            impact_count_range=(0, 0),
            swapped_component_count_range=(0, 0),
            anomaly_free_probability=0.0,
        ),
    )
    (leak,) = world.gas_leaks
    np.testing.assert_array_equal(
        gas_concentration_ppm(points, 30.0, world), gas_concentration_ppm(points, 30.0, [leak])
    )


def test_docstring_examples_run() -> None:
    assert doctest.testmod(fields_module).failed == 0


# --------------------------------------------------------------------------------------------- raises

BAD_POINTS: list[Any] = [
    np.zeros(3),
    np.zeros((4, 2)),
    np.zeros((2, 3, 1)),
    np.array([[0.0, np.nan, 0.0]]),
    np.array([[0.0, np.inf, 0.0]]),
    [[0.0, 0.0], [0.0, 0.0, 0.0]],
    "points",
]


@pytest.mark.parametrize("points", BAD_POINTS)
def test_bad_points_raise_naming_points_m(points: Any) -> None:
    with pytest.raises(InputError, match="points_m"):
        surface_temperature_k(points, [HOT])
    with pytest.raises(InputError, match="points_m"):
        emissivity(points, "aluminium")
    with pytest.raises(InputError, match="points_m"):
        gas_concentration_ppm(points, 1.0, [LEAK])


@pytest.mark.parametrize("time_s", [-1.0, float("nan"), float("inf"), np.zeros((2, 2)), np.zeros(5), "now"])
def test_bad_times_raise(time_s: Any) -> None:
    with pytest.raises(InputError, match="time_s"):
        gas_concentration_ppm(np.zeros((3, 3)), time_s, [LEAK])


def test_bad_arguments_raise() -> None:
    points = np.zeros((2, 3))
    with pytest.raises(InputError, match="spots"):
        surface_temperature_k(points, [LEAK])  # type: ignore[list-item]
    with pytest.raises(InputError, match="spots"):
        surface_temperature_k(points, HOT)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="ambient_k"):
        surface_temperature_k(points, [HOT], ambient_k=0.0)
    with pytest.raises(InputError, match="ambient_k"):
        surface_temperature_k(points, [COLD], ambient_k=20.0)
    with pytest.raises(InputError, match="leaks"):
        gas_concentration_ppm(points, 1.0, [HOT])  # type: ignore[list-item]
    with pytest.raises(InputError, match="leaks"):
        gas_concentration_ppm(points, 1.0, "leak_0")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="jet"):
        gas_concentration_ppm(points, 1.0, [LEAK], jet={"concentration_decay": 5.0})  # type: ignore[arg-type]
    with pytest.raises(InputError, match="surface"):
        emissivity(points, "granite")
    with pytest.raises(InputError, match="surface"):
        emissivity(points, ["aluminium"])
    with pytest.raises(InputError, match="table"):
        emissivity(points, "aluminium", table={"aluminium": 1.5})
    kapton = [Site("p", (0, 0, 0), (0, 0, 1))]
    with pytest.raises(InputError, match="kapton"):
        emissivity(points, "aluminium", kapton_sites=kapton, table={"aluminium": 0.05})
    with pytest.raises(InputError, match="kapton_radius_m"):
        emissivity(points, "aluminium", kapton_sites=kapton, kapton_radius_m=0.0)
    with pytest.raises(InputError, match="kapton_sites"):
        emissivity(points, "aluminium", kapton_sites=[(0, 0, 0)])  # type: ignore[list-item]


@pytest.mark.parametrize(
    ("changes", "argument"),
    [
        ({"concentration_decay": 0.0}, "concentration_decay"),
        ({"half_width_rate": -0.1}, "half_width_rate"),
        ({"velocity_decay": float("nan")}, "velocity_decay"),
        ({"front_speed_fraction": 1.5}, "front_speed_fraction"),
        ({"front_speed_fraction": 0.0}, "front_speed_fraction"),
    ],
)
def test_bad_jet_constants_raise(changes: dict[str, float], argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        RoundJet(**changes)
