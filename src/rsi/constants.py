"""The paper's numbers and the physical constants that more than one room uses, in SI units.

Each is written once here and imported where used (seed sections cited). Imports nothing.
"""

from __future__ import annotations

# seed §2.1: "solar illumination at earth orbit at approximately 130000 lux"
SUN_ILLUMINANCE_LUX = 130_000.0
# seed §2.1: the laboratory strobe gives 1.3 lumen s, in about 20 us
STROBE_ENERGY_LM_S = 1.3
STROBE_DURATION_S = 20e-6
# seed §2.1: the electronic shutter at 1/10000 s, one video field 1/60 s
SHUTTER_S = 1e-4
FIELD_S = 1.0 / 60.0
# seed §2.2: the sun subtends approximately 0.01 rad
SUN_ANGULAR_DIAMETER_RAD = 0.01
# seed §3.1: the proximity sensors were read through an A/D board at 44 Hz
PROXIMITY_SAMPLE_RATE_HZ = 44.0
# a laboratory room: the mock-up's surfaces away from the Peltier spots (seed §4)
ROOM_TEMPERATURE_K = 293.15

__all__ = [
    "FIELD_S",
    "PROXIMITY_SAMPLE_RATE_HZ",
    "ROOM_TEMPERATURE_K",
    "SHUTTER_S",
    "STROBE_DURATION_S",
    "STROBE_ENERGY_LM_S",
    "SUN_ANGULAR_DIAMETER_RAD",
    "SUN_ILLUMINANCE_LUX",
]
