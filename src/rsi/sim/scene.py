"""Seed §4: MJCF of the truss mock-up with its anomalies, materials, textures, lights and the ISEE camera.

:func:`scene_mjcf` is pure (text and PNG bytes); :func:`build_model` compiles it with MuJoCo.

Light groups (one basis image each, see :mod:`rsi.sim.render`):

- ``"sun"``: the solar-simulator lamp (a spot light 3 m away on the mocap body ``solar_lamp``, cutoff
  12 deg, exponent 0, shadows from a 2048 map: a directional light puts 1-px shadow acne on panels that
  looks like flaws) and the room's dim ambient (seed §4: a room darkened by black curtains);
- ``"strobe"``: the end-effector strobe (seed §2.1), a spot light beside the camera falling off as 1/d^2;
- ``"other_strobe"``: the ISEE's second strobe (seed §3 B), as far on the lens's other side, flashed only for
  a second look (seed §2.5);
- ``"lamps"``: the two end-effector halogen lamps (seed §3), likewise.

Geom groups keep the pristine mock-up and the anomalous one in a single model: group 0 is common, group 3
holds what anomalies add (impact spots, screw holes, defective components: the *inspection* state) and
group 4 what they remove (removed screws, the original components: the *reference* state).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import cache
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.anomalies import (
    DENT_RIM_M,
    DENT_RIM_PER_DEPTH,
    AnomalySet,
    Impact,
    MissingScrew,
    SwappedComponent,
)
from rsi.sim.dent import (
    BoxMesh,
    Crater,
    SkinDent,
    box_mesh,
    crater_on_box,
    crater_surface,
    dent_on_skin,
    local_rotation,
    skin_mesh,
    skin_surface,
)
from rsi.sim.mockup import (
    SCREW_RADIUS_M,
    Door,
    Mockup,
    Part,
    vector3,
)

if TYPE_CHECKING:
    import mujoco

COMMON_GROUP, ANOMALY_GROUP, PRISTINE_GROUP = 0, 3, 4
MESH_MATERIAL_SUFFIX = "_mesh"  # materials of mesh geoms: texture coordinates come with the mesh

# Render levels: the light's diffuse colour in the classic renderer, which returns
# 255 * reflectance * level * cos(incidence) * attenuation (linear, measured). Each group's level fills
# most of the 8-bit range on its own (a white Lambertian surface facing the lamp renders at 0.9 * 255), so
# the uint8 basis images lose less than the camera's own 8-bit quantisation (see rsi.sim.render).
SUN_LEVEL = 0.9
STROBE_LEVEL = 0.2  # with 1/d^2 fall-off: 0.8 at the reference distance
# The strobe beside the lens (seed §2.1), in the camera's frame (x right, y up, looking along -z), and its
# beam's half-angle: at the CAD plan's closest standoffs (~0.24 m) the frame's far corners reach 30 deg
STROBE_OFFSET_M = (0.0, 0.03, 0.0)
# The ISEE's second strobe (seed §3 B: "two fast pulse strobe flashes"), as far below the lens: the other
# light of active inspection (seed §2.5, "different illuminator/camera combinations")
OTHER_STROBE_OFFSET_M = (0.0, -0.03, 0.0)
STROBE_CUTOFF_DEG = 32.0
HALOGEN_LEVEL = 0.1  # each of two lamps: 0.8 together at the reference distance
REFERENCE_DISTANCE_M = 0.5  # seed §2.1 inspection standoff at which strobe and lamps are calibrated
LAMP_DISTANCE_M = 3.0
LAMP_CUTOFF_DEG = 12.0
SHADOW_MAP_PX = 2048
# seed §2.1: the strobe lights each point by its distance and its angle off the beam. MuJoCo's renderer
# lights each vertex and interpolates across the triangle, and draws a box face as numquads x numquads quads
# (default 4: 13 cm quads on the panel, 10 cm on a plate), so a vertex past a spot light's cut-off darkens
# its whole quad: the panel's strobe image moved by 16 % from 4 quads to 8. Between two visits a vertex that
# crossed the cut-off moved a wedge of its quad: a 75-sigma false swapped component on a plate 23 deg inside
# the 32-deg beam (truss-b seed 2062 in space, cad_04). Quads of 1.5 cm subtend at most 4.1 deg at the
# closest plan standoff (0.21 m), inside the beam margin the mission trusts (5 deg,
# ``MissionSettings.strobe_beam_margin_deg``).
BOX_QUAD_M = 0.015
# numquads is one count for every box and every face: 35 a side for the 0.52 m panel drew a 7 mm screw slot
# and a 12 mm edge with 35 x 35 quads too, 265 000 quads in all and most of a frame's cost on the CPU
# renderer (a shadowed sun frame 240 ms). Boxes longer than four quads are drawn as grid meshes instead
# (rsi.sim.dent.box_mesh: a vertex every centimetre along each side, 22 000 quads in all, 130 ms), the
# others at MuJoCo's four quads; the strobe image is the same within 2 % (tests/sim/test_render.py).
MESHED_BOX_M = 4 * BOX_QUAD_M
# MuJoCo stores a mesh's vertices as float32: rounded inwards, a box's edge would leave a ray that meets the
# box exactly there (the CAD coverage's samples on a face's border) no triangle to hit, where MuJoCo's own box
# is hit. A micrometre outside, the mesh covers the box (the camera's pixels are 0.5 mm).
MESH_EDGE_MARGIN_M = 1e-6
STEREO_BASELINE_M = 0.06
CAMERA_FOVY_DEG = 35.0  # 0.32 m x 0.32 m at 0.5 m: the seed's ~0.1 m^2 scene (seed §2.1)
MAX_RENDER_PX = 2048
DECAL_HALF_THICKNESS_M = 5e-5
DECAL_LIFT_M = 1e-4  # above the surface: clear of depth-buffer fighting at 0.5 m

LIGHT_GROUPS: dict[str, tuple[str, ...]] = {
    "sun": ("solar_lamp", "room"),
    "strobe": ("strobe",),
    "other_strobe": ("other_strobe",),
    "lamps": ("halogen_0", "halogen_1"),
}


@dataclass(frozen=True)
class Material:
    """Optical look of a surface in the classic renderer.

    Attributes
    ----------
    rgb : (float, float, float)
        Diffuse reflectance (multiplied by the texture, whose mean is ~0.9).
    specular : float
        Specular reflectance in [0, 1].
    shininess : float
        Specular exponent / 128 in [0, 1].
    texture : str or None
        Procedural texture: ``"brushed"``, ``"grain"``, ``"cells"`` or None.
    """

    rgb: tuple[float, float, float]
    specular: float
    shininess: float
    texture: str | None


# Visible-band optics: polished aluminium is bright and specular (and of low thermal emissivity, seed §4),
# black Kapton dark and glossy, solar cells dark blue with silver grid lines.
MATERIALS: dict[str, Material] = {
    "aluminium": Material((0.60, 0.61, 0.63), 0.5, 0.3, "brushed"),
    "plate": Material((0.62, 0.62, 0.60), 0.15, 0.1, "grain"),
    "kapton": Material((0.04, 0.035, 0.03), 0.35, 0.6, "grain"),
    "solar_cell": Material((0.10, 0.13, 0.30), 0.3, 0.5, "cells"),
    "cold_plate": Material((0.70, 0.55, 0.30), 0.4, 0.4, "grain"),
    "connector": Material((0.18, 0.18, 0.19), 0.3, 0.3, None),
    "screw": Material((0.60, 0.60, 0.62), 0.6, 0.5, None),
    "hole": Material((0.02, 0.02, 0.02), 0.0, 0.0, None),
}
# The material under an anomaly, by its truth surface (rsi.sim.mockup.SURFACES); older truth named materials.
_SURFACE_MATERIALS = {"kapton": "kapton", "panel": "solar_cell", "plate": "plate"}
_TEXTURE_PX = 256
_TEXTURE_REPEAT_PER_M = 10.0  # one 256-texel tile per 0.1 m: ~0.4 mm texels, finer than a pixel at 0.5 m
# Lights: the room is dark (seed §4, black curtains); its ambient is 0.5 % of the lamp's illuminance.
ROOM_FRACTION = 0.005


@dataclass(frozen=True)
class SceneIndex:
    """Names the renderer and the world need: which geoms show each anomaly.

    Attributes
    ----------
    flaw_geoms : dict of int to tuple of str
        Index into ``AnomalySet.anomalies`` -> geoms whose image is that anomaly's truth (inspection state).
    pristine_geoms : dict of int to tuple of str
        Index -> geoms of the pristine state it replaces (a removed screw's head, an original component).
    """

    flaw_geoms: dict[int, tuple[str, ...]]
    pristine_geoms: dict[int, tuple[str, ...]]


def _texture(kind: str) -> np.ndarray:
    """A seamless grey texture of mean ~0.9 (uint8 RGB), fixed: the mock-up's surfaces do not change."""
    rng = np.random.default_rng(1994)  # the seed paper's year: a fixed texture, not a per-world draw
    side = _TEXTURE_PX
    if kind == "cells":
        # seed §4 C: square cells with silver fingers every 8 texels and a bus bar per cell
        image = np.full((side, side), 0.85)
        image[::8, :] = 1.0
        image[:, ::64] = 1.0
        image[::64, :] = 0.35
        image[:, 63::64] = 0.35
        image += 0.03 * rng.standard_normal((side, side))
    else:
        noise = rng.standard_normal((side, side))
        # wrap-around filtering keeps the tile seamless
        sigma = (0.6, 6.0) if kind == "brushed" else (1.2, 1.2)
        smooth = cv2.GaussianBlur(np.tile(noise, (3, 3)), (0, 0), sigmaX=sigma[1], sigmaY=sigma[0])
        smooth = smooth[side : 2 * side, side : 2 * side]
        image = 0.9 + 0.06 * smooth / smooth.std()
    grey = np.clip(np.rint(255 * image), 0, 255).astype(np.uint8)
    return np.repeat(grey[:, :, None], 3, axis=2)


def _png(image: np.ndarray) -> bytes:
    ok, encoded = cv2.imencode(".png", image)
    if not ok:  # pragma: no cover - OpenCV always encodes a uint8 RGB array
        raise RuntimeError("OpenCV could not encode a texture as PNG.")
    return bytes(encoded.tobytes())


def _fmt(values: tuple[float, ...] | list[float] | np.ndarray) -> str:
    return " ".join(f"{float(value):.6g}" for value in values)


def _material_xml(name: str, material: Material, factor: float = 1.0, *, mesh: bool = False) -> str:
    rgb = _fmt([min(channel * factor, 1.0) for channel in material.rgb])
    texture = ""
    if material.texture is not None and mesh:
        # a mesh carries its own texture coordinates (rsi.sim.dent), already in tiles
        texture = f' texture="tex_{material.texture}" texuniform="false" texrepeat="1 1"'
    elif material.texture is not None:
        texture = (
            f' texture="tex_{material.texture}" texuniform="true" '
            f'texrepeat="{_TEXTURE_REPEAT_PER_M:g} {_TEXTURE_REPEAT_PER_M:g}"'
        )
    # emission 0 and reflectance 0: every pixel then comes from the lights, linearly (basis images add up)
    return (
        f'<material name="{name}" rgba="{rgb} 1" specular="{material.specular}" '
        f'shininess="{material.shininess}" emission="0" reflectance="0"{texture}/>'
    )


def _geom_xml(
    part: Part,
    *,
    group: int,
    material: str | None = None,
    origin: tuple[float, ...] = (0, 0, 0),
    meshes: dict[str, str] | None = None,
) -> str:
    pos = np.asarray(part.pos) - np.asarray(origin)
    mesh = (meshes or {}).get(part.name)
    shape = f'type="mesh" mesh="{mesh}"' if mesh else f'type="{part.shape}" size="{_fmt(part.size)}"'
    material = material or part.material
    if mesh and not material.endswith(MESH_MATERIAL_SUFFIX):
        material += MESH_MATERIAL_SUFFIX
    return (
        f'<geom name="{part.name}" {shape} pos="{_fmt(pos)}" '
        f'zaxis="{_fmt(part.zaxis)}" material="{material}" group="{group}"/>'
    )


def _decal(
    name: str, centre: np.ndarray, normal: np.ndarray, radius_m: float, *, material: str, lift_m: float
) -> Part:
    position = centre + normal * (lift_m + DECAL_HALF_THICKNESS_M)
    return Part(
        name,
        "decal",
        "cylinder",
        (radius_m, DECAL_HALF_THICKNESS_M),
        vector3(*position),
        material,
        vector3(*normal),
    )


def _impact_parts(
    index: int, impact: Impact, centre: np.ndarray, normal: np.ndarray
) -> tuple[list[Part], list[str]]:
    """Seed §2.4 flaw models: a uniform disc, or one with a stronger centre ("crater")."""
    parts = [
        _decal(
            f"impact_{index}",
            centre,
            normal,
            impact.size_m / 2,
            material=f"impact_{index}",
            lift_m=DECAL_LIFT_M,
        )
    ]
    materials = [f"impact_{index}"]
    if impact.profile == "crater" and impact.centre_diameter_m > 0:
        parts.append(
            _decal(
                f"impact_{index}_core",
                centre,
                normal,
                impact.centre_diameter_m / 2,
                material=f"impact_{index}_core",
                lift_m=DECAL_LIFT_M + 2 * DECAL_HALF_THICKNESS_M,
            )
        )
        materials.append(f"impact_{index}_core")
    return parts, materials


@cache
def _texture_mean(kind: str | None) -> float:
    """Mean of a procedural texture (1 for none): what a flat decal multiplies to match the surface."""
    return 1.0 if kind is None else float(_texture(kind).mean()) / 255.0


def _surface_material(surface: str) -> Material:
    return MATERIALS[surface if surface in MATERIALS else _SURFACE_MATERIALS.get(surface, "aluminium")]


def _spot_material(base: Material, factor: float, contrast: float, polarity: str) -> Material:
    """A flat decal of `contrast` on `base` (scaled by `factor`), the texture's mean folded in.

    Dark spots (tape, ink, soot: seed §4) lose the fraction `contrast` of the reflectance and are matte;
    bright ones (spall, exposed metal) gain that fraction of what the surface lacks of white and keep the
    surface's gloss.
    """
    rgb = [channel * factor * _texture_mean(base.texture) for channel in base.rgb]
    if polarity == "bright":
        return Material(tuple(c + (1.0 - c) * contrast for c in rgb), base.specular, base.shininess, None)  # type: ignore[arg-type]
    return Material(tuple(c * (1.0 - contrast) for c in rgb), 0.05, 0.1, None)  # type: ignore[arg-type]


def _impact_surface(impact: Impact, mockup: Mockup) -> str:
    """What an impact lies on: the surface of the mock-up's patch it was drawn on (older truth named the
    material there, "aluminium" for a bead-blasted plate or the door), else its own truth surface."""
    for patch in mockup.candidates.impact_patches:
        if patch.name == impact.site:
            return patch.surface
    return impact.surface


def _impact_materials(index: int, impact: Impact, surface_factor: float, surface: str) -> list[str]:
    base = _surface_material(surface)
    xml = [
        _material_xml(
            f"impact_{index}", _spot_material(base, surface_factor, impact.darkening, impact.polarity)
        )
    ]
    if impact.profile == "crater":
        core = _spot_material(base, surface_factor, impact.centre_darkening, impact.polarity)
        xml.append(_material_xml(f"impact_{index}_core", core))
    return xml


def _on_part(part: Part, point: np.ndarray, tolerance_m: float = 2e-3) -> bool:
    """Whether `point` lies on the surface of a box, cylinder or capsule part (within `tolerance_m`)."""
    local = local_rotation(part.zaxis).T @ (point - np.asarray(part.pos))
    if part.shape == "box":
        return bool(np.all(np.abs(local) <= np.asarray(part.size) + tolerance_m))
    if part.shape in ("cylinder", "capsule"):
        radial = float(np.hypot(local[0], local[1]))
        return abs(radial - part.size[0]) <= tolerance_m and abs(local[2]) <= part.size[1] + tolerance_m
    return False


def _impact(
    index: int, impact: Impact, swaps: list[SwappedComponent], mockup: Mockup
) -> tuple[list[Part], list[str], bool]:
    """An impact's decals, their materials, and whether it lies on the door (and so rides on it)."""
    centre, normal, surface_factor = _planted(impact, swaps, mockup)
    parts, _ = _impact_parts(index, impact, centre, normal)
    surface = _impact_surface(impact, mockup)
    return parts, _impact_materials(index, impact, surface_factor, surface), surface == "door"


def _planted(
    impact: Impact, swaps: list[SwappedComponent], mockup: Mockup
) -> tuple[np.ndarray, np.ndarray, float]:
    """Centre and normal of an impact's decal and the reflectance factor of the surface it lies on.

    Seed §4: spots and swapped components are planted independently, so a spot may land on the replacement:
    on a discoloured one (or its discoloured patch) it changes the new finish, in a dent it follows the
    metal (a box's crater, a tank's dented skin).
    """
    centre, normal = np.asarray(impact.position_m, dtype=float), np.asarray(impact.normal, dtype=float)
    by_name = {part.name: part for part in mockup.parts}
    for swap in swaps:
        originals = [by_name[name] for name in mockup.components[swap.site]]
        hosts = [part for part in originals if _on_part(part, centre)]
        if not hosts:
            continue
        defect_centre, _ = swap.defect_at
        if swap.defect == "discoloured":
            inside = float(np.linalg.norm(centre - np.asarray(defect_centre))) <= swap.defect_radius_m
            return centre, normal, swap.reflectance_factor if swap.defect_radius_m == 0 or inside else 1.0
        host = hosts[0]
        if host is originals[0] and host.shape == "box":  # the dented box of :func:`_swapped`
            surface, tilted = crater_surface(_crater(swap, host), host.pos, host.zaxis, impact.position_m)
            return surface, tilted, 1.0
        if host is originals[0]:  # a dented tank
            dent = _skin_dent(swap, host)
            surface, tilted = skin_surface(dent, host.size[0], host.pos, host.zaxis, impact.position_m)
            return surface, tilted, 1.0
    return centre, normal, 1.0


def scene_mjcf(
    mockup: Mockup, anomalies: AnomalySet, *, grid_meshes: bool = True
) -> tuple[str, dict[str, bytes], SceneIndex]:
    """MJCF text, its texture assets and the flaw index for a mock-up carrying `anomalies`.

    Parameters
    ----------
    mockup : Mockup
        The geometry (:func:`rsi.sim.mockup.mockup`).
    anomalies : AnomalySet
        What to plant: impacts become dark or bright decals, removed screws leave a hole, swapped components
        are dented (a crater pressed into a box face or a tank's skin) or discoloured (as a whole, or a
        patch decal). Thermal spots and leaks do not show in visible light.
    grid_meshes : bool
        Draw the boxes longer than :data:`MESHED_BOX_M` as grid meshes (default: the camera's frames).
        False keeps MuJoCo's boxes, all at one fine quad count: a model for rays and reach (the CAD coverage
        and plan) or live video (the console), where the meshes' triangles only cost time.

    Returns
    -------
    xml : str
        The MJCF document.
    assets : dict of str to bytes
        PNG textures named as in `xml` (pass to ``mujoco.MjModel.from_xml_string``).
    index : SceneIndex
        Which geoms show each anomaly.
    """
    v.instance_of(mockup, "mockup", Mockup, none_allowed=False)
    v.instance_of(anomalies, "anomalies", AnomalySet, none_allowed=False)
    meshed_over_m = _meshed_over_m(grid_meshes)
    by_name = {part.name: part for part in mockup.parts}
    materials = [_material_xml(name, material) for name, material in MATERIALS.items()]
    anomaly_parts: list[Part] = []
    pristine_names: set[str] = set()
    door_parts: list[Part] = []
    flaw_geoms: dict[int, tuple[str, ...]] = {}
    pristine_geoms: dict[int, tuple[str, ...]] = {}
    meshes: dict[str, str] = {}  # geom name -> mesh asset, for dented boxes and the boxes they replace
    mesh_xml: list[str] = []
    swaps = [anomaly for anomaly in anomalies.anomalies if isinstance(anomaly, SwappedComponent)]
    for index, anomaly in enumerate(anomalies.anomalies):
        if isinstance(anomaly, Impact):
            parts, spot_materials, on_door = _impact(index, anomaly, swaps, mockup)
            materials += spot_materials
            (door_parts if on_door else anomaly_parts).extend(parts)  # a spot on the door rides on it
            flaw_geoms[index] = tuple(part.name for part in parts)
        elif isinstance(anomaly, MissingScrew):
            heads = (anomaly.site, f"{anomaly.site}_slot")
            pristine_names.update(heads)
            hole = _hole(anomaly)
            anomaly_parts.append(hole)
            flaw_geoms[index] = (hole.name,)
            pristine_geoms[index] = heads
        elif isinstance(anomaly, SwappedComponent):
            originals = [by_name[name] for name in mockup.components[anomaly.site]]
            parts, flaw_geoms[index], extra = _swapped(index, anomaly, originals, meshes)
            anomaly_parts += parts
            (materials if anomaly.defect == "discoloured" else mesh_xml).extend(extra)
            if not _is_patch(anomaly):  # a patch lies on the original: nothing of it is replaced
                pristine_names.update(part.name for part in originals)
                pristine_geoms[index] = tuple(part.name for part in originals)
    mesh_xml += _mesh_large_boxes([*mockup.parts, *anomaly_parts, *door_parts], meshes, meshed_over_m)
    hinge = np.asarray(mockup.door.hinge_m)
    world_xml, door_xml = [], []
    for part in mockup.parts:
        group = PRISTINE_GROUP if part.name in pristine_names else COMMON_GROUP
        if part.component == mockup.door.body:
            door_xml.append(_geom_xml(part, group=group, origin=tuple(hinge), meshes=meshes))
        else:
            world_xml.append(_geom_xml(part, group=group, meshes=meshes))
    world_xml += [_geom_xml(part, group=ANOMALY_GROUP, meshes=meshes) for part in anomaly_parts]
    door_xml += [
        _geom_xml(part, group=ANOMALY_GROUP, origin=tuple(hinge), meshes=meshes) for part in door_parts
    ]
    if meshes:
        materials += [
            _material_xml(name + MESH_MATERIAL_SUFFIX, material, mesh=True)
            for name, material in MATERIALS.items()
        ]
    textures = {kind: _png(_texture(kind)) for kind in ("brushed", "grain", "cells")}
    texture_xml = [
        f'<texture name="tex_{kind}" type="2d" file="{kind}.png"/>' for kind in textures
    ] + mesh_xml
    xml = _document(
        materials, texture_xml, world_xml, door_xml, mockup, quads=_box_quads(mockup, meshed_over_m)
    )
    index_record = SceneIndex(flaw_geoms=flaw_geoms, pristine_geoms=pristine_geoms)
    return xml, {f"{kind}.png": data for kind, data in textures.items()}, index_record


def _material_of(part: Part) -> Material:
    return MATERIALS[part.material]


def _hole(screw: MissingScrew) -> Part:
    """The dark threaded hole a removed screw leaves (seed §4)."""
    return _decal(
        f"hole_{screw.site}",
        np.asarray(screw.position_m),
        np.asarray(screw.normal),
        0.45 * SCREW_RADIUS_M,
        material="hole",
        lift_m=DECAL_LIFT_M,
    )


def _is_patch(anomaly: SwappedComponent) -> bool:
    return anomaly.defect == "discoloured" and anomaly.defect_radius_m > 0.0


def _discoloured_patch(index: int, anomaly: SwappedComponent, part: Part) -> tuple[Part, str]:
    """A replacement discoloured over a patch (issue 13): a flat decal of the face's finish, scaled.

    Only flat faces get patches (:func:`rsi.sim.anomalies.seed_anomalies`); the decal lies flush on the face,
    below an impact spot planted on it.
    """
    centre, normal = (np.asarray(value, dtype=float) for value in anomaly.defect_at)
    base = _material_of(part)
    flat = Material(
        tuple(c * _texture_mean(base.texture) for c in base.rgb),  # type: ignore[arg-type]
        base.specular,
        base.shininess,
        None,
    )
    name = f"discolour_{index}"
    decal = _decal(name, centre, normal, anomaly.defect_radius_m, material=name, lift_m=0.0)
    return decal, _material_xml(name, flat, anomaly.reflectance_factor)


def _swapped(
    index: int, anomaly: SwappedComponent, originals: list[Part], meshes: dict[str, str]
) -> tuple[list[Part], tuple[str, ...], list[str]]:
    """Parts of a defective replacement (seed §4), the geoms that show the defect, and their assets.

    The assets are materials of a discoloured component or patch, or the meshes of a dented box or tank
    (registered in `meshes`): the dent is pressed into the first part, the one a camera sees.
    """
    if _is_patch(anomaly):
        decal, material = _discoloured_patch(index, anomaly, originals[0])
        return [decal], (decal.name,), [material]
    if anomaly.defect == "discoloured":
        copies = [
            Part(f"{p.name}_swapped", p.component, p.shape, p.size, p.pos, f"{p.name}_swapped", p.zaxis)
            for p in originals
        ]
        materials = [  # a box drawn as a grid mesh takes the material's mesh variant
            _material_xml(
                copy.name + suffix, _material_of(part), anomaly.reflectance_factor, mesh=bool(suffix)
            )
            for copy, part in zip(copies, originals, strict=True)
            for suffix in ("", MESH_MATERIAL_SUFFIX)
        ]
        return copies, tuple(copy.name for copy in copies), materials
    copies = [
        Part(f"{p.name}_swapped", p.component, p.shape, p.size, p.pos, p.material, p.zaxis) for p in originals
    ]
    first = originals[0]
    if first.shape == "box":
        crater = _crater(anomaly, first)
        pair = (box_mesh(first.size, _TEXTURE_REPEAT_PER_M, replace(crater, depth_m=0.0)),
                box_mesh(first.size, _TEXTURE_REPEAT_PER_M, crater))  # fmt: skip
    else:
        dent = _skin_dent(anomaly, first)
        pair = tuple(  # type: ignore[assignment]
            skin_mesh(
                first.size[0],
                first.size[1],
                capsule=first.shape == "capsule",
                repeat_per_m=_TEXTURE_REPEAT_PER_M,
                dent=shape,
            )
            for shape in (replace(dent, depth_m=0.0), dent)
        )
    return copies, (copies[0].name,), _register_meshes((first.name, copies[0].name), pair, meshes)


def _dent_radius_m(anomaly: SwappedComponent) -> float:
    # truth written before issue 13 carried no rim: 3 cm plus twice the depth, as drawn today
    if anomaly.defect_radius_m > 0.0:
        return anomaly.defect_radius_m
    return DENT_RIM_M + DENT_RIM_PER_DEPTH * anomaly.dent_depth_m


def _crater(anomaly: SwappedComponent, part: Part) -> Crater:
    centre, normal = anomaly.defect_at
    return crater_on_box(
        part.size,
        part.pos,
        part.zaxis,
        centre,
        normal,
        depth_m=anomaly.dent_depth_m,
        radius_m=_dent_radius_m(anomaly),
    )


def _skin_dent(anomaly: SwappedComponent, part: Part) -> SkinDent:
    centre, _ = anomaly.defect_at
    return dent_on_skin(
        part.size[0],
        part.size[1],
        part.pos,
        part.zaxis,
        centre,
        depth_m=anomaly.dent_depth_m,
        radius_m=_dent_radius_m(anomaly),
    )


def _register_meshes(names: tuple[str, ...], grids: tuple[BoxMesh, ...], meshes: dict[str, str]) -> list[str]:
    """Mesh assets of the parts `names` (a dented part and the undented part it replaces, or a large box),
    registered in `meshes`.

    The pristine part is drawn as a mesh of the same grid, so both states share one texture mapping: the
    reference and the inspection images then differ by the dent alone.
    """
    xml = []
    for geom, mesh in zip(names, grids, strict=True):
        meshes[geom] = f"mesh_{geom}"
        xml.append(
            f'<mesh name="mesh_{geom}" vertex="{_fmt(mesh.vertices.ravel())}" '
            f'texcoord="{_fmt(mesh.texcoords.ravel())}" face="{_fmt(mesh.faces.ravel())}"/>'
        )
    return xml


def _door_xml(door: Door, geoms: list[str]) -> str:
    return (
        f'<body name="{door.body}" pos="{_fmt(door.hinge_m)}">\n'
        f'      <joint name="{door.joint}" type="hinge" axis="{_fmt(door.axis)}" '
        f'range="0 {door.max_angle_rad:g}" limited="true"/>\n'
        f"      {''.join(geoms)}\n"
        "    </body>"
    )


def _document(
    materials: list[str],
    textures: list[str],
    world: list[str],
    door: list[str],
    mockup: Mockup,
    *,
    quads: int,
) -> str:
    lamp_dir = "0 0 -1"
    strobe = _spot("strobe", STROBE_OFFSET_M, STROBE_LEVEL, STROBE_CUTOFF_DEG) + _spot(
        "other_strobe", OTHER_STROBE_OFFSET_M, STROBE_LEVEL, STROBE_CUTOFF_DEG
    )
    halogens = "".join(
        _spot(f"halogen_{k}", (x, -0.03, 0.0), HALOGEN_LEVEL, 35.0) for k, x in enumerate((-0.05, 0.05))
    )
    room, sun = f"{ROOM_FRACTION * SUN_LEVEL:.6g}", f"{SUN_LEVEL} {SUN_LEVEL} {SUN_LEVEL}"
    middle, _, height = mockup.centre_m
    return f"""<mujoco model="rsi_truss_mockup">
  <compiler angle="radian"/>
  <statistic extent="{mockup.length_m + 1.2:.6g}" center="{middle:.6g} 0 {height:.6g}"/>
  <visual>
    <headlight active="0" ambient="0 0 0" diffuse="0 0 0" specular="0 0 0"/>
    <global offwidth="{MAX_RENDER_PX}" offheight="{MAX_RENDER_PX}" fovy="{CAMERA_FOVY_DEG}"/>
    <quality shadowsize="{SHADOW_MAP_PX}" numquads="{quads}"/>
    <map znear="0.004" zfar="20" haze="0"/>
    <rgba fog="0 0 0 1" haze="0 0 0 1"/>
  </visual>
  <asset>
    {"".join(textures)}
    {"".join(materials)}
  </asset>
  <worldbody>
    <light name="room" type="directional" pos="{middle:.6g} 0 4" dir="0 0 -1" castshadow="false"
           diffuse="0 0 0" specular="0 0 0" ambient="{room} {room} {room}"/>
    <body name="solar_lamp" mocap="true" pos="{middle:.6g} -2.5 2.9">
      <light name="solar_lamp" mode="fixed" type="spot" pos="0 0 0" dir="{lamp_dir}" castshadow="true"
             cutoff="{LAMP_CUTOFF_DEG:g}" exponent="0" attenuation="1 0 0"
             diffuse="{sun}" specular="{sun}" ambient="0 0 0"/>
    </body>
    <body name="isee" mocap="true" pos="0.3 -1 1.2">
      <camera name="isee" pos="0 0 0" fovy="{CAMERA_FOVY_DEG}"/>
      <camera name="isee_left" pos="0 0 0" fovy="{CAMERA_FOVY_DEG}"/>
      <camera name="isee_right" pos="{STEREO_BASELINE_M} 0 0" fovy="{CAMERA_FOVY_DEG}"/>
      <site name="isee_range" pos="0 0 0" zaxis="0 0 -1" size="0.005"/>
      {strobe}{halogens}
    </body>
    {"".join(world)}
    {_door_xml(mockup.door, door)}
  </worldbody>
  <sensor>
    <rangefinder name="isee_range" site="isee_range"/>
  </sensor>
</mujoco>"""


def _box_quads(mockup: Mockup, meshed_over_m: float) -> int:
    """Quads along a box face's side (MuJoCo's ``numquads``, one for all boxes): none over BOX_QUAD_M."""
    longest = max(
        (2.0 * max(part.size) for part in mockup.parts if _drawn_as_box(part, meshed_over_m)), default=0.0
    )
    return max(4, math.ceil(longest / BOX_QUAD_M))


def _meshed_over_m(grid_meshes: object) -> float:
    """The longest box drawn as MuJoCo's box: :data:`MESHED_BOX_M` with grid meshes, any without."""
    if not isinstance(grid_meshes, bool):
        raise InputError(f"grid_meshes must be True or False; got {grid_meshes!r}.")
    return MESHED_BOX_M if grid_meshes else math.inf


def _drawn_as_box(part: Part, meshed_over_m: float) -> bool:
    return part.shape == "box" and 2.0 * max(part.size) <= meshed_over_m


def _mesh_large_boxes(parts: list[Part], meshes: dict[str, str], meshed_over_m: float) -> list[str]:
    """Mesh assets of the boxes longer than `meshed_over_m`, registered in `meshes`; a dented box and the
    one it replaces are registered already, with their crater's grid."""
    xml = []
    for part in parts:
        if part.shape == "box" and not _drawn_as_box(part, meshed_over_m) and part.name not in meshes:
            grown = tuple(half + MESH_EDGE_MARGIN_M for half in part.size)
            xml += _register_meshes((part.name,), (box_mesh(grown, _TEXTURE_REPEAT_PER_M),), meshes)
    return xml


def _spot(name: str, pos: tuple[float, float, float], level: float, cutoff_deg: float) -> str:
    # 1/d^2 fall-off (attenuation 0 0 1) as for any small source; no shadows: the source is by the lens
    return (
        f'<light name="{name}" pos="{_fmt(pos)}" dir="0 0 -1" type="spot" castshadow="false" '
        f'cutoff="{cutoff_deg:g}" exponent="0" attenuation="0 0 1" ambient="0 0 0" '
        f'diffuse="{level} {level} {level}" specular="{level} {level} {level}"/>'
    )


def build_model(
    mockup: Mockup, anomalies: AnomalySet, *, arm_home_tool_tip_m: object = None, grid_meshes: bool = True
) -> tuple[mujoco.MjModel, SceneIndex]:
    """Compile the mock-up with its anomalies into a MuJoCo model, optionally with the arm on its rail.

    Parameters
    ----------
    mockup : Mockup
        The geometry.
    anomalies : AnomalySet
        The anomalies to plant.
    arm_home_tool_tip_m : (float, float, float), optional
        Put the K1207-style arm with the ISEE in the same world (:func:`rsi.sim.arm.attach_arm`, names
        prefixed :data:`rsi.sim.arm.WORLD_ARM_PREFIX`), its home tool tip here. None (default): no arm,
        and the model is compiled straight from the MJCF text as always.
    grid_meshes : bool
        As :func:`scene_mjcf`: False for a model of rays and reach, or live video.

    Returns
    -------
    model : mujoco.MjModel
    index : SceneIndex
    """
    from rsi.sim.render import import_mujoco

    if arm_home_tool_tip_m is not None:  # checked before the scene is built (a second or so)
        v.vector3(arm_home_tool_tip_m, "arm_home_tool_tip_m")
    mujoco_module: Any = import_mujoco()
    xml, assets, index = scene_mjcf(mockup, anomalies, grid_meshes=grid_meshes)
    if arm_home_tool_tip_m is None:
        return mujoco_module.MjModel.from_xml_string(xml, assets), index
    from rsi.sim.arm import attach_arm

    spec = mujoco_module.MjSpec.from_string(xml, assets=assets)
    attach_arm(spec, home_tool_tip_m=arm_home_tool_tip_m)
    return spec.compile(), index
