"""The sun seen from a station in low Earth orbit, and the lamp path that reproduces it (seed §4.1, §2.1).

Orbit: circular, altitude ``h`` above a spherical Earth (``a = R_E + h``), period ``T = 2 pi sqrt(a^3 / mu)``
(Kepler). The sun is at infinity; its direction makes the beta angle ``beta`` with the orbit plane. The
orbit angle ``u`` is measured in the orbit plane from "orbit noon", where the station is nearest the sun;
``u = u_0 + 2 pi t / T``.

Station frame: LVLH, the attitude the station holds (x ram, z nadir)::

    z_LVLH = -r_hat  (nadir)        y_LVLH = -h_hat  (opposite the orbit normal)
    x_LVLH = y x z   (along the velocity for a circular orbit)

In LVLH the unit vector toward the sun is ``(-cos beta sin u, -sin beta, -cos beta cos u)``: overhead
(``-z``) at noon, rising ahead (``+x``) at ``u = -90 deg`` and setting behind at ``u = +90 deg``.

Eclipse (cylindrical Earth shadow): the station is dark when ``r . s_hat < 0`` and its distance from the
Earth-sun line is below ``R_E``, i.e. ``cos u < 0`` and ``cos^2 beta cos^2 u > 1 - (R_E / a)^2``. So there is
an eclipse only when ``|beta| < beta* = asin(R_E / a)``, centred on midnight (``u = pi``), of half-width
``u_e = acos(sqrt(1 - (R_E / a)^2) / cos beta)``; entry at ``u = pi - u_e``, exit at ``pi + u_e``, and the
fraction of the orbit in shadow ``u_e / pi`` (the textbook ``acos(sqrt(h^2 + 2 R_E h) / (a cos beta)) / pi``).

Lab reproduction: the mock-up is fixed to the station, so ``world_from_lvlh`` (a rotation) places the LVLH
axes in the lab. The default puts the mock-up's zenith face (``-z_LVLH``) toward the lamp rail (world ``-y``),
the wake (``-x_LVLH``) along the rail (world ``+x``) and ``y_LVLH`` up, so the lamp's reachable quadrant
holds the afternoon half of a beta = 0 sun arc. The lamp holds the lab's 1.5 % of sunlight (seed §4.1) at
the spot and the camera shutter lengthens to keep the orbit's ambient-to-strobe ratio (seed §2.1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi import constants
from rsi.errors import InputError
from rsi.sim import solar_simulator as ss

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

EARTH_MU_M3_S2 = 3.986004418e14  # IERS / WGS-84 geocentric gravitational constant
EARTH_RADIUS_M = 6_378_137.0  # WGS-84 equatorial radius
# The paper's numbers live in rsi.constants; these names are the orbit room's aliases of them.
SUN_ILLUMINANCE_LUX = constants.SUN_ILLUMINANCE_LUX  # seed §2.1: solar illumination in Earth orbit
LAB_SUN_FRACTION = 0.015  # seed §4.1: the simulated sun is 1.5 % of orbital sunlight
ORBIT_EXPOSURE_S = constants.SHUTTER_S  # seed §2.1: electronic shutter at 1/10000 s in orbit
STROBE_LM_S = constants.STROBE_ENERGY_LM_S  # seed §2.1: the laboratory strobe's illumination
SCENE_AREA_M2 = 0.1  # seed §2.1: a typical inspection scene
FIELD_S = constants.FIELD_S  # seed §2.1: one video field; the shutter cannot stay open longer
FLASH_S = constants.STROBE_DURATION_S  # seed §2.1: the ~20 us flash; no shorter shutter holds all of it

# Default lab placement of the station's LVLH axes (columns: images of x, y, z LVLH in the world).
DEFAULT_WORLD_FROM_LVLH: FloatArray = np.array([[-1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
DEFAULT_WORLD_FROM_LVLH.setflags(write=False)

_ROTATION_TOLERANCE = 1e-9
# Below this many seconds of lag behind its target, a rate-limited joint is on its path.
_LAG_TOLERANCE_S = 1e-9
# A wanted focus this close outside its range is rounding, not a clipped intensity.
_FOCUS_TOLERANCE_M = 1e-12


@dataclass(frozen=True)
class Orbit:
    """A circular low Earth orbit and where the sun is relative to it.

    Parameters
    ----------
    altitude_m : float
        Height above the Earth's equatorial radius, > 0 m (the station flies near 400 km).
    beta_rad : float
        Beta angle, the sun's elevation above the orbit plane, in [-pi/2, pi/2] rad.
    start_angle_rad : float
        Orbit angle ``u`` at ``t = 0``, measured from orbit noon, radians.
    """

    altitude_m: float = 400_000.0
    beta_rad: float = 0.0
    start_angle_rad: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "altitude_m", v.in_range(self.altitude_m, "altitude_m", low=0.0, low_inclusive=False)
        )
        object.__setattr__(
            self, "beta_rad", v.in_range(self.beta_rad, "beta_rad", low=-math.pi / 2, high=math.pi / 2)
        )
        object.__setattr__(self, "start_angle_rad", v.finite_number(self.start_angle_rad, "start_angle_rad"))

    @property
    def semi_major_axis_m(self) -> float:
        """Orbit radius ``a = R_E + h``, metres."""
        return EARTH_RADIUS_M + self.altitude_m


@dataclass(frozen=True)
class Eclipse:
    """Where and when the station enters and leaves the Earth's (cylindrical) shadow.

    Attributes
    ----------
    fraction : float
        Fraction of each orbit in shadow, ``u_e / pi`` (0 when ``|beta| >= beta*``).
    duration_s : float
        Time in shadow per orbit, seconds.
    entry_angle_rad, exit_angle_rad : float or None
        Orbit angles of entry and exit, in [0, 2 pi); None without an eclipse.
    entry_time_s, exit_time_s : float or None
        First entry and first exit at or after ``t = 0``, seconds; None without an eclipse.
    """

    fraction: float
    duration_s: float
    entry_angle_rad: float | None
    exit_angle_rad: float | None
    entry_time_s: float | None
    exit_time_s: float | None


@dataclass(frozen=True)
class ExposureSettings:
    """Seed §2.1: the shutter that keeps the orbit's ambient-to-strobe ratio under the lab's dimmer sun.

    Attributes
    ----------
    orbit_exposure_s : float
        Shutter in orbit (1/10000 s).
    lab_exposure_s : float
        Shutter in the lab, ``orbit_exposure_s * sun_illuminance_lux / lab_illuminance_lux``.
    exposure_ratio : float
        ``lab_exposure_s / orbit_exposure_s`` (about 67 at 1.5 % of sunlight).
    orbit_ambient_lm_s, lab_ambient_lm_s : float
        Ambient light on the scene area during one exposure, lumen seconds (equal by construction).
    strobe_lm_s : float
        Strobe light per flash, lumen seconds (the ~20 us flash fits inside either shutter).
    ambient_to_strobe_ratio : float
        ``orbit_ambient_lm_s / strobe_lm_s``, kept in the lab.
    """

    sun_illuminance_lux: float
    lab_illuminance_lux: float
    orbit_exposure_s: float
    lab_exposure_s: float
    exposure_ratio: float
    orbit_ambient_lm_s: float
    lab_ambient_lm_s: float
    strobe_lm_s: float
    ambient_to_strobe_ratio: float


@dataclass(frozen=True)
class SunPath:
    """A sampled orbit's sun and the lamp trajectory that reproduces it over the mock-up.

    Attributes
    ----------
    time_s : ndarray of shape (K,)
        Sample times, seconds.
    orbit_angle_rad : ndarray of shape (K,)
        Orbit angle ``u`` from orbit noon (unwrapped).
    sun_lvlh, sun_world : ndarray of shape (K, 3)
        Unit vector toward the sun in LVLH and in the lab world.
    sunlit : ndarray of shape (K,), bool
        False in the Earth's shadow: the lamp is off there.
    trajectory : Trajectory
        What the lamp does: the targets followed within the joint rate limits.
    light_world : ndarray of shape (K, 3)
        Unit vector from the spot toward the lamp as it is.
    direction_error_rad : ndarray of shape (K,)
        Angle between ``light_world`` and ``sun_world``.
    intensity_lux : ndarray of shape (K,)
        Lamp illuminance at the spot centre (normal to the beam); 0 where the sun is eclipsed.
    target_intensity_lux : float
        ``lab_sun_fraction * 130000 lux``.
    direction_unreachable, focus_clipped, rate_limited : ndarray of shape (K,), bool
        Where the rail could not give the sun's direction within tolerance, where the focus hit a limit so
        the intensity is not held, and where a joint lags its target at its rate limit.
    exposure : ExposureSettings
        The lab shutter for the target intensity (seed §2.1).
    """

    time_s: FloatArray
    orbit_angle_rad: FloatArray
    sun_lvlh: FloatArray
    sun_world: FloatArray
    sunlit: BoolArray
    trajectory: ss.Trajectory
    light_world: FloatArray
    direction_error_rad: FloatArray
    intensity_lux: FloatArray
    target_intensity_lux: float
    direction_unreachable: BoolArray
    focus_clipped: BoolArray
    rate_limited: BoolArray
    exposure: ExposureSettings

    @property
    def clipped(self) -> BoolArray:
        """Samples where the lab does not reproduce the orbit (any flag set)."""
        return self.direction_unreachable | self.focus_clipped | self.rate_limited


def _orbit(orbit: object) -> Orbit:
    if orbit is None:
        return Orbit()
    if not isinstance(orbit, Orbit):
        raise InputError(f"orbit must be an Orbit; got {type(orbit).__name__}.")
    return orbit


def _times(time_s: object, *, strictly_increasing: bool = False) -> FloatArray:
    try:
        times = np.atleast_1d(np.asarray(time_s, dtype=np.float64))
    except (TypeError, ValueError):
        raise InputError(f"time_s must be numbers in seconds; got {time_s!r}.") from None
    if times.ndim != 1 or times.size == 0:
        raise InputError(f"time_s must be a scalar or a non-empty 1-D array; got shape {times.shape}.")
    if not np.isfinite(times).all():
        raise InputError("time_s contains NaN or inf; pass finite times in seconds.")
    if (times < 0).any():
        raise InputError(
            f"time_s must be >= 0 s (time since the orbit's start); got a minimum of {times.min():g} s. "
            "Shift the start with Orbit(start_angle_rad=...) instead."
        )
    if strictly_increasing and (np.diff(times) <= 0).any():
        raise InputError("time_s must be strictly increasing for a lamp trajectory.")
    return times


def orbital_period_s(orbit: Orbit | None = None) -> float:
    """Kepler's period of the circular orbit, ``2 pi sqrt(a^3 / mu)``, seconds."""
    a = _orbit(orbit).semi_major_axis_m
    return 2.0 * math.pi * math.sqrt(a**3 / EARTH_MU_M3_S2)


def critical_beta_rad(altitude_m: float) -> float:
    """``beta* = asin(R_E / (R_E + h))``: above this beta angle a circular orbit sees no eclipse."""
    altitude = v.in_range(altitude_m, "altitude_m", low=0.0, low_inclusive=False)
    return math.asin(EARTH_RADIUS_M / (EARTH_RADIUS_M + altitude))


def orbit_angle_rad(orbit: Orbit | None, time_s: object) -> FloatArray:
    """Orbit angle ``u = u_0 + 2 pi t / T`` from orbit noon at each time (unwrapped), radians."""
    orbit = _orbit(orbit)
    times = _times(time_s)
    return np.asarray(
        orbit.start_angle_rad + 2.0 * math.pi * times / orbital_period_s(orbit), dtype=np.float64
    )


def sun_direction_lvlh(orbit: Orbit | None, time_s: object) -> FloatArray:
    """Unit vector toward the sun in the station's LVLH frame, shape (K, 3)."""
    orbit = _orbit(orbit)
    u = orbit_angle_rad(orbit, time_s)
    cos_beta, sin_beta = math.cos(orbit.beta_rad), math.sin(orbit.beta_rad)
    return np.stack([-cos_beta * np.sin(u), np.full(u.shape, -sin_beta), -cos_beta * np.cos(u)], axis=-1)


def in_sunlight(orbit: Orbit | None, time_s: object) -> BoolArray:
    """Whether the station is outside the Earth's cylindrical shadow at each time.

    Evaluated from the geometry (the station's position against the shadow cylinder), independently of
    the closed-form :func:`eclipse`.
    """
    orbit = _orbit(orbit)
    a = orbit.semi_major_axis_m
    u = orbit_angle_rad(orbit, time_s)
    # Inertial basis: p toward the sun's projection on the orbit plane, q = h x p, h the orbit normal.
    sun = np.array([math.cos(orbit.beta_rad), 0.0, math.sin(orbit.beta_rad)])
    position = a * np.stack([np.cos(u), np.sin(u), np.zeros_like(u)], axis=-1)
    along_sun = position @ sun
    off_axis = np.linalg.norm(position - along_sun[:, None] * sun, axis=-1)
    return np.asarray(~((along_sun < 0.0) & (off_axis < EARTH_RADIUS_M)), dtype=np.bool_)


def eclipse(orbit: Orbit | None = None) -> Eclipse:
    """Closed-form eclipse entry, exit and fraction for the cylindrical shadow (see the module notes)."""
    orbit = _orbit(orbit)
    period = orbital_period_s(orbit)
    ratio = EARTH_RADIUS_M / orbit.semi_major_axis_m
    off_axis = math.sqrt(1.0 - ratio * ratio)  # cos u_e * cos beta at the shadow's edge
    cos_beta = math.cos(orbit.beta_rad)
    if cos_beta <= off_axis:  # |beta| >= beta*: the orbit never crosses the shadow cylinder
        return Eclipse(0.0, 0.0, None, None, None, None)
    half = math.acos(off_axis / cos_beta)
    entry, exit_ = math.pi - half, math.pi + half

    def first_time(angle: float) -> float:
        return ((angle - orbit.start_angle_rad) % (2.0 * math.pi)) / (2.0 * math.pi) * period

    return Eclipse(
        fraction=half / math.pi,
        duration_s=half / math.pi * period,
        entry_angle_rad=entry,
        exit_angle_rad=exit_,
        entry_time_s=first_time(entry),
        exit_time_s=first_time(exit_),
    )


def compensating_exposure(
    lab_illuminance_lux: float,
    *,
    sun_illuminance_lux: float = SUN_ILLUMINANCE_LUX,
    orbit_exposure_s: float = ORBIT_EXPOSURE_S,
    strobe_lm_s: float = STROBE_LM_S,
    scene_area_m2: float = SCENE_AREA_M2,
    field_s: float = FIELD_S,
) -> ExposureSettings:
    """Seed §2.1: the lab shutter that keeps orbit's ambient-to-strobe ratio under a dimmer simulated sun.

    In orbit, ``130000 lux * 0.1 m^2 * 1e-4 s = 1.3 lm s`` of sunlight meets the strobe's 1.3 lm s (the seed
    rounds the former to 1.5). The strobe's ~20 us flash fits in any shutter, so only the ambient term
    scales with the exposure: ``t_lab = t_orbit * E_sun / E_lab`` (about 67x at 1.5 % of sunlight).

    Parameters
    ----------
    lab_illuminance_lux : float
        The simulated sun's illuminance on the scene, > 0 lux.
    sun_illuminance_lux, orbit_exposure_s, strobe_lm_s, scene_area_m2 : float
        Orbit illuminance (lux), orbit shutter (s), strobe output (lm s) and scene area (m^2); all > 0.
    field_s : float
        Longest shutter the camera allows (one video field, 1/60 s), > 0 s.

    Raises
    ------
    InputError
        If the lab sun is so dim that the shutter would have to exceed ``field_s``.
    """
    sun = v.in_range(sun_illuminance_lux, "sun_illuminance_lux", low=0.0, low_inclusive=False)
    lab = v.in_range(lab_illuminance_lux, "lab_illuminance_lux", low=0.0, low_inclusive=False)
    orbit_s = v.in_range(orbit_exposure_s, "orbit_exposure_s", low=0.0, low_inclusive=False)
    strobe = v.in_range(strobe_lm_s, "strobe_lm_s", low=0.0, low_inclusive=False)
    area = v.in_range(scene_area_m2, "scene_area_m2", low=0.0, low_inclusive=False)
    field = v.in_range(field_s, "field_s", low=0.0, low_inclusive=False)
    orbit_ambient = sun * area * orbit_s
    ratio = orbit_ambient / strobe
    lab_s = ratio * strobe / (lab * area)
    if lab_s > field:
        raise InputError(
            f"lab_illuminance_lux={lab:g} would need a {lab_s:.4g} s shutter, longer than one field "
            f"({field:.4g} s; seed §2.1). Light the scene with at least "
            f"{orbit_ambient / (area * field):.4g} lux."
        )
    return ExposureSettings(
        sun_illuminance_lux=sun,
        lab_illuminance_lux=lab,
        orbit_exposure_s=orbit_s,
        lab_exposure_s=lab_s,
        exposure_ratio=lab_s / orbit_s,
        orbit_ambient_lm_s=orbit_ambient,
        lab_ambient_lm_s=lab * area * lab_s,
        strobe_lm_s=strobe,
        ambient_to_strobe_ratio=ratio,
    )


def _rotation(matrix: object, name: str) -> FloatArray:
    try:  # an int beyond the float range, text, a ragged list
        rotation = v.as_float_array(matrix, name)
    except InputError:
        raise InputError(f"{name} must be a 3x3 rotation matrix; got {matrix!r:.80}.") from None
    if rotation.shape != (3, 3) or not np.isfinite(rotation).all():
        raise InputError(f"{name} must be a finite 3x3 rotation matrix; got shape {rotation.shape}.")
    if (
        not np.allclose(rotation.T @ rotation, np.eye(3), atol=_ROTATION_TOLERANCE)
        or np.linalg.det(rotation) < 0
    ):
        raise InputError(
            f"{name} must be a proper rotation (orthonormal, det +1); got {rotation.tolist()}. "
            "Its columns are the LVLH x, y, z axes in world coordinates."
        )
    return rotation


def sun_path(
    orbit: Orbit | None,
    time_s: object,
    *,
    spot_world_m: object,
    world_from_lvlh: object = None,
    lab_sun_fraction: float = LAB_SUN_FRACTION,
    direction_tolerance_rad: float = math.radians(0.5),
    mount: ss.LampMount | None = None,
    optics: ss.LampOptics | None = None,
    rates: ss.RateLimits | None = None,
) -> SunPath:
    """The lamp trajectory that reproduces the orbit's sun direction over a spot of the mock-up.

    At each time the lamp is put where the light must come from (the rail position closest in angle to the
    sun direction, seed §4.1), pointed at the spot, focused to hold ``lab_sun_fraction`` of sunlight there
    (open loop from the computed ``rho``), then followed within the joint rate limits. Samples the lab
    cannot reproduce are clipped to the simulator's limits and flagged, not raised.

    Parameters
    ----------
    orbit : Orbit or None
        The orbit; the default (400 km, beta 0) when None.
    time_s : array_like of shape (K,)
        Strictly increasing times >= 0 s. Sample finely enough for the rate limits (tens of seconds).
    spot_world_m : array_like of shape (3,)
        The spot centre on the mock-up, world metres.
    world_from_lvlh : array_like of shape (3, 3), optional
        Rotation whose columns are the LVLH axes in the world; :data:`DEFAULT_WORLD_FROM_LVLH` when omitted.
    lab_sun_fraction : float
        The simulated sun's share of orbital sunlight, in (0, 1]; seed §4.1's 1.5 % by default.
    direction_tolerance_rad : float
        Direction error above which a sample is flagged ``direction_unreachable``, >= 0 rad.
    mount, optics, rates : optional
        Solar-simulator rail placement, optics and joint rate limits.

    Returns
    -------
    SunPath

    Raises
    ------
    InputError
        Bad times (negative, NaN, not increasing), a spot the lamp cannot see from anywhere on the rail, a
        non-rotation ``world_from_lvlh``, or a fraction outside (0, 1].
    """
    orbit = _orbit(orbit)
    mount = ss.LampMount() if mount is None else mount
    optics = ss.LampOptics() if optics is None else optics
    rates = ss.RateLimits() if rates is None else rates
    times = _times(time_s, strictly_increasing=True)
    rotation = _rotation(
        DEFAULT_WORLD_FROM_LVLH if world_from_lvlh is None else world_from_lvlh, "world_from_lvlh"
    )
    fraction = v.in_range(lab_sun_fraction, "lab_sun_fraction", low=0.0, high=1.0, low_inclusive=False)
    tolerance = v.in_range(direction_tolerance_rad, "direction_tolerance_rad", low=0.0)
    spot = ss._vector3(spot_world_m, "spot_world_m")
    target_lux = fraction * SUN_ILLUMINANCE_LUX
    exposure = compensating_exposure(target_lux)

    sun_lvlh = sun_direction_lvlh(orbit, times)
    sun_world = sun_lvlh @ rotation.T
    world_from_rail = ss.rotation_world_from_rail(mount)
    spot_r = ss._spot_in_rail(np.asarray(spot), mount)
    interval = ss._rail_interval(spot_r, spot)
    rail_target, _ = ss._best_rail(spot_r, sun_world @ world_from_rail, interval)

    # Joint targets: point at the spot from the chosen rail position, focus to hold the lab intensity.
    offsets = spot_r[None, :] - np.column_stack([rail_target, np.zeros((len(times), 2))])
    rho, theta, phi = ss._spherical(offsets)
    theta = np.clip(theta, *ss.THETA_RANGE_RAD)  # rounding only: the rail interval keeps theta in range
    phi = np.clip(phi, *ss.PHI_RANGE_RAD)
    rho = np.maximum(rho, ss.RHO_MIN_M)
    gamma_wanted = ss._focus_for_half_angle(ss._half_angle_for_intensity(rho, target_lux, optics), optics)
    gamma = np.clip(gamma_wanted, *ss.GAMMA_RANGE_M)
    targets = np.column_stack([theta, phi, rail_target, gamma])

    path, lag_s = ss._track(times, targets, rates)
    # rho is computed from the spot (seed §4.1, open loop): the distance from where the lamp is to the spot.
    lamp_to_spot = spot_r[None, :] - np.column_stack([path[:, 2], np.zeros((len(times), 2))])
    rho_path = np.maximum(np.linalg.norm(lamp_to_spot, axis=-1), ss.RHO_MIN_M)
    trajectory = ss._trajectory(times, rho_path, path)

    light_world = (-lamp_to_spot / np.linalg.norm(lamp_to_spot, axis=-1, keepdims=True)) @ world_from_rail.T
    cross = np.linalg.norm(np.cross(light_world, sun_world), axis=-1)
    direction_error = np.arctan2(cross, np.sum(light_world * sun_world, axis=-1))
    sunlit = in_sunlight(orbit, times)
    intensity = np.where(sunlit, ss._intensity(rho_path, ss._half_angle(path[:, 3], optics), optics), 0.0)
    return SunPath(
        time_s=times,
        orbit_angle_rad=orbit_angle_rad(orbit, times),
        sun_lvlh=sun_lvlh,
        sun_world=sun_world,
        sunlit=sunlit,
        trajectory=trajectory,
        light_world=light_world,
        direction_error_rad=direction_error,
        intensity_lux=intensity,
        target_intensity_lux=target_lux,
        direction_unreachable=direction_error > tolerance,
        focus_clipped=np.abs(gamma_wanted - gamma) > _FOCUS_TOLERANCE_M,
        rate_limited=lag_s > _LAG_TOLERANCE_S,
        exposure=exposure,
    )
