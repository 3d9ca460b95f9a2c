"""Seed §3: the Integrated Sensor End-Effector's sensors as pure models (readings in, readings out).

- :mod:`rsi.sensors.proximity`     IR triangulation proximity sensors, A/D, 44 Hz low-pass filter (§3.1)
- :mod:`rsi.sensors.pyrometer`     8-12 um optical pyrometer, emissivity, spot size (§3, §4)
- :mod:`rsi.sensors.gas`           MOS gas sensor: power-law resistance, response and recovery, drift (§3)
- :mod:`rsi.sensors.force_torque`  six-axis force/torque sensor with noise, bias and tare (§3)
- :mod:`rsi.sensors.lamps`         feedback-controlled halogen lamps and jaw-mounted strobes (§2.1, §3)

No simulator is imported here: randomness is passed in, settings and results are frozen dataclasses.
"""

from __future__ import annotations

from rsi.sensors.force_torque import ForceTorqueSensor, read_wrench, tare
from rsi.sensors.gas import GasReadings, MosGasSensor, read_gas
from rsi.sensors.lamps import HalogenLamp, LampController, LampDisturbance, LampRun, Strobe, simulate_lamp
from rsi.sensors.proximity import (
    LowPassFilter,
    ProximityChannel,
    ProximityReadings,
    ProximitySensor,
    read_proximity,
)
from rsi.sensors.pyrometer import Pyrometer, PyrometerReading, band_radiance_w_m2_sr, read_pyrometer

__all__ = [
    "ForceTorqueSensor",
    "GasReadings",
    "HalogenLamp",
    "LampController",
    "LampDisturbance",
    "LampRun",
    "LowPassFilter",
    "MosGasSensor",
    "ProximityChannel",
    "ProximityReadings",
    "ProximitySensor",
    "Pyrometer",
    "PyrometerReading",
    "Strobe",
    "band_radiance_w_m2_sr",
    "read_gas",
    "read_proximity",
    "read_pyrometer",
    "read_wrench",
    "simulate_lamp",
    "tare",
]
