"""Seed §4.1, Fig. 10: the robotic solar-illumination simulator's kinematics, optics and trajectories.

A 1500 W arc lamp rides a 4-DOF computer-controlled platform: a rail carriage (``lambda``), a pan/tilt head
(``theta``, ``phi``) and a focus lead screw (``gamma``). The seed writes its configuration as
``(rho, theta, phi, lambda, gamma)`` and its task as ``x = (A_w, s, I)``; ``x = F(config)`` below.

Frames (all right-handed; the world's ``z_W`` points up)::

    side view along the rail (x_R into the page)       top view (z_R out of the page), default mount

          z_R (= z_W, up)                                 y_R  (toward the mock-up)
           ^       n (beam axis)                           ^         * A  spot centre on the mock-up
           |      /                                        |        /
           | phi /   rho                                   |  rho  /
           |    /  . . . . * A                             |      / theta (pan, from x_R)
           |   /                                           |     /  )
           |  /                                            |    /    )
           | /                                   O ========|===L=============> x_R  rail axis
           L --------> y_R                       rail     lamp centre at O + lambda * x_R
    lamp centre                                 origin

- Rail frame ``R``: origin ``O`` = ``LampMount.rail_origin_world_m``; ``x_R`` = the rail's direction in the
  world (``LampMount.rail_direction_world``); ``z_R`` = world up with its component along the rail removed;
  ``y_R = z_R x x_R``. With the default mount the rail runs along world ``+x`` at ``y = -2 m``, ``z = 1 m``
  and ``y_R`` = world ``+y`` looks at the mock-up.
- Lamp frame ``L``: the rail frame carried to the lamp centre ``O + lambda x_R`` (the pan and tilt axes meet
  there; the carriage translates, it does not rotate).
- Beam axis ``n`` (the seed's "lamp frame n axis"): in ``L``,
  ``n = (sin phi cos theta, sin phi sin theta, cos phi)``: ``theta`` is the pan (azimuth from ``x_R`` about
  ``z_R``), ``phi`` the tilt (polar angle from ``z_R``). The seed's ranges, theta 90..180 deg and phi 60..120
  deg, let the lamp look from straight across the rail (``+y_R``) back along it (``-x_R``), 30 deg above or
  below horizontal. Head frame ``H = (n, o, n x o)`` with ``o = (-sin theta, cos theta, 0)``.
- Spot centre ``A_w = O + lambda x_R + rho R_WR n``. ``rho`` is not actuated and not measured: it is computed
  from the requested spot (seed §4.1, open loop).

Optics (an assumed model; the seed's [13] verified its own experimentally): the focus ``gamma`` sets the beam
half-angle ``s`` linearly between a spot setting (``gamma = 0``) and a flood setting (``gamma = 0.076 m``),
and the beam's flux ``P`` spreads uniformly over the spot disc, so the illuminance at the spot centre, on a
surface normal to the beam, is ``I = P / (pi (rho tan s)^2)``: it falls with ``rho^2`` at a fixed focus.
Holding ``I`` while ``rho`` changes (seed §4.1: maintained open loop from the computed ``rho``) means
``tan s = sqrt(P / (pi I)) / rho``, i.e. a spot of fixed radius ``sqrt(P / (pi I))``.

Angles are radians inside; degrees appear only in messages and docs.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.float64]

# Seed §4.1, the configuration table (rho has no upper limit).
RHO_MIN_M = 0.15
THETA_RANGE_RAD = (math.pi / 2.0, math.pi)
PHI_RANGE_RAD = (math.pi / 3.0, 2.0 * math.pi / 3.0)
LAMBDA_RANGE_M = (0.0, 4.5)
GAMMA_RANGE_M = (0.0, 0.076)

LIMITS: dict[str, tuple[float, float]] = {
    "rho": (RHO_MIN_M, math.inf),
    "theta": THETA_RANGE_RAD,
    "phi": PHI_RANGE_RAD,
    "lambda": LAMBDA_RANGE_M,
    "gamma": GAMMA_RANGE_M,
}
_ANGLES = ("theta", "phi")
ACTUATED = ("theta", "phi", "lambda", "gamma")  # seed §4.1: rho is the unactuated DOF

# A computed joint this close to a limit is on it (rounding of the spherical coordinates), not beyond it.
_LIMIT_TOLERANCE = 1e-12
# Relative slack on squared distances when solving for the rail interval: a hundred times their rounding,
# and small enough that the joint it admits is within _LIMIT_TOLERANCE of its limit.
_SQUARED_SLACK = 1e-13
# A rail this close to vertical has no defined "up" for the pan axis.
_MIN_RAIL_TILT_FROM_VERTICAL_RAD = math.radians(1.0)
_VECTOR_SIZE = 3

Vector3 = tuple[float, float, float]


def _range_text(name: str) -> str:
    low, high = LIMITS[name]
    if name in _ANGLES:
        return f"[{math.degrees(low):g}, {math.degrees(high):g}] deg"
    return f"[{low:g}, {'inf' if math.isinf(high) else f'{high:g}'}] m"


def _value_text(name: str, value: float) -> str:
    if name in _ANGLES:
        return f"{name}={value:.6g} rad ({math.degrees(value):.4g} deg)"
    return f"{name}={value:.6g} m"


def _limit_error(name: str, value: float, context: str, fix: str) -> InputError:
    return InputError(
        f"{context} needs {_value_text(name, value)}, outside {name}'s range {_range_text(name)} "
        f"(seed §4.1). {fix}"
    )


def _on_limit(name: str, value: float, context: str, fix: str) -> float:
    """``value`` clipped onto its range if within rounding of it, else an error naming the limit."""
    low, high = LIMITS[name]
    if low - _LIMIT_TOLERANCE <= value <= high + _LIMIT_TOLERANCE:
        return min(max(value, low), high)
    raise _limit_error(name, value, context, fix)


def _vector3(value: object, name: str) -> Vector3:
    array = v.as_float_array(value, name)
    if array.shape != (_VECTOR_SIZE,):
        raise InputError(f"{name} must have shape (3,) = (x, y, z); got shape {array.shape}.")
    if not np.isfinite(array).all():
        raise InputError(f"{name} contains NaN or inf; got {value!r}. Pass finite world coordinates.")
    return (float(array[0]), float(array[1]), float(array[2]))


def _unit3(value: object, name: str) -> FloatArray:
    array = np.asarray(_vector3(value, name))
    norm = float(np.linalg.norm(array))
    if norm == 0.0:
        raise InputError(f"{name} must be a non-zero direction; got {value!r}.")
    return array / norm


@dataclass(frozen=True)
class LampConfiguration:
    """The simulator's configuration ``(rho, theta, phi, lambda, gamma)`` (seed §4.1, Fig. 10).

    Parameters
    ----------
    rho_m : float
        Distance from the lamp centre to the spot centre, >= 0.15 m (computed, not actuated).
    theta_rad : float
        Pan: azimuth of the beam axis from the rail axis ``x_R`` about ``z_R``, in [pi/2, pi] rad
        (90..180 deg).
    phi_rad : float
        Tilt: polar angle of the beam axis from ``z_R``, in [pi/3, 2 pi/3] rad (60..120 deg).
    lambda_m : float
        Travel of the lamp centre along the rail from its origin, in [0, 4.5] m.
    gamma_m : float
        Focus: bulb carriage position on its lead screw, in [0, 0.076] m.
    """

    rho_m: float
    theta_rad: float
    phi_rad: float
    lambda_m: float
    gamma_m: float

    def __post_init__(self) -> None:
        for field in fields(self):
            name = field.name.split("_")[0]
            value = v.finite_number(getattr(self, field.name), field.name)
            low, high = LIMITS[name]
            if not low <= value <= high:
                raise InputError(
                    f"{field.name}={value!r} is outside {name}'s range {_range_text(name)} (seed §4.1). "
                    f"Pass a value inside it."
                )
            object.__setattr__(self, field.name, value)


@dataclass(frozen=True)
class LampTask:
    """The simulator's task ``x = (A_w, s, I)`` (seed §4.1).

    Attributes
    ----------
    spot_world_m : tuple of 3 floats
        ``A_w``: world vector to the centre of the projected spot, metres.
    beam_angle_rad : float
        ``s``: beam half-angle measured from the beam axis ``n``, radians.
    intensity_lux : float
        ``I``: illuminance at the spot centre on a surface normal to the beam, lux.
    """

    spot_world_m: Vector3
    beam_angle_rad: float
    intensity_lux: float


@dataclass(frozen=True)
class LampPose:
    """Where the lamp is and where it points, for a renderer's spot light.

    Attributes
    ----------
    position_world_m : tuple of 3 floats
        Lamp centre in the world, metres.
    rotation_world_from_head : ndarray of shape (3, 3)
        Columns are the head frame's axes ``(n, o, n x o)`` in world coordinates; ``n`` is the beam axis.
    """

    position_world_m: Vector3
    rotation_world_from_head: FloatArray

    @property
    def beam_axis_world(self) -> FloatArray:
        """Unit beam axis ``n`` in the world."""
        return np.asarray(self.rotation_world_from_head[:, 0], dtype=np.float64)


@dataclass(frozen=True)
class LampMount:
    """Where the rail is in the world.

    Parameters
    ----------
    rail_origin_world_m : tuple of 3 floats
        The rail's origin ``O`` (the lamp centre at ``lambda = 0``) in world coordinates, metres.
    rail_direction_world : tuple of 3 floats
        Direction of increasing ``lambda`` in the world (normalised here); not within 1 deg of vertical.
    """

    rail_origin_world_m: Vector3 = (0.0, -2.0, 1.0)
    rail_direction_world: Vector3 = (1.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "rail_origin_world_m", _vector3(self.rail_origin_world_m, "rail_origin_world_m")
        )
        direction = _unit3(self.rail_direction_world, "rail_direction_world")
        if abs(direction[2]) > math.cos(_MIN_RAIL_TILT_FROM_VERTICAL_RAD):
            raise InputError(
                f"rail_direction_world={self.rail_direction_world!r} is within 1 deg of vertical, so the pan "
                "axis (world up, square to the rail) is undefined. Use a rail that is not vertical."
            )
        object.__setattr__(self, "rail_direction_world", (direction[0], direction[1], direction[2]))


@dataclass(frozen=True)
class LampOptics:
    """The focus-to-beam optics model (assumed; the seed's [13] measured its own).

    Parameters
    ----------
    beam_flux_lm : float
        Luminous flux delivered into the beam, > 0 lm. The default, about 4 lm per electrical watt of the
        1500 W lamp, lights a spot of 1 m radius at the seed's 1.5 % of sunlight (1950 lux; seed §4.1).
    spot_half_angle_rad : float
        Beam half-angle at ``gamma = 0`` (spot), in (0, flood_half_angle_rad).
    flood_half_angle_rad : float
        Beam half-angle at ``gamma = 0.076 m`` (flood), below pi/2.
    """

    beam_flux_lm: float = 6000.0
    spot_half_angle_rad: float = math.radians(10.0)
    flood_half_angle_rad: float = math.radians(40.0)

    def __post_init__(self) -> None:
        flux = v.in_range(self.beam_flux_lm, "beam_flux_lm", low=0.0, low_inclusive=False)
        flood = v.in_range(
            self.flood_half_angle_rad,
            "flood_half_angle_rad",
            low=0.0,
            high=math.pi / 2.0,
            low_inclusive=False,
            high_inclusive=False,
        )
        spot = v.in_range(
            self.spot_half_angle_rad,
            "spot_half_angle_rad",
            low=0.0,
            high=flood,
            low_inclusive=False,
            high_inclusive=False,
        )
        object.__setattr__(self, "beam_flux_lm", flux)
        object.__setattr__(self, "flood_half_angle_rad", flood)
        object.__setattr__(self, "spot_half_angle_rad", spot)


@dataclass(frozen=True)
class RateLimits:
    """Joint speed limits of the actuated DOF (assumed; the seed gives none), all > 0.

    Parameters
    ----------
    theta_rad_s, phi_rad_s : float
        Pan and tilt speed, rad/s.
    lambda_m_s : float
        Rail carriage speed, m/s.
    gamma_m_s : float
        Focus lead-screw speed, m/s (the full 0.076 m in about 4 s by default).
    """

    theta_rad_s: float = 0.5
    phi_rad_s: float = 0.5
    lambda_m_s: float = 0.25
    gamma_m_s: float = 0.02

    def __post_init__(self) -> None:
        for field in fields(self):
            value = v.in_range(getattr(self, field.name), field.name, low=0.0, low_inclusive=False)
            object.__setattr__(self, field.name, value)

    def as_array(self) -> FloatArray:
        """The limits in :data:`ACTUATED` order ``(theta, phi, lambda, gamma)``."""
        return np.array([self.theta_rad_s, self.phi_rad_s, self.lambda_m_s, self.gamma_m_s])


# ---------------------------------------------------------------------------------------------- geometry


def rotation_world_from_rail(mount: LampMount | None = None) -> FloatArray:
    """Columns ``(x_R, y_R, z_R)`` of the rail (and lamp) frame in world coordinates, shape (3, 3)."""
    mount = v.instance_or_default(mount, "mount", LampMount)
    x_axis = np.asarray(mount.rail_direction_world)
    up = np.array([0.0, 0.0, 1.0])
    z_axis = up - (up @ x_axis) * x_axis
    z_axis /= np.linalg.norm(z_axis)
    return np.column_stack([x_axis, np.cross(z_axis, x_axis), z_axis])


def _beam_axis(theta: FloatArray, phi: FloatArray) -> FloatArray:
    return np.stack([np.sin(phi) * np.cos(theta), np.sin(phi) * np.sin(theta), np.cos(phi)], axis=-1)


def _spot_in_rail(spot_world_m: FloatArray, mount: LampMount) -> FloatArray:
    """The spot ``p = R_WR^T (A_w - O)`` in the rail frame."""
    offset = spot_world_m - np.asarray(mount.rail_origin_world_m)
    return np.asarray(offset @ rotation_world_from_rail(mount), dtype=np.float64)


def _spherical(
    vector_r: FloatArray,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``(rho, theta, phi)`` of lamp-to-spot vectors in the lamp frame; theta near -pi is taken as +pi."""
    x, y, z = vector_r[..., 0], vector_r[..., 1], vector_r[..., 2]
    rho = np.sqrt(x * x + y * y + z * z)
    theta = np.arctan2(y, x)
    # atan2 returns -pi for a spot a rounding error below y_R = 0 straight back along the rail: that is theta
    # = pi, on the pan limit, not a spot behind the lamp.
    theta = np.where(theta < -math.pi / 2.0, theta + 2.0 * math.pi, theta)
    phi = np.arctan2(np.hypot(x, y), z)
    return rho, theta, phi


# ------------------------------------------------------------------------------------------------ optics


def _half_angle(gamma_m: FloatArray | float, optics: LampOptics) -> FloatArray:
    fraction = np.asarray(gamma_m, dtype=np.float64) / GAMMA_RANGE_M[1]
    spread = optics.flood_half_angle_rad - optics.spot_half_angle_rad
    return np.asarray(optics.spot_half_angle_rad + spread * fraction, dtype=np.float64)


def _focus_for_half_angle(half_angle_rad: FloatArray | float, optics: LampOptics) -> FloatArray:
    spread = optics.flood_half_angle_rad - optics.spot_half_angle_rad
    half_angle = np.asarray(half_angle_rad, dtype=np.float64)
    return np.asarray((half_angle - optics.spot_half_angle_rad) / spread * GAMMA_RANGE_M[1], dtype=np.float64)


def _intensity(
    rho_m: FloatArray | float, half_angle_rad: FloatArray | float, optics: LampOptics
) -> FloatArray:
    radius_m = np.asarray(rho_m, dtype=np.float64) * np.tan(half_angle_rad)
    return np.asarray(optics.beam_flux_lm / (math.pi * radius_m * radius_m), dtype=np.float64)


def _half_angle_for_intensity(
    rho_m: FloatArray | float, intensity_lux: FloatArray | float, optics: LampOptics
) -> FloatArray:
    # A fixed illuminance is a fixed spot radius sqrt(P / (pi I)): the beam narrows as rho grows.
    radius_m = np.sqrt(optics.beam_flux_lm / (math.pi * np.asarray(intensity_lux, dtype=np.float64)))
    return np.asarray(np.arctan(radius_m / np.asarray(rho_m, dtype=np.float64)), dtype=np.float64)


def beam_half_angle_rad(gamma_m: float, *, optics: LampOptics | None = None) -> float:
    """Beam half-angle ``s`` from the focus ``gamma`` (linear from spot to flood).

    Parameters
    ----------
    gamma_m : float
        Focus (bulb carriage position), in [0, 0.076] m.
    optics : LampOptics, optional
        The optics model; the default :class:`LampOptics` when omitted.

    Returns
    -------
    float
        ``s = s_spot + (s_flood - s_spot) gamma / 0.076 m``, radians.
    """
    optics = v.instance_or_default(optics, "optics", LampOptics)
    gamma = _checked_joint(gamma_m, "gamma_m", "gamma")
    return float(_half_angle(gamma, optics))


def focus_for_beam_angle_m(beam_angle_rad: float, *, optics: LampOptics | None = None) -> float:
    """Focus ``gamma`` that gives the beam half-angle ``s`` (inverse of :func:`beam_half_angle_rad`).

    Raises
    ------
    InputError
        If ``beam_angle_rad`` needs a focus outside ``gamma``'s [0, 0.076] m.
    """
    optics = v.instance_or_default(optics, "optics", LampOptics)
    angle = v.finite_number(beam_angle_rad, "beam_angle_rad")
    gamma = float(_focus_for_half_angle(angle, optics))
    return _on_limit(
        "gamma",
        gamma,
        f"beam_angle_rad={angle:.6g} ({math.degrees(angle):.4g} deg)",
        f"Ask for a beam half-angle in [{math.degrees(optics.spot_half_angle_rad):g}, "
        f"{math.degrees(optics.flood_half_angle_rad):g}] deg.",
    )


def spot_intensity_lux(rho_m: float, beam_angle_rad: float, *, optics: LampOptics | None = None) -> float:
    """Illuminance at the spot centre, ``I = P / (pi (rho tan s)^2)``, lux.

    Parameters
    ----------
    rho_m : float
        Lamp-to-spot distance, >= 0.15 m.
    beam_angle_rad : float
        Beam half-angle ``s``, in (0, pi/2) rad.
    optics : LampOptics, optional
        The optics model.
    """
    optics = v.instance_or_default(optics, "optics", LampOptics)
    rho = _checked_joint(rho_m, "rho_m", "rho")
    angle = v.in_range(
        beam_angle_rad, "beam_angle_rad", low=0.0, high=math.pi / 2, low_inclusive=False, high_inclusive=False
    )
    return float(_intensity(rho, angle, optics))


def focus_for_intensity_m(rho_m: float, intensity_lux: float, *, optics: LampOptics | None = None) -> float:
    """Focus ``gamma`` that holds ``intensity_lux`` at the spot centre ``rho_m`` away (seed §4.1, open loop).

    Raises
    ------
    InputError
        If no focus in [0, 0.076] m gives that intensity at that distance; the message gives the intensities
        the lamp can reach there.
    """
    optics = v.instance_or_default(optics, "optics", LampOptics)
    rho = _checked_joint(rho_m, "rho_m", "rho")
    intensity = v.in_range(intensity_lux, "intensity_lux", low=0.0, low_inclusive=False)
    return _focus_holding(rho, intensity, optics)


def _focus_holding(rho: float, intensity: float, optics: LampOptics) -> float:
    gamma = float(_focus_for_half_angle(_half_angle_for_intensity(rho, intensity, optics), optics))
    brightest = float(_intensity(rho, optics.spot_half_angle_rad, optics))
    dimmest = float(_intensity(rho, optics.flood_half_angle_rad, optics))
    return _on_limit(
        "gamma",
        gamma,
        f"intensity_lux={intensity:.6g} at rho={rho:.6g} m",
        f"At this distance the lamp gives {dimmest:.4g}..{brightest:.4g} lux; ask for an intensity in that "
        "range or move the lamp.",
    )


def _checked_joint(value: object, argument: str, name: str) -> float:
    number = v.finite_number(value, argument)
    low, high = LIMITS[name]
    if not low <= number <= high:
        raise InputError(
            f"{argument}={number!r} is outside {name}'s range {_range_text(name)} (seed §4.1). "
            "Pass a value inside it."
        )
    return number


# -------------------------------------------------------------------------------------------- kinematics


def lamp_pose(configuration: LampConfiguration, *, mount: LampMount | None = None) -> LampPose:
    """Lamp centre and head frame ``(n, o, n x o)`` in the world for a configuration."""
    v.instance_of(configuration, "configuration", LampConfiguration, none_allowed=False)
    mount = v.instance_or_default(mount, "mount", LampMount)
    rotation = rotation_world_from_rail(mount)
    theta, phi = configuration.theta_rad, configuration.phi_rad
    beam = _beam_axis(np.array(theta), np.array(phi))
    pan = np.array([-math.sin(theta), math.cos(theta), 0.0])
    head_r = np.column_stack([beam, pan, np.cross(beam, pan)])
    centre = np.asarray(mount.rail_origin_world_m) + configuration.lambda_m * rotation[:, 0]
    return LampPose(
        position_world_m=(float(centre[0]), float(centre[1]), float(centre[2])),
        rotation_world_from_head=rotation @ head_r,
    )


def forward_kinematics(
    configuration: LampConfiguration, *, mount: LampMount | None = None, optics: LampOptics | None = None
) -> LampTask:
    """Seed §4.1: ``x = F(theta)``, the task reached by a configuration.

    Parameters
    ----------
    configuration : LampConfiguration
        ``(rho, theta, phi, lambda, gamma)`` within the seed's ranges.
    mount : LampMount, optional
        Where the rail is; the default mount when omitted.
    optics : LampOptics, optional
        Focus-to-beam model; the default when omitted.

    Returns
    -------
    LampTask
        ``A_w = O + lambda x_R + rho R_WR n(theta, phi)``, ``s = s(gamma)``, ``I = P / (pi (rho tan s)^2)``.
    """
    if not isinstance(configuration, LampConfiguration):
        raise InputError(f"configuration must be a LampConfiguration; got {type(configuration).__name__}.")
    optics = v.instance_or_default(optics, "optics", LampOptics)
    pose = lamp_pose(configuration, mount=mount)
    spot = np.asarray(pose.position_world_m) + configuration.rho_m * pose.beam_axis_world
    half_angle = float(_half_angle(configuration.gamma_m, optics))
    return LampTask(
        spot_world_m=(float(spot[0]), float(spot[1]), float(spot[2])),
        beam_angle_rad=half_angle,
        intensity_lux=float(_intensity(configuration.rho_m, half_angle, optics)),
    )


@dataclass(frozen=True)
class _RailInterval:
    """Rail positions from which the lamp can reach a spot, and which limit sets the lower end."""

    low_m: float
    high_m: float
    low_set_by: str


def _rail_interval(spot_r: FloatArray, spot_world: Vector3) -> _RailInterval:
    """The closed interval of lambda from which every joint limit holds for the spot (closed form).

    With the spot at ``p`` in the rail frame, the lamp-to-spot vector is ``(p_x - lambda, p_y, p_z)``. Pan in
    [90, 180] deg needs ``p_y >= 0`` and ``p_x - lambda <= 0``; tilt in [60, 120] deg needs
    ``|p_z| <= rho cos 60 deg``, i.e. ``(p_x - lambda)^2 >= 3 p_z^2 - p_y^2``; ``rho >= 0.15 m`` needs
    ``(p_x - lambda)^2 >= 0.15^2 - p_y^2 - p_z^2``. So ``lambda >= p_x + x_min``, an interval.
    """
    px, py, pz = (float(value) for value in spot_r)
    context = f"spot_world_m={spot_world}"
    if py < -_LIMIT_TOLERANCE:
        raise InputError(
            f"{context} lies {-py:.4g} m on the far side of the rail (y_R < 0): with theta's range "
            f"{_range_text('theta')} (seed §4.1) the lamp only looks toward +y_R. Move the spot or the mount."
        )
    # The squared forms lose their rounding error through the square root (a 1e-16 slip becomes 1e-8 in
    # lambda on a corner of the joint box), so each is relaxed by far less than the limits' tolerance.
    tilt_slack = _SQUARED_SLACK * (3.0 * pz * pz + py * py)
    reach_slack = _SQUARED_SLACK * RHO_MIN_M**2
    needs = {
        "theta": 0.0,
        "phi": math.sqrt(max(0.0, 3.0 * pz * pz - py * py - tilt_slack)),
        "rho": math.sqrt(max(0.0, RHO_MIN_M**2 - py * py - pz * pz - reach_slack)),
    }
    binding = max(needs, key=lambda name: needs[name])
    low = px + needs[binding]
    if low < LAMBDA_RANGE_M[0]:
        low, binding = LAMBDA_RANGE_M[0], "lambda"
    if low > LAMBDA_RANGE_M[1] + _LIMIT_TOLERANCE:
        raise InputError(
            f"{context} needs the lamp at lambda >= {low:.6g} m (set by {binding}'s range "
            f"{_range_text(binding)}), beyond the rail's lambda range {_range_text('lambda')} (seed §4.1). "
            "Pick a spot nearer the rail's origin."
        )
    return _RailInterval(low_m=min(low, LAMBDA_RANGE_M[1]), high_m=LAMBDA_RANGE_M[1], low_set_by=binding)


def _best_rail(
    spot_r: FloatArray, light_from_r: FloatArray, interval: _RailInterval
) -> tuple[FloatArray, FloatArray]:
    """Rail positions whose lamp direction (seen from the spot) is closest to ``light_from_r``, and the angle.

    Seen from the spot ``p``, the lamp at ``lambda`` lies along ``w = w0 + mu x_R`` with
    ``w0 = (0, -p_y, -p_z)`` (the foot of the perpendicular on the rail) and ``mu = lambda - p_x``.
    The cosine ``f(mu) = (w0.d + mu d_x) / sqrt(|w0|^2 + mu^2)`` has a single stationary point
    ``mu* = d_x |w0|^2 / w0.d`` (its maximum when ``w0.d > 0``, else a minimum). ``f`` is unimodal, so the
    best on the interval is one of ``mu*`` clipped to it and the two ends: all three are compared.
    Works on ``light_from_r`` of shape (K, 3).
    """
    px = float(spot_r[0])
    w0 = np.array([0.0, -float(spot_r[1]), -float(spot_r[2])])
    along = light_from_r @ w0
    with np.errstate(divide="ignore", invalid="ignore"):
        mu_star = light_from_r[:, 0] * (w0 @ w0) / along
    candidates = np.stack(
        [
            np.full(along.shape, interval.low_m),
            np.full(along.shape, interval.high_m),
            np.clip(
                np.nan_to_num(
                    px + mu_star, nan=interval.low_m, posinf=interval.high_m, neginf=interval.low_m
                ),
                interval.low_m,
                interval.high_m,
            ),
        ],
        axis=-1,
    )
    angles = _angle_to_lamp(spot_r, candidates, light_from_r[:, None, :])
    best = np.argmin(angles, axis=-1)
    rows = np.arange(best.size)
    return candidates[rows, best], angles[rows, best]


def _angle_to_lamp(spot_r: FloatArray, rail_m: FloatArray, light_from_r: FloatArray) -> FloatArray:
    """Angle between the direction from the spot to the lamp at ``rail_m`` and ``light_from_r`` (unit)."""
    to_lamp = np.stack(
        [rail_m - spot_r[0], np.full(rail_m.shape, -spot_r[1]), np.full(rail_m.shape, -spot_r[2])], axis=-1
    )
    cross = np.linalg.norm(np.cross(to_lamp, light_from_r), axis=-1)
    return np.asarray(np.arctan2(cross, np.sum(to_lamp * light_from_r, axis=-1)), dtype=np.float64)


def _joints_at(spot_r: FloatArray, rail_m: float, spot_world: Vector3) -> tuple[float, float, float]:
    rho, theta, phi = _spherical(spot_r - np.array([rail_m, 0.0, 0.0]))
    context = f"spot_world_m={spot_world} from lambda={rail_m:.6g} m"
    fix = "Choose a spot the lamp can see from there, or another rail position."
    return (
        _on_limit("rho", float(rho), context, fix),
        _on_limit("theta", float(theta), context, fix),
        _on_limit("phi", float(phi), context, fix),
    )


def inverse_kinematics(
    spot_world_m: object,
    *,
    beam_angle_rad: float | None = None,
    intensity_lux: float | None = None,
    rail_m: float | None = None,
    light_from: object = None,
    direction_tolerance_rad: float = math.radians(0.1),
    mount: LampMount | None = None,
    optics: LampOptics | None = None,
) -> LampConfiguration:
    """Seed §4.1: the configuration that puts the spot at ``spot_world_m`` with a beam angle or intensity.

    Four DOF are actuated (theta, phi, lambda, gamma); ``rho`` is computed from the requested spot, open loop.
    The rail is redundant, so one rule picks lambda: either ``rail_m`` (a requested lambda) or ``light_from``
    (light must arrive at the spot from this direction: lambda puts the lamp closest in angle to it).

    Parameters
    ----------
    spot_world_m : array_like of shape (3,)
        Requested spot centre ``A_w`` in the world, metres.
    beam_angle_rad : float, optional
        Requested beam half-angle ``s``; give this or ``intensity_lux``.
    intensity_lux : float, optional
        Requested illuminance at the spot centre, > 0 lux; focus is chosen to give it at the computed ``rho``.
    rail_m : float, optional
        Requested lambda in [0, 4.5] m; give this or ``light_from``.
    light_from : array_like of shape (3,), optional
        World direction from the spot toward the light (the reverse of the light's travel); need not be unit.
    direction_tolerance_rad : float
        How far (rad) the lamp's direction from the spot may be from ``light_from``; default 0.1 deg.
    mount, optics : optional
        Rail placement and optics model; defaults when omitted.

    Returns
    -------
    LampConfiguration

    Raises
    ------
    InputError
        Naming the argument and the limit it violates: a spot that needs a joint outside the seed's ranges,
        a beam angle or intensity that needs a focus outside [0, 0.076] m, a direction the rail cannot give,
        both or neither of each pair of options, NaN.
    """
    mount = v.instance_or_default(mount, "mount", LampMount)
    optics = v.instance_or_default(optics, "optics", LampOptics)
    spot = _vector3(spot_world_m, "spot_world_m")
    spot_r = _spot_in_rail(np.asarray(spot), mount)
    if (rail_m is None) == (light_from is None):
        raise InputError(
            "give exactly one of rail_m (a requested lambda, m) or light_from (the direction the light must "
            f"come from); got rail_m={rail_m!r}, light_from={light_from!r}."
        )
    if (beam_angle_rad is None) == (intensity_lux is None):
        raise InputError(
            "give exactly one of beam_angle_rad or intensity_lux; got "
            f"beam_angle_rad={beam_angle_rad!r}, intensity_lux={intensity_lux!r}."
        )
    if rail_m is not None:
        lam = _checked_joint(rail_m, "rail_m", "lambda")
    else:
        lam = _rail_for_direction(spot, spot_r, light_from, direction_tolerance_rad, mount)
    rho, theta, phi = _joints_at(spot_r, lam, spot)
    if beam_angle_rad is not None:
        gamma = focus_for_beam_angle_m(beam_angle_rad, optics=optics)
    else:
        intensity = v.in_range(intensity_lux, "intensity_lux", low=0.0, low_inclusive=False)
        gamma = _focus_holding(rho, intensity, optics)
    return LampConfiguration(rho_m=rho, theta_rad=theta, phi_rad=phi, lambda_m=lam, gamma_m=gamma)


def _rail_for_direction(
    spot: Vector3, spot_r: FloatArray, light_from: object, tolerance_rad: object, mount: LampMount
) -> float:
    tolerance = v.in_range(tolerance_rad, "direction_tolerance_rad", low=0.0)
    direction_r = _unit3(light_from, "light_from") @ rotation_world_from_rail(mount)
    interval = _rail_interval(spot_r, spot)
    rails, errors = _best_rail(spot_r, direction_r[None, :], interval)
    lam, error = float(rails[0]), float(errors[0])
    if error > tolerance:
        if lam >= interval.high_m:
            why = f"the rail ends at lambda = {LAMBDA_RANGE_M[1]:g} m"
        elif lam <= interval.low_m:
            why = f"lambda >= {interval.low_m:.4g} m is set by {interval.low_set_by}'s range " + _range_text(
                interval.low_set_by
            )
        else:
            why = "the rail only moves the lamp in the plane through the spot and the rail"
        raise InputError(
            f"light_from={light_from!r} cannot be reproduced at spot_world_m={spot}: the nearest direction "
            f"the lamp can give is {math.degrees(error):.4g} deg away (tolerance "
            f"{math.degrees(tolerance):.4g} deg) because {why} (seed §4.1). Request a direction in that "
            "plane and range, or move the mount."
        )
    return lam


# ------------------------------------------------------------------------------------------ trajectories


@dataclass(frozen=True)
class Trajectory:
    """A time-parametrised path of configurations; joints move linearly in time between samples.

    ``rho_m`` is the planned (computed) distance, not a measurement (seed §4.1).

    Attributes
    ----------
    time_s : ndarray of shape (K,)
        Strictly increasing sample times, seconds.
    rho_m, theta_rad, phi_rad, lambda_m, gamma_m : ndarray of shape (K,)
        The configuration at each time, within the seed's ranges.
    """

    time_s: FloatArray
    rho_m: FloatArray
    theta_rad: FloatArray
    phi_rad: FloatArray
    lambda_m: FloatArray
    gamma_m: FloatArray

    def __post_init__(self) -> None:
        time = np.array(v.as_float_array(self.time_s, "time_s"))
        if time.ndim != 1 or time.size == 0:
            raise InputError(f"time_s must be a non-empty 1-D array; got shape {time.shape}.")
        if not np.isfinite(time).all() or (np.diff(time) <= 0).any():
            raise InputError("time_s must be finite and strictly increasing (seconds).")
        time.setflags(write=False)
        object.__setattr__(self, "time_s", time)
        for field in fields(self)[1:]:
            values = np.array(v.as_float_array(getattr(self, field.name), field.name))
            if values.shape != time.shape:
                raise InputError(f"{field.name} must have shape {time.shape} (time_s's); got {values.shape}.")
            name = field.name.split("_")[0]
            low, high = LIMITS[name]
            bad = ~((values >= low) & (values <= high))
            if bad.any():
                index = int(np.flatnonzero(bad)[0])
                raise InputError(
                    f"{field.name}[{index}]={float(values[index])!r} is outside {name}'s range "
                    f"{_range_text(name)} (seed §4.1)."
                )
            values.setflags(write=False)
            object.__setattr__(self, field.name, values)

    @property
    def joints(self) -> FloatArray:
        """Actuated joints, shape (K, 4), in :data:`ACTUATED` order ``(theta, phi, lambda, gamma)``."""
        return np.column_stack([self.theta_rad, self.phi_rad, self.lambda_m, self.gamma_m])

    def configuration(self, index: int) -> LampConfiguration:
        """The configuration at sample ``index``."""
        return LampConfiguration(
            rho_m=float(self.rho_m[index]),
            theta_rad=float(self.theta_rad[index]),
            phi_rad=float(self.phi_rad[index]),
            lambda_m=float(self.lambda_m[index]),
            gamma_m=float(self.gamma_m[index]),
        )


def _trajectory(time_s: FloatArray, rho: FloatArray, joints: FloatArray) -> Trajectory:
    return Trajectory(
        time_s=time_s,
        rho_m=rho,
        theta_rad=joints[:, 0],
        phi_rad=joints[:, 1],
        lambda_m=joints[:, 2],
        gamma_m=joints[:, 3],
    )


def plan_trajectory(
    waypoints: Sequence[LampConfiguration],
    *,
    rates: RateLimits | None = None,
    start_time_s: float = 0.0,
) -> Trajectory:
    """Minimum-time path through waypoints with every joint inside its rate limit.

    Each segment moves all actuated joints linearly and together; it lasts as long as its slowest joint
    needs, ``max_j |dq_j| / rate_j``, so no joint exceeds its rate. ``rho`` is interpolated as planned.

    Parameters
    ----------
    waypoints : sequence of LampConfiguration
        At least one; consecutive waypoints must differ in some actuated joint.
    rates : RateLimits, optional
        Joint speed limits; defaults when omitted.
    start_time_s : float
        Time of the first waypoint, >= 0 s.

    Returns
    -------
    Trajectory
    """
    rates = v.instance_or_default(rates, "rates", RateLimits)
    start = v.in_range(start_time_s, "start_time_s", low=0.0)
    if isinstance(waypoints, LampConfiguration) or not isinstance(waypoints, Sequence):
        raise InputError(
            "waypoints must be a sequence (list or tuple) of LampConfiguration; "
            f"got {type(waypoints).__name__}."
        )
    points = list(waypoints)
    if not points:
        raise InputError("waypoints must hold at least one LampConfiguration; got none.")
    for index, point in enumerate(points):
        if not isinstance(point, LampConfiguration):
            raise InputError(f"waypoints[{index}] must be a LampConfiguration; got {type(point).__name__}.")
    joints = np.array([[p.theta_rad, p.phi_rad, p.lambda_m, p.gamma_m] for p in points])
    rho = np.array([p.rho_m for p in points])
    durations = np.max(np.abs(np.diff(joints, axis=0)) / rates.as_array(), axis=1)
    if (durations <= 0).any():
        index = int(np.flatnonzero(durations <= 0)[0]) + 1
        raise InputError(
            f"waypoints[{index}] has the same actuated joints as waypoints[{index - 1}]; remove the repeat."
        )
    time = start + np.concatenate([[0.0], np.cumsum(durations)])
    return _trajectory(time, rho, joints)


def sample_trajectory(trajectory: Trajectory, time_s: object) -> Trajectory:
    """The trajectory at new times (linear in time between its samples, as the joints move).

    Parameters
    ----------
    trajectory : Trajectory
    time_s : float or array_like of shape (T,)
        Strictly increasing times within ``[trajectory.time_s[0], trajectory.time_s[-1]]``, seconds.

    Returns
    -------
    Trajectory
        Configurations at ``time_s``.
    """
    if not isinstance(trajectory, Trajectory):
        raise InputError(f"trajectory must be a Trajectory; got {type(trajectory).__name__}.")
    try:
        times = np.atleast_1d(np.asarray(time_s, dtype=np.float64))
    except (TypeError, ValueError):
        raise InputError(f"time_s must be numbers in seconds; got {time_s!r}.") from None
    if times.ndim != 1 or times.size == 0 or not np.isfinite(times).all():
        raise InputError(f"time_s must be a finite scalar or non-empty 1-D array; got {time_s!r}.")
    first, last = float(trajectory.time_s[0]), float(trajectory.time_s[-1])
    if times.min() < first or times.max() > last:
        raise InputError(
            f"time_s must lie within the trajectory's [{first:g}, {last:g}] s; got "
            f"[{times.min():g}, {times.max():g}] s."
        )
    columns = [np.interp(times, trajectory.time_s, getattr(trajectory, name)) for name in _COLUMNS]
    return Trajectory(times, *columns)


_COLUMNS = ("rho_m", "theta_rad", "phi_rad", "lambda_m", "gamma_m")


def _track(time_s: FloatArray, targets: FloatArray, rates: RateLimits) -> tuple[FloatArray, FloatArray]:
    """Follow target joints (K, 4) as closely as the rate limits allow; returns the path and where it lags.

    The lamp starts on the first target (placed there before the run) and each step moves every joint
    toward its next target by at most ``rate * dt``; the joint box is convex, so the path stays in limits.
    """
    steps = np.diff(time_s)[:, None] * rates.as_array()
    path = np.empty_like(targets)
    path[0] = targets[0]
    for index in range(1, len(targets)):
        move = np.clip(targets[index] - path[index - 1], -steps[index - 1], steps[index - 1])
        path[index] = path[index - 1] + move
    lag = np.max(np.abs(path - targets) / rates.as_array(), axis=1)
    return path, lag
