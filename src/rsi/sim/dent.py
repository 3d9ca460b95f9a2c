"""Seed §4: a dented box-shaped component drawn as a closed triangle mesh with a smooth crater in one face.

A dent in a flat face is concave: no union of MuJoCo primitives draws it, and a facet sunk into an opaque
box is hidden by the box. :func:`box_mesh` builds the box itself as a mesh (each face its own grid, so the
edges stay sharp), with the crater ``depth * (1 - (rho / radius)^2)^2`` pressed into the face that holds the
dent: zero depth and zero slope at the rim, as metal pushed in by a blow. Texture coordinates follow
MuJoCo's own box mapping of a top face (measured: ``u`` from the face's low edge, ``v`` from its high edge,
half the material's repeat per metre), so a flat mesh renders as the box it replaces. The pristine box is
drawn from the same grid with a crater of zero depth: both are lit at the same vertices.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

F64 = NDArray[np.float64]
MAX_HALF_SIZE_M = 5.0
"""Largest half size (or tank radius, half length) meshed: the mockup's parts are under a metre, and a mesh
with a vertex every centimetre grows with the square of the side (10 m faces: millions of vertices)."""

CRATER_SPACING_M = 1e-3  # grid step inside the crater: ~2 px at the 0.5 m standoff (seed §2.1)
# The classic renderer lights vertices and interpolates: a face needs vertices every centimetre or so to
# show the strobe's highlight as MuJoCo's own subdivided box does.
FACE_SPACING_M = 0.01


@dataclass(frozen=True)
class Crater:
    """A dent in the face of a box, in the box's own frame.

    Attributes
    ----------
    axis : int
        Index (0, 1, 2) of the local axis normal to the dented face.
    sign : int
        +1 or -1: which of the two faces along `axis`.
    centre : (float, float)
        Centre of the crater in the face, along the face's two other axes in increasing order, metres.
    depth_m : float
        Depth at the centre, metres.
    radius_m : float
        Radius of the rim, metres.
    """

    axis: int
    sign: int
    centre: tuple[float, float]
    depth_m: float
    radius_m: float


@dataclass(frozen=True)
class BoxMesh:
    """Vertices (N, 3), texture coordinates (N, 2) and outward triangles (M, 3) of a box mesh."""

    vertices: F64
    texcoords: F64
    faces: NDArray[np.int64]


def local_rotation(zaxis: tuple[float, float, float] | F64) -> F64:
    """The 3x3 rotation MuJoCo gives a geom whose ``zaxis`` is `zaxis` (the shortest turn from +z)."""
    target = v.direction3(zaxis, "zaxis")
    z = np.array([0.0, 0.0, 1.0])
    cosine = float(np.dot(z, target))
    if cosine < -1.0 + 1e-12:
        return np.diag([1.0, -1.0, -1.0])  # MuJoCo turns -z by pi about x
    axis = np.cross(z, target)
    skew = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
    rotation: F64 = np.eye(3) + skew + skew @ skew / (1.0 + cosine)
    return rotation


def crater_on_box(
    size: tuple[float, ...],
    pos: tuple[float, float, float],
    zaxis: tuple[float, float, float],
    point_m: tuple[float, float, float],
    normal: tuple[float, float, float],
    *,
    depth_m: float,
    radius_m: float,
) -> Crater:
    """The crater of a dent at world `point_m`, outward `normal`, in the box (`size`, `pos`, `zaxis`)."""
    size = _half_sizes(size)
    pos, point_m, normal = (
        v.vector3(pos, "pos"),
        v.vector3(point_m, "point_m"),
        tuple(v.direction3(normal, "normal")),
    )
    depth_m, radius_m = v.positive(depth_m, "depth_m"), v.positive(radius_m, "radius_m")
    rotation = local_rotation(zaxis)
    local_normal = rotation.T @ np.asarray(normal, dtype=float)
    axis = int(np.argmax(np.abs(local_normal)))
    sign = 1 if local_normal[axis] > 0 else -1
    local_point = rotation.T @ (np.asarray(point_m, dtype=float) - np.asarray(pos, dtype=float))
    first, second = (k for k in range(3) if k != axis)
    # the rim stays on the face: a crater wider than the face would tear its edges
    radius = min(radius_m, 0.95 * min(size[first], size[second]))
    centre = tuple(
        float(np.clip(local_point[k], -size[k] + radius, size[k] - radius)) for k in (first, second)
    )
    return Crater(axis, sign, (centre[0], centre[1]), min(depth_m, 1.9 * size[axis]), radius)


def crater_surface(
    crater: Crater,
    pos: tuple[float, float, float],
    zaxis: tuple[float, float, float],
    point_m: tuple[float, float, float],
) -> tuple[F64, F64]:
    """World point and outward unit normal of the dented face under `point_m` (a point of the flat face).

    A decal planted on the face before the blow (an impact spot, seed §4) follows the metal into the crater:
    it sinks with the face and tilts with its slope.
    """
    v.instance_of(crater, "crater", Crater, none_allowed=False)
    pos, point_m = v.vector3(pos, "pos"), v.vector3(point_m, "point_m")
    rotation = local_rotation(zaxis)
    local = rotation.T @ (np.asarray(point_m, dtype=float) - np.asarray(pos, dtype=float))
    first, second = (k for k in range(3) if k != crater.axis)
    offset = np.array([local[first] - crater.centre[0], local[second] - crater.centre[1]])
    rho2 = float(offset @ offset) / crater.radius_m**2
    inside = max(1.0 - rho2, 0.0)
    local[crater.axis] -= crater.sign * crater.depth_m * inside**2
    # slope of the sink along the face: d/dx [depth (1 - rho^2)^2] = -4 depth (1 - rho^2) x / radius^2
    slope = -4.0 * crater.depth_m * inside * offset / crater.radius_m**2
    normal = np.zeros(3)
    normal[crater.axis] = crater.sign
    normal[first], normal[second] = slope[0], slope[1]
    return rotation @ local + np.asarray(pos, dtype=float), rotation @ (normal / np.linalg.norm(normal))


def box_mesh(size: tuple[float, ...], repeat_per_m: float, crater: Crater | None = None) -> BoxMesh:
    """A closed box mesh of half sizes `size`, flat or with `crater` pressed into one face."""
    size = _half_sizes(size)
    repeat_per_m = v.positive(repeat_per_m, "repeat_per_m")
    if crater is not None:
        v.instance_of(crater, "crater", Crater)
    # one set of grid lines per axis, shared by the faces that meet at an edge: no T-junctions, no cracks
    lines = [_grid_lines(size[axis], None, 0.0) for axis in range(3)]
    if crater is not None:
        in_face = [k for k in range(3) if k != crater.axis]
        for k, centre in zip(in_face, crater.centre, strict=True):
            lines[k] = _grid_lines(size[k], centre, crater.radius_m)
    vertices: list[F64] = []
    texcoords: list[F64] = []
    faces: list[NDArray[np.int64]] = []
    count = 0
    for axis in range(3):
        for sign in (1, -1):
            dented = crater if crater is not None and (crater.axis, crater.sign) == (axis, sign) else None
            face_vertices, face_uv, face_triangles = _face(
                size, axis, sign, lines, repeat_per_m=repeat_per_m, crater=dented
            )
            vertices.append(face_vertices)
            texcoords.append(face_uv)
            faces.append(face_triangles + count)
            count += len(face_vertices)
    return BoxMesh(np.concatenate(vertices), np.concatenate(texcoords), np.concatenate(faces))


def _half_sizes(size: object) -> tuple[float, float, float]:
    sizes = v.size3(size, "size")
    if max(sizes) > MAX_HALF_SIZE_M:
        raise InputError(f"size must be half sizes <= {MAX_HALF_SIZE_M} m (a mockup part); got {size!r:.80}.")
    return sizes


def _skin_size(radius: object, name: str) -> float:
    return v.in_range(radius, name, low=0.0, high=MAX_HALF_SIZE_M, low_inclusive=False)


def _grid_lines(half: float, centre: float | None, radius: float) -> F64:
    lines = np.linspace(-half, half, max(int(np.ceil(2 * half / FACE_SPACING_M)), 1) + 1)
    if centre is None:
        return lines
    count = max(int(np.ceil(2 * radius / CRATER_SPACING_M)), 8)
    inner = np.linspace(centre - radius, centre + radius, count + 1)
    return np.unique(np.concatenate([lines, inner]))


def _face(
    size: tuple[float, ...],
    axis: int,
    sign: int,
    lines: list[F64],
    *,
    repeat_per_m: float,
    crater: Crater | None,
) -> tuple[F64, F64, NDArray[np.int64]]:
    first, second = (k for k in range(3) if k != axis)
    lines_a, lines_b = lines[first], lines[second]
    grid_a, grid_b = np.meshgrid(lines_a, lines_b, indexing="ij")
    points = np.zeros((grid_a.size, 3))
    points[:, first], points[:, second] = grid_a.ravel(), grid_b.ravel()
    points[:, axis] = sign * size[axis]
    if crater is not None:
        rho2 = ((grid_a - crater.centre[0]) ** 2 + (grid_b - crater.centre[1]) ** 2) / crater.radius_m**2
        sink = crater.depth_m * np.clip(1.0 - rho2, 0.0, None) ** 2
        points[:, axis] -= sign * sink.ravel()  # seed §4: pressed in, against the outward normal
    scale = repeat_per_m / 2  # MuJoCo maps a box face's texture at half the repeat per metre
    uv = np.column_stack(
        [scale * (points[:, first] + size[first]), scale * (size[second] - points[:, second])]
    )
    n_a, n_b = len(lines_a), len(lines_b)
    corner = (np.arange(n_a - 1)[:, None] * n_b + np.arange(n_b - 1)[None, :]).ravel()
    lower = np.column_stack([corner, corner + n_b, corner + n_b + 1])
    upper = np.column_stack([corner, corner + n_b + 1, corner + 1])
    triangles = np.concatenate([lower, upper]).astype(np.int64)
    # (first, second, axis) is right-handed only for some faces: flip winding so every normal points out
    outward = np.zeros(3)
    outward[axis] = sign
    e_first, e_second = np.eye(3)[first], np.eye(3)[second]
    if np.dot(np.cross(e_first, e_second), outward) < 0:
        triangles = triangles[:, ::-1]
    return points, uv, triangles


# ------------------------------------------------------------------------------------- cylinders, capsules

SKIN_SEGMENTS_PER_M = 100.0  # grid lines around and along a tank's skin: every centimetre, as a box face
CAP_RINGS = 8


@dataclass(frozen=True)
class SkinDent:
    """A dent in the side of a cylinder or capsule, in its own frame (axis along the local z).

    Attributes
    ----------
    angle_rad : float
        Azimuth of the dent's centre around the local z, from the local x axis.
    height_m : float
        Position of the centre along the local z, metres.
    depth_m : float
        Depth at the centre, metres (radially inwards).
    radius_m : float
        Radius of the rim, measured along the skin, metres.
    """

    angle_rad: float
    height_m: float
    depth_m: float
    radius_m: float


def dent_on_skin(
    radius: float,
    half_length: float,
    pos: tuple[float, float, float],
    zaxis: tuple[float, float, float],
    point_m: tuple[float, float, float],
    *,
    depth_m: float,
    radius_m: float,
) -> SkinDent:
    """The dent centred at world `point_m` on the side of a cylinder or capsule (`radius`, `half_length`)."""
    radius, half_length = _skin_size(radius, "radius"), _skin_size(half_length, "half_length")
    pos, point_m = v.vector3(pos, "pos"), v.vector3(point_m, "point_m")
    depth_m, radius_m = v.positive(depth_m, "depth_m"), v.positive(radius_m, "radius_m")
    local = local_rotation(zaxis).T @ (np.asarray(point_m, dtype=float) - np.asarray(pos, dtype=float))
    # the rim stays on the side (a dent wider than the tank would fold it) and the centre clear of the ends
    rim = min(radius_m, 0.95 * half_length, 0.5 * np.pi * radius)
    height = float(np.clip(local[2], -half_length + rim, half_length - rim))
    return SkinDent(float(np.arctan2(local[1], local[0])), height, min(depth_m, 0.5 * radius), rim)


def _skin_sink(dent: SkinDent, radius: float, angle: F64, height: F64) -> tuple[F64, F64, F64]:
    """Radial sink ``depth (1 - s^2 / rim^2)^2`` at skin points, ``s`` the distance along the skin, and its
    slopes along the arc and the axis (the same profile as a box's crater)."""
    arc = radius * (np.angle(np.exp(1j * (angle - dent.angle_rad))))
    along = height - dent.height_m
    inside = np.clip(1.0 - (arc**2 + along**2) / dent.radius_m**2, 0.0, None)
    sink = dent.depth_m * inside**2
    scale = -4.0 * dent.depth_m * inside / dent.radius_m**2
    return sink, scale * arc, scale * along


def skin_surface(
    dent: SkinDent,
    radius: float,
    pos: tuple[float, float, float],
    zaxis: tuple[float, float, float],
    point_m: tuple[float, float, float],
) -> tuple[F64, F64]:
    """World point and outward unit normal of the dented skin under `point_m` (a point of the round skin).

    A spot planted before the blow follows the metal into the dent, as on a box (:func:`crater_surface`).
    """
    v.instance_of(dent, "dent", SkinDent, none_allowed=False)
    radius = _skin_size(radius, "radius")
    pos, point_m = v.vector3(pos, "pos"), v.vector3(point_m, "point_m")
    rotation = local_rotation(zaxis)
    local = rotation.T @ (np.asarray(point_m, dtype=float) - np.asarray(pos, dtype=float))
    angle = float(np.arctan2(local[1], local[0]))
    sink, slope_arc, slope_along = (
        float(value[0]) for value in _skin_sink(dent, radius, np.array([angle]), np.array([local[2]]))
    )
    radial = np.array([np.cos(angle), np.sin(angle), 0.0])
    tangent = np.array([-np.sin(angle), np.cos(angle), 0.0])
    point = (radius - sink) * radial + np.array([0.0, 0.0, local[2]])
    # the sink deepens towards the centre: the normal leans towards it by the slope (as crater_surface)
    normal = radial + slope_arc * tangent + slope_along * np.array([0.0, 0.0, 1.0])
    return rotation @ point + np.asarray(pos, dtype=float), rotation @ (normal / np.linalg.norm(normal))


def skin_mesh(
    radius: float, half_length: float, *, capsule: bool, repeat_per_m: float, dent: SkinDent | None = None
) -> BoxMesh:
    """A closed mesh of a cylinder (flat ends) or capsule (round ends) along the local z, flat or dented.

    The side is a grid in azimuth and height, refined to :data:`CRATER_SPACING_M` over the dent, its seam
    opposite the dent; each end is its own set of rings, so a cylinder's rims stay sharp.
    """
    radius, half_length = _skin_size(radius, "radius"), _skin_size(half_length, "half_length")
    repeat_per_m = v.positive(repeat_per_m, "repeat_per_m")
    if not isinstance(capsule, (bool, np.bool_)):
        raise InputError(f"capsule must be True (round ends) or False (flat ends); got {capsule!r:.80}.")
    if dent is not None:
        v.instance_of(dent, "dent", SkinDent)
    centre = 0.0 if dent is None else dent.angle_rad
    step = 1.0 / (SKIN_SEGMENTS_PER_M * radius)
    angles = np.linspace(centre - np.pi, centre + np.pi, max(int(np.ceil(2 * np.pi / step)), 16) + 1)
    heights = _grid_lines(half_length, None, 0.0)
    if dent is not None:
        span = dent.radius_m / radius
        count = max(int(np.ceil(2 * dent.radius_m / CRATER_SPACING_M)), 8)
        angles = np.unique(np.concatenate([angles, np.linspace(centre - span, centre + span, count + 1)]))
        heights = _grid_lines(half_length, dent.height_m, dent.radius_m)
    scale = repeat_per_m / 2  # as a box face: half the material's repeat per metre
    grid_angle, grid_height = np.meshgrid(angles, heights, indexing="ij")
    sink = np.zeros_like(grid_angle)
    if dent is not None:
        sink = _skin_sink(dent, radius, grid_angle, grid_height)[0]
    reach = radius - sink
    side = np.column_stack(
        [(reach * np.cos(grid_angle)).ravel(), (reach * np.sin(grid_angle)).ravel(), grid_height.ravel()]
    )
    side_uv = np.column_stack(
        [scale * radius * (grid_angle - angles[0]).ravel(), scale * grid_height.ravel()]
    )
    triangles = _grid_triangles(len(angles), len(heights))
    parts = [(side, side_uv, triangles)]
    for sign in (1, -1):
        parts.append(_end(radius, half_length, angles, sign, capsule=capsule, scale=scale))
    vertices, texcoords, faces, count = [], [], [], 0
    for points, uv, tris in parts:
        vertices.append(points)
        texcoords.append(uv)
        faces.append(_outward(points, tris, half_length, capsule) + count)
        count += len(points)
    return BoxMesh(np.concatenate(vertices), np.concatenate(texcoords), np.concatenate(faces))


def _grid_triangles(n_a: int, n_b: int) -> NDArray[np.int64]:
    corner = (np.arange(n_a - 1)[:, None] * n_b + np.arange(n_b - 1)[None, :]).ravel()
    lower = np.column_stack([corner, corner + n_b, corner + n_b + 1])
    upper = np.column_stack([corner, corner + n_b + 1, corner + 1])
    return np.concatenate([lower, upper]).astype(np.int64)


def _end(
    radius: float, half_length: float, angles: F64, sign: int, *, capsule: bool, scale: float
) -> tuple[F64, F64, NDArray[np.int64]]:
    """Rings from the rim to the pole of one end: a hemisphere (capsule) or a flat disc (cylinder)."""
    polar = np.linspace(0.0, 0.5 * np.pi, CAP_RINGS + 1)[:-1]
    rings = radius * np.cos(polar) if capsule else radius * (1.0 - np.arange(CAP_RINGS) / CAP_RINGS)
    lift = radius * np.sin(polar) if capsule else np.zeros(CAP_RINGS)
    grid_angle, grid_ring = np.meshgrid(angles, np.arange(CAP_RINGS), indexing="ij")
    reach, height = rings[grid_ring], sign * (half_length + lift[grid_ring])
    ring_points = np.column_stack(
        [(reach * np.cos(grid_angle)).ravel(), (reach * np.sin(grid_angle)).ravel(), height.ravel()]
    )
    pole = np.array([[0.0, 0.0, sign * (half_length + (radius if capsule else 0.0))]])
    points = np.concatenate([ring_points, pole])
    triangles = [_grid_triangles(len(angles), CAP_RINGS)]
    last = np.arange(len(angles) - 1) * CAP_RINGS + CAP_RINGS - 1
    triangles.append(np.column_stack([last, last + CAP_RINGS, np.full(len(last), len(points) - 1)]))
    uv = scale * points[:, :2]
    return points, uv, np.concatenate(triangles)


def _outward(
    points: F64, triangles: NDArray[np.int64], half_length: float, capsule: bool
) -> NDArray[np.int64]:
    """The triangles wound so that every normal points out of the solid (away from its axis segment)."""
    a, b, c = (points[triangles[:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    centroid = (a + b + c) / 3
    if capsule:
        inside = np.column_stack(
            [np.zeros((len(centroid), 2)), np.clip(centroid[:, 2], -half_length, half_length)]
        )
        reference = centroid - inside
    else:
        on_end = np.abs(np.abs(centroid[:, 2]) - half_length) < 1e-12
        reference = np.where(
            on_end[:, None],
            np.column_stack([np.zeros((len(centroid), 2)), np.sign(centroid[:, 2])]),
            np.column_stack([centroid[:, :2], np.zeros(len(centroid))]),
        )
    flip = np.einsum("ij,ij->i", normal, reference) < 0
    wound = triangles.copy()
    wound[flip] = wound[flip][:, ::-1]
    return wound
