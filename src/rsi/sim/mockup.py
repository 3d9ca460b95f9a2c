"""Seed §4, Fig. 8: geometry of the one-third-scale Space Station truss mock-up, in metres (pure data).

World frame: x along the truss, y from the front face (y < 0, where the inspection robot works) to the back,
z up. Square bays of ``BAY_M`` = 0.6 m (one third of a ~1.8 m station truss bay) start at x = 0; the
square section spans y = -0.3..0.3 m and z = 0.9..1.5 m. The components carry the seed's letters:

- **A** electrical ORU on the front of a bay: a hinged door over a pocket holding four connectors and a cold
  plate; four black Kapton circles over the Peltier modules (seed §4: "a circle of Black Kapton" so the
  pyrometer reads the temperature of the low-emissivity aluminium skin).
- **B** tank ORU on the front of a bay: a horizontal tank on a base plate with two straps.
- **C** solar panel on top of a bay, on four posts.
- **D** (and **E**) tank-and-tubing ORU on the front of a bay: two tanks joined by tubing with three leak
  holes.
- Screws on every ORU plate and on the panel frame.

A :class:`Layout` says where each component goes (bay, face, rotation, hinge side); :data:`LAYOUTS` holds
``"truss"`` (the seed's arrangement: A, B, C on top of bay 2 and D over three bays) and ``"truss-b"`` (four
bays: D, B with C turned 90 deg on top, A hinged on its right edge, a second tubing ORU E). Build one with
:func:`mockup`. Nothing here imports MuJoCo: :mod:`rsi.sim.scene` turns a :class:`Mockup` into MJCF.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.anomalies import Candidates, CylinderPatch, Patch, Site, Surface

Vector3 = tuple[float, float, float]

BAY_M = 0.6  # bay length and section side
BAYS = 3  # of the seed's "truss" layout (truss-b has four: Layout.bays)
TRUSS_Z0_M = 0.9  # bottom longerons
STRUT_RADIUS_M = 0.012
NODE_RADIUS_M = 0.028
SCREW_RADIUS_M = 0.004
SCREW_HEIGHT_M = 0.002
KAPTON_RADIUS_M = 0.025
KAPTON_THICKNESS_M = 5e-4
LEAK_HOLE_RADIUS_M = 1.5e-3
VISTA_STANDOFF_M = 0.5  # seed §2.1: a ~0.1 m^2 scene at a typical inspection standoff
DOOR_HINGE_AXIS = (0.0, 0.0, -1.0)  # a door hinged on its left edge: a positive angle swings it out to -y
DOOR_MAX_ANGLE_RAD = 1.92  # 110 deg: wide open, clear of the ORU beside it
SHAPES = ("box", "cylinder", "capsule", "sphere")
# What an anomaly sits on (its truth `surface`, for stratified scoring; issue 13): the ORU's skin, its door,
# a Kapton circle, a tank, tubing, a bead-blasted base plate, the solar panel's cells.
SURFACES = ("oru_face", "door", "kapton", "tank", "tubing", "plate", "panel")
# The part of a round skin a camera in front sees well: +-60 deg, foreshortened at most by half.
SKIN_HALF_ANGLE_RAD = np.pi / 3


@dataclass(frozen=True)
class Part:
    """One primitive of the mock-up.

    Attributes
    ----------
    name : str
        Unique geom name.
    component : str
        What it belongs to: ``"truss"``, ``"A"``, ``"A_door"`` (moves with the door), ``"B"``, ``"C"``,
        ``"D"``, or a screw's site name.
    shape : {"box", "cylinder", "capsule", "sphere"}
        MuJoCo geom type.
    size : tuple of float
        MuJoCo half sizes (box: 3 half lengths; cylinder/capsule: radius, half length; sphere: radius).
    pos : (float, float, float)
        Centre in the world frame, metres (for ``"A_door"`` parts: at the closed door).
    zaxis : (float, float, float)
        Direction of the geom's z axis (cylinder axis).
    material : str
        Material name (see :data:`rsi.sim.scene.MATERIALS`).
    """

    name: str
    component: str
    shape: str
    size: tuple[float, ...]
    pos: Vector3
    material: str
    zaxis: Vector3 = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class Vista:
    """A viewpoint of the inspection camera (seed §2.3: visited again for every inspection).

    Attributes
    ----------
    name : str
        Vista name, e.g. ``"A_door"``.
    target_m : (float, float, float)
        Surface point at the image centre.
    position_m : (float, float, float)
        Camera centre, ``target_m + standoff_m * normal``.
    forward : (float, float, float)
        Unit viewing direction (minus the surface normal).
    up : (float, float, float)
        Unit image-up direction (perpendicular to `forward`).
    standoff_m : float
        Distance from the camera to the target.
    """

    name: str
    target_m: Vector3
    position_m: Vector3
    forward: Vector3
    up: Vector3
    standoff_m: float


@dataclass(frozen=True)
class Door:
    """The electrical ORU's hinged door (seed §4 A): the MuJoCo body and joint it becomes.

    Attributes
    ----------
    body : str
        Body name, and the ``Part.component`` of every part that rides on the door (e.g. ``"A_door"``).
    joint : str
        Hinge joint name (e.g. ``"A_door_hinge"``).
    hinge_m : (float, float, float)
        A point on the hinge axis, world metres.
    axis : (float, float, float)
        Hinge axis, oriented so that a positive angle swings the door's free edge out towards -y.
    vista : str
        The vista that looks at the door (open it to see the connectors and cold plate behind).
    max_angle_rad : float
        Widest opening.
    """

    body: str
    joint: str
    hinge_m: Vector3
    axis: Vector3
    vista: str
    max_angle_rad: float = DOOR_MAX_ANGLE_RAD


@dataclass(frozen=True)
class Mockup:
    """The mock-up: parts, the door, anomaly candidates and vista points, built from a :class:`Layout`.

    Attributes
    ----------
    parts : tuple of Part
        Every primitive, screws included.
    door : Door
        The electrical ORU's door.
    candidates : Candidates
        Places where :func:`rsi.sim.anomalies.seed_anomalies` may plant anomalies.
    vistas : dict of str to Vista
        Named viewpoints, one or two per component, plus ``"overview"`` (the whole mock-up, 3.4 m away).
    components : dict of str to tuple of str
        Part names of each swappable component site (``"B_tank"``, ...).
    layout : str
        The layout's name (:data:`LAYOUTS`).
    length_m : float
        Length of the truss along x (it spans x = 0..length_m).
    instrument_vistas : dict of str to tuple of str
        The vistas each non-visual instrument's readings are filed under (seed §3-4): ``"pyrometer"`` -> the
        vista of the Kapton circles, ``"gas"`` -> the vista of each tank-and-tubing ORU.
    tubing_leaks : tuple of tuple of str
        The leak-site names of each tank-and-tubing ORU, in ``candidates.leak_sites`` order: a gas survey
        runs along each tubing.
    """

    parts: tuple[Part, ...]
    door: Door
    candidates: Candidates
    vistas: dict[str, Vista]
    components: dict[str, tuple[str, ...]]
    layout: str
    length_m: float
    instrument_vistas: dict[str, tuple[str, ...]]
    tubing_leaks: tuple[tuple[str, ...], ...]

    @property
    def door_hinge_m(self) -> Vector3:
        """A point on the door hinge axis (``door.hinge_m``)."""
        return self.door.hinge_m

    @property
    def centre_m(self) -> Vector3:
        """Middle of the truss: mid-length, on its axis."""
        return vector3(round(self.length_m / 2, 9), 0.0, TRUSS_Z0_M + BAY_M / 2)


def vector3(x: float, y: float, z: float) -> Vector3:
    """A 3-vector of Python floats."""
    return (v.finite_number(x, "x"), v.finite_number(y, "y"), v.finite_number(z, "z"))


def _unit(vector: np.ndarray) -> Vector3:
    unit = vector / np.linalg.norm(vector)
    return vector3(*unit)


def vista(name: str, target_m: Vector3, normal: Vector3, up: Vector3, standoff_m: float) -> Vista:
    """A viewpoint `standoff_m` out along `normal` from `target_m`, looking back at it, `up` on top."""
    if not isinstance(name, str) or not name:
        raise InputError(f"name must be a non-empty string; got {name!r}.")
    target = np.array(v.vector3(target_m, "target_m"))
    forward = -v.direction3(normal, "normal")
    up_vector = v.direction3(up, "up")
    up_vector = up_vector - (up_vector @ forward) * forward
    if np.linalg.norm(up_vector) < 1e-9:
        raise InputError(
            f"up={up!r} is parallel to normal={normal!r}: pass an up direction across the normal."
        )
    standoff = v.positive(standoff_m, "standoff_m")
    position = target - standoff * forward
    return Vista(
        name, vector3(*target), v.vector3(position, "position"), vector3(*forward), _unit(up_vector), standoff
    )


def _truss(bays: int) -> list[Part]:
    """Longerons, battens, face diagonals and corner nodes of the square truss."""
    parts: list[Part] = []
    corners = [(y, z) for y in (-BAY_M / 2, BAY_M / 2) for z in (TRUSS_Z0_M, TRUSS_Z0_M + BAY_M)]
    length = BAY_M * bays

    def strut(name: str, start: np.ndarray, end: np.ndarray) -> Part:
        centre, axis = (start + end) / 2, end - start
        half = float(np.linalg.norm(axis)) / 2
        return Part(
            name, "truss", "cylinder", (STRUT_RADIUS_M, half), vector3(*centre), "aluminium", _unit(axis)
        )

    for k, (y, z) in enumerate(corners):
        parts.append(strut(f"longeron_{k}", np.array([0.0, y, z]), np.array([length, y, z])))
    square = [corners[0], corners[1], corners[3], corners[2]]  # around the section
    for bay in range(bays + 1):
        x = bay * BAY_M
        for k in range(4):
            (y0, z0), (y1, z1) = square[k], square[(k + 1) % 4]
            parts.append(strut(f"batten_{bay}_{k}", np.array([x, y0, z0]), np.array([x, y1, z1])))
            parts.append(
                Part(f"node_{bay}_{k}", "truss", "sphere", (NODE_RADIUS_M,), vector3(x, y0, z0), "aluminium")
            )
    for bay in range(bays):
        x0, x1 = bay * BAY_M, (bay + 1) * BAY_M
        for k in range(4):
            (y0, z0), (y1, z1) = square[k], square[(k + 1) % 4]
            # alternate the diagonals bay by bay, as on the station truss
            start, end = ((x0, y0, z0), (x1, y1, z1)) if bay % 2 == 0 else ((x0, y1, z1), (x1, y0, z0))
            parts.append(strut(f"diagonal_{bay}_{k}", np.array(start), np.array(end)))
    return parts


_FRONT = (0.0, -1.0, 0.0)
_UP = (0.0, 0.0, 1.0)
_MOUNT_Y_M = -BAY_M / 2 - STRUT_RADIUS_M  # ORU plates sit against the front struts
A_FACE_Y_M = _MOUNT_Y_M - 0.16  # front face of the A electrical ORU (its pocket is 20 mm deep)
_PLATE_FACE_Y_M = _MOUNT_Y_M - 0.02  # front face of the B and D base plates
_CZ_M = TRUSS_Z0_M + BAY_M / 2  # front ORUs are centred on the bay's height

# ------------------------------------------------------------------------------------------ layouts

KINDS = ("electrical_oru", "tank_oru", "solar_panel", "tubing_oru")
# The faces the arm on its rail can see (seed §3: the robot works on the front face; the panel faces up)
FACES = {"front": ("electrical_oru", "tank_oru", "tubing_oru"), "top": ("solar_panel",)}
HINGES = ("left", "right")
ROTATIONS_DEG = (0, 90)  # a box part keeps its own axes: quarter turns of the panel about its normal
MAX_BAYS = 8


@dataclass(frozen=True)
class Placement:
    """Where one component goes on the truss.

    Attributes
    ----------
    kind : {"electrical_oru", "tank_oru", "solar_panel", "tubing_oru"}
        What it is (seed §4: A, B, C, D).
    letter : str
        One capital letter: the prefix of its part, site and vista names (``"A"`` -> ``"A_door"``).
    bay : int
        Bay index from x = 0; the component is centred on the bay.
    face : {"front", "top"}
        ORUs hang on the front face (y < 0), the solar panel stands on the top.
    rotation_deg : {0, 90}
        Turn about the face normal (the panel's long side along x at 0, along y at 90).
    hinge : {"left", "right"}
        Electrical ORU only: the door edge that holds the hinge, seen from the front. "right" mirrors the
        whole ORU (pocket on the right, Kapton circles on the left), so the door opens the other way.
    """

    kind: str
    letter: str
    bay: int
    face: str = "front"
    rotation_deg: int = 0
    hinge: str = "left"

    def __post_init__(self) -> None:
        v.choice(self.kind, "kind", KINDS)
        if not isinstance(self.letter, str) or len(self.letter) != 1 or not "A" <= self.letter <= "Z":
            raise InputError(f"letter must be one capital letter, e.g. 'E'; got {self.letter!r}.")
        object.__setattr__(self, "bay", v.positive_int(self.bay, "bay", minimum=0))
        face = v.choice(self.face, "face", FACES)
        if self.kind not in FACES[face]:
            where = next(name for name, kinds in FACES.items() if self.kind in kinds)
            raise InputError(f"a {self.kind} goes on the {where!r} face; got face={face!r}.")
        if self.rotation_deg not in ROTATIONS_DEG or (self.rotation_deg and self.kind != "solar_panel"):
            raise InputError(
                f"rotation_deg={self.rotation_deg!r} is not possible for a {self.kind}: the panel turns by "
                f"one of {ROTATIONS_DEG} deg, the ORUs stand upright (0)."
            )
        v.choice(self.hinge, "hinge", HINGES)
        if self.hinge != "left" and self.kind != "electrical_oru":
            raise InputError(
                f"hinge={self.hinge!r} is for the electrical ORU's door; a {self.kind} has none."
            )


@dataclass(frozen=True)
class Layout:
    """An arrangement of the mock-up's components on a truss of `bays` bays.

    Attributes
    ----------
    name : str
        The layout's name.
    bays : int
        Number of bays (1..MAX_BAYS), each BAY_M long.
    placements : tuple of Placement
        One electrical ORU (the door) and any tank, panel and tubing components, at most one per bay face.
    """

    name: str
    bays: int
    placements: tuple[Placement, ...]

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"name must be a non-empty string; got {self.name!r}.")
        bays = v.positive_int(self.bays, "bays")
        if bays > MAX_BAYS:
            raise InputError(f"bays must be at most {MAX_BAYS}; got {bays}.")
        if not isinstance(self.placements, tuple) or not all(
            isinstance(item, Placement) for item in self.placements
        ):
            raise InputError(f"placements must be a tuple of Placement; got {self.placements!r}.")
        for item in self.placements:
            if item.bay >= bays:
                raise InputError(f"{item.letter} is on bay {item.bay}, but the truss has bays 0-{bays - 1}.")
        for label, keys in (
            ("letter", [item.letter for item in self.placements]),
            ("bay face", [(item.bay, item.face) for item in self.placements]),
        ):
            if len(set(keys)) != len(keys):
                raise InputError(
                    f"two placements share a {label} in layout {self.name!r}; give each its own."
                )
        doors = sum(item.kind == "electrical_oru" for item in self.placements)
        if doors != 1:
            raise InputError(
                f"layout {self.name!r} has {doors} electrical ORUs; it needs exactly one (the door)."
            )


LAYOUTS: dict[str, Layout] = {
    # seed §4, Fig. 8
    "truss": Layout(
        "truss",
        3,
        (
            Placement("electrical_oru", "A", 0),
            Placement("tank_oru", "B", 1),
            Placement("solar_panel", "C", 2, "top"),
            Placement("tubing_oru", "D", 2),
        ),
    ),
    # issue 15: the same kinds arranged differently, to show that nothing in the mission is fitted to one
    "truss-b": Layout(
        "truss-b",
        4,
        (
            Placement("tubing_oru", "D", 0),
            Placement("tank_oru", "B", 1),
            Placement("solar_panel", "C", 1, "top", rotation_deg=90),
            Placement("electrical_oru", "A", 2, hinge="right"),
            Placement("tubing_oru", "E", 3),
        ),
    ),
}
LAYOUT_NAMES = tuple(LAYOUTS)


@dataclass
class _Piece:
    """What one placed component adds to the mock-up."""

    parts: list[Part]
    patches: list[Surface]
    screws: list[Site]
    components: dict[str, tuple[str, ...]]
    component_sites: list[Site]
    dent_patches: dict[str, tuple[Surface, ...]]
    vistas: list[Vista]
    peltier: list[Site] = field(default_factory=list)
    leaks: list[Site] = field(default_factory=list)
    door: Door | None = None


def _bay_centre_x(bay: int) -> float:
    return _at((bay + 0.5) * BAY_M)


def _at(x: float) -> float:
    # layout sums land on the nearest double of the seed's decimal dimensions (0.9, not 0.8999999999999999)
    return round(x, 12)


def _screw_sites(
    prefix: str, xs: tuple[float, ...], y: float, zs: tuple[float, ...], surface: str
) -> list[Site]:
    return [
        Site(f"screw_{prefix}_{i}", vector3(x, y, z), _FRONT, surface, 2 * SCREW_RADIUS_M)
        for i, (x, z) in enumerate((x, z) for x in xs for z in zs)
    ]


def _oru_a(place: Placement) -> _Piece:
    """Electrical ORU (A): body, door pocket with connectors and cold plate, Kapton circles."""
    name = place.letter
    hand = 1.0 if place.hinge == "left" else -1.0  # "right" mirrors the ORU about its centre

    def x(offset: float) -> float:
        return _at(centre + hand * offset)

    back, front, face = _MOUNT_Y_M, _MOUNT_Y_M - 0.14, A_FACE_Y_M  # pocket 20 mm deep
    centre, cz = _bay_centre_x(place.bay), _CZ_M
    parts = [
        Part(
            f"{name}_body",
            name,
            "box",
            (0.17, 0.07, 0.14),
            vector3(centre, (back + front) / 2, cz),
            "aluminium",
        )
    ]
    # the pocket's rim on the hinge side; the other half is filled flush with the face
    x0, z0, z1 = x(-0.15), cz - 0.11, cz + 0.11  # hinge edge; the pocket spans x(-0.15)..x(-0.01)
    mid, rim_y = x(-0.08), (front + face) / 2
    parts += [
        Part(f"{name}_rim_left", name, "box", (0.01, 0.01, 0.14), vector3(x(-0.16), rim_y, cz), "aluminium"),
        Part(
            f"{name}_rim_bottom",
            name,
            "box",
            (0.07, 0.01, 0.015),
            vector3(mid, rim_y, z0 - 0.015),
            "aluminium",
        ),
        Part(
            f"{name}_rim_top", name, "box", (0.07, 0.01, 0.015), vector3(mid, rim_y, z1 + 0.015), "aluminium"
        ),
        Part(f"{name}_fill", name, "box", (0.09, 0.01, 0.14), vector3(x(0.08), rim_y, cz), "aluminium"),
        Part(
            f"{name}_cold_plate",
            name,
            "box",
            (0.055, 0.002, 0.06),
            vector3(mid, front - 0.002, cz + 0.03),
            "cold_plate",
        ),
    ]
    for k, dx in enumerate((-0.12, -0.09, -0.06, -0.03)):
        parts.append(
            Part(
                f"{name}_connector_{k}",
                name,
                "cylinder",
                (0.009, 0.007),
                vector3(x(dx), front - 0.007, cz - 0.07),
                "connector",
                _FRONT,
            )
        )
    door = Door(
        f"{name}_door",
        f"{name}_door_hinge",
        vector3(x0, face - 0.002, cz),
        vector3(0.0, 0.0, -hand),  # hinge on the left: -z; on the right: +z (both swing out to -y)
        f"{name}_door",
    )
    parts.append(
        Part(door.body, door.body, "box", (0.07, 0.002, 0.11), vector3(mid, face - 0.002, cz), "aluminium")
    )
    parts.append(
        Part(
            f"{name}_door_handle",
            door.body,
            "box",
            (0.004, 0.006, 0.025),
            vector3(x(-0.025), face - 0.01, cz),
            "connector",
        )
    )
    peltier: list[Site] = []
    for k, (kx, z) in enumerate((kx, z) for z in (cz + 0.06, cz - 0.06) for kx in (x(0.04), x(0.12))):
        parts.append(
            Part(
                f"{name}_kapton_{k}",
                name,
                "cylinder",
                (KAPTON_RADIUS_M, KAPTON_THICKNESS_M / 2),
                vector3(kx, face - KAPTON_THICKNESS_M / 2, z),
                "kapton",
                _FRONT,
            )
        )
        peltier.append(
            Site(
                f"peltier_{k}",
                vector3(kx, face - KAPTON_THICKNESS_M, z),
                _FRONT,
                "kapton",
                2 * KAPTON_RADIUS_M,
            )
        )
    fill_x = x(0.08)
    patches: list[Surface] = [
        # above and below the Kapton circles, so that a planted spot is never hidden under one
        Patch(
            f"{name}_face_upper",
            vector3(fill_x, face, cz + 0.1125),
            _FRONT,
            (1, 0, 0),
            (0.085, 0.0225),
            "oru_face",
        ),
        Patch(
            f"{name}_face_lower",
            vector3(fill_x, face, cz - 0.1125),
            _FRONT,
            (1, 0, 0),
            (0.085, 0.0225),
            "oru_face",
        ),
        Patch(f"{name}_door_face", vector3(mid, face - 0.004, cz), _FRONT, (1, 0, 0), (0.065, 0.105), "door"),
    ]
    # the square inside each Kapton circle (issue 13: impacts on the Kapton too)
    half = KAPTON_RADIUS_M / np.sqrt(2.0)
    patches += [
        Patch(f"{name}_kapton_patch_{k}", site.position_m, _FRONT, (1, 0, 0), (half, half), "kapton")
        for k, site in enumerate(peltier)
    ]
    site = f"{name}_oru"
    return _Piece(
        parts=parts,
        patches=patches,
        screws=_screw_sites(name, (x(-0.145), x(0.145)), face, (cz - 0.125, cz + 0.125), "oru_face"),
        # the first part of a component is the one a defect marks: the fill plate, whose face a camera sees
        # (its body's front lies behind the fill and the door: the hidden-dent fault of issue 13)
        components={site: (f"{name}_fill", f"{name}_body")},
        component_sites=[Site(site, vector3(centre, face, cz), _FRONT, "oru_face", 0.34)],
        # the fill plate's middle, between the Kapton circles: the seed mock-up's centred defect
        dent_patches={
            site: (
                Patch(
                    f"{name}_fill_face",
                    vector3(fill_x, face, cz),
                    _FRONT,
                    (1, 0, 0),
                    (0.09, 0.14),
                    "oru_face",
                ),
            )
        },
        vistas=[
            vista(door.vista, vector3(mid, face, cz), _FRONT, _UP, VISTA_STANDOFF_M),
            vista(f"{name}_kapton", vector3(fill_x, face, cz), _FRONT, _UP, VISTA_STANDOFF_M),
        ],
        peltier=peltier,
        door=door,
    )


def _oru_b(place: Placement) -> _Piece:
    """Tank ORU (B): base plate, horizontal tank, two straps."""
    name = place.letter
    cx, cz, plate = _bay_centre_x(place.bay), _CZ_M, _MOUNT_Y_M - 0.01
    tank_y = plate - 0.01 - 0.075
    parts = [
        Part(f"{name}_plate", name, "box", (0.2, 0.01, 0.14), vector3(cx, plate, cz), "plate"),
        Part(
            f"{name}_tank",
            name,
            "capsule",
            (0.07, 0.12),
            vector3(cx, tank_y, cz),
            "aluminium",
            (1.0, 0.0, 0.0),
        ),
    ]
    for k, x in enumerate((_at(cx - 0.08), _at(cx + 0.08))):
        parts.append(
            Part(
                f"{name}_strap_{k}",
                name,
                "cylinder",
                (0.0715, 0.006),
                vector3(x, tank_y, cz),
                "connector",
                (1.0, 0.0, 0.0),
            )
        )
    patches: list[Surface] = [
        Patch(
            f"{name}_plate_top",
            vector3(cx, plate - 0.01, cz + 0.11),
            _FRONT,
            (1, 0, 0),
            (0.18, 0.02),
            "plate",
        ),
        Patch(
            f"{name}_plate_bottom",
            vector3(cx, plate - 0.01, cz - 0.11),
            _FRONT,
            (1, 0, 0),
            (0.18, 0.02),
            "plate",
        ),
    ]
    # the tank's round skin between and beside the straps (a spot under a strap would be hidden)
    for part_name, (start, end) in (
        (f"{name}_tank_left", (-0.12, -0.088)),
        (f"{name}_tank_mid", (-0.072, 0.072)),
        (f"{name}_tank_right", (0.088, 0.12)),
    ):
        patches.append(
            CylinderPatch(
                part_name,
                vector3(_at(cx + (start + end) / 2), tank_y, cz),
                (1.0, 0.0, 0.0),
                _FRONT,
                0.07,
                (end - start) / 2,
                SKIN_HALF_ANGLE_RAD,
                "tank",
            )
        )
    site, target = f"{name}_tank", vector3(cx, _PLATE_FACE_Y_M - 0.15, cz)
    return _Piece(
        parts=parts,
        patches=patches,
        screws=_screw_sites(
            name, (_at(cx - 0.18), _at(cx + 0.18)), _PLATE_FACE_Y_M, (cz - 0.12, cz + 0.12), "plate"
        ),
        components={site: (f"{name}_tank",)},
        component_sites=[Site(site, target, _FRONT, "tank", 0.38)],
        dent_patches={site: (patches[3],)},  # the tank's front between its straps
        vistas=[vista(f"{name}_tank", target, _FRONT, _UP, VISTA_STANDOFF_M)],
    )


def _panel_c(place: Placement) -> _Piece:
    """Solar panel (C) on four posts over the top face of a bay, its long side along x (or y, turned)."""
    name = place.letter
    cx, top = _bay_centre_x(place.bay), TRUSS_Z0_M + BAY_M + STRUT_RADIUS_M
    surface_z = top + 0.06 + 0.006
    turned = place.rotation_deg == 90

    def xy(dx: float, dy: float) -> tuple[float, float]:  # a quarter turn about +z: (dx, dy) -> (-dy, dx)
        return (_at(cx - dy), dx) if turned else (_at(cx + dx), dy)

    def axes(a: float, b: float) -> tuple[float, float]:
        return (b, a) if turned else (a, b)

    parts = [
        Part(
            f"{name}_panel",
            name,
            "box",
            (*axes(0.26, 0.2), 0.006),
            vector3(*xy(0.0, 0.0), top + 0.06),
            "solar_cell",
        )
    ]
    for k, (dx, dy) in enumerate((dx, dy) for dx in (-0.22, 0.22) for dy in (-0.16, 0.16)):
        parts.append(
            Part(
                f"{name}_post_{k}",
                name,
                "cylinder",
                (0.008, 0.027),
                vector3(*xy(dx, dy), top + 0.027),
                "aluminium",
            )
        )
    screws = [
        Site(f"screw_{name}_{k}", vector3(*xy(dx, dy), surface_z), _UP, "panel", 2 * SCREW_RADIUS_M)
        for k, (dx, dy) in enumerate((dx, dy) for dx in (-0.245, 0.245) for dy in (-0.185, 0.185))
    ]
    long_side = (0, 1, 0) if turned else (1, 0, 0)
    cells = Patch(f"{name}_cells", vector3(*xy(0.0, 0.0), surface_z), _UP, long_side, (0.23, 0.17), "panel")
    site = f"{name}_panel"
    # straight down, image up towards the back, on either turn (the turned panel's long side runs up the
    # image); beyond the reach of the arm on its rail (issue 5: the plan flags such views)
    look = vista(site, cells.centre_m, _UP, (0.0, 1.0, 0.0), VISTA_STANDOFF_M)
    return _Piece(
        parts=parts,
        patches=[cells],
        screws=screws,
        components={site: (f"{name}_panel",)},
        component_sites=[Site(site, cells.centre_m, _UP, "panel", 0.52)],
        dent_patches={site: (cells,)},
        vistas=[look],
    )


def _oru_d(place: Placement, first_leak: int) -> _Piece:
    """Tank-and-tubing ORU (D): two upright tanks, tubing, three leak holes (numbered from `first_leak`)."""
    name = place.letter
    cx, cz, plate = _bay_centre_x(place.bay), _CZ_M, _MOUNT_Y_M - 0.01
    tank_y, tube_y, tube_r = plate - 0.01 - 0.05, plate - 0.01 - 0.05, 0.008
    left, right = _at(cx - 0.1), _at(cx + 0.1)
    parts = [Part(f"{name}_plate", name, "box", (0.2, 0.01, 0.14), vector3(cx, plate, cz), "plate")]
    for k, x in enumerate((left, right)):
        parts.append(
            Part(f"{name}_tank_{k}", name, "cylinder", (0.045, 0.075), vector3(x, tank_y, cz), "aluminium")
        )
    high, low = cz + 0.11, cz - 0.11
    tubes = [
        (f"{name}_tube_high", (left, high), (right, high)),
        (f"{name}_tube_low", (left, low), (right, low)),
        (f"{name}_riser_0", (left, cz + 0.075), (left, high)),
        (f"{name}_riser_1", (right, cz + 0.075), (right, high)),
        (f"{name}_drop_0", (left, cz - 0.075), (left, low)),
        (f"{name}_drop_1", (right, cz - 0.075), (right, low)),
    ]
    for tube, (xa, za), (xb, zb) in tubes:
        axis = np.array([xb - xa, 0.0, zb - za])
        parts.append(
            Part(
                tube,
                name,
                "capsule",
                (tube_r, float(np.linalg.norm(axis)) / 2),
                vector3(_at((xa + xb) / 2), tube_y, (za + zb) / 2),
                "aluminium",
                _unit(axis),
            )
        )
    # seed §4: three holes on the tubing from which an ammonia mist may spray
    holes = ((_at(cx - 0.04), high), (_at(cx + 0.04), high), (cx, low))
    leaks = [
        Site(
            f"leak_{first_leak + k}", vector3(x, tube_y - tube_r, z), _FRONT, "tubing", 2 * LEAK_HOLE_RADIUS_M
        )
        for k, (x, z) in enumerate(holes)
    ]
    patches: list[Surface] = [
        Patch(f"{name}_plate_centre", vector3(cx, plate - 0.01, cz), _FRONT, (1, 0, 0), (0.04, 0.06), "plate")
    ]
    skins = [
        CylinderPatch(
            f"{name}_tank_{k}_skin",
            vector3(x, tank_y, cz),
            _UP,
            _FRONT,
            0.045,
            0.07,
            SKIN_HALF_ANGLE_RAD,
            "tank",
        )
        for k, x in enumerate((left, right))
    ]
    patches += skins
    # the two horizontal tubes, clear of the risers at their ends; +-50 deg of a 16 mm tube
    patches += [
        CylinderPatch(
            f"{tube}_skin", vector3(cx, tube_y, z), (1.0, 0.0, 0.0), _FRONT, tube_r, 0.09, 0.87, "tubing"
        )
        for tube, z in ((f"{name}_tube_high", high), (f"{name}_tube_low", low))
    ]
    site = f"{name}_tank_0"
    return _Piece(
        parts=parts,
        patches=patches,
        screws=_screw_sites(
            name, (_at(cx - 0.18), _at(cx + 0.18)), _PLATE_FACE_Y_M, (cz - 0.12, cz, cz + 0.12), "plate"
        ),
        components={site: (f"{name}_tank_0",)},
        component_sites=[Site(site, vector3(left, _PLATE_FACE_Y_M - 0.1, cz), _FRONT, "tank", 0.15)],
        # a dent's rim may reach round to the tank's sides: the window is the whole front half
        dent_patches={site: (replace(skins[0], half_angle_rad=np.pi / 2),)},
        vistas=[
            vista(f"{name}_tubing", vector3(cx, _PLATE_FACE_Y_M - 0.05, cz), _FRONT, _UP, VISTA_STANDOFF_M)
        ],
        leaks=leaks,
    )


def _screw_parts(site: Site) -> list[Part]:
    """A screw head standing on the surface along its normal, with a dark slot across it."""
    position, normal = np.asarray(site.position_m), np.asarray(site.normal)
    head = position + normal * SCREW_HEIGHT_M / 2
    slot = position + normal * (SCREW_HEIGHT_M + 1e-4)
    slot_half = (
        (SCREW_RADIUS_M * 0.9, 4e-4, 1e-4) if abs(normal[2]) > 0.5 else (SCREW_RADIUS_M * 0.9, 1e-4, 4e-4)
    )
    return [
        Part(
            site.name,
            site.name,
            "cylinder",
            (SCREW_RADIUS_M, SCREW_HEIGHT_M / 2),
            vector3(*head),
            "screw",
            site.normal,
        ),
        Part(f"{site.name}_slot", site.name, "box", slot_half, vector3(*slot), "hole"),
    ]


def _pieces(layout: Layout) -> list[_Piece]:
    pieces: list[_Piece] = []
    for place in layout.placements:
        if place.kind == "electrical_oru":
            pieces.append(_oru_a(place))
        elif place.kind == "tank_oru":
            pieces.append(_oru_b(place))
        elif place.kind == "solar_panel":
            pieces.append(_panel_c(place))
        else:
            pieces.append(_oru_d(place, first_leak=sum(len(piece.leaks) for piece in pieces)))
    return pieces


def build_mockup(layout: Layout) -> Mockup:
    """Build the mock-up a :class:`Layout` describes (deterministic: anomalies are drawn later, from a seed).

    Raises InputError for something other than a Layout.
    """
    if not isinstance(layout, Layout):
        raise InputError(f"layout must be an rsi.sim.mockup.Layout; got {type(layout).__name__}.")
    pieces = _pieces(layout)
    parts = _truss(layout.bays) + [part for piece in pieces for part in piece.parts]
    # screws on the front ORUs first, then on the panel (the seed mock-up's order)
    faces = [place.face for place in layout.placements]
    screws = [
        site
        for face in FACES
        for piece, on in zip(pieces, faces, strict=True)
        if on == face
        for site in piece.screws
    ]
    for site in screws:
        parts += _screw_parts(site)
    candidates = Candidates(
        peltier_sites=tuple(site for piece in pieces for site in piece.peltier),
        leak_sites=tuple(site for piece in pieces for site in piece.leaks),
        screw_sites=tuple(screws),
        impact_patches=tuple(patch for piece in pieces for patch in piece.patches),
        component_sites=tuple(site for piece in pieces for site in piece.component_sites),
        dent_patches={key: value for piece in pieces for key, value in piece.dent_patches.items()},
    )
    length = BAY_M * layout.bays
    centre = vector3(_at(length / 2), 0.0, _CZ_M)
    vistas = [item for piece in pieces for item in piece.vistas]
    # the whole mock-up from the front, a little to the left and above (3.4 m: four bays still fit the frame)
    vistas.append(vista("overview", centre, _unit(np.array([-0.1, -1.0, 0.45])), _UP, 3.4))
    door = next(piece.door for piece in pieces if piece.door is not None)
    kapton = next(piece.vistas[1].name for piece in pieces if piece.door is not None)
    tubings = [piece for piece in pieces if piece.leaks]
    return Mockup(
        parts=tuple(parts),
        door=door,
        candidates=candidates,
        vistas={item.name: item for item in vistas},
        components={key: value for piece in pieces for key, value in piece.components.items()},
        layout=layout.name,
        length_m=length,
        instrument_vistas={"pyrometer": (kapton,), "gas": tuple(piece.vistas[0].name for piece in tubings)},
        tubing_leaks=tuple(tuple(site.name for site in piece.leaks) for piece in tubings),
    )


def mockup(layout: str = "truss") -> Mockup:
    """The mock-up of a named layout (:data:`LAYOUT_NAMES`): ``"truss"`` is seed §4, Fig. 8.

    Returns
    -------
    Mockup
        Parts, door, anomaly candidates (on "truss": 4 Peltier sites, 3 leak sites, 18 screws, impact
        patches and 4 swappable components) and vistas. InputError names the layouts for another name.
    """
    return build_mockup(LAYOUTS[v.choice(layout, "layout", LAYOUTS)])


def truss_mockup() -> Mockup:
    """The seed mock-up (seed §4, Fig. 8): ``mockup("truss")``."""
    return mockup("truss")
