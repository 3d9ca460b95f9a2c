"""Seed §4: the fields the anomalies produce: surface temperature, emissivity, ammonia concentration.

Three read-outs, each queried at world points of shape (K, 3) in metres and returning one value per point:

- :func:`surface_temperature_k` -- ambient plus the active Peltier spots (seed §4 E), each a Gaussian bump
  of ``+-delta_k`` at its centre falling off over its radius (default: the Kapton circle's radius)::

      T(p) = T_ambient + sum_i delta_i * exp(-|p - c_i|^2 / R_i^2)

  The steady heat equation is linear, so overlapping spots add.
- :func:`emissivity` -- the thermal-infrared emissivity of the surface at each point, from a table of the
  mock-up's materials, with black Kapton over every Peltier site (seed §4: the aluminium's low emissivity is
  why the Kapton is there). Together with the temperature it is what :func:`rsi.sensors.read_pyrometer`
  takes (``surface_temperature_k``, ``surface_emissivity``).
- :func:`gas_concentration_ppm` -- the ammonia mist from each active leak hole (seed §4 F), a steady
  turbulent round jet along the hole's normal switched on at the leak's start time; see :class:`RoundJet`.

Everything is pure numpy. The model choices and their sources are in ``docs/anomalies-and-fields.md``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import ROOM_TEMPERATURE_K
from rsi.errors import InputError
from rsi.sim.anomalies import KAPTON_RADIUS_M, AnomalySet, GasLeak, Site, ThermalSpot

FloatArray = NDArray[np.float64]

# A laboratory room (seed §4: the mock-up stands in a darkened room); the pyrometer's default background.
AMBIENT_K = ROOM_TEMPERATURE_K

# Thermal-infrared (8-12 um, the pyrometer's band, seed §3) emissivities of the mock-up's materials.
# Specular (polished) aluminium 0.04-0.1, black Kapton ~0.95, silicon solar cells behind cover glass ~0.85
# (the glass dominates in the thermal infrared).
EMISSIVITY: Mapping[str, float] = MappingProxyType(
    {
        "aluminium": 0.05,
        "kapton": 0.95,
        "solar_cell": 0.85,
    }
)

_LN2 = math.log(2.0)
_PLANE_TOLERANCE_M = 1e-9


def _as_points(points_m: object, name: str = "points_m") -> FloatArray:
    """Return `points_m` as a finite float64 array of shape (K, 3) or raise naming it."""
    points = v.as_float_array(points_m, name)  # refuses text, ragged lists and ints beyond the float range
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(
            f"{name} must have shape (K, 3) (one x, y, z row per point, metres); got shape {points.shape}. "
            f"For a single point pass np.reshape(point, (1, 3))."
        )
    if not np.isfinite(points).all():
        bad = int(np.count_nonzero(~np.isfinite(points).all(axis=1)))
        raise InputError(f"{name} contains {bad} row(s) with NaN or inf. Drop or fix those points.")
    return points


def _records(source: object, name: str, record_type: type[Any], attribute: str) -> tuple[Any, ...]:
    """The records of `record_type` in an AnomalySet (via `attribute`) or a sequence of them."""
    if isinstance(source, AnomalySet):
        return tuple(getattr(source, attribute))
    if isinstance(source, Sequence) and not isinstance(source, str):
        for item in source:
            if not isinstance(item, record_type):
                raise InputError(
                    f"{name} must be an AnomalySet or a sequence of {record_type.__name__}; "
                    f"it holds {type(item).__name__}."
                )
        return tuple(source)
    raise InputError(
        f"{name} must be an AnomalySet or a sequence of {record_type.__name__}; got {type(source).__name__}."
    )


# ----------------------------------------------------------------------------------------- temperature


def surface_temperature_k(
    points_m: object,
    spots: AnomalySet | Sequence[ThermalSpot],
    *,
    ambient_k: float = AMBIENT_K,
) -> FloatArray:
    """Surface temperature at world points: ambient plus the active Peltier spots (seed §4 E).

    Parameters
    ----------
    points_m : array_like of shape (K, 3)
        World points on the mock-up's surfaces, metres.
    spots : AnomalySet or sequence of ThermalSpot
        The world's anomalies (only its hot and cold spots are used).
    ambient_k : float
        Temperature of every surface away from the spots, > 0 K (default 293.15 K, a laboratory room).

    Returns
    -------
    ndarray of shape (K,)
        Temperature in kelvin.

    Raises
    ------
    InputError
        If `points_m` is not a finite (K, 3) array, `spots` holds something else, or `ambient_k` is not
        positive or too low for the cold spots (the temperature would not stay above 0 K).

    Notes
    -----
    ``T(p) = T_ambient + sum_i delta_i exp(-|p - c_i|^2 / R_i^2)`` with ``c_i`` the spot's centre,
    ``delta_i`` its temperature difference (``+-`` :attr:`AnomalySettings.peltier_delta_k`) and ``R_i``
    its radius. The distance is the 3-D distance: a thin skin is heated through, so both its faces warm.
    A Gaussian is a smooth stand-in for the conduction profile around a module glued inside a plate; at
    ``R`` (the Kapton circle's edge by default) the difference has fallen to ``1/e``, and beyond ``3 R`` it
    is below 0.02 % of ``delta``.

    Examples
    --------
    >>> from rsi.sim.anomalies import ThermalSpot
    >>> spot = ThermalSpot("peltier_0", (0.0, 0.0, 0.0), (0, 0, 1), 0.05, "kapton", delta_k=30.0)
    >>> surface_temperature_k([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]], [spot]).round(2).tolist()
    [323.15, 293.15]
    """
    points = _as_points(points_m)
    records: tuple[ThermalSpot, ...] = _records(spots, "spots", ThermalSpot, "thermal_spots")
    ambient = v.in_range(ambient_k, "ambient_k", low=0.0, low_inclusive=False)
    coldest = ambient + sum(min(spot.delta_k, 0.0) for spot in records)
    if coldest <= 0.0:
        raise InputError(
            f"ambient_k={ambient_k!r} is too low for the cold spots (it would reach {coldest:.2f} K). "
            "Raise ambient_k or lower the spots' delta_k."
        )
    temperature = np.full(points.shape[0], ambient)
    for spot in records:
        squared_m2 = np.sum((points - np.asarray(spot.position_m)) ** 2, axis=1)
        temperature += spot.delta_k * np.exp(-squared_m2 / spot.radius_m**2)
    return temperature


def emissivity(
    points_m: object,
    surface: str | Sequence[str],
    *,
    kapton_sites: Sequence[Site] = (),
    kapton_radius_m: float = KAPTON_RADIUS_M,
    table: Mapping[str, float] = EMISSIVITY,
) -> FloatArray:
    """Thermal-infrared emissivity of the surface at world points, for the pyrometer (seed §3, §4).

    Parameters
    ----------
    points_m : array_like of shape (K, 3)
        World points on the mock-up's surfaces, metres.
    surface : str or sequence of K str
        Material at every point, or one per point (keys of `table`).
    kapton_sites : sequence of Site
        Peltier sites carrying a black Kapton circle (seed §4: every Peltier module has one, on or off);
        points within `kapton_radius_m` of a site's centre read Kapton's emissivity whatever `surface` says.
    kapton_radius_m : float
        Radius of the Kapton circles, > 0 m.
    table : mapping of str to float
        Emissivity per material, each in (0, 1] (default :data:`EMISSIVITY`; extend it for new materials).

    Returns
    -------
    ndarray of shape (K,)
        Emissivity, dimensionless in (0, 1]; pass it as ``surface_emissivity`` to
        :func:`rsi.sensors.read_pyrometer`.

    Raises
    ------
    InputError
        If `points_m` is not a finite (K, 3) array, a material is not in `table`, `surface` has the wrong
        length, a table value is outside (0, 1], or `table` has no ``"kapton"`` entry while Kapton sites are
        given.

    Examples
    --------
    >>> emissivity([[0.0, 0.0, 0.0]], "aluminium").tolist()
    [0.05]
    """
    points = _as_points(points_m)
    if not isinstance(table, Mapping):
        raise InputError(f"table must be a mapping of material to emissivity; got {type(table).__name__}.")
    for material, value in table.items():
        v.in_range(value, f"table[{material!r}]", low=0.0, high=1.0, low_inclusive=False)
    for name, given in (("surface", surface), ("kapton_sites", kapton_sites)):
        if not isinstance(given, (list, tuple, np.ndarray)) and not (
            name == "surface" and isinstance(given, str)
        ):
            raise InputError(f"{name} must be a sequence (list or tuple); got {type(given).__name__}.")
    names = [surface] * points.shape[0] if isinstance(surface, str) else list(surface)
    if len(names) != points.shape[0]:
        raise InputError(
            f"surface must be one material or one per point ({points.shape[0]}); got {len(names)} names."
        )
    for material in set(names):
        v.choice(material, "surface", table)
    values = np.array([table[material] for material in names], dtype=np.float64)
    if len(kapton_sites):
        if "kapton" not in table:
            raise InputError("table has no 'kapton' entry but kapton_sites were given; add one.")
        radius_m = v.in_range(kapton_radius_m, "kapton_radius_m", low=0.0, low_inclusive=False)
        for site in kapton_sites:
            if not isinstance(site, Site):
                raise InputError(f"kapton_sites must hold Site objects; got {site!r}.")
            inside = np.sum((points - np.asarray(site.position_m)) ** 2, axis=1) <= radius_m**2
            values[inside] = table["kapton"]
    return values


# ------------------------------------------------------------------------------------------------- gas


@dataclass(frozen=True)
class RoundJet:
    """Constants of the turbulent round jet that carries a leak's ammonia mist (seed §4 F).

    The lab leak sprays with compressed air from a small hole, so its mean concentration far from the
    hole is the self-similar round jet's (Pope 2000, §5.1; Chen & Rodi 1980): concentration on the axis
    falling as ``1 / distance`` and a Gaussian cross-section whose width grows linearly with distance.

    Parameters
    ----------
    concentration_decay : float
        ``K_c`` in ``c_axis / c_exit = K_c d / (x + x0)``, > 0 (5.0; reported 4.4-5.6).
    half_width_rate : float
        ``S_c`` in ``r_half = S_c (x + x0)``, the concentration half-width's growth, > 0 (0.11, a spreading
        half-angle of ``atan(0.11)`` = 6.3 deg; the velocity's is 0.094, Pope 2000, Table 5.1).
    velocity_decay : float
        ``B`` in ``u_axis / u_exit = B d / x``, > 0 (5.8, Pope 2000, Table 5.1).
    front_speed_fraction : float
        Speed of the front of a starting jet as a fraction of the steady axis speed there, in (0, 1]
        (0.5, a modelling choice: the front of a switched-on jet runs behind the steady flow; the resulting
        front position grows as ``sqrt(t)``, as found by Craske, Debugne & van Reeuwijk 2015).
    """

    concentration_decay: float = 5.0
    half_width_rate: float = 0.11
    velocity_decay: float = 5.8
    front_speed_fraction: float = 0.5

    def __post_init__(self) -> None:
        for name in ("concentration_decay", "half_width_rate", "velocity_decay"):
            object.__setattr__(
                self, name, v.in_range(getattr(self, name), name, low=0.0, low_inclusive=False)
            )
        object.__setattr__(
            self,
            "front_speed_fraction",
            v.in_range(
                self.front_speed_fraction, "front_speed_fraction", low=0.0, high=1.0, low_inclusive=False
            ),
        )

    @property
    def half_angle_rad(self) -> float:
        """Half-angle of the cone on which the concentration is half the axis value, radians."""
        return math.atan(self.half_width_rate)


def _as_times_s(time_s: object, count: int) -> FloatArray:
    """`time_s` as a finite, >= 0 array broadcast to (count,), or raise naming it."""
    times = v.as_float_array(time_s, "time_s")  # an int beyond the float range overflowed numpy's cast
    if times.ndim > 1 or (times.ndim == 1 and times.shape[0] not in (1, count)):
        raise InputError(
            f"time_s must be a number or have shape ({count},) (one per point); got shape {times.shape}."
        )
    if not np.isfinite(times).all() or (times < 0).any():
        raise InputError(f"time_s must be finite and >= 0 s (time since the world began); got {time_s!r}.")
    return np.broadcast_to(times, (count,)).astype(np.float64)


def _jet_ppm(points: FloatArray, times_s: FloatArray, leak: GasLeak, jet: RoundJet) -> FloatArray:
    """Concentration of one leak's jet at the points and times (ppm)."""
    diameter_m = leak.hole_diameter_m
    offset = points - np.asarray(leak.position_m)
    axial_m = offset @ np.asarray(leak.normal)
    radial2_m2 = np.maximum(np.sum(offset**2, axis=1) - axial_m**2, 0.0)
    # A point computed on the hole's plane lands a rounding error either side of it: count it as on it.
    downstream = axial_m >= -_PLANE_TOLERANCE_M
    axial_m = np.maximum(axial_m, 0.0)
    # Virtual origin x0 puts the half-width at the hole's radius at the exit: r_half(0) = d / 2.
    from_origin_m = axial_m + diameter_m / (2.0 * jet.half_width_rate)
    # Potential core: the axis keeps the exit concentration until the 1/x law falls below it.
    axis_ppm = leak.exit_ppm * np.minimum(1.0, jet.concentration_decay * diameter_m / from_origin_m)
    half_width_m = jet.half_width_rate * from_origin_m
    steady_ppm = axis_ppm * np.exp(-_LN2 * radial2_m2 / half_width_m**2)
    # Turn-on: the front travels at f * u_axis(x) = f B d u0 / x, so it reaches x at x^2 / (2 f B d u0);
    # behind it the source builds up with the valve's time constant.
    front_speed_m2_s = jet.front_speed_fraction * jet.velocity_decay * diameter_m * leak.exit_velocity_m_s
    arrival_s = leak.start_time_s + axial_m**2 / (2.0 * front_speed_m2_s)
    elapsed_s = times_s - arrival_s
    build_up = np.where(elapsed_s > 0.0, -np.expm1(-np.maximum(elapsed_s, 0.0) / leak.turn_on_time_s), 0.0)
    return np.where(downstream, steady_ppm * build_up, 0.0)


def gas_concentration_ppm(
    points_m: object,
    time_s: object,
    leaks: AnomalySet | Sequence[GasLeak],
    *,
    jet: RoundJet | None = None,
) -> FloatArray:
    """Ammonia concentration at world points and times from the active leak holes (seed §4 F).

    Parameters
    ----------
    points_m : array_like of shape (K, 3)
        World points, metres.
    time_s : float or array_like of shape (K,)
        Time since the world began, seconds >= 0 (one for all points or one per point).
    leaks : AnomalySet or sequence of GasLeak
        The world's anomalies (only its gas leaks are used).
    jet : RoundJet, optional
        Jet constants (default: :class:`RoundJet`'s).

    Returns
    -------
    ndarray of shape (K,)
        Concentration in ppm by volume, >= 0; zero before each leak starts and behind its hole's plane.

    Raises
    ------
    InputError
        If `points_m` is not a finite (K, 3) array, `time_s` is negative, not finite or of the wrong
        shape, or `leaks` holds something else.

    Notes
    -----
    For a hole of diameter ``d`` at ``h`` with outward normal ``n``, a point ``p`` has axial distance
    ``x = (p - h) . n`` and radial distance ``r``. With the virtual origin ``x0 = d / (2 S_c)``::

        c_steady = c_exit min(1, K_c d / (x + x0)) exp(-ln 2 r^2 / (S_c (x + x0))^2)      for x >= 0
        c(p, t)  = c_steady (1 - exp(-(t - t_start - x^2 / (2 f B d u_exit)) / tau))     after the front

    and zero for ``x < 0`` or before the front arrives. Several leaks add (the mist is a passive,
    dilute scalar). This is the laboratory's leak in air; in orbit a leak expands into vacuum instead.

    Examples
    --------
    >>> from rsi.sim.anomalies import GasLeak
    >>> leak = GasLeak("leak_0", (0.0, 0.0, 0.0), (1, 0, 0), 1e-3, "aluminium", start_time_s=5.0)
    >>> gas_concentration_ppm([[0.5, 0.0, 0.0]], 1.0, [leak]).tolist()
    [0.0]
    >>> round(float(gas_concentration_ppm([[0.5, 0.0, 0.0]], 1000.0, [leak])[0]), 1)
    49.5
    """
    points = _as_points(points_m)
    times = _as_times_s(time_s, points.shape[0])
    records: tuple[GasLeak, ...] = _records(leaks, "leaks", GasLeak, "gas_leaks")
    constants = RoundJet() if jet is None else jet
    if not isinstance(constants, RoundJet):
        raise InputError(f"jet must be a RoundJet or None; got {type(jet).__name__}.")
    total = np.zeros(points.shape[0])
    for leak in records:
        total += _jet_ppm(points, times, leak, constants)
    return total


__all__: list[str] = [
    "AMBIENT_K",
    "EMISSIVITY",
    "RoundJet",
    "emissivity",
    "gas_concentration_ppm",
    "surface_temperature_k",
]
