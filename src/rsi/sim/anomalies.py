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
from dataclasses import asdict, dataclass, field, fields
from typing import Any, ClassVar

import numpy as np

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
IMPACT_PROFILES: tuple[str, ...] = ("uniform", "peak")
COMPONENT_DEFECTS: tuple[str, ...] = ("dented", "discoloured")

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
        normal = np.asarray(_unit3(self.normal, "normal"))
        raw_u = np.asarray(_vector3(self.u_axis, "u_axis"))
        in_plane = raw_u - float(raw_u @ normal) * normal
        if float(np.linalg.norm(in_plane)) < 1e-9 * max(1.0, float(np.linalg.norm(raw_u))):
            raise InputError(
                f"u_axis must not be parallel to normal; got u_axis={self.u_axis!r}, normal={self.normal!r}. "
                "Pass a direction along one side of the rectangle."
            )
        object.__setattr__(self, "normal", _unit3(normal, "normal"))
        object.__setattr__(self, "u_axis", _unit3(in_plane, "u_axis"))
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


def _unique_names(items: Sequence[Site] | Sequence[Patch], name: str) -> None:
    seen: set[str] = set()
    for item in items:
        if item.name in seen:
            raise InputError(f"{name} has two entries named {item.name!r}; give every site a unique name.")
        seen.add(item.name)


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
    impact_patches : sequence of Patch
        Flat surfaces that may receive micrometeorite impact spots.
    component_sites : sequence of Site
        Whole components (tanks, ORUs) that may be swapped for a defective version.
    """

    peltier_sites: tuple[Site, ...] = ()
    leak_sites: tuple[Site, ...] = ()
    screw_sites: tuple[Site, ...] = ()
    impact_patches: tuple[Patch, ...] = ()
    component_sites: tuple[Site, ...] = ()

    def __post_init__(self) -> None:
        for label, kind in (
            ("peltier_sites", Site),
            ("leak_sites", Site),
            ("screw_sites", Site),
            ("impact_patches", Patch),
            ("component_sites", Site),
        ):
            items = getattr(self, label)
            if isinstance(items, (str, kind)) or not isinstance(items, Sequence):
                raise InputError(f"{label} must be a sequence of {kind.__name__}; got {items!r}.")
            for item in items:
                if not isinstance(item, kind):
                    raise InputError(f"{label} must hold only {kind.__name__} objects; got {item!r}.")
            _unique_names(items, label)
            object.__setattr__(self, label, tuple(items))


# ---------------------------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class AnomalySettings:
    """How many anomalies of each kind to plant, and the ranges their parameters are drawn from.

    Parameters
    ----------
    active_peltier_count : int
        Peltier modules switched on, >= 0 (seed §4: "only two ... are turned on at any time").
    peltier_delta_k : float
        Temperature difference of an active spot's centre from ambient, > 0 K; hot spots are ``+delta``,
        cold spots ``-delta`` (a Peltier module pumps either way by the current's direction, seed §4).
    hot_probability : float
        Probability in [0, 1] that an active module runs hot rather than cold.
    peltier_radius_m : float
        Fall-off radius of a spot's temperature, > 0 m (default: the Kapton circle's radius).
    active_leak_count : int
        Leak holes spraying, >= 0 (seed §4: one selected from three).
    leak_start_window_s : (float, float)
        Each active leak's start time is drawn uniformly from this window, seconds >= 0.
    leak_hole_diameter_m : float
        Hole (nozzle) diameter, > 0 m (seed §4: "a small hole").
    leak_exit_velocity_m_s : float
        Mean speed of the compressed-air jet at the hole, > 0 m/s.
    leak_exit_ppm : float
        Ammonia concentration of the jet at the hole, > 0 ppm by volume.
    leak_turn_on_time_s : float
        Time constant of the valve/pressure build-up at the hole, > 0 s.
    missing_screw_count : int or None
        Exactly this many screws are removed (<= the screw sites); None removes each screw independently
        with `missing_screw_probability`.
    missing_screw_probability : float
        Probability in [0, 1] that each screw is removed, used when `missing_screw_count` is None.
    impact_count : int
        Impact spots planted on the patches, >= 0.
    impact_diameter_range_m : (float, float)
        Spot diameters are drawn uniformly from this range, metres (issue 3: 0.5 to 3 mm; seed §2: impact
        flaws are about 1 mm).
    impact_profiles : tuple of str
        Profiles to draw from, each ``"uniform"`` or ``"peak"`` (seed §2.4 flaw models).
    impact_darkening_range : (float, float)
        Fraction of the surface's reflectance removed over the spot, in [0, 1].
    impact_peak_extra_range : (float, float)
        For ``"peak"`` spots, the further fraction of the remaining reflectance removed at the crater's
        centre, in [0, 1] (seed §2.4: "the center of the crater is darker than the rest").
    impact_core_fraction : float
        Diameter of a peak spot's dark centre as a fraction of its diameter, in (0, 1].
    swapped_component_count : int
        Components replaced by defective versions, >= 0 (seed §4).
    component_defects : tuple of str
        Defects to draw from, each ``"dented"`` or ``"discoloured"``.
    dent_depth_range_m : (float, float)
        Dent depths, metres >= 0.
    reflectance_factor_range : (float, float)
        A discoloured component's reflectance is multiplied by a factor from this range, in [0, 1].
    """

    active_peltier_count: int = 2
    peltier_delta_k: float = 30.0
    hot_probability: float = 0.5
    peltier_radius_m: float = KAPTON_RADIUS_M
    active_leak_count: int = 1
    leak_start_window_s: tuple[float, float] = (0.0, 30.0)
    leak_hole_diameter_m: float = 1e-3
    leak_exit_velocity_m_s: float = 10.0
    leak_exit_ppm: float = 5000.0
    leak_turn_on_time_s: float = 1.0
    missing_screw_count: int | None = None
    missing_screw_probability: float = 0.1
    impact_count: int = 5
    impact_diameter_range_m: tuple[float, float] = (0.5e-3, 3e-3)
    impact_profiles: tuple[str, ...] = IMPACT_PROFILES
    impact_darkening_range: tuple[float, float] = (0.3, 0.7)
    impact_peak_extra_range: tuple[float, float] = (0.3, 0.8)
    impact_core_fraction: float = 1.0 / 3.0
    swapped_component_count: int = 1
    component_defects: tuple[str, ...] = COMPONENT_DEFECTS
    dent_depth_range_m: tuple[float, float] = (2e-3, 10e-3)
    reflectance_factor_range: tuple[float, float] = (0.4, 0.8)

    def __post_init__(self) -> None:
        checked: dict[str, object] = {
            "active_peltier_count": _count(self.active_peltier_count, "active_peltier_count"),
            "peltier_delta_k": v.in_range(
                self.peltier_delta_k, "peltier_delta_k", low=0.0, low_inclusive=False
            ),
            "hot_probability": v.in_range(self.hot_probability, "hot_probability", low=0.0, high=1.0),
            "peltier_radius_m": v.in_range(
                self.peltier_radius_m, "peltier_radius_m", low=0.0, low_inclusive=False
            ),
            "active_leak_count": _count(self.active_leak_count, "active_leak_count"),
            "leak_start_window_s": _interval(self.leak_start_window_s, "leak_start_window_s", low=0.0),
            "missing_screw_probability": v.in_range(
                self.missing_screw_probability, "missing_screw_probability", low=0.0, high=1.0
            ),
            "impact_count": _count(self.impact_count, "impact_count"),
            "impact_diameter_range_m": _interval(
                self.impact_diameter_range_m, "impact_diameter_range_m", low=1e-9
            ),
            "impact_darkening_range": _interval(
                self.impact_darkening_range, "impact_darkening_range", low=0.0, high=1.0
            ),
            "impact_peak_extra_range": _interval(
                self.impact_peak_extra_range, "impact_peak_extra_range", low=0.0, high=1.0
            ),
            "impact_core_fraction": v.in_range(
                self.impact_core_fraction, "impact_core_fraction", low=0.0, high=1.0, low_inclusive=False
            ),
            "swapped_component_count": _count(self.swapped_component_count, "swapped_component_count"),
            "dent_depth_range_m": _interval(self.dent_depth_range_m, "dent_depth_range_m", low=0.0),
            "reflectance_factor_range": _interval(
                self.reflectance_factor_range, "reflectance_factor_range", low=0.0, high=1.0
            ),
        }
        for name in (
            "leak_hole_diameter_m",
            "leak_exit_velocity_m_s",
            "leak_exit_ppm",
            "leak_turn_on_time_s",
        ):
            checked[name] = v.in_range(getattr(self, name), name, low=0.0, low_inclusive=False)
        if self.missing_screw_count is not None:
            checked["missing_screw_count"] = _count(self.missing_screw_count, "missing_screw_count")
        checked["impact_profiles"] = _options(self.impact_profiles, "impact_profiles", IMPACT_PROFILES)
        checked["component_defects"] = _options(
            self.component_defects, "component_defects", COMPONENT_DEFECTS
        )
        v.store_checked(self, checked)


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

    def to_dict(self) -> dict[str, object]:
        """A JSON-ready dict of the truth: ``kind`` first, then every field (vectors as lists)."""
        return {"kind": self.kind, **{key: _json_ready(value) for key, value in asdict(self).items()}}


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


@dataclass(frozen=True)
class MissingScrew(Anomaly):
    """A screw removed from the truss (seed §4); `size_m` is the screw-head diameter of the site."""

    KIND: ClassVar[str] = "missing_screw"


@dataclass(frozen=True)
class Impact(Anomaly):
    """A simulated micrometeorite impact: a dark spot (seed §4: black tape or pen marks; seed §2.4 profiles).

    Attributes
    ----------
    profile : str
        ``"uniform"`` (the whole disc equally dark) or ``"peak"`` (a darker centre inside a uniformly dark
        surround: seed §2.4's crater model).
    darkening : float
        Fraction of the reflectance removed over the disc of diameter `size_m`, in [0, 1].
    centre_darkening : float
        Fraction removed over the centre disc, >= `darkening` (equal for ``"uniform"``).
    centre_diameter_m : float
        Diameter of the centre disc, metres (equal to `size_m` for ``"uniform"``).
    """

    KIND: ClassVar[str] = "impact"

    profile: str = "uniform"
    darkening: float = 0.5
    centre_darkening: float = 0.5
    centre_diameter_m: float = 0.0

    def __post_init__(self) -> None:
        super().__post_init__()
        v.choice(self.profile, "profile", IMPACT_PROFILES)
        darkening = v.in_range(self.darkening, "darkening", low=0.0, high=1.0)
        centre = v.in_range(self.centre_darkening, "centre_darkening", low=darkening, high=1.0)
        core = v.in_range(self.centre_diameter_m, "centre_diameter_m", low=0.0, high=self.size_m)
        object.__setattr__(self, "darkening", darkening)
        object.__setattr__(self, "centre_darkening", centre)
        object.__setattr__(self, "centre_diameter_m", core)


@dataclass(frozen=True)
class SwappedComponent(Anomaly):
    """A whole component replaced by a defective version (seed §4).

    Attributes
    ----------
    defect : str
        ``"dented"`` or ``"discoloured"``.
    dent_depth_m : float
        Depth of the dent, metres (0 unless dented).
    reflectance_factor : float
        Factor on the component's reflectance (1 unless discoloured).
    """

    KIND: ClassVar[str] = "swapped_component"

    defect: str = "dented"
    dent_depth_m: float = 0.0
    reflectance_factor: float = 1.0

    def __post_init__(self) -> None:
        super().__post_init__()
        v.choice(self.defect, "defect", COMPONENT_DEFECTS)
        object.__setattr__(self, "dent_depth_m", v.in_range(self.dent_depth_m, "dent_depth_m", low=0.0))
        object.__setattr__(
            self,
            "reflectance_factor",
            v.in_range(self.reflectance_factor, "reflectance_factor", low=0.0, high=1.0),
        )


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
            missing = names - set(entry)
            if missing:
                raise InputError(f"truth entry of kind {kind!r} lacks {sorted(missing)}; got {entry!r}.")
            record = record_type(**{key: entry[key] for key in names})
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


def _draw_thermal(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    count = settings.active_peltier_count
    _require(count, len(candidates.peltier_sites), "active_peltier_count", "peltier_sites")
    chosen = rng.choice(len(candidates.peltier_sites), size=count, replace=False)
    # Seed §4: the direction of the current, chosen per module, makes the surface hot or cold.
    hot = rng.random(count) < settings.hot_probability
    spots: list[Anomaly] = []
    for index, is_hot in zip(chosen, hot, strict=True):
        site = candidates.peltier_sites[int(index)]
        spots.append(
            ThermalSpot(
                site=site.name,
                position_m=site.position_m,
                normal=site.normal,
                size_m=2.0 * settings.peltier_radius_m,
                surface=site.surface,
                delta_k=settings.peltier_delta_k if is_hot else -settings.peltier_delta_k,
                radius_m=settings.peltier_radius_m,
            )
        )
    return spots


def _draw_leaks(candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator) -> list[Anomaly]:
    count = settings.active_leak_count
    _require(count, len(candidates.leak_sites), "active_leak_count", "leak_sites")
    chosen = rng.choice(len(candidates.leak_sites), size=count, replace=False)
    starts = rng.uniform(*settings.leak_start_window_s, size=count)
    leaks: list[Anomaly] = []
    for index, start in zip(chosen, starts, strict=True):
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
                exit_ppm=settings.leak_exit_ppm,
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


def _draw_impacts(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    count = settings.impact_count
    patches = candidates.impact_patches
    if count == 0:
        return []
    if not patches:
        raise InputError(
            f"settings.impact_count={count} needs impact_patches, but none were given. "
            "Pass the mock-up's surface patches or set impact_count=0."
        )
    largest_m = settings.impact_diameter_range_m[1]
    for patch in patches:
        if min(patch.half_extent_m) < largest_m / 2.0:
            raise InputError(
                f"impact_patches entry {patch.name!r} (half extents {patch.half_extent_m} m) cannot hold an "
                f"impact of {largest_m} m diameter. Drop the patch or lower impact_diameter_range_m."
            )
    area = np.array([patch.area_m2 for patch in patches])
    # Micrometeoroid flux is uniform per unit area, so a patch is chosen with probability by its area.
    which = rng.choice(len(patches), size=count, p=area / area.sum())
    diameters = rng.uniform(*settings.impact_diameter_range_m, size=count)
    unit = rng.random((count, 2))
    profiles = rng.choice(len(settings.impact_profiles), size=count)
    darkening = rng.uniform(*settings.impact_darkening_range, size=count)
    extra = rng.uniform(*settings.impact_peak_extra_range, size=count)
    impacts: list[Anomaly] = []
    for k in range(count):
        patch = patches[int(which[k])]
        radius_m = diameters[k] / 2.0
        # The whole spot lies inside the patch: the centre stays a radius away from every edge.
        reach = np.asarray(patch.half_extent_m) - radius_m
        offset_uv = (2.0 * unit[k] - 1.0) * reach
        centre = (
            np.asarray(patch.centre_m)
            + offset_uv[0] * np.asarray(patch.u_axis)
            + offset_uv[1] * np.asarray(patch.v_axis)
        )
        profile = settings.impact_profiles[int(profiles[k])]
        is_peak = profile == "peak"
        # Seed §2.4 peak/adjacent model: a darker centre inside a uniformly darkened surround.
        centre_darkening = darkening[k] + (1.0 - darkening[k]) * extra[k] if is_peak else darkening[k]
        impacts.append(
            Impact(
                site=patch.name,
                position_m=(float(centre[0]), float(centre[1]), float(centre[2])),
                normal=patch.normal,
                size_m=float(diameters[k]),
                surface=patch.surface,
                profile=profile,
                darkening=float(darkening[k]),
                centre_darkening=float(centre_darkening),
                centre_diameter_m=float(
                    diameters[k] * settings.impact_core_fraction if is_peak else diameters[k]
                ),
            )
        )
    return impacts


def _draw_components(
    candidates: Candidates, settings: AnomalySettings, rng: np.random.Generator
) -> list[Anomaly]:
    count = settings.swapped_component_count
    _require(count, len(candidates.component_sites), "swapped_component_count", "component_sites")
    chosen = np.sort(rng.choice(len(candidates.component_sites), size=count, replace=False))
    defects = rng.choice(len(settings.component_defects), size=count)
    depths = rng.uniform(*settings.dent_depth_range_m, size=count)
    factors = rng.uniform(*settings.reflectance_factor_range, size=count)
    swapped: list[Anomaly] = []
    for k, index in enumerate(chosen):
        site = candidates.component_sites[int(index)]
        defect = settings.component_defects[int(defects[k])]
        swapped.append(
            SwappedComponent(
                site=site.name,
                position_m=site.position_m,
                normal=site.normal,
                size_m=site.size_m,
                surface=site.surface,
                defect=defect,
                dent_depth_m=float(depths[k]) if defect == "dented" else 0.0,
                reflectance_factor=float(factors[k]) if defect == "discoloured" else 1.0,
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
        Counts and parameter ranges (default: two Peltier spots of +-30 K, one leak, screws removed with
        probability 0.1, five impacts of 0.5-3 mm, one swapped component).

    Returns
    -------
    AnomalySet

    Raises
    ------
    InputError
        If a count exceeds the candidates of its kind (naming the setting), the candidates are not a
        :class:`Candidates`, or a patch is too small for the largest impact.

    Examples
    --------
    >>> sites = tuple(Site(f"peltier_{k}", (0.1 * k, 0.0, 0.0), (0, 0, 1), "kapton") for k in range(4))
    >>> leaks = (Site("leak_0", (0.0, 1.0, 0.0), (0, 1, 0)),)
    >>> settings = AnomalySettings(impact_count=0, swapped_component_count=0)
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
    for draw in _DRAWERS:
        anomalies.extend(draw(candidates, chosen, generator))
    return AnomalySet(tuple(anomalies))


__all__: list[str] = [
    "ANOMALY_KINDS",
    "COMPONENT_DEFECTS",
    "IMPACT_PROFILES",
    "KAPTON_RADIUS_M",
    "Anomaly",
    "AnomalySet",
    "AnomalySettings",
    "Candidates",
    "GasLeak",
    "Impact",
    "MissingScrew",
    "Patch",
    "Site",
    "SwappedComponent",
    "ThermalSpot",
    "seed_anomalies",
]
