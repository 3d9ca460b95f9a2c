"""What a plan sees of the mock-up's inspectable surface, measured from the CAD model (issue 15).

The **inspectable surface** (:func:`inspectable_samples`) is, in this one place, the union of every place an
anomaly can be (seed §4): each impact patch (flat faces, tank and tube skins: where micrometeorite spots
are planted), each screw, Peltier and leak site's disc (a missing screw, a hot or cold spot, a leak's hole)
and each swappable component's dent patches (where a replacement's dent or discoloured patch is centred).
Nothing else of the CAD is inspected: a flaw can only be missed where one can be, so those surfaces are the
ones the plan must see. They are sampled on a grid of ``sample_spacing_m`` with area weights (a point, its
outward normal, the area it stands for); where two overlap (a dent patch over an impact patch) the skin is
counted once for each, as each is its own candidate.

A sample is **covered** by a view (a vista and a door opening) when (:class:`CoverageRules`):

- it projects inside the image, ``margin_px`` clear of its border (registration shifts and the detector's
  windows lose the border, seed §2.3-2.4);
- its incidence (the angle between its normal and the line to the camera) is at most
  ``max_incidence_deg``: beyond it a flaw is foreshortened by more than cos 45 deg = 0.71 and its shading
  (a crater's slopes, seed §4) turns with the light;
- the pixel's footprint on the surface, ``distance / (focal_px * cos(incidence))`` along the tilt (its
  longer side), is at most ``max_pixel_m``: seed §2.4's flaw model needs a 1 mm impact to cover 2 pixels
  (seed §2.1: a 1 mm flaw at the standoff), so 0.5 mm;
- the ray from the camera meets the CAD first within ``depth_tolerance_m`` of the sample (MuJoCo's
  ``mj_multiRay`` on the pristine mock-up with the door at the view's opening): nothing occludes it, and it
  is there at that opening (a point on the door is not there when the door is open, a point in the
  door's pocket is hidden while it is closed).

:func:`coverage` measures any plan (the hand plan too); :mod:`rsi.mission.plan_cad` generates one.
See docs/mission.md, "Plan from the CAD model".
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.plan_point import PlanPoint
from rsi.mission.settings import FRAME_MARGIN_PX, MISSION_SIZE
from rsi.mission.viewing import focal_px
from rsi.mission.views import point_region
from rsi.sim.anomalies import CylinderPatch, Patch, Site, Surface

if TYPE_CHECKING:
    from rsi.sim.mockup import Mockup, Vista
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

# What each sample is: an impact patch, a site's disc or a component's dent patch (see the module notes).
SAMPLE_KINDS = ("impact", "screw", "peltier", "leak", "dent")
_RAY_CUTOFF_PAST_M = 0.1  # a ray looks this far past its sample (an opened door's gap shows what is behind)


@dataclass(frozen=True)
class CoverageRules:
    """When a view covers a sample of the inspectable surface (see the module notes for each reason).

    Attributes
    ----------
    max_pixel_m : float
        Largest pixel footprint on the surface, metres (seed §2.1/§2.4: a 1 mm impact covers 2 pixels).
    max_incidence_deg : float
        Largest angle between the surface normal and the line of sight, in (0, 90) degrees.
    margin_px : int
        Border of the image where nothing counts as seen (registration shift plus the detector's windows:
        the 9-pixel nuisance window and a few pixels of pose error).
    size : (int, int)
        Frame (rows, cols) of the mission (seed §2.1 video frame).
    sample_spacing_m : float
        Grid spacing of the samples on every surface (area weights keep the measure exact on the grid).
    depth_tolerance_m : float
        The CAD hit may lie this far before or after the sample: a screw head stands 2 mm proud of its
        site's disc (2.8 mm along a ray at 45 deg); the door's pocket is 20 mm deep.
    """

    max_pixel_m: float = 5e-4
    max_incidence_deg: float = 45.0
    margin_px: int = FRAME_MARGIN_PX
    size: tuple[int, int] = MISSION_SIZE
    sample_spacing_m: float = 0.01
    depth_tolerance_m: float = 4e-3

    def __post_init__(self) -> None:
        v.in_range(self.max_pixel_m, "max_pixel_m", low=0.0, low_inclusive=False)
        v.in_range(
            self.max_incidence_deg,
            "max_incidence_deg",
            low=0.0,
            high=90.0,
            low_inclusive=False,
            high_inclusive=False,
        )
        v.in_range(self.sample_spacing_m, "sample_spacing_m", low=1e-3, high=0.1)
        v.in_range(self.depth_tolerance_m, "depth_tolerance_m", low=0.0, low_inclusive=False, high=0.02)
        if not isinstance(self.size, tuple) or len(self.size) != 2:
            raise InputError(f"size must be a (rows, cols) tuple; got {self.size!r}. Try size=(480, 640).")
        rows, cols = (v.positive_int(side, "size", minimum=16) for side in self.size)
        object.__setattr__(self, "size", (rows, cols))
        margin = v.positive_int(self.margin_px, "margin_px", minimum=0)
        if 2 * margin >= min(rows, cols):
            raise InputError(
                f"margin_px={margin} leaves nothing of a {rows}x{cols} image; "
                f"keep it under {min(rows, cols) // 2}."
            )

    @property
    def focal_px(self) -> float:
        """Focal length in pixels of the ISEE camera in this frame."""
        return focal_px(self.size[0])

    @property
    def nominal_standoff_m(self) -> float:
        """Farthest a camera may be from a surface it faces for its image centre to meet ``max_pixel_m``."""
        return self.max_pixel_m * self.focal_px


# ------------------------------------------------------------------------------------------ samples


@dataclass(frozen=True, eq=False)
class Samples:
    """The inspectable surface, sampled: points with outward normals and the area each stands for.

    Attributes
    ----------
    points_m, normals : ndarray of shape (N, 3)
    area_m2 : ndarray of shape (N,)
    surface : ndarray of shape (N,), str
        The patch or site each sample lies on.
    kind : ndarray of shape (N,), str
        One of :data:`SAMPLE_KINDS`.
    """

    points_m: FloatArray
    normals: FloatArray
    area_m2: FloatArray
    surface: NDArray[np.str_]
    kind: NDArray[np.str_]

    def __len__(self) -> int:
        return int(self.area_m2.size)


def _grid(half: float, spacing: float) -> FloatArray:
    """Cell centres across [-half, half], cells no wider than `spacing`."""
    count = max(1, math.ceil(2 * half / spacing))
    return ((np.arange(count) + 0.5) / count * 2 - 1) * half


def _patch_samples(patch: Patch, spacing: float) -> tuple[FloatArray, FloatArray]:
    u, w = (_grid(half, spacing) for half in patch.half_extent_m)
    uu, ww = (grid.ravel() for grid in np.meshgrid(u, w, indexing="ij"))
    points = np.asarray(patch.centre_m) + np.outer(uu, patch.u_axis) + np.outer(ww, patch.v_axis)
    return points, np.tile(np.asarray(patch.normal), (len(points), 1))


def _cylinder_samples(patch: CylinderPatch, spacing: float) -> tuple[FloatArray, FloatArray]:
    angles = _grid(patch.half_angle_rad, spacing / patch.radius_m)
    along = _grid(patch.half_length_m, spacing)
    aa, ll = (grid.ravel() for grid in np.meshgrid(angles, along, indexing="ij"))
    axis, front = np.asarray(patch.axis), np.asarray(patch.front)
    normals = np.outer(np.cos(aa), front) + np.outer(np.sin(aa), np.cross(axis, front))
    return np.asarray(patch.centre_m) + np.outer(ll, axis) + patch.radius_m * normals, normals


def _site_samples(site: Site, spacing: float) -> tuple[FloatArray, FloatArray]:
    """A site's disc (its size as diameter) on the square grid, the points inside it (its centre at least)."""
    normal = np.asarray(site.normal)
    u_axis, v_axis = _across(normal)
    radius = site.size_m / 2
    grid = _grid(radius, spacing)
    uu, ww = (g.ravel() for g in np.meshgrid(grid, grid, indexing="ij"))
    inside = np.hypot(uu, ww) <= radius
    uu, ww = (uu[inside], ww[inside]) if inside.any() else (np.zeros(1), np.zeros(1))
    points = np.asarray(site.position_m) + np.outer(uu, u_axis) + np.outer(ww, v_axis)
    return points, np.tile(normal, (len(points), 1))


def _across(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors across `normal` (any pair: a disc has no preferred side)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(normal, first)


def _surface_samples(item: Surface | Site, spacing: float) -> tuple[FloatArray, FloatArray, float]:
    if isinstance(item, Site):
        points, normals = _site_samples(item, spacing)
        return points, normals, math.pi * (item.size_m / 2) ** 2
    points, normals = (
        _patch_samples(item, spacing) if isinstance(item, Patch) else _cylinder_samples(item, spacing)
    )
    return points, normals, item.area_m2


def inspectable_items(mockup: Mockup) -> list[tuple[str, Surface | Site]]:
    """Every inspectable surface of `mockup` with its kind (the definition: see the module notes)."""
    from rsi.sim.mockup import Mockup

    candidates = v.instance_of(mockup, "mockup", Mockup, none_allowed=False).candidates
    items: list[tuple[str, Surface | Site]] = [("impact", patch) for patch in candidates.impact_patches]
    items += [("screw", site) for site in candidates.screw_sites]
    items += [("peltier", site) for site in candidates.peltier_sites]
    items += [("leak", site) for site in candidates.leak_sites]
    items += [("dent", patch) for patches in candidates.dent_patches.values() for patch in patches]
    return items


def inspectable_samples(mockup: Mockup, spacing_m: float = 0.01) -> Samples:
    """The inspectable surface of `mockup` sampled every `spacing_m` with area weights (module notes).

    Raises InputError for something that is not a Mockup or a spacing outside [1 mm, 0.1 m].
    """
    from rsi.sim.mockup import Mockup

    v.instance_of(mockup, "mockup", Mockup, none_allowed=False)
    spacing = v.in_range(spacing_m, "spacing_m", low=1e-3, high=0.1)
    points, normals, areas, surfaces, kinds = [], [], [], [], []
    for kind, item in inspectable_items(mockup):
        at, normal, area = _surface_samples(item, spacing)
        points.append(at)
        normals.append(normal)
        areas.append(np.full(len(at), area / len(at)))
        surfaces += [item.name] * len(at)
        kinds += [kind] * len(at)
    if not points:
        raise InputError("mockup has no inspectable surface: its candidates list no patch and no site.")
    return Samples(
        points_m=np.concatenate(points),
        normals=np.concatenate(normals),
        area_m2=np.concatenate(areas),
        surface=np.asarray(surfaces, dtype=np.str_),
        kind=np.asarray(kinds, dtype=np.str_),
    )


# ----------------------------------------------------------------------------------------- visibility


class Sight:
    """Which samples a view covers, ray-cast on the pristine mock-up (no anomaly, no arm).

    Parameters
    ----------
    mockup : Mockup
        The CAD model; a world of its own is built for the rays (tens of milliseconds).
    rules : CoverageRules
    """

    def __init__(self, mockup: Mockup, rules: CoverageRules) -> None:
        from rsi.sim.anomalies import AnomalySet
        from rsi.sim.render import import_mujoco
        from rsi.sim.world import World

        self.rules = v.instance_of(rules, "rules", CoverageRules, none_allowed=False)
        self.samples = inspectable_samples(mockup, rules.sample_spacing_m)
        self.world = World(mockup, AnomalySet(()), seed=0, arm=False, grid_meshes=False)
        self._mujoco: Any = import_mujoco()
        model = self.world.model
        moving = {int(model.jnt_bodyid[joint]) for joint in range(model.njnt)}
        # the door: the only jointed body of the pristine world without the arm
        self.door_geoms = frozenset(g for g in range(model.ngeom) if int(model.geom_bodyid[g]) in moving)

    def in_frame(self, vista: Vista) -> tuple[NDArray[np.intp], NDArray[np.intp], NDArray[np.intp]]:
        """The samples that meet the image, incidence and resolution rules from `vista`: their indices and
        the (row, col) pixel each falls on."""
        rules, samples = self.rules, self.samples
        camera = np.asarray(vista.position_m, dtype=np.float64)
        forward, up = np.asarray(vista.forward, float), np.asarray(vista.up, float)
        ray = samples.points_m - camera
        depth = ray @ forward
        right = ray @ np.array(  # forward x up: the image's right (a vista's up is across its forward)
            [
                forward[1] * up[2] - forward[2] * up[1],
                forward[2] * up[0] - forward[0] * up[2],
                forward[0] * up[1] - forward[1] * up[0],
            ]
        )
        distance = np.linalg.norm(ray, axis=1)
        cos_incidence = -np.einsum("ij,ij->i", samples.normals, ray) / distance
        rows, cols = rules.size
        f, margin = rules.focal_px, rules.margin_px
        with np.errstate(divide="ignore", invalid="ignore"):
            col = cols / 2 + f * right / depth
            row = rows / 2 - f * (ray @ up) / depth
            footprint = distance / (f * cos_incidence)
        ok = (depth > 0) & (cos_incidence >= math.cos(math.radians(rules.max_incidence_deg)))
        ok &= (col >= margin) & (col <= cols - margin) & (row >= margin) & (row <= rows - margin)
        ok &= footprint <= rules.max_pixel_m
        indices = np.flatnonzero(ok)
        return indices, row[indices].astype(np.intp), col[indices].astype(np.intp)

    def candidates(self, vista: Vista, inspected: BoolArray | None = None) -> NDArray[np.intp]:
        """Indices of the samples that meet the image, incidence and resolution rules from `vista`, and
        fall on its `inspected` pixels (a frame-sized mask; None: the whole frame less its margin)."""
        indices, rows, cols = self.in_frame(vista)
        if inspected is None:
            return indices
        if np.shape(inspected) != self.rules.size:
            raise InputError(
                f"inspected must be a boolean mask of the frame's {self.rules.size} pixels; "
                f"got shape {np.shape(inspected)}. Try rsi.mission.views.point_region(...)."
            )
        kept: NDArray[np.intp] = indices[np.asarray(inspected, dtype=bool)[rows, cols]]
        return kept

    def cast(self, vista: Vista, door_angle_rad: float, indices: NDArray[np.intp]) -> tuple[BoolArray, bool]:
        """Of the samples `indices`, those the CAD shows from `vista` at the door opening; and whether a
        ray met the door."""
        if indices.size == 0:
            return np.zeros(0, dtype=bool), False
        if self.world.door_angle_rad != door_angle_rad:
            self.world.set_door(door_angle_rad)
        camera = np.asarray(vista.position_m, dtype=np.float64)
        ray = self.samples.points_m[indices] - camera
        distance = np.linalg.norm(ray, axis=1)
        directions = np.ascontiguousarray(ray / distance[:, None])
        geoms = np.full(indices.size, -1, dtype=np.int32)
        hits = np.full(indices.size, -1.0)
        cutoff = float(distance.max()) + _RAY_CUTOFF_PAST_M
        model, data = self.world.model, self.world.data
        self._mujoco.mj_multiRay(
            model, data, camera, directions.ravel(), None, 1, -1, geoms, hits, None, indices.size, cutoff
        )
        seen = (geoms >= 0) & (np.abs(hits - distance) <= self.rules.depth_tolerance_m)
        return seen, bool(self.door_geoms & set(geoms.tolist()))

    def seen(
        self, vista: Vista, door_angle_rad: float = 0.0, inspected: BoolArray | None = None
    ) -> NDArray[np.intp]:
        """Indices of the samples `vista` covers at the door opening (every rule of the module notes), on
        its `inspected` pixels (None: the whole frame)."""
        indices = self.candidates(vista, inspected)
        visible, _ = self.cast(vista, door_angle_rad, indices)
        return indices[visible]


# ------------------------------------------------------------------------------------------ coverage


@dataclass(frozen=True, eq=False)
class Coverage:
    """What a plan covers of the inspectable surface (measured from the CAD, :func:`coverage`).

    Attributes
    ----------
    rules : CoverageRules
    samples : Samples
    first_seen : ndarray of shape (N,), int
        Per sample, the index in `points` of the first plan point that covers it (-1: uncovered).
    points : tuple of str
        The plan points' names, in visiting order.
    seen_counts : tuple of int
        How many samples each plan point covers.
    """

    rules: CoverageRules
    samples: Samples
    first_seen: NDArray[np.int64]
    points: tuple[str, ...]
    seen_counts: tuple[int, ...] = field(default=())

    @property
    def covered(self) -> BoolArray:
        """Per sample, whether some plan point covers it."""
        result: BoolArray = self.first_seen >= 0
        return result

    @property
    def total_area_m2(self) -> float:
        """Area of the inspectable surface, m^2."""
        return float(self.samples.area_m2.sum())

    @property
    def fraction(self) -> float:
        """Covered fraction of the inspectable surface's area."""
        return float(self.samples.area_m2[self.covered].sum()) / self.total_area_m2

    def by_kind(self) -> dict[str, float]:
        """Covered area fraction of each sample kind present (:data:`SAMPLE_KINDS`)."""
        area, covered = self.samples.area_m2, self.covered
        result = {}
        for kind in SAMPLE_KINDS:
            mine = self.samples.kind == kind
            if mine.any():
                result[kind] = float(area[mine & covered].sum() / area[mine].sum())
        return result

    def uncovered(self) -> tuple[tuple[str, str, float, float], ...]:
        """Every surface with some area uncovered: (name, kind, uncovered m^2, its area m^2), worst first."""
        rows = []
        area, covered = self.samples.area_m2, self.covered
        for name in dict.fromkeys(self.samples.surface.tolist()):
            mine = self.samples.surface == name
            missing = float(area[mine & ~covered].sum())
            if missing > 0:
                kind = str(self.samples.kind[mine][0])
                rows.append((name, kind, missing, float(area[mine].sum())))
        return tuple(sorted(rows, key=lambda row: -row[2]))


def coverage(
    points: Sequence[PlanPoint],
    world: World,
    rules: CoverageRules | None = None,
    *,
    sight: Sight | None = None,
) -> Coverage:
    """Measure what the plan `points` (their vistas in `world`, each at its door opening) cover.

    Parameters
    ----------
    points : sequence of PlanPoint
        A plan, e.g. ``plan_vistas(world)`` (the default: generated from the CAD model) or the hand plan's
        points (``plan_vistas(world, MissionSettings(plan="hand"))``).
    world : World
        Holds the points' vistas and the mock-up (its anomalies are ignored: the CAD is measured). With the
        arm, each frame loses what the ISEE's jaws hide at the point's opening (seed §3.1).
    rules : CoverageRules, optional
        Default ``CoverageRules()``: 0.5 mm per pixel, 45 deg.
    sight : Sight, optional
        A :class:`Sight` of the same mock-up and rules to reuse (saves building it).

    Raises
    ------
    InputError
        `points` not a sequence of PlanPoint, a vista the world lacks, `world` not a World, bad rules.
    """
    from rsi.sim.world import World

    v.instance_of(world, "world", World, none_allowed=False)
    rules = v.instance_or_default(rules, "rules", CoverageRules)
    if isinstance(points, (str, PlanPoint)) or not isinstance(points, Sequence):
        raise InputError(f"points must be a sequence of PlanPoint; got {points!r}.")
    for point in points:
        if not isinstance(point, PlanPoint):
            raise InputError(f"points must hold only PlanPoint objects; got {point!r}.")
    sight = Sight(world.mockup, rules) if sight is None else sight
    first = np.full(len(sight.samples), -1, dtype=np.int64)
    counts = []
    for number, point in enumerate(points):
        inspected = point_region(world, point, rules.size, rules.margin_px)
        seen = sight.seen(world.vista(point.vista), point.door_angle_rad, inspected)
        fresh = seen[first[seen] < 0]
        first[fresh] = number
        counts.append(int(seen.size))
    return Coverage(rules, sight.samples, first, tuple(point.name for point in points), tuple(counts))


__all__ = [
    "SAMPLE_KINDS",
    "Coverage",
    "CoverageRules",
    "Samples",
    "Sight",
    "coverage",
    "inspectable_items",
    "inspectable_samples",
]
