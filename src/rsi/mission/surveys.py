"""The ISEE's non-visual surveys (seed §3-4): the pyrometer over the Kapton circles (hot and cold spots) and
the MOS gas sensor along each tank-and-tubing ORU's tubing (the active leaks), wherever the layout put them.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.constants import ROOM_TEMPERATURE_K
from rsi.mission.evidence import confidence
from rsi.mission.records import MissionFinding
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.sensors.gas import MosGasSensor
    from rsi.sim.anomalies import Site
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]


def pyrometer_pass(
    world: World, rng: np.random.Generator, settings: MissionSettings
) -> tuple[list[MissionFinding], dict[str, float]]:
    """Read each Kapton circle with the pyrometer aimed from 0.5 m (seed §3-4) -> hot and cold spots."""
    from rsi.sensors.pyrometer import Pyrometer

    instrument = Pyrometer()
    findings: list[MissionFinding] = []
    readings: dict[str, float] = {}
    for site in world.mockup.candidates.peltier_sites:
        reading = world.read_pyrometer(site, standoff_m=0.5, pyrometer=instrument, rng=rng)
        temperature_k = float(reading.temperature_k)
        readings[site.name] = temperature_k
        delta = temperature_k - ROOM_TEMPERATURE_K
        if abs(delta) > settings.thermal_threshold_k:
            findings.append(
                MissionFinding(
                    kind="hot_spot" if delta > 0 else "cold_spot",
                    position_m=site.position_m,  # where the spot was aimed
                    size_m=site.size_m,
                    confidence=confidence(
                        (abs(delta) - settings.thermal_threshold_k) / instrument.noise_std_k
                    ),
                    source="pyrometer",
                    score=delta,
                )
            )
    return findings, readings


def _tubings(world: World) -> list[tuple[Site, ...]]:
    """The leak holes of each tank-and-tubing ORU of the world's layout (``Mockup.tubing_leaks``)."""
    by_name = {site.name: site for site in world.mockup.candidates.leak_sites}
    return [tuple(by_name[name] for name in names) for names in world.mockup.tubing_leaks]


def gas_stations(world: World, settings: MissionSettings) -> FloatArray:
    """Stations 0.1 m in front of each tubing's horizontal runs, where the leak holes are (seed §4 F)."""
    stations: list[tuple[float, float, float]] = []
    for leaks in _tubings(world):
        front = np.asarray(leaks[0].normal)
        heights = sorted({round(site.position_m[2], 4) for site in leaks})
        xs = [site.position_m[0] for site in leaks]
        # the whole run of each tube, one station per spacing, plus a margin of one jet half-width
        low, high = min(xs) - 0.1, max(xs) + 0.1
        count = round((high - low) / settings.gas_station_spacing_m) + 1
        y = leaks[0].position_m[1] + settings.gas_standoff_m * front[1]
        stations += [(x, y, z) for z in heights for x in np.linspace(low, high, count)]
    return np.asarray(stations, dtype=np.float64).reshape(-1, 3)


def _leak_y(world: World, station: FloatArray) -> float:
    """Depth of the tubing a station faces: its nearest leak hole's, along and up the truss (x, z)."""
    sites = world.mockup.candidates.leak_sites
    nearest = min(sites, key=lambda site: math.dist(site.position_m[::2], station[::2]))
    return float(nearest.position_m[1])


# Seed §4 has up to two leaks on: each plume is its own peak along the tubing. A round turbulent jet's
# concentration half-width grows as 0.11 x (Pope, Turbulent Flows §5.1; rsi.sim.fields.RoundJet), ~1 cm at
# the 0.1 m standoff, and the MOS sensor's slow recovery drags a tail behind the peak as the survey moves
# on: a station with a stronger one within 5 cm on its run reads a flank, not a plume of its own.
_PLUME_SEPARATION_M = 0.05


def _plume_peaks(stations: FloatArray, estimate: FloatArray, settings: MissionSettings) -> list[int]:
    """Stations above the threshold that read the most within _PLUME_SEPARATION_M on their run: a plume's
    peak (its flanks and the slow sensor's tail behind it, seed §3 H, fall away from it on the run)."""
    peaks: list[int] = []
    for index in np.flatnonzero(estimate > settings.gas_threshold_ppm):
        run = stations[:, 2] == stations[index][2]
        window = run & (np.abs(stations[:, 0] - stations[index][0]) < _PLUME_SEPARATION_M)
        if estimate[index] >= estimate[window].max():
            peaks.append(int(index))
    return peaks


def _leak_finding(
    stations: FloatArray, estimate: FloatArray, best: int, leak_y: float, settings: MissionSettings
) -> MissionFinding:
    """A leak at a plume's peak station, refined along the run by a parabola through its neighbours."""
    position = stations[best].copy()
    # the jet is round: a parabola through the neighbours on the same run refines the peak
    if (
        0 < best < len(stations) - 1
        and stations[best - 1][2] == stations[best + 1][2] == position[2]
        # neighbours on the same run: not the last station of another tubing's
        and abs(stations[best + 1][0] - stations[best - 1][0]) < 3 * settings.gas_station_spacing_m
    ):
        left, mid, right = estimate[best - 1 : best + 2]
        curvature = left - 2 * mid + right
        if curvature < 0:
            position[0] += 0.5 * (left - right) / curvature * settings.gas_station_spacing_m
    return MissionFinding(
        kind="gas_leak",
        position_m=(float(position[0]), leak_y, float(position[2])),
        size_m=settings.gas_station_spacing_m,
        confidence=confidence(float(estimate[best]) / settings.gas_threshold_ppm - 1.0),
        source="gas",
        score=float(estimate[best]),
    )


def _held_ppm(dwells: FloatArray, sensor: MosGasSensor) -> FloatArray:
    """The concentration held at each station, from the sensor's readings over its dwell (rows), by
    inverting the sensor's own first-order dynamics (seed §3 H; :mod:`rsi.sensors.gas`).

    Over a dwell at a held concentration ``C`` the reading relaxes as ``r_k = C + (r_0 - C) a^k``, with
    ``a = exp(-1 / (rate tau))`` and ``tau`` the response time constant while it rises, the recovery one
    while it falls; ``C`` is the intercept of the straight line of ``r_k`` against ``a^k`` (least squares
    over the dwell). The mean of the dwell's last 2 s read ``C`` only where the sensor had settled: with
    the 40 s recovery a 20 s dwell keeps 61 % of the last station's excess, so a strong plume's tail
    outread a weak plume 8 cm further on (truss seed 1910: 708 ppm of tail 5 cm before a second leak
    reading 164 ppm over a tail of ~85, and the second leak was never reported).
    """
    steps = np.arange(dwells.shape[1], dtype=np.float64)
    rising = dwells[:, -1] >= dwells[:, 0]
    held = np.empty(dwells.shape[0])
    for direction, tau_s in ((True, sensor.response_time_s), (False, sensor.recovery_time_s)):
        chosen = rising == direction
        decay = np.exp(-steps / (sensor.sample_rate_hz * tau_s))
        design = np.column_stack([np.ones_like(decay), decay])
        solution, *_ = np.linalg.lstsq(design, dwells[chosen].T, rcond=None)
        held[chosen] = solution[0]
    return held


def gas_pass(
    world: World, rng: np.random.Generator, settings: MissionSettings
) -> tuple[list[MissionFinding], FloatArray, FloatArray]:
    """Dwell the MOS sensor at each station (seed §3 H) and locate each leak's plume along the tubing."""
    from rsi.sensors.gas import MosGasSensor

    sensor = MosGasSensor()
    stations = gas_stations(world, settings)
    per_station = int(settings.gas_dwell_s * sensor.sample_rate_hz)
    samples = np.repeat(np.arange(len(stations)), per_station)
    times = settings.gas_survey_start_s + np.arange(samples.size) / sensor.sample_rate_hz
    readings = world.read_gas(stations[samples], times, sensor=sensor, rng=rng)
    estimate = _held_ppm(readings.estimated_ppm.reshape(len(stations), per_station), sensor)
    # a leak lies on the tubing, not at the station
    findings = [
        _leak_finding(stations, estimate, peak, _leak_y(world, stations[peak]), settings)
        for peak in _plume_peaks(stations, estimate, settings)
    ]
    return findings, stations, estimate


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
