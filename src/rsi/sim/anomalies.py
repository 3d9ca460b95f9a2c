"""Seed §4: the anomalies planted on the truss mock-up, drawn from a passed random generator.

The JPL mock-up (seed §4, Fig. 8 E and F) carries four kinds of planted trouble, and "to introduce a degree of
randomness into the inspection process" a different selection is switched on for each run:

- **Peltier hot and cold spots.** Peltier modules behind the electrical ORU's aluminium skin, each under a
  black Kapton circle; "only two of the Peltier modules are turned on at any time, and the selected
  direction of electrical current determines if the surface becomes hot or cold".
- **Gas leaks.** "A similar selection is available from amongst the three possible gas leaks": compressed
  air sprays an ammonia mist from a small hole on the tank-and-tubing ORU.
- **Random defects.** "Screws throughout the truss can be randomly removed"; "small pieces of black tape on
  pen markings ... simulate micrometeorite impact sites"; "entire components, such as tanks, can be
  replaced with defective versions".

This module only *chooses* anomalies: it takes the mock-up's candidate places as inputs (:class:`Site`,
:class:`Patch`, gathered in :class:`Candidates`), so it knows nothing of the scene geometry, and returns an
:class:`AnomalySet` of frozen records, each with its ground truth (kind, world position in metres, size in
metres and the kind's own data). The temperature and gas fields these anomalies produce live in
:mod:`rsi.sim.fields`. See ``docs/anomalies-and-fields.md``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import MISSING, asdict, dataclass, field, fields, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

Vector3 = tuple[float, float, float]

ANOMALY_KINDS: tuple[str, ...] = (
    "hot_spot",
    "cold_spot",
    "gas_leak",
    "missing_screw",
    "impact",
    "swapped_component",
)
IMPACT_PROFILES: tuple[str, ...] = ("uniform", "crater")
IMPACT_POLARITIES: tuple[str, ...] = ("dark", "bright")
COMPONENT_DEFECTS: tuple[str, ...] = ("dented", "discoloured")
# Leak strength bands (exit concentration, ppm) for stratified scoring; the seed mock-up's 5000 ppm: "medium".
LEAK_BANDS_PPM: tuple[float, float] = (2000.0, 10000.0)
# A brighter replacement's reflectance factor: the brightest finish (aluminium, 0.63) stays below white.
MAX_BRIGHTENING = 1.5
# A dent's rim radius: 3 cm plus twice its depth (a blunt blow on thin skin), shrunk to fit its surface.
DENT_RIM_M = 0.03
DENT_RIM_PER_DEPTH = 2.0

# Seed §4: a Kapton circle covers each Peltier module (a 40 mm square module under a ~50 mm circle); the
# spot's temperature fall-off radius defaults to the circle's radius so the pyrometer sees the full
# difference on Kapton and little of it on the bare aluminium around it.
KAPTON_RADIUS_M = 0.025
_TRUTH_SCHEMA = "rsi.sim.anomalies/1"


# ---------------------------------------------------------------------------------------------- validation


def _vector3(value: object, name: str) -> Vector3:
    """Return `value` as a finite 3-vector (a tuple, so records compare and hash by value)."""
    array = v.as_float_array(value, name)
    if array.shape != (3,):
        raise InputError(f"{name} must be a 3-vector (x, y, z); got {value!r}. Pass three numbers.")
    if not np.isfinite(array).all():
        raise InputError(f"{name} must be finite; got {value!r}.")
    return (float(array[0]), float(array[1]), float(array[2]))


def _unit3(value: object, name: str) -> Vector3:
    vector = np.asarray(_vector3(value, name))
    norm = float(np.linalg.norm(vector))
    if norm < 1e-12:
        raise InputError(f"{name} must be a non-zero direction; got {value!r}. Pass the outward normal.")
    unit = vector / norm
    return (float(unit[0]), float(unit[1]), float(unit[2]))


def _across(value: object, name: str, unit: Vector3, unit_name: str, hint: str) -> Vector3:
    """The unit part of `value` perpendicular to the unit vector `unit` (refused when parallel to it)."""
    raw = np.asarray(_vector3(value, name))
    direction = np.asarray(unit)
    part = raw - float(raw @ direction) * direction
    if float(np.linalg.norm(part)) < 1e-9 * max(1.0, float(np.linalg.norm(raw))):
        raise InputError(
            f"{name} must not be parallel to {unit_name}; got {name}={value!r}, {unit_name}={unit!r}. "
            f"Pass {hint}."
        )
    return _unit3(part, name)


def _name(value: object, name: str) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} must be a non-empty string; got {value!r}.")
    return value


def _interval(value: object, name: str, *, low: float, high: float = math.inf) -> tuple[float, float]:
    """A (min, max) pair with low <= min <= max <= high."""
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) != 2:
        raise InputError(f"{name} must be a (min, max) pair; got {value!r}.")
    first = v.in_range(value[0], name, low=low, high=high)
    second = v.in_range(value[1], name, low=low, high=high)
    if first > second:
        raise InputError(f"{name} must be (min, max) with min <= max; got {value!r}. Swap the two.")
    return (first, second)


def _count(value: object, name: str) -> int:
    return v.positive_int(value, name, minimum=0)


# ------------------------------------------------------------------------------------------------ places


@dataclass(frozen=True)
class Site:
    """A candidate place for an anomaly on the mock-up (a Peltier module, a leak hole, a screw, a component).

    Parameters
    ----------
    name : str
        Unique name in the scene (the mock-up's site name), e.g. ``"peltier_1"``.
    position_m : array_like of shape (3,)
        World position of the site's centre on the surface, metres.
    normal : array_like of shape (3,)
        Outward surface normal (normalised here); a leak jets along it.
    surface : str
        Material of the surface around the site (``"aluminium"``, ``"kapton"``, ``"solar_cell"``, ...; see
        :data:`rsi.sim.fields.EMISSIVITY`).
    size_m : float
        Characteristic size, >= 0 m: screw-head diameter, hole diameter, largest extent of a component
        (0 when not known). A missing screw's or swapped component's truth size is this value.
    """

    name: str
    position_m: Vector3
    normal: Vector3
    surface: str = "aluminium"
    size_m: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", _name(self.name, "name"))
        object.__setattr__(self, "position_m", _vector3(self.position_m, "position_m"))
        object.__setattr__(self, "normal", _unit3(self.normal, "normal"))
        object.__setattr__(self, "surface", _name(self.surface, "surface"))
        object.__setattr__(self, "size_m", v.in_range(self.size_m, "size_m", low=0.0))


@dataclass(frozen=True)
class Patch:
    """A flat rectangle of surface on which impact spots may be planted (a panel face, a door).

    Parameters
    ----------
    name : str
        Unique name in the scene.
    centre_m : array_like of shape (3,)
        World position of the rectangle's centre, metres.
    normal : array_like of shape (3,)
        Outward normal (normalised here).
    u_axis : array_like of shape (3,)
        Direction of the rectangle's first side; its component along `normal` is removed and the rest
        normalised. The second side is ``normal x u_axis``.
    half_extent_m : (float, float)
        Half lengths along ``u`` and ``v``, > 0 m.
    surface : str
        Material of the patch (see :data:`rsi.sim.fields.EMISSIVITY`).
    """

    name: str
    centre_m: Vector3
    normal: Vector3
    u_axis: Vector3
    half_extent_m: tuple[float, float]
    surface: str = "aluminium"

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", _name(self.name, "name"))
        object.__setattr__(self, "centre_m", _vector3(self.centre_m, "centre_m"))
        normal = _unit3(self.normal, "normal")
        in_plane = _across(
            self.u_axis, "u_axis", normal, "normal", "a direction along one side of the rectangle"
        )
        object.__setattr__(
            self, "normal", _unit3(normal, "normal")
        )  # re-normalised: stored truth stays bit-identical
        object.__setattr__(self, "u_axis", in_plane)
        half = self.half_extent_m
        if isinstance(half, str) or not isinstance(half, Sequence) or len(half) != 2:
            raise InputError(f"half_extent_m must be a (u, v) pair of lengths; got {half!r}.")
        object.__setattr__(
            self,
            "half_extent_m",
            tuple(v.in_range(side, "half_extent_m", low=0.0, low_inclusive=False) for side in half),
        )
        object.__setattr__(self, "surface", _name(self.surface, "surface"))

    @property
    def v_axis(self) -> Vector3:
        """Second in-plane direction, ``normal x u_axis`` (unit)."""
        cross = np.cross(self.normal, self.u_axis)
        return (float(cross[0]), float(cross[1]), float(cross[2]))

    @property
    def area_m2(self) -> float:
        """Area of the rectangle, m^2."""
        return 4.0 * self.half_extent_m[0] * self.half_extent_m[1]

    @property
    def largest_radius_m(self) -> float:
        """Radius of the largest disc that fits inside the rectangle, metres."""
        return min(self.half_extent_m)

    def fits(self, radius_m: float) -> bool:
        """Whether a disc of `radius_m` fits inside the rectangle."""
        return self.largest_radius_m >= radius_m

    def place(self, unit: Sequence[float] | NDArray[np.float64], margin_m: float) -> tuple[Vector3, Vector3]:
        """Surface point and outward normal at `unit` in [0, 1]^2, kept `margin_m` clear of every edge."""
        reach = np.asarray(self.half_extent_m) - margin_m
        offset = (2.0 * np.asarray(unit, dtype=float) - 1.0) * reach
        point = (
            np.asarray(self.centre_m)
            + offset[0] * np.asarray(self.u_axis)
            + offset[1] * np.asarray(self.v_axis)
        )
        return (float(point[0]), float(point[1]), float(point[2])), self.normal


@dataclass(frozen=True)
class CylinderPatch:
    """A window of a cylinder's skin on which anomalies may be planted (a tank's front, a tube).

    Parameters
    ----------
    name : str
        Unique name in the scene.
    centre_m : array_like of shape (3,)
        Point on the cylinder's axis at the middle of the window, metres.
    axis : array_like of shape (3,)
        Direction of the cylinder's axis (normalised here).
    front : array_like of shape (3,)
        Outward direction at the middle of the window; its component along `axis` is removed.
    radius_m : float
        Radius of the cylinder, > 0 m.
    half_length_m : float
        Half the window's length along the axis, > 0 m.
    half_angle_rad : float
        Half the window's angle around the axis from `front`, in (0, pi] rad (the part a camera in front
        sees without grazing).
    surface : str
        What the skin is (see :data:`rsi.sim.mockup.SURFACES`).
    """

    name: str
    centre_m: Vector3
    axis: Vector3
    front: Vector3
    radius_m: float
    half_length_m: float
    half_angle_rad: float
    surface: str = "tank"

    def __post_init__(self) -> None:
        object.__setattr__(self, "name", _name(self.name, "name"))
        object.__setattr__(self, "centre_m", _vector3(self.centre_m, "centre_m"))
        axis = _unit3(self.axis, "axis")
        front = _across(self.front, "front", axis, "axis", "the outward direction at the window's middle")
        object.__setattr__(
            self, "axis", _unit3(axis, "axis")
        )  # re-normalised: stored truth stays bit-identical
        object.__setattr__(self, "front", front)
        for label in ("radius_m", "half_length_m"):
            object.__setattr__(
                self, label, v.in_range(getattr(self, label), label, low=0.0, low_inclusive=False)
            )
        object.__setattr__(
            self,
            "half_angle_rad",
            v.in_range(self.half_angle_rad, "half_angle_rad", low=0.0, high=math.pi, low_inclusive=False),
        )
        object.__setattr__(self, "surface", _name(self.surface, "surface"))

    @property
    def area_m2(self) -> float:
        """Area of the window, m^2 (arc length times length)."""
        return 4.0 * self.radius_m * self.half_angle_rad * self.half_length_m

    @property
    def largest_radius_m(self) -> float:
        """Radius (along the skin) of the largest disc that fits inside the window, metres."""
        return min(self.half_length_m, self.radius_m * self.half_angle_rad)

    def fits(self, radius_m: float) -> bool:
        """Whether a disc of `radius_m` (measured along the skin) fits inside the window."""
        return self.largest_radius_m >= radius_m

    def place(self, unit: Sequence[float] | NDArray[np.float64], margin_m: float) -> tuple[Vector3, Vector3]:
        """Skin point and outward (radial) normal at `unit` in [0, 1]^2, `margin_m` clear of the edges.

        The first coordinate runs around the axis, the second along it; a uniform `unit` gives a point
        uniform per unit area (the skin's area element is constant on a cylinder).
        """
        first, second = (2.0 * float(value) - 1.0 for value in unit)
        angle = first * (self.half_angle_rad - margin_m / self.radius_m)
        along = second * (self.half_length_m - margin_m)
        axis, front = np.asarray(self.axis), np.asarray(self.front)
        normal = math.cos(angle) * front + math.sin(angle) * np.cross(axis, front)
        point = np.asarray(self.centre_m) + along * axis + self.radius_m * normal
        return (float(point[0]), float(point[1]), float(point[2])), (
            float(normal[0]),
            float(normal[1]),
            float(normal[2]),
        )


Surface = Patch | CylinderPatch


def _unique_names(items: Sequence[Site] | Sequence[Surface], name: str) -> None:
    seen: set[str] = set()
    for item in items:
        if item.name in seen:
            raise InputError(f"{name} has two entries named {item.name!r}; give every site a unique name.")
        seen.add(item.name)


def _surfaces(items: object, label: str) -> tuple[Surface, ...]:
    if isinstance(items, (str, Patch, CylinderPatch)) or not isinstance(items, Sequence):
        raise InputError(f"{label} must be a sequence of Patch or CylinderPatch; got {items!r}.")
    for item in items:
        if not isinstance(item, (Patch, CylinderPatch)):
            raise InputError(f"{label} must hold only Patch or CylinderPatch objects; got {item!r}.")
    _unique_names(items, label)
    return tuple(items)


@dataclass(frozen=True)
class Candidates:
    """Every place on the mock-up where an anomaly may be planted (seed §4, Fig. 8).

    Parameters
    ----------
    peltier_sites : sequence of Site
        Peltier modules under Kapton circles (the mock-up has at least four; seed §4 E).
    leak_sites : sequence of Site
        Leak holes on the tank-and-tubing ORU (three on the mock-up; seed §4 F), normals along the jet.
    screw_sites : sequence of Site
        Screws that may be removed.
    impact_patches : sequence of Patch or CylinderPatch
        Surfaces a camera sees that may receive micrometeorite impact spots (flat faces, tank and tube skins).
    component_sites : sequence of Site
        Whole components (tanks, ORUs) that may be swapped for a defective version.
    dent_patches : mapping of str to sequence of Patch or CylinderPatch
        Per component site name, the visible surfaces where a defect (a dent, a discoloured patch) may be
        centred. A component without an entry takes its defects at its site's position.
    """

    peltier_sites: tuple[Site, ...] = ()
    leak_sites: tuple[Site, ...] = ()
    screw_sites: tuple[Site, ...] = ()
    impact_patches: tuple[Surface, ...] = ()
    component_sites: tuple[Site, ...] = ()
    dent_patches: Mapping[str, tuple[Surface, ...]] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for label in ("peltier_sites", "leak_sites", "screw_sites", "component_sites"):
            items = getattr(self, label)
            if isinstance(items, (str, Site)) or not isinstance(items, Sequence):
                raise InputError(f"{label} must be a sequence of Site; got {items!r}.")
            for item in items:
                if not isinstance(item, Site):
                    raise InputError(f"{label} must hold only Site objects; got {item!r}.")
            _unique_names(items, label)
            object.__setattr__(self, label, tuple(items))
        object.__setattr__(self, "impact_patches", _surfaces(self.impact_patches, "impact_patches"))
        if not isinstance(self.dent_patches, Mapping):
            raise InputError(
                f"dent_patches must be a dict of component name -> patches; got {self.dent_patches!r}."
            )
        names = {site.name for site in self.component_sites}
        dents: dict[str, tuple[Surface, ...]] = {}
        for key, patches in self.dent_patches.items():
            if key not in names:
                raise InputError(
                    f"dent_patches names {key!r}, which is not one of the component_sites {sorted(names)}."
                )
            dents[key] = _surfaces(patches, "dent_patches")
        object.__setattr__(self, "dent_patches", dents)


# ---------------------------------------------------------------------------------------------- settings


def _count_range(value: object, name: str) -> tuple[int, int]:
    """A (min, max) pair of counts with 0 <= min <= max."""
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) != 2:
        raise InputError(f"{name} must be a (min, max) pair of counts; got {value!r}. Try (0, 2).")
    first, second = (_count(item, name) for item in value)
    if first > second:
        raise InputError(f"{name} must be (min, max) with min <= max; got {value!r}. Swap the two.")
    return (first, second)


@dataclass(frozen=True)
class AnomalySettings:
    """How many anomalies of each kind to plant, and the ranges their parameters are drawn from.

    The defaults are the wide draw of issue 13: counts, sizes, contrasts and strengths spread so that a
    detector scored on them is scored on more than the seed mock-up's fixed selection.
    :meth:`seed_mockup` is the paper's own selection (seed §4), for tests and figures that need fixed
    counts. Count ranges are inclusive and drawn uniformly; see ``docs/anomalies-and-fields.md`` for the
    reason of every range.

    Parameters
    ----------
    anomaly_free_probability : float
        Probability in [0, 1] that a run has no anomaly at all (issue 13: about one run in ten, so false
        alarms are measured on runs with nothing to find). Screws are then all in place too.
    active_peltier_count : int
        Peltier modules switched on, >= 0 (seed §4: "only two ... are turned on at any time").
    peltier_delta_range_k : (float, float)
        Temperature difference of an active spot's centre from ambient, drawn uniformly, kelvin > 0; hot
        spots are ``+delta``, cold spots ``-delta`` (a Peltier module pumps either way, seed §4).
    hot_probability : float
        Probability in [0, 1] that an active module runs hot rather than cold.
    peltier_radius_m : float
        Fall-off radius of a spot's temperature, > 0 m (default: the Kapton circle's radius).
    active_leak_count_range : (int, int)
        Leak holes spraying, drawn uniformly in this inclusive range (seed §4: one selected from three).
    leak_start_window_s : (float, float)
        Each active leak's start time is drawn uniformly from this window, seconds >= 0.
    leak_hole_diameter_m : float
        Hole (nozzle) diameter, > 0 m (seed §4: "a small hole").
    leak_exit_velocity_m_s : float
        Mean speed of the compressed-air jet at the hole, > 0 m/s.
    leak_exit_ppm_range : (float, float)
        Ammonia concentration of the jet at the hole, ppm by volume > 0, drawn log-uniformly (a leak's
        strength is a scale quantity: two decades by default).
    leak_turn_on_time_s : float
        Time constant of the valve/pressure build-up at the hole, > 0 s.
    missing_screw_count : int or None
        Exactly this many screws are removed (<= the screw sites); None removes each screw independently
        with `missing_screw_probability`.
    missing_screw_probability : float
        Probability in [0, 1] that each screw is removed, used when `missing_screw_count` is None.
    impact_count_range : (int, int)
        Impact spots planted on the impact patches, drawn uniformly in this inclusive range.
    impact_diameter_range_m : (float, float)
        Spot diameters are drawn uniformly from this range, metres (seed §2: impact flaws are about 1 mm).
    impact_profiles : tuple of str
        Profiles to draw from, each ``"uniform"`` or ``"crater"`` (seed §2.4 flaw models).
    impact_bright_probability : float
        Probability in [0, 1] that a spot is bright (spall, exposed metal) rather than dark.
    impact_contrast_range : (float, float)
        Strength of a spot, in [0, 1]: a dark spot loses this fraction of the surface's reflectance, a
        bright one gains this fraction of what the surface lacks of a white one.
    impact_crater_extra_range : (float, float)
        For ``"crater"`` spots, the further fraction of the remaining contrast added at the crater's centre,
        in [0, 1] (seed §2.4: "the center of the crater is darker than the rest").
    impact_core_fraction : float
        Diameter of a crater spot's centre as a fraction of its diameter, in (0, 1].
    swapped_component_count_range : (int, int)
        Components replaced by defective versions, drawn uniformly in this inclusive range (seed §4).
    component_defects : tuple of str
        Defects to draw from, each ``"dented"`` or ``"discoloured"``.
    dent_depth_range_m : (float, float)
        Dent depths, metres >= 0.
    defect_off_centre : bool
        True: a dent or a discoloured patch is centred anywhere on the component's visible surfaces
        (``Candidates.dent_patches``), uniform per unit area; False: at the middle of the first of them.
    discolour_patch_probability : float
        Probability in [0, 1] that a discoloured component changes over a patch rather than as a whole.
    discolour_patch_radius_range_m : (float, float)
        Radius of a discoloured patch, metres > 0.
    discolour_brighter_probability : float
        Probability in [0, 1] that a discoloured component is brighter rather than darker.
    reflectance_factor_range : (float, float)
        A darker component's reflectance is multiplied by a factor from this range, in [0, 1].
    brightening_factor_range : (float, float)
        A brighter component's reflectance is multiplied by a factor from this range, in [1, 1.5] (the
        mock-up's brightest finish, aluminium at 0.63, then stays below a white surface's reflectance).
    """

    anomaly_free_probability: float = 0.1
    active_peltier_count: int = 2
    peltier_delta_range_k: tuple[float, float] = (2.0, 40.0)
    hot_probability: float = 0.5
    peltier_radius_m: float = KAPTON_RADIUS_M
    active_leak_count_range: tuple[int, int] = (0, 2)
    leak_start_window_s: tuple[float, float] = (0.0, 30.0)
    leak_hole_diameter_m: float = 1e-3
    leak_exit_velocity_m_s: float = 10.0
    leak_exit_ppm_range: tuple[float, float] = (500.0, 50000.0)
    leak_turn_on_time_s: float = 1.0
    missing_screw_count: int | None = None
    missing_screw_probability: float = 0.1
    impact_count_range: tuple[int, int] = (0, 8)
    impact_diameter_range_m: tuple[float, float] = (0.5e-3, 4e-3)
    impact_profiles: tuple[str, ...] = IMPACT_PROFILES
    impact_bright_probability: float = 0.25
    impact_contrast_range: tuple[float, float] = (0.1, 0.8)
    impact_crater_extra_range: tuple[float, float] = (0.3, 0.8)
    impact_core_fraction: float = 1.0 / 3.0
    swapped_component_count_range: tuple[int, int] = (0, 2)
    component_defects: tuple[str, ...] = COMPONENT_DEFECTS
    dent_depth_range_m: tuple[float, float] = (1e-3, 10e-3)
    defect_off_centre: bool = True
    discolour_patch_probability: float = 0.5
    discolour_patch_radius_range_m: tuple[float, float] = (0.015, 0.04)
    discolour_brighter_probability: float = 0.5
    reflectance_factor_range: tuple[float, float] = (0.4, 0.8)
    brightening_factor_range: tuple[float, float] = (1.2, 1.5)

    @classmethod
    def seed_mockup(cls) -> AnomalySettings:
        """The seed paper's own selection (seed §4) and the draw this project used before issue 13.

        Two Peltier modules at +-30 K, one leak of 5000 ppm, five dark impacts of 0.5-3 mm (darkening
        0.3-0.7), one swapped component whose dent (2-10 mm) sits at the middle of its visible face,
        discoloured as a whole and darker; never a run without anomalies.
        """
        return cls(
            anomaly_free_probability=0.0,
            peltier_delta_range_k=(30.0, 30.0),
            active_leak_count_range=(1, 1),
            leak_exit_ppm_range=(5000.0, 5000.0),
            impact_count_range=(5, 5),
            impact_diameter_range_m=(0.5e-3, 3e-3),
            impact_bright_probability=0.0,
            impact_contrast_range=(0.3, 0.7),
            swapped_component_count_range=(1, 1),
            dent_depth_range_m=(2e-3, 10e-3),
            defect_off_centre=False,
            discolour_patch_probability=0.0,
            discolour_brighter_probability=0.0,
        )

    def __post_init__(self) -> None:
        checked: dict[str, object] = {
            "active_peltier_count": _count(self.active_peltier_count, "active_peltier_count"),
            "peltier_delta_range_k": _interval(self.peltier_delta_range_k, "peltier_delta_range_k", low=1e-9),
            "peltier_radius_m": v.in_range(
                self.peltier_radius_m, "peltier_radius_m", low=0.0, low_inclusive=False
            ),
            "leak_start_window_s": _interval(self.leak_start_window_s, "leak_start_window_s", low=0.0),
            "leak_exit_ppm_range": _interval(self.leak_exit_ppm_range, "leak_exit_ppm_range", low=1e-9),
            "impact_diameter_range_m": _interval(
                self.impact_diameter_range_m, "impact_diameter_range_m", low=1e-9
            ),
            "impact_core_fraction": v.in_range(
                self.impact_core_fraction, "impact_core_fraction", low=0.0, high=1.0, low_inclusive=False
            ),
            "dent_depth_range_m": _interval(self.dent_depth_range_m, "dent_depth_range_m", low=0.0),
            "discolour_patch_radius_range_m": _interval(
                self.discolour_patch_radius_range_m, "discolour_patch_radius_range_m", low=1e-9
            ),
            "brightening_factor_range": _interval(
                self.brightening_factor_range, "brightening_factor_range", low=1.0, high=MAX_BRIGHTENING
            ),
        }
        for name in (
            "anomaly_free_probability",
            "hot_probability",
            "missing_screw_probability",
            "impact_bright_probability",
            "discolour_patch_probability",
            "discolour_brighter_probability",
        ):
            checked[name] = v.in_range(getattr(self, name), name, low=0.0, high=1.0)
        for name in ("impact_contrast_range", "impact_crater_extra_range", "reflectance_factor_range"):
            checked[name] = _interval(getattr(self, name), name, low=0.0, high=1.0)
        for name in ("active_leak_count_range", "impact_count_range", "swapped_component_count_range"):
            checked[name] = _count_range(getattr(self, name), name)
        for name in (
            "leak_hole_diameter_m",
            "leak_exit_velocity_m_s",
            "leak_turn_on_time_s",
        ):
            checked[name] = v.in_range(getattr(self, name), name, low=0.0, low_inclusive=False)
        if self.missing_screw_count is not None:
            checked["missing_screw_count"] = _count(self.missing_screw_count, "missing_screw_count")
        if not isinstance(self.defect_off_centre, bool):
            raise InputError(f"defect_off_centre must be True or False; got {self.defect_off_centre!r}.")
        checked["impact_profiles"] = _options(self.impact_profiles, "impact_profiles", IMPACT_PROFILES)
        checked["component_defects"] = _options(
            self.component_defects, "component_defects", COMPONENT_DEFECTS
        )
        v.store_checked(self, checked)

    @classmethod
    def from_dict(cls, fields_: Mapping[str, Any]) -> AnomalySettings:
        """Settings from a dict of field names (a JSON file's object); unknown names raise, listing them.

        ``{"preset": "seed-mockup"}`` (or ``"wide"``) starts from that preset; the other keys override it.
        """
        if not isinstance(fields_, Mapping):
            raise InputError(
                f"anomaly settings must be a JSON object of fields; got {type(fields_).__name__}."
            )
        known = {item.name for item in fields(cls)}
        unknown = sorted(set(fields_) - known - {"preset"})
        if unknown:
            raise InputError(
                f"anomaly settings have unknown fields {unknown}; known fields: {', '.join(sorted(known))}."
            )
        base = preset(fields_.get("preset", "wide"))
        values: dict[str, Any] = {
            key: tuple(value) if isinstance(value, list) else value
            for key, value in fields_.items()
            if key != "preset"
        }
        return replace(base, **values)


ANOMALY_PRESETS: tuple[str, ...] = ("wide", "seed-mockup")


def preset(name: str) -> AnomalySettings:
    """The named anomaly draw: ``"wide"`` (issue 13, the default) or ``"seed-mockup"`` (seed §4)."""
    v.choice(name, "anomalies preset", ANOMALY_PRESETS)
    return AnomalySettings() if name == "wide" else AnomalySettings.seed_mockup()


def _options(value: object, name: str, allowed: tuple[str, ...]) -> tuple[str, ...]:
    if isinstance(value, str) or not isinstance(value, Sequence) or len(value) == 0:
        raise InputError(f"{name} must be a non-empty tuple drawn from {allowed}; got {value!r}.")
    return tuple(v.choice(item, name, allowed) for item in value)


# ---------------------------------------------------------------------------------------------- records


def _json_ready(value: object) -> object:
    if isinstance(value, tuple):
        return [_json_ready(item) for item in value]
    return value


@dataclass(frozen=True)
class Anomaly:
    """Ground truth shared by every anomaly (subclasses add their kind's data).

    Attributes
    ----------
    site : str
        Name of the site or patch it was planted on.
    position_m : (float, float, float)
        World position of its centre on the surface, metres.
    normal : (float, float, float)
        Outward surface normal there (unit).
    size_m : float
        Its size in metres (diameter of a spot, a hole or a screw head; a component's extent).
    surface : str
        Material of the surface it sits on.
    """

    KIND: ClassVar[str] = ""

    site: str
    position_m: Vector3
    normal: Vector3
    size_m: float
    surface: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "site", _name(self.site, "site"))
        object.__setattr__(self, "position_m", _vector3(self.position_m, "position_m"))
        object.__setattr__(self, "normal", _unit3(self.normal, "normal"))
        object.__setattr__(self, "size_m", v.in_range(self.size_m, "size_m", low=0.0))
        object.__setattr__(self, "surface", _name(self.surface, "surface"))

    @property
    def kind(self) -> str:
        """One of :data:`ANOMALY_KINDS`."""
        return self.KIND

    @property
    def subtype(self) -> str:
        """What sort of anomaly of its kind it is, for stratified scoring (see each record)."""
        return self.kind

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dict of the truth: ``kind``, ``subtype``, then every field (vectors as lists)."""
        return {
            "kind": self.kind,
            "subtype": self.subtype,
            **{key: _json_ready(value) for key, value in asdict(self).items()},
        }


@dataclass(frozen=True)
class ThermalSpot(Anomaly):
    """An active Peltier module (seed §4 E): ``hot_spot`` when `delta_k` > 0, else ``cold_spot``.

    Attributes
    ----------
    delta_k : float
        Surface temperature minus ambient at the spot's centre, kelvin (non-zero).
    radius_m : float
        Fall-off radius of the temperature difference, metres (see :mod:`rsi.sim.fields`).
    """

    delta_k: float = 0.0
    radius_m: float = KAPTON_RADIUS_M

    def __post_init__(self) -> None:
        super().__post_init__()
        delta_k = v.finite_number(self.delta_k, "delta_k")
        if delta_k == 0.0:
            raise InputError("delta_k must be non-zero (a spot is hot or cold); got 0.0.")
        object.__setattr__(self, "delta_k", delta_k)
        object.__setattr__(
            self, "radius_m", v.in_range(self.radius_m, "radius_m", low=0.0, low_inclusive=False)
        )

    @property
    def kind(self) -> str:
        """``"hot_spot"`` or ``"cold_spot"``, by the sign of `delta_k`."""
        return "hot_spot" if self.delta_k > 0 else "cold_spot"

    @property
    def subtype(self) -> str:
        """``"hot"`` or ``"cold"``."""
        return "hot" if self.delta_k > 0 else "cold"


@dataclass(frozen=True)
class GasLeak(Anomaly):
    """An active leak hole spraying ammonia mist (seed §4 F); `size_m` is the hole diameter.

    Attributes
    ----------
    start_time_s : float
        When the spray starts, seconds (the concentration is zero before).
    exit_velocity_m_s : float
        Jet speed at the hole, m/s.
    exit_ppm : float
        Ammonia concentration at the hole, ppm by volume.
    turn_on_time_s : float
        Time constant of the source's build-up, seconds.
    """

    KIND: ClassVar[str] = "gas_leak"

    start_time_s: float = 0.0
    exit_velocity_m_s: float = 10.0
    exit_ppm: float = 5000.0
    turn_on_time_s: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "start_time_s", v.in_range(self.start_time_s, "start_time_s", low=0.0))
        for name in ("size_m", "exit_velocity_m_s", "exit_ppm", "turn_on_time_s"):
            object.__setattr__(
                self, name, v.in_range(getattr(self, name), name, low=0.0, low_inclusive=False)
            )

    @property
    def hole_diameter_m(self) -> float:
        """Diameter of the hole, metres (the truth `size_m`)."""
        return self.size_m

    @property
    def subtype(self) -> str:
        """Strength band of the exit concentration (:data:`LEAK_BANDS_PPM`): ``"weak"``, ``"medium"``,
        ``"strong"``."""
        low, high = LEAK_BANDS_PPM
        return "weak" if self.exit_ppm < low else "medium" if self.exit_ppm <= high else "strong"


@dataclass(frozen=True)
class MissingScrew(Anomaly):
    """A screw removed from the truss (seed §4); `size_m` is the screw-head diameter of the site."""

    KIND: ClassVar[str] = "missing_screw"

    @property
    def subtype(self) -> str:
        """``"screw"``: every missing screw is alike."""
        return "screw"


@dataclass(frozen=True)
class Impact(Anomaly):
    """A simulated micrometeorite impact: a spot of changed reflectance (seed §4 tape and pen marks, §2.4).

    Attributes
    ----------
    profile : str
        ``"uniform"`` (the whole disc alike) or ``"crater"`` (a stronger centre inside a uniform surround:
        seed §2.4's crater model). ``"peak"``, this profile's name in older truth, reads as ``"crater"``.
    darkening : float
        Contrast over the disc of diameter `size_m`, in [0, 1]: a dark spot loses this fraction of the
        surface's reflectance, a bright one gains this fraction of what it lacks of white (``r + (1 - r) c``).
    centre_darkening : float
        Contrast over the centre disc, >= `darkening` (equal for ``"uniform"``).
    centre_diameter_m : float
        Diameter of the centre disc, metres (equal to `size_m` for ``"uniform"``).
    polarity : str
        ``"dark"`` (ink, tape, soot: seed §4) or ``"bright"`` (spall, exposed metal).
    """

    KIND: ClassVar[str] = "impact"

    profile: str = "uniform"
    darkening: float = 0.5
    centre_darkening: float = 0.5
    centre_diameter_m: float = 0.0
    polarity: str = "dark"

    def __post_init__(self) -> None:
        super().__post_init__()
        profile = "crater" if self.profile == "peak" else self.profile
        object.__setattr__(self, "profile", v.choice(profile, "profile", IMPACT_PROFILES))
        v.choice(self.polarity, "polarity", IMPACT_POLARITIES)
        darkening = v.in_range(self.darkening, "darkening", low=0.0, high=1.0)
        centre = v.in_range(self.centre_darkening, "centre_darkening", low=darkening, high=1.0)
        core = v.in_range(self.centre_diameter_m, "centre_diameter_m", low=0.0, high=self.size_m)
        object.__setattr__(self, "darkening", darkening)
        object.__setattr__(self, "centre_darkening", centre)
        object.__setattr__(self, "centre_diameter_m", core)

    @property
    def subtype(self) -> str:
        """``"<polarity>-<profile>"``: ``"dark-uniform"``, ``"dark-crater"``, ``"bright-uniform"`` or
        ``"bright-crater"``."""
        return f"{self.polarity}-{self.profile}"


@dataclass(frozen=True)
class SwappedComponent(Anomaly):
    """A whole component replaced by a defective version (seed §4); `position_m` is the component's site.

    Attributes
    ----------
    defect : str
        ``"dented"`` or ``"discoloured"``.
    dent_depth_m : float
        Depth of the dent, metres (0 unless dented).
    reflectance_factor : float
        Factor on the component's reflectance, in [0, :data:`MAX_BRIGHTENING`] (1 unless discoloured; below
        1 darker, above brighter).
    defect_centre_m : (float, float, float) or None
        Where the dent or the discoloured patch is centred on the component's skin (None: `position_m`).
    defect_normal : (float, float, float) or None
        Outward skin normal there (None: `normal`).
    defect_radius_m : float
        Radius of the dent's rim (along the skin) or of the discoloured patch, metres; 0 when the whole
        component is discoloured.
    """

    KIND: ClassVar[str] = "swapped_component"

    defect: str = "dented"
    dent_depth_m: float = 0.0
    reflectance_factor: float = 1.0
    defect_centre_m: Vector3 | None = None
    defect_normal: Vector3 | None = None
    defect_radius_m: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        v.choice(self.defect, "defect", COMPONENT_DEFECTS)
        object.__setattr__(self, "dent_depth_m", v.in_range(self.dent_depth_m, "dent_depth_m", low=0.0))
        object.__setattr__(
            self,
            "reflectance_factor",
            v.in_range(self.reflectance_factor, "reflectance_factor", low=0.0, high=MAX_BRIGHTENING),
        )
        centre = self.position_m if self.defect_centre_m is None else self.defect_centre_m
        normal = self.normal if self.defect_normal is None else self.defect_normal
        object.__setattr__(self, "defect_centre_m", _vector3(centre, "defect_centre_m"))
        object.__setattr__(self, "defect_normal", _unit3(normal, "defect_normal"))
        object.__setattr__(
            self, "defect_radius_m", v.in_range(self.defect_radius_m, "defect_radius_m", low=0.0)
        )

    @property
    def subtype(self) -> str:
        """``"dent"``, or ``"discolour-<whole|patch>-<darker|brighter>"``."""
        if self.defect == "dented":
            return "dent"
        extent = "patch" if self.defect_radius_m > 0.0 else "whole"
        shade = "brighter" if self.reflectance_factor > 1.0 else "darker"
        return f"discolour-{extent}-{shade}"

    @property
    def defect_at(self) -> tuple[Vector3, Vector3]:
        """Centre and outward normal of the dent or discoloured patch (never None once built)."""
        assert self.defect_centre_m is not None and self.defect_normal is not None  # set in __post_init__
        return self.defect_centre_m, self.defect_normal


_RECORDS: Mapping[str, type[Anomaly]] = {
    "hot_spot": ThermalSpot,
    "cold_spot": ThermalSpot,
    "gas_leak": GasLeak,
    "missing_screw": MissingScrew,
    "impact": Impact,
    "swapped_component": SwappedComponent,
}


@dataclass(frozen=True)
class AnomalySet:
    """Every anomaly planted in one world, with its ground truth.

    Attributes
    ----------
    anomalies : tuple of Anomaly
        In drawing order: thermal spots, gas leaks, missing screws, impacts, swapped components.
    """

    anomalies: tuple[Anomaly, ...] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        if isinstance(self.anomalies, (str, bytes, Anomaly)) or not isinstance(self.anomalies, Iterable):
            raise InputError(
                f"anomalies must be a tuple of Anomaly records; got {type(self.anomalies).__name__}. "
                "Wrap a single record as (record,)."
            )
        items = tuple(self.anomalies)
        for item in items:
            if not isinstance(item, Anomaly):
                raise InputError(f"anomalies must hold only Anomaly records; got {item!r}.")
        object.__setattr__(self, "anomalies", items)

    def __len__(self) -> int:
        return len(self.anomalies)

    def of_kind(self, kind: str) -> tuple[Anomaly, ...]:
        """The anomalies of one kind (one of :data:`ANOMALY_KINDS`)."""
        v.choice(kind, "kind", ANOMALY_KINDS)
        return tuple(item for item in self.anomalies if item.kind == kind)

    @property
    def thermal_spots(self) -> tuple[ThermalSpot, ...]:
        """Active Peltier spots, hot and cold."""
        return tuple(item for item in self.anomalies if isinstance(item, ThermalSpot))

    @property
    def gas_leaks(self) -> tuple[GasLeak, ...]:
        """Active leak holes."""
        return tuple(item for item in self.anomalies if isinstance(item, GasLeak))

    def counts(self) -> dict[str, int]:
        """Number of anomalies of every kind (zeros included)."""
        return {kind: sum(item.kind == kind for item in self.anomalies) for kind in ANOMALY_KINDS}

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready truth record: ``{"schema", "counts", "anomalies": [...]}``."""
        return {
            "schema": _TRUTH_SCHEMA,
            "counts": self.counts(),
            "anomalies": [item.to_dict() for item in self.anomalies],
        }

    @classmethod
    def from_dict(cls, truth: Mapping[str, Any]) -> AnomalySet:
        """Rebuild an AnomalySet from :meth:`to_dict`'s output (e.g. a truth file read back with json)."""
        if not isinstance(truth, Mapping) or truth.get("schema") != _TRUTH_SCHEMA:
            raise InputError(
                f"truth must be a dict with schema {_TRUTH_SCHEMA!r} (from AnomalySet.to_dict); "
                f"got {str(truth)[:120]!r}."
            )
        records: list[Anomaly] = []
        for entry in truth.get("anomalies", ()):
            kind = v.choice(entry.get("kind") if isinstance(entry, Mapping) else entry, "kind", ANOMALY_KINDS)
            record_type = _RECORDS[kind]
            names = {item.name for item in fields(record_type)}
            # fields added since (an impact's polarity, a dent's centre) keep their defaults in older truth
            required = {
                item.name
                for item in fields(record_type)
                if item.default is MISSING and item.default_factory is MISSING
            }
            missing = required - set(entry)
            if missing:
                raise InputError(f"truth entry of kind {kind!r} lacks {sorted(missing)}; got {entry!r}.")
            record = record_type(**{key: entry[key] for key in names & set(entry)})
            if record.kind != kind:
                raise InputError(f"truth entry says kind {kind!r} but its data make it {record.kind!r}.")
            records.append(record)
        return cls(tuple(records))


# ---------------------------------------------------------------------------------------------- drawing


def _require(count: int, available: int, setting: str, candidates: str) -> None:
    if count > available:
        raise InputError(
            f"settings.{setting}={count} exceeds the {available} {candidates} given. "
            f"Lower {setting} or pass more {candidates}."
        )


def _draw_count(count_range: tuple[int, int], rng: np.random.Generator) -> int:
    return int(rng.integers(count_range[0], count_range[1] + 1))


def _draw_thermal(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    count = settings.active_peltier_count
    _require(count, len(candidates.peltier_sites), "active_peltier_count", "peltier_sites")
    chosen = rng.choice(len(candidates.peltier_sites), size=count, replace=False)
    # Seed §4: the direction of the current, chosen per module, makes the surface hot or cold.
    hot = rng.random(count) < settings.hot_probability
    deltas = rng.uniform(*settings.peltier_delta_range_k, size=count)
    spots: list[Anomaly] = []
    for index, is_hot, delta in zip(chosen, hot, deltas, strict=True):
        site = candidates.peltier_sites[int(index)]
        spots.append(
            ThermalSpot(
                site=site.name,
                position_m=site.position_m,
                normal=site.normal,
                size_m=2.0 * settings.peltier_radius_m,
                surface=site.surface,
                delta_k=float(delta) if is_hot else -float(delta),
                radius_m=settings.peltier_radius_m,
            )
        )
    return spots


def _draw_leaks(candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator) -> list[Anomaly]:
    _require(
        settings.active_leak_count_range[1],
        len(candidates.leak_sites),
        "active_leak_count_range",
        "leak_sites",
    )
    count = _draw_count(settings.active_leak_count_range, rng)
    chosen = rng.choice(len(candidates.leak_sites), size=count, replace=False)
    starts = rng.uniform(*settings.leak_start_window_s, size=count)
    # log-uniform: a leak's strength is a scale quantity, each decade as likely as the next
    low_ppm, high_ppm = settings.leak_exit_ppm_range
    ppm = np.exp(rng.uniform(math.log(low_ppm), math.log(high_ppm), size=count))
    leaks: list[Anomaly] = []
    for index, start, exit_ppm in zip(chosen, starts, ppm, strict=True):
        site = candidates.leak_sites[int(index)]
        leaks.append(
            GasLeak(
                site=site.name,
                position_m=site.position_m,
                normal=site.normal,
                size_m=settings.leak_hole_diameter_m,
                surface=site.surface,
                start_time_s=float(start),
                exit_velocity_m_s=settings.leak_exit_velocity_m_s,
                exit_ppm=float(np.clip(exit_ppm, low_ppm, high_ppm)),
                turn_on_time_s=settings.leak_turn_on_time_s,
            )
        )
    return leaks


def _draw_screws(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    screws = candidates.screw_sites
    if settings.missing_screw_count is None:
        removed = np.flatnonzero(rng.random(len(screws)) < settings.missing_screw_probability)
    else:
        _require(settings.missing_screw_count, len(screws), "missing_screw_count", "screw_sites")
        removed = np.sort(rng.choice(len(screws), size=settings.missing_screw_count, replace=False))
    return [
        MissingScrew(
            site=screws[int(index)].name,
            position_m=screws[int(index)].position_m,
            normal=screws[int(index)].normal,
            size_m=screws[int(index)].size_m,
            surface=screws[int(index)].surface,
        )
        for index in removed
    ]


def _by_area(patches: Sequence[Surface], count: int, rng: np.random.Generator) -> NDArray[np.int64]:
    """Indices of `count` patches, each chosen with probability by its area."""
    area = np.array([patch.area_m2 for patch in patches])
    return rng.choice(len(patches), size=count, p=area / area.sum())


def _draw_impacts(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    count = _draw_count(settings.impact_count_range, rng)
    patches = candidates.impact_patches
    if settings.impact_count_range[1] == 0:
        return []
    if not patches:
        raise InputError(
            f"settings.impact_count_range={settings.impact_count_range} needs impact_patches, but none were "
            "given. Pass the mock-up's surface patches or set impact_count_range=(0, 0)."
        )
    largest_m = settings.impact_diameter_range_m[1]
    for patch in patches:
        if not patch.fits(largest_m / 2.0):
            raise InputError(
                f"impact_patches entry {patch.name!r} cannot hold an impact of {largest_m} m diameter. "
                "Drop the patch or lower impact_diameter_range_m."
            )
    # Micrometeoroid flux is uniform per unit area, so a patch is chosen with probability by its area.
    which = _by_area(patches, count, rng)
    diameters = rng.uniform(*settings.impact_diameter_range_m, size=count)
    unit = rng.random((count, 2))
    profiles = rng.choice(len(settings.impact_profiles), size=count)
    bright = rng.random(count) < settings.impact_bright_probability
    contrast = rng.uniform(*settings.impact_contrast_range, size=count)
    extra = rng.uniform(*settings.impact_crater_extra_range, size=count)
    impacts: list[Anomaly] = []
    for k in range(count):
        patch = patches[int(which[k])]
        # The whole spot lies inside the patch: the centre stays a radius away from every edge.
        centre, normal = _clear_of_heads(patch, unit[k], diameters[k] / 2.0, candidates.screw_sites)
        profile = settings.impact_profiles[int(profiles[k])]
        is_crater = profile == "crater"
        # Seed §2.4 peak/adjacent model: a stronger centre inside a uniform surround.
        centre_contrast = contrast[k] + (1.0 - contrast[k]) * extra[k] if is_crater else contrast[k]
        impacts.append(
            Impact(
                site=patch.name,
                position_m=centre,
                normal=normal,
                size_m=float(diameters[k]),
                surface=patch.surface,
                profile=profile,
                darkening=float(contrast[k]),
                centre_darkening=float(centre_contrast),
                centre_diameter_m=float(
                    diameters[k] * settings.impact_core_fraction if is_crater else diameters[k]
                ),
                polarity="bright" if bright[k] else "dark",
            )
        )
    return impacts


# Another draw of a spot's centre, from the R2 sequence (Roberts 2018: the plastic number's powers), for a
# spot that fell under a screw head: deterministic, so the seed's other draws stay as they were, and
# uniform over the patch, so the flux stays uniform per unit area of exposed surface.
_R2_STEP = (0.7548776662466927, 0.5698402909980532)
# Draws of a clear centre before a spot under a head is kept: a head and the largest spot's radius about it
# cover at most a third of a patch (truss-b's centre plates, 16 heads), and the sequence spreads its draws
# over the whole patch, so 40 of them all under heads do not happen.
_CLEAR_DRAWS = 40


def _clear_of_heads(
    patch: Surface, unit: NDArray[np.float64], radius_m: float, screws: Sequence[Site]
) -> tuple[Vector3, Vector3]:
    """`patch.place(unit, radius_m)`, moved by the R2 sequence until the spot lies clear of every screw head.

    A screw head stands 2 mm proud of its plate (seed §4 mock-up): a spot painted on the plate under it is
    hidden from every viewpoint, and a micrometeoroid that strikes there marks the head, not the plate
    (truss seed 2269: a 2.2 mm spot 2.9 mm from screw_B_1's axis showed one pixel of itself).
    """
    point = np.asarray(unit, dtype=float)
    for draw in range(_CLEAR_DRAWS):
        centre, normal = patch.place((point + draw * np.asarray(_R2_STEP)) % 1.0, radius_m)
        if all(math.dist(centre, head.position_m) > radius_m + head.size_m / 2.0 for head in screws):
            return centre, normal
    return patch.place(point, radius_m)


# Draws of a defect's centre before a component whose dent patches all lie under Kapton is refused: 21-29 %
# of the centres the electrical ORU's fill face allows (15-40 mm patches) lie under its four circles, so
# 40 draws all hidden come once in 1e21.
_DEFECT_DRAWS = 40


def _defect_place(
    site: Site,
    patches: Sequence[Surface],
    radius_m: float,
    off_centre: bool,
    rng: np.random.Generator,
    *,
    covers: Sequence[Site],
) -> tuple[Vector3, Vector3, float]:
    """Centre, normal and radius (shrunk to fit) of a component's dent or discoloured patch.

    On the component's visible surfaces (issue 13), uniform per unit area and the whole defect inside one
    of them when off centre, else at the middle of the first (the seed mock-up's centred defect); at the
    site itself for a component without patches. An off-centre defect is centred off every Kapton circle
    (`covers`, the Peltier sites' discs): the circle lies over the face, and a discolouration or a dent
    under it is seen only where it reaches past the circle's edge (held-out truss seed 2243 in the mission
    benchmark: a brighter patch of 19.5 mm radius centred under one showed a crescent 2 mm wide). Centred
    off the circles, at least 56 % of a 15-40 mm patch is in sight on the ORU's fill face (sampled over the
    centres allowed); impact spots are kept off the circles by their patches the same way.
    """
    for _ in range(_DEFECT_DRAWS):
        unit = rng.random(2)
        if not patches:
            return site.position_m, site.normal, radius_m
        which = int(_by_area(patches, 1, rng)[0]) if off_centre else 0
        patch = patches[which]
        radius = min(radius_m, patch.largest_radius_m)
        centre, normal = patch.place(unit if off_centre else (0.5, 0.5), radius)
        if not off_centre or not _under(centre, covers):
            return centre, normal, radius
    raise InputError(
        f"dent_patches of component {site.name!r} lie under the Kapton circles of peltier_sites in "
        f"{_DEFECT_DRAWS} draws running: give the component dent patches that a camera sees."
    )


def _under(point: Vector3, covers: Sequence[Site]) -> bool:
    """Whether `point` lies within one of the `covers` discs (their size is a diameter)."""
    return any(math.dist(point, cover.position_m) < 0.5 * cover.size_m for cover in covers)


def _draw_components(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    most = settings.swapped_component_count_range[1]
    _require(most, len(candidates.component_sites), "swapped_component_count_range", "component_sites")
    count = _draw_count(settings.swapped_component_count_range, rng)
    chosen = np.sort(rng.choice(len(candidates.component_sites), size=count, replace=False))
    swapped: list[Anomaly] = []
    for index in chosen:
        site = candidates.component_sites[int(index)]
        defect = settings.component_defects[int(rng.integers(len(settings.component_defects)))]
        patches = candidates.dent_patches.get(site.name, ())
        if defect == "dented":
            depth = float(rng.uniform(*settings.dent_depth_range_m))
            # a blow's dent widens as it deepens: 3 cm across the rim plus twice its depth
            rim = DENT_RIM_M + DENT_RIM_PER_DEPTH * depth
            centre, normal, radius = _defect_place(
                site, patches, rim, settings.defect_off_centre, rng, covers=candidates.peltier_sites
            )
            factor = 1.0
        else:
            depth = 0.0
            brighter = rng.random() < settings.discolour_brighter_probability
            span = settings.brightening_factor_range if brighter else settings.reflectance_factor_range
            factor = float(rng.uniform(*span))
            # a patch needs a flat face to lie on: a round skin (a tank) discolours as a whole
            flat = bool(patches) and all(isinstance(patch, Patch) for patch in patches)
            radius = float(rng.uniform(*settings.discolour_patch_radius_range_m))
            if flat and rng.random() < settings.discolour_patch_probability:
                centre, normal, radius = _defect_place(
                    site, patches, radius, settings.defect_off_centre, rng, covers=candidates.peltier_sites
                )
            else:
                centre, normal, radius = site.position_m, site.normal, 0.0
        swapped.append(
            SwappedComponent(
                site=site.name,
                position_m=site.position_m,
                normal=site.normal,
                size_m=site.size_m,
                surface=site.surface,
                defect=defect,
                dent_depth_m=depth,
                reflectance_factor=factor,
                defect_centre_m=centre,
                defect_normal=normal,
                defect_radius_m=radius,
            )
        )
    return swapped


# Drawn in this order from one generator, so a seed fixes the whole set (and adding candidates of one kind
# changes only the draws from that kind on).
_DRAWERS = (_draw_thermal, _draw_leaks, _draw_screws, _draw_impacts, _draw_components)


def seed_anomalies(
    candidates: Candidates,
    *,
    rng: np.random.Generator | int | None,
    settings: AnomalySettings | None = None,
) -> AnomalySet:
    """Choose this world's anomalies among the mock-up's candidate places (seed §4).

    Parameters
    ----------
    candidates : Candidates
        Peltier sites, leak sites, screws, impact patches and components of the mock-up.
    rng : numpy.random.Generator or int or None
        Source of every random choice; identical seeds give identical anomaly sets.
    settings : AnomalySettings, optional
        Counts and parameter ranges (default: the wide draw of :class:`AnomalySettings`;
        :meth:`AnomalySettings.seed_mockup` for the paper's fixed selection).

    Returns
    -------
    AnomalySet

    Raises
    ------
    InputError
        If a count (a range's maximum) exceeds the candidates of its kind (naming the setting), the
        candidates are not a :class:`Candidates`, or a patch is too small for the largest impact.

    Examples
    --------
    >>> sites = tuple(Site(f"peltier_{k}", (0.1 * k, 0.0, 0.0), (0, 0, 1), "kapton") for k in range(4))
    >>> leaks = (Site("leak_0", (0.0, 1.0, 0.0), (0, 1, 0)),)
    >>> settings = AnomalySettings.seed_mockup()
    >>> settings = replace(settings, impact_count_range=(0, 0), swapped_component_count_range=(0, 0))
    >>> world = seed_anomalies(Candidates(sites, leaks), rng=7, settings=settings)
    >>> world.counts()["gas_leak"], len(world.thermal_spots)
    (1, 2)
    """
    if not isinstance(candidates, Candidates):
        raise InputError(
            f"candidates must be a Candidates record; got {type(candidates).__name__}. "
            "Build one with Candidates(peltier_sites=..., leak_sites=..., ...)."
        )
    chosen = AnomalySettings() if settings is None else settings
    if not isinstance(chosen, AnomalySettings):
        raise InputError(f"settings must be an AnomalySettings or None; got {type(settings).__name__}.")
    generator = v.as_rng(rng)
    anomalies: list[Anomaly] = []
    # issue 13: some runs have nothing to find, so false alarms are measured where every finding is false
    if generator.random() < chosen.anomaly_free_probability:
        return AnomalySet(())
    for draw in _DRAWERS:
        anomalies.extend(draw(candidates, chosen, generator))
    return AnomalySet(tuple(anomalies))


__all__: list[str] = [
    "ANOMALY_KINDS",
    "ANOMALY_PRESETS",
    "COMPONENT_DEFECTS",
    "IMPACT_POLARITIES",
    "IMPACT_PROFILES",
    "KAPTON_RADIUS_M",
    "LEAK_BANDS_PPM",
    "MAX_BRIGHTENING",
    "Anomaly",
    "AnomalySet",
    "AnomalySettings",
    "Candidates",
    "CylinderPatch",
    "GasLeak",
    "Impact",
    "MissingScrew",
    "Patch",
    "Site",
    "Surface",
    "SwappedComponent",
    "ThermalSpot",
    "preset",
    "seed_anomalies",
]
