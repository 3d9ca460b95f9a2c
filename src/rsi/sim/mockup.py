"""Seed §4, Fig. 8: geometry of the one-third-scale Space Station truss mock-up, in metres (pure data).

World frame: x along the truss, y from the front face (y < 0, where the inspection robot works) to the back,
z up. Three square bays of ``BAY_M`` = 0.6 m (one third of a ~1.8 m station truss bay) span x = 0..1.8 m;
the square section spans y = -0.3..0.3 m and z = 0.9..1.5 m. The components carry the seed's letters:

- **A** electrical ORU on the front of bay 0: a hinged door (hinge on its left edge, axis -z so a positive
  angle swings it out towards -y) over a pocket holding four connectors and a cold plate; four black Kapton
  circles over the Peltier modules (seed §4: "a circle of Black Kapton" so the pyrometer reads the
  temperature of the low-emissivity aluminium skin).
- **B** tank ORU on the front of bay 1: a horizontal tank on a base plate with two straps.
- **C** solar panel on top of bay 2, on four posts.
- **D** tank-and-tubing ORU on the front of bay 2: two tanks joined by tubing with three leak holes.
- Screws on every ORU plate and on the panel frame.

Nothing here imports MuJoCo: :mod:`rsi.sim.scene` turns :func:`truss_mockup` into MJCF.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.anomalies import Candidates, CylinderPatch, Patch, Site, Surface

Vector3 = tuple[float, float, float]

BAY_M = 0.6  # bay length and section side
BAYS = 3
TRUSS_Z0_M = 0.9  # bottom longerons
STRUT_RADIUS_M = 0.012
NODE_RADIUS_M = 0.028
SCREW_RADIUS_M = 0.004
SCREW_HEIGHT_M = 0.002
KAPTON_RADIUS_M = 0.025
KAPTON_THICKNESS_M = 5e-4
LEAK_HOLE_RADIUS_M = 1.5e-3
VISTA_STANDOFF_M = 0.5  # seed §2.1: a ~0.1 m^2 scene at a typical inspection standoff
DOOR_HINGE_AXIS = (0.0, 0.0, -1.0)
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
class Mockup:
    """The mock-up: parts, the door hinge, anomaly candidates and vista points.

    Attributes
    ----------
    parts : tuple of Part
        Every primitive, screws included.
    door_hinge_m : (float, float, float)
        A point on the door hinge axis (:data:`DOOR_HINGE_AXIS`).
    candidates : Candidates
        Places where :func:`rsi.sim.anomalies.seed_anomalies` may plant anomalies.
    vistas : dict of str to Vista
        Named viewpoints, one or two per component, plus ``"overview"`` (the whole mock-up, 3.4 m away).
    components : dict of str to tuple of str
        Part names of each swappable component site (``"B_tank"``, ...).
    """

    parts: tuple[Part, ...]
    door_hinge_m: Vector3
    candidates: Candidates
    vistas: dict[str, Vista]
    components: dict[str, tuple[str, ...]]


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


def _truss() -> list[Part]:
    """Longerons, battens, face diagonals and corner nodes of the square truss."""
    parts: list[Part] = []
    corners = [(y, z) for y in (-BAY_M / 2, BAY_M / 2) for z in (TRUSS_Z0_M, TRUSS_Z0_M + BAY_M)]
    length = BAY_M * BAYS

    def strut(name: str, start: np.ndarray, end: np.ndarray) -> Part:
        centre, axis = (start + end) / 2, end - start
        half = float(np.linalg.norm(axis)) / 2
        return Part(
            name, "truss", "cylinder", (STRUT_RADIUS_M, half), vector3(*centre), "aluminium", _unit(axis)
        )

    for k, (y, z) in enumerate(corners):
        parts.append(strut(f"longeron_{k}", np.array([0.0, y, z]), np.array([length, y, z])))
    square = [corners[0], corners[1], corners[3], corners[2]]  # around the section
    for bay in range(BAYS + 1):
        x = bay * BAY_M
        for k in range(4):
            (y0, z0), (y1, z1) = square[k], square[(k + 1) % 4]
            parts.append(strut(f"batten_{bay}_{k}", np.array([x, y0, z0]), np.array([x, y1, z1])))
            parts.append(
                Part(f"node_{bay}_{k}", "truss", "sphere", (NODE_RADIUS_M,), vector3(x, y0, z0), "aluminium")
            )
    for bay in range(BAYS):
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


def _screw_sites(
    prefix: str, xs: tuple[float, ...], y: float, zs: tuple[float, ...], surface: str
) -> list[Site]:
    return [
        Site(f"screw_{prefix}_{i}", vector3(x, y, z), _FRONT, surface, 2 * SCREW_RADIUS_M)
        for i, (x, z) in enumerate((x, z) for x in xs for z in zs)
    ]


def _oru_a() -> tuple[list[Part], list[Site], list[Surface], Vector3]:
    """Electrical ORU (A): body, door pocket with connectors and cold plate, Kapton circles."""
    back, front, face = _MOUNT_Y_M, _MOUNT_Y_M - 0.14, A_FACE_Y_M  # pocket 20 mm deep
    cx, cz = 0.3, TRUSS_Z0_M + BAY_M / 2
    parts = [Part("A_body", "A", "box", (0.17, 0.07, 0.14), vector3(cx, (back + front) / 2, cz), "aluminium")]
    # the pocket's rim on the left half; the right half is filled flush with the face
    x0, x1, z0, z1 = 0.15, 0.29, cz - 0.11, cz + 0.11
    rim_y = (front + face) / 2
    parts += [
        Part("A_rim_left", "A", "box", (0.01, 0.01, 0.14), vector3(x0 - 0.01, rim_y, cz), "aluminium"),
        Part(
            "A_rim_bottom",
            "A",
            "box",
            ((x1 - x0) / 2, 0.01, 0.015),
            vector3((x0 + x1) / 2, rim_y, z0 - 0.015),
            "aluminium",
        ),
        Part(
            "A_rim_top",
            "A",
            "box",
            ((x1 - x0) / 2, 0.01, 0.015),
            vector3((x0 + x1) / 2, rim_y, z1 + 0.015),
            "aluminium",
        ),
        Part("A_fill", "A", "box", (0.09, 0.01, 0.14), vector3(0.38, rim_y, cz), "aluminium"),
        Part(
            "A_cold_plate",
            "A",
            "box",
            (0.055, 0.002, 0.06),
            vector3(0.22, front - 0.002, cz + 0.03),
            "cold_plate",
        ),
    ]
    for k, x in enumerate((0.18, 0.21, 0.24, 0.27)):
        parts.append(
            Part(
                f"A_connector_{k}",
                "A",
                "cylinder",
                (0.009, 0.007),
                vector3(x, front - 0.007, cz - 0.07),
                "connector",
                _FRONT,
            )
        )
    hinge = vector3(x0, face - 0.002, cz)
    parts.append(
        Part(
            "A_door",
            "A_door",
            "box",
            (0.07, 0.002, 0.11),
            vector3((x0 + x1) / 2, face - 0.002, cz),
            "aluminium",
        )
    )
    parts.append(
        Part(
            "A_door_handle",
            "A_door",
            "box",
            (0.004, 0.006, 0.025),
            vector3(x1 - 0.015, face - 0.01, cz),
            "connector",
        )
    )
    peltier: list[Site] = []
    for k, (x, z) in enumerate((x, z) for z in (cz + 0.06, cz - 0.06) for x in (0.34, 0.42)):
        parts.append(
            Part(
                f"A_kapton_{k}",
                "A",
                "cylinder",
                (KAPTON_RADIUS_M, KAPTON_THICKNESS_M / 2),
                vector3(x, face - KAPTON_THICKNESS_M / 2, z),
                "kapton",
                _FRONT,
            )
        )
        peltier.append(
            Site(
                f"peltier_{k}",
                vector3(x, face - KAPTON_THICKNESS_M, z),
                _FRONT,
                "kapton",
                2 * KAPTON_RADIUS_M,
            )
        )
    patches: list[Surface] = [
        # above and below the Kapton circles, so that a planted spot is never hidden under one
        Patch(
            "A_face_upper", vector3(0.38, face, cz + 0.1125), _FRONT, (1, 0, 0), (0.085, 0.0225), "oru_face"
        ),
        Patch(
            "A_face_lower", vector3(0.38, face, cz - 0.1125), _FRONT, (1, 0, 0), (0.085, 0.0225), "oru_face"
        ),
        Patch(
            "A_door_face",
            vector3((x0 + x1) / 2, face - 0.004, cz),
            _FRONT,
            (1, 0, 0),
            (0.065, 0.105),
            "door",
        ),
    ]
    # the square inside each Kapton circle (issue 13: impacts on the Kapton too)
    half = KAPTON_RADIUS_M / np.sqrt(2.0)
    patches += [
        Patch(f"A_kapton_patch_{k}", site.position_m, _FRONT, (1, 0, 0), (half, half), "kapton")
        for k, site in enumerate(peltier)
    ]
    return parts, peltier, patches, hinge


def _oru_b() -> tuple[list[Part], list[Surface]]:
    """Tank ORU (B): base plate, horizontal tank, two straps."""
    cx, cz, plate = 0.9, TRUSS_Z0_M + BAY_M / 2, _MOUNT_Y_M - 0.01
    tank_y = plate - 0.01 - 0.075
    parts = [
        Part("B_plate", "B", "box", (0.2, 0.01, 0.14), vector3(cx, plate, cz), "aluminium"),
        Part("B_tank", "B", "capsule", (0.07, 0.12), vector3(cx, tank_y, cz), "aluminium", (1.0, 0.0, 0.0)),
    ]
    for k, x in enumerate((cx - 0.08, cx + 0.08)):
        parts.append(
            Part(
                f"B_strap_{k}",
                "B",
                "cylinder",
                (0.0715, 0.006),
                vector3(x, tank_y, cz),
                "connector",
                (1.0, 0.0, 0.0),
            )
        )
    patches: list[Surface] = [
        Patch("B_plate_top", vector3(cx, plate - 0.01, cz + 0.11), _FRONT, (1, 0, 0), (0.18, 0.02), "plate"),
        Patch(
            "B_plate_bottom", vector3(cx, plate - 0.01, cz - 0.11), _FRONT, (1, 0, 0), (0.18, 0.02), "plate"
        ),
    ]
    # the tank's round skin between and beside the straps (a spot under a strap would be hidden)
    for name, (start, end) in (
        ("B_tank_left", (cx - 0.12, cx - 0.088)),
        ("B_tank_mid", (cx - 0.072, cx + 0.072)),
        ("B_tank_right", (cx + 0.088, cx + 0.12)),
    ):
        patches.append(
            CylinderPatch(
                name,
                vector3((start + end) / 2, tank_y, cz),
                (1.0, 0.0, 0.0),
                _FRONT,
                0.07,
                (end - start) / 2,
                SKIN_HALF_ANGLE_RAD,
                "tank",
            )
        )
    return parts, patches


def _panel_c() -> tuple[list[Part], list[Site], list[Surface]]:
    """Solar panel (C) on four posts over the top face of bay 2."""
    cx, top = 1.5, TRUSS_Z0_M + BAY_M + STRUT_RADIUS_M
    surface_z = top + 0.06 + 0.006
    parts = [Part("C_panel", "C", "box", (0.26, 0.2, 0.006), vector3(cx, 0.0, top + 0.06), "solar_cell")]
    for k, (x, y) in enumerate((x, y) for x in (cx - 0.22, cx + 0.22) for y in (-0.16, 0.16)):
        parts.append(
            Part(f"C_post_{k}", "C", "cylinder", (0.008, 0.027), vector3(x, y, top + 0.027), "aluminium")
        )
    screws = [
        Site(f"screw_C_{k}", vector3(x, y, surface_z), _UP, "panel", 2 * SCREW_RADIUS_M)
        for k, (x, y) in enumerate((x, y) for x in (cx - 0.245, cx + 0.245) for y in (-0.185, 0.185))
    ]
    patches: list[Surface] = [
        Patch("C_cells", vector3(cx, 0.0, surface_z), _UP, (1, 0, 0), (0.23, 0.17), "panel")
    ]
    return parts, screws, patches


def _oru_d() -> tuple[list[Part], list[Site], list[Surface]]:
    """Tank-and-tubing ORU (D): two upright tanks, tubing, three leak holes."""
    cx, cz, plate = 1.5, TRUSS_Z0_M + BAY_M / 2, _MOUNT_Y_M - 0.01
    tank_y, tube_y, tube_r = plate - 0.01 - 0.05, plate - 0.01 - 0.05, 0.008
    parts = [Part("D_plate", "D", "box", (0.2, 0.01, 0.14), vector3(cx, plate, cz), "aluminium")]
    for k, x in enumerate((cx - 0.1, cx + 0.1)):
        parts.append(
            Part(f"D_tank_{k}", "D", "cylinder", (0.045, 0.075), vector3(x, tank_y, cz), "aluminium")
        )
    high, low = cz + 0.11, cz - 0.11
    tubes = [
        ("D_tube_high", (cx - 0.1, high), (cx + 0.1, high)),
        ("D_tube_low", (cx - 0.1, low), (cx + 0.1, low)),
        ("D_riser_0", (cx - 0.1, cz + 0.075), (cx - 0.1, high)),
        ("D_riser_1", (cx + 0.1, cz + 0.075), (cx + 0.1, high)),
        ("D_drop_0", (cx - 0.1, cz - 0.075), (cx - 0.1, low)),
        ("D_drop_1", (cx + 0.1, cz - 0.075), (cx + 0.1, low)),
    ]
    for name, (xa, za), (xb, zb) in tubes:
        axis = np.array([xb - xa, 0.0, zb - za])
        parts.append(
            Part(
                name,
                "D",
                "capsule",
                (tube_r, float(np.linalg.norm(axis)) / 2),
                vector3((xa + xb) / 2, tube_y, (za + zb) / 2),
                "aluminium",
                _unit(axis),
            )
        )
    # seed §4: three holes on the tubing from which an ammonia mist may spray
    leaks = [
        Site(f"leak_{k}", vector3(x, tube_y - tube_r, z), _FRONT, "tubing", 2 * LEAK_HOLE_RADIUS_M)
        for k, (x, z) in enumerate(((cx - 0.04, high), (cx + 0.04, high), (cx, low)))
    ]
    patches: list[Surface] = [
        Patch("D_plate_centre", vector3(cx, plate - 0.01, cz), _FRONT, (1, 0, 0), (0.04, 0.06), "plate")
    ]
    patches += [
        CylinderPatch(
            f"D_tank_{k}_skin", vector3(x, tank_y, cz), _UP, _FRONT, 0.045, 0.07, SKIN_HALF_ANGLE_RAD, "tank"
        )
        for k, x in enumerate((cx - 0.1, cx + 0.1))
    ]
    # the two horizontal tubes, clear of the risers at their ends; +-50 deg of a 16 mm tube
    patches += [
        CylinderPatch(
            f"{name}_skin", vector3(cx, tube_y, z), (1.0, 0.0, 0.0), _FRONT, tube_r, 0.09, 0.87, "tubing"
        )
        for name, z in (("D_tube_high", high), ("D_tube_low", low))
    ]
    return parts, leaks, patches


def _dent_patches(
    a_face: float, b_patches: list[Surface], c_patches: list[Surface], d_patches: list[Surface]
) -> dict[str, tuple[Surface, ...]]:
    """Where a swapped component's dent or discoloured patch may be centred: the visible skin (issue 13).

    The first patch of each holds the seed mock-up's centred defect: the A fill plate's middle, between the
    Kapton circles; the B tank's front between its straps; the panel's centre; the D tank's front.
    """
    cz = TRUSS_Z0_M + BAY_M / 2
    by_name = {patch.name: patch for patch in (*b_patches, *c_patches, *d_patches)}
    tank = by_name["D_tank_0_skin"]
    assert isinstance(tank, CylinderPatch)  # built as one in _oru_d
    return {
        "A_oru": (
            Patch("A_fill_face", vector3(0.38, a_face, cz), _FRONT, (1, 0, 0), (0.09, 0.14), "oru_face"),
        ),
        "B_tank": (by_name["B_tank_mid"],),
        "C_panel": (by_name["C_cells"],),
        # a dent's rim may reach round to the tank's sides: the window is the whole front half
        "D_tank_0": (replace(tank, half_angle_rad=np.pi / 2),),
    }


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


def truss_mockup() -> Mockup:
    """Build the mock-up of seed §4, Fig. 8 (deterministic: anomalies are drawn later, from a seed).

    Returns
    -------
    Mockup
        Parts, hinge, anomaly candidates (4 Peltier sites, 3 leak sites, 18 screws, impact patches and 4
        swappable components) and vistas.
    """
    parts = _truss()
    a_parts, peltier, a_patches, hinge = _oru_a()
    b_parts, b_patches = _oru_b()
    c_parts, c_screws, c_patches = _panel_c()
    d_parts, leaks, d_patches = _oru_d()
    parts += a_parts + b_parts + c_parts + d_parts
    cz = TRUSS_Z0_M + BAY_M / 2
    a_face, plate_face = A_FACE_Y_M, _MOUNT_Y_M - 0.02
    screws = (
        _screw_sites("A", (0.155, 0.445), a_face, (cz - 0.125, cz + 0.125), "oru_face")
        + _screw_sites("B", (0.72, 1.08), plate_face, (cz - 0.12, cz + 0.12), "plate")
        + _screw_sites("D", (1.32, 1.68), plate_face, (cz - 0.12, cz, cz + 0.12), "plate")
        + c_screws
    )
    for site in screws:
        parts += _screw_parts(site)
    # the first part of a component is the one a defect marks: the A ORU's fill plate, whose face a camera
    # sees (its body's front lies behind the fill and the door: the hidden-dent fault of issue 13)
    components = {
        "A_oru": ("A_fill", "A_body"),
        "B_tank": ("B_tank",),
        "C_panel": ("C_panel",),
        "D_tank_0": ("D_tank_0",),
    }
    component_sites = (
        Site("A_oru", vector3(0.3, a_face, cz), _FRONT, "oru_face", 0.34),
        Site("B_tank", vector3(0.9, plate_face - 0.15, cz), _FRONT, "tank", 0.38),
        Site("C_panel", c_patches[0].centre_m, _UP, "panel", 0.52),
        Site("D_tank_0", vector3(1.4, plate_face - 0.1, cz), _FRONT, "tank", 0.15),
    )
    candidates = Candidates(
        peltier_sites=tuple(peltier),
        leak_sites=tuple(leaks),
        screw_sites=tuple(screws),
        impact_patches=tuple(a_patches + b_patches + c_patches + d_patches),
        component_sites=component_sites,
        dent_patches=_dent_patches(a_face, b_patches, c_patches, d_patches),
    )
    standoff = VISTA_STANDOFF_M
    vistas = [
        vista("A_door", vector3(0.22, a_face, cz), _FRONT, _UP, standoff),
        vista("A_kapton", vector3(0.38, a_face, cz), _FRONT, _UP, standoff),
        vista("B_tank", vector3(0.9, plate_face - 0.15, cz), _FRONT, _UP, standoff),
        vista("C_panel", c_patches[0].centre_m, _UP, (0.0, 1.0, 0.0), standoff),
        vista("D_tubing", vector3(1.5, plate_face - 0.05, cz), _FRONT, _UP, standoff),
        vista("overview", vector3(0.9, 0.0, cz), _unit(np.array([-0.1, -1.0, 0.45])), _UP, 3.4),
    ]
    return Mockup(
        parts=tuple(parts),
        door_hinge_m=hinge,
        candidates=candidates,
        vistas={item.name: item for item in vistas},
        components=components,
    )
