"""The ISEE's non-visual surveys (seed §3-4): the pyrometer over the Kapton circles (hot and cold spots) and
the MOS gas sensor along the tubing (the active leak).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from rsi.constants import ROOM_TEMPERATURE_K
from rsi.mission.evidence import confidence
from rsi.mission.records import MissionFinding
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
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


def gas_stations(world: World, settings: MissionSettings) -> FloatArray:
    """Stations 0.1 m in front of the tubing's horizontal runs, where the leak holes are (seed §4 F)."""
    leaks = world.mockup.candidates.leak_sites
    front = np.asarray(leaks[0].normal)
    heights = sorted({round(site.position_m[2], 4) for site in leaks})
    xs = [site.position_m[0] for site in leaks]
    # the whole run of each tube, one station per spacing, plus a margin of one jet half-width
    low, high = min(xs) - 0.1, max(xs) + 0.1
    count = round((high - low) / settings.gas_station_spacing_m) + 1
    y = leaks[0].position_m[1] + settings.gas_standoff_m * front[1]
    stations = [(x, y, z) for z in heights for x in np.linspace(low, high, count)]
    return np.asarray(stations, dtype=np.float64)


def gas_pass(
    world: World, rng: np.random.Generator, settings: MissionSettings
) -> tuple[list[MissionFinding], FloatArray, FloatArray]:
    """Dwell the MOS sensor at each station (seed §3 H) and locate the leak along the tubing."""
    from rsi.sensors.gas import MosGasSensor

    sensor = MosGasSensor()
    stations = gas_stations(world, settings)
    per_station = int(settings.gas_dwell_s * sensor.sample_rate_hz)
    samples = np.repeat(np.arange(len(stations)), per_station)
    times = settings.gas_survey_start_s + np.arange(samples.size) / sensor.sample_rate_hz
    readings = world.read_gas(stations[samples], times, sensor=sensor, rng=rng)
    tail = int(2.0 * sensor.sample_rate_hz)  # the last 2 s of each dwell, the sensor nearly settled
    estimate = readings.estimated_ppm.reshape(len(stations), per_station)[:, -tail:].mean(axis=1)
    findings: list[MissionFinding] = []
    best = int(np.argmax(estimate))
    if estimate[best] > settings.gas_threshold_ppm:
        position = stations[best].copy()
        # the jet is round: a parabola through the neighbours on the same run refines the peak
        if 0 < best < len(stations) - 1 and stations[best - 1][2] == stations[best + 1][2] == position[2]:
            left, mid, right = estimate[best - 1 : best + 2]
            curvature = left - 2 * mid + right
            if curvature < 0:
                position[0] += 0.5 * (left - right) / curvature * settings.gas_station_spacing_m
        position[1] = world.mockup.candidates.leak_sites[0].position_m[1]  # on the tubing, not the station
        findings.append(
            MissionFinding(
                kind="gas_leak",
                position_m=(float(position[0]), float(position[1]), float(position[2])),
                size_m=settings.gas_station_spacing_m,
                confidence=confidence(float(estimate[best]) / settings.gas_threshold_ppm - 1.0),
                source="gas",
                score=float(estimate[best]),
            )
        )
    return findings, stations, estimate
