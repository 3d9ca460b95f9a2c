"""Dented boxes (rsi.sim.dent): a closed mesh with the seed §4 crater, drawn as MuJoCo draws the box."""

from __future__ import annotations

import math
import os
import re
from collections import Counter
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.sim.anomalies import AnomalySet, Impact, Site, SwappedComponent
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
from rsi.sim.mockup import Mockup, truss_mockup
from rsi.sim.scene import scene_mjcf

SIZE = (0.26, 0.2, 0.006)  # the solar panel's half sizes


def _signed_volume(mesh: BoxMesh) -> float:
    a, b, c = (mesh.vertices[mesh.faces[:, k]] for k in range(3))
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def _edges(mesh: BoxMesh) -> Counter[tuple[int, int]]:
    """Directed edges keyed by vertex position, so faces meeting at a box edge count as joined."""
    keys = {tuple(np.round(v, 9)): k for k, v in enumerate(mesh.vertices)}
    ids = np.array([keys[tuple(np.round(v, 9))] for v in mesh.vertices])
    count: Counter[tuple[int, int]] = Counter()
    for triangle in ids[mesh.faces]:
        for start, end in ((0, 1), (1, 2), (2, 0)):
            count[(int(triangle[start]), int(triangle[end]))] += 1
    return count


def test_flat_mesh_is_the_box_with_outward_faces() -> None:
    mesh = box_mesh(SIZE, 10.0)
    assert np.allclose(np.abs(mesh.vertices).max(axis=0), SIZE)
    assert _signed_volume(mesh) == pytest.approx(8 * math.prod(SIZE), rel=1e-9)


def test_crater_removes_its_volume_and_sinks_its_centre() -> None:
    crater = Crater(axis=2, sign=1, centre=(0.05, -0.02), depth_m=0.008, radius_m=0.046)
    mesh = box_mesh(SIZE, 10.0, crater)
    removed = math.pi * crater.radius_m**2 * crater.depth_m / 3  # integral of d (1 - rho^2/R^2)^2
    assert 8 * math.prod(SIZE) - _signed_volume(mesh) == pytest.approx(removed, rel=0.01)
    rho = np.hypot(mesh.vertices[:, 0] - 0.05, mesh.vertices[:, 1] + 0.02)
    top = mesh.vertices[mesh.vertices[:, 2] > -SIZE[2]]  # the bottom face is flat
    inside = top[np.hypot(top[:, 0] - 0.05, top[:, 1] + 0.02) < crater.radius_m]
    deepest = inside[np.argmin(inside[:, 2])]
    assert deepest[:2] == pytest.approx(crater.centre, abs=1.1e-3)
    assert deepest[2] == pytest.approx(SIZE[2] - crater.depth_m, abs=1e-6)
    rim = (rho >= crater.radius_m) & (mesh.vertices[:, 2] > 0) & (np.abs(mesh.vertices[:, 0]) < SIZE[0])
    assert np.allclose(mesh.vertices[rim & (np.abs(mesh.vertices[:, 1]) < SIZE[1]), 2], SIZE[2])


@pytest.mark.parametrize(("axis", "sign"), [(0, 1), (1, -1), (2, -1)])
def test_dented_mesh_stays_closed_on_any_face(axis: int, sign: int) -> None:
    crater = Crater(axis=axis, sign=sign, centre=(0.0, 0.0), depth_m=0.004, radius_m=0.005)
    edges = _edges(box_mesh((0.03, 0.02, 0.01), 10.0, crater))
    # every edge of a closed, consistently wound surface is walked once each way
    assert all(edges[(end, start)] == n for (start, end), n in edges.items())


def test_local_rotation_is_mujocos_zaxis_frame() -> None:
    import mujoco

    axes = [(0, 0, 1), (0, 0, -1), (0, -1, 0), (1, 0, 0), (0.3, -0.5, 0.8)]
    geoms = "".join(f'<geom type="box" size="1 1 1" zaxis="{x} {y} {z}"/>' for x, y, z in axes)
    model = mujoco.MjModel.from_xml_string(f"<mujoco><worldbody>{geoms}</worldbody></mujoco>")
    for k, axis in enumerate(axes):
        assert local_rotation(axis) == pytest.approx(_matrix(model.geom_quat[k]), abs=1e-9)


def _matrix(quaternion: np.ndarray) -> np.ndarray:
    import mujoco

    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, quaternion)
    return matrix.reshape(3, 3)


def test_crater_on_box_finds_the_face_and_keeps_the_rim_on_it() -> None:
    crater = crater_on_box(
        (0.17, 0.07, 0.14),
        (0.3, -0.4, 1.2),
        (0.0, 0.0, 1.0),
        (0.45, -0.47, 1.2),
        (0.0, -1.0, 0.0),
        depth_m=0.005,
        radius_m=0.04,
    )
    assert (crater.axis, crater.sign) == (1, -1)
    assert crater.centre == pytest.approx((0.17 - 0.04, 0.0))  # pulled in so the rim stays on the face
    deep = crater_on_box(SIZE, (0, 0, 0), (0, 0, 1), (0, 0, 0.006), (0, 0, 1), depth_m=0.05, radius_m=0.3)
    assert deep.depth_m < 2 * SIZE[2] and deep.radius_m < SIZE[1]


def test_flat_mesh_renders_as_mujocos_box() -> None:
    import mujoco

    _, assets, _ = scene_mjcf(truss_mockup(), AnomalySet(()))
    png = assets["cells.png"]  # the panel's own cell texture, as the scene hands it to MuJoCo
    mesh = box_mesh(SIZE, 10.0)
    fmt = " ".join

    def picture(geom: str, extra: str = "") -> np.ndarray:
        xml = f"""<mujoco><visual><global offwidth="160" offheight="160"/>
          <headlight ambient="0.3 0.3 0.3" diffuse="0.6 0.6 0.6" specular="0 0 0"/></visual>
          <asset><texture name="t" type="2d" file="c.png"/>
            <material name="box" texture="t" texuniform="true" texrepeat="10 10" specular="0"/>
            <material name="mesh" texture="t" texuniform="false" texrepeat="1 1" specular="0"/>{extra}</asset>
          <worldbody><camera name="c" pos="0.05 0.02 0.5"/>{geom}</worldbody></mujoco>"""
        model = mujoco.MjModel.from_xml_string(xml, {"c.png": png})
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        with mujoco.Renderer(model, 160, 160) as renderer:
            renderer.update_scene(data, camera="c")
            return renderer.render().astype(int)

    box = picture(f'<geom type="box" size="{fmt(map(str, SIZE))}" material="box"/>')
    asset = (
        f'<mesh name="m" vertex="{fmt(map(str, mesh.vertices.ravel()))}" '
        f'texcoord="{fmt(map(str, mesh.texcoords.ravel()))}" face="{fmt(map(str, mesh.faces.ravel()))}"/>'
    )
    drawn = picture('<geom type="mesh" mesh="m" material="mesh"/>', asset)
    assert np.abs(drawn - box).mean() < 1.0


def test_scene_draws_a_dented_panel_as_meshes_of_one_grid() -> None:
    mockup = truss_mockup()
    _, dent = _panel_swap(mockup, defect="dented", dent_depth_m=0.006)
    xml, _, index = scene_mjcf(mockup, AnomalySet((dent,)))
    assert index.flaw_geoms[0] == ("C_panel_swapped",) and index.pristine_geoms[0] == ("C_panel",)
    assert 'name="C_panel" type="mesh" mesh="mesh_C_panel"' in xml
    assert 'name="C_panel_swapped" type="mesh" mesh="mesh_C_panel_swapped"' in xml
    pristine, dented = (
        xml.split(f'<mesh name="{name}" vertex="')[1].split('"')[0]
        for name in ("mesh_C_panel", "mesh_C_panel_swapped")
    )
    assert pristine.count(" ") == dented.count(" ") and pristine != dented


def test_crater_surface_follows_the_mesh_and_its_slope() -> None:
    pos, zaxis = (1.5, 0.0, 1.57), (0.0, 0.0, 1.0)
    crater = Crater(axis=2, sign=1, centre=(0.05, -0.02), depth_m=0.008, radius_m=0.046)
    mesh = box_mesh(SIZE, 10.0, crater)
    top = mesh.vertices[mesh.vertices[:, 2] > 0]
    for vertex in top[:: max(len(top) // 40, 1)]:  # every mesh vertex of the dented face lies on the surface
        flat = np.array([vertex[0], vertex[1], SIZE[2]]) + pos
        point, _ = crater_surface(crater, pos, zaxis, tuple(flat))
        assert point == pytest.approx(vertex + pos, abs=1e-9)
    centre = np.array([0.05, -0.02, SIZE[2]]) + pos
    point, normal = crater_surface(crater, pos, zaxis, tuple(centre))
    assert point[2] == pytest.approx(pos[2] + SIZE[2] - crater.depth_m) and normal == pytest.approx((0, 0, 1))
    # the steepest wall, rho = R / sqrt(3): slope 8 d / (3 sqrt(3) R), tilted towards the centre
    rho = crater.radius_m / math.sqrt(3)
    _, normal = crater_surface(crater, pos, zaxis, tuple(centre + np.array([rho, 0.0, 0.0])))
    slope = 8 * crater.depth_m / (3 * math.sqrt(3) * crater.radius_m)
    assert normal == pytest.approx(np.array([-slope, 0.0, 1.0]) / math.hypot(slope, 1.0))
    outside, flat_normal = crater_surface(crater, pos, zaxis, tuple(centre + np.array([0.1, 0.0, 0.0])))
    assert outside == pytest.approx(centre + np.array([0.1, 0.0, 0.0])) and flat_normal == pytest.approx(
        (0, 0, 1)
    )


def _panel_swap(mockup: Mockup, **defect: Any) -> tuple[Site, SwappedComponent]:
    """The solar panel's component site and a replacement of it with the SwappedComponent fields `defect`."""
    site = next(s for s in mockup.candidates.component_sites if s.name == "C_panel")
    swap = SwappedComponent(
        site="C_panel",
        position_m=site.position_m,
        normal=site.normal,
        surface=site.surface,
        size_m=site.size_m,
        **defect,
    )
    return site, swap


def _impact_on(site: str, position: tuple[float, float, float], normal: tuple[float, float, float]) -> Impact:
    return Impact(
        site=site, position_m=position, normal=normal, size_m=0.002, surface="solar_cell", darkening=0.5
    )


def _attribute(xml: str, tag: str, name: str, attribute: str) -> np.ndarray:
    element = re.search(rf'<{tag} name="{name}"[^>]*>', xml)
    assert element is not None
    value = re.search(rf'{attribute}="([^"]*)"', element.group(0))
    assert value is not None
    return np.array([float(x) for x in value.group(1).split()])


def test_an_impact_on_a_dented_panel_lies_in_the_crater() -> None:
    mockup = truss_mockup()
    site, dent = _panel_swap(mockup, defect="dented", dent_depth_m=0.008)
    inside = _impact_on("C_cells", site.position_m, site.normal)
    far = (site.position_m[0] + 0.2, site.position_m[1], site.position_m[2])
    outside = _impact_on("C_cells", far, site.normal)
    xml, _, _ = scene_mjcf(mockup, AnomalySet((dent, inside, outside)))
    sunk, flat = _attribute(xml, "geom", "impact_1", "pos"), _attribute(xml, "geom", "impact_2", "pos")
    assert sunk[2] == pytest.approx(flat[2] - 0.008, abs=1e-6)  # the crater's centre is 8 mm down
    assert sunk[:2] == pytest.approx(site.position_m[:2], abs=1e-6)


def test_an_impact_darkens_a_discoloured_replacement_by_its_own_fraction() -> None:
    mockup = truss_mockup()
    site, faded = _panel_swap(mockup, defect="discoloured", reflectance_factor=0.6)
    spot = _impact_on("C_cells", site.position_m, site.normal)
    plain, _, _ = scene_mjcf(mockup, AnomalySet((spot,)))
    on_faded, _, _ = scene_mjcf(mockup, AnomalySet((faded, spot)))
    assert _attribute(on_faded, "material", "impact_1", "rgba")[:3] == pytest.approx(
        0.6 * _attribute(plain, "material", "impact_0", "rgba")[:3],
        rel=1e-5,  # 6 digits in the MJCF
    )
    assert _attribute(on_faded, "material", "C_panel_swapped", "rgba")[:3] == pytest.approx(
        0.6 * _attribute(plain, "material", "solar_cell", "rgba")[:3]
    )


@pytest.mark.parametrize("capsule", [False, True])
def test_skin_mesh_is_closed_and_holds_its_volume(capsule: bool) -> None:
    radius, half = 0.045, 0.075
    flat = skin_mesh(radius, half, capsule=capsule, repeat_per_m=10.0)
    solid = math.pi * radius**2 * 2 * half + (4 / 3 * math.pi * radius**3 if capsule else 0.0)
    # a polygon of 29 sides of 1 cm inscribed in the 45 mm circle: (2 pi / 29)^2 / 6 = 0.8 % less area
    assert _signed_volume(flat) == pytest.approx(solid, rel=1.5e-2)
    dent = SkinDent(angle_rad=-math.pi / 2, height_m=0.01, depth_m=0.006, radius_m=0.04)
    dented = skin_mesh(radius, half, capsule=capsule, repeat_per_m=10.0, dent=dent)
    edges = _edges(dented)
    assert all(edges[(end, start)] == n for (start, end), n in edges.items())
    # the dent takes volume away (pressed in, not proud): pi a^2 d / 3 of a flat crater, less the skin's
    # curvature (the sunk skin is shorter by (1 - sink / R)), on the same grid without the dent
    same_grid = skin_mesh(radius, half, capsule=capsule, repeat_per_m=10.0, dent=replace(dent, depth_m=0.0))
    removed = _signed_volume(same_grid) - _signed_volume(dented)
    assert removed == pytest.approx(math.pi * 0.04**2 * 0.006 / 3, rel=0.1)
    # at the dent's centre (azimuth -90 deg: the -y side, 1 cm up) the skin is pressed in by the depth
    x, y, z = dented.vertices.T
    centre = (np.abs(x) < 5e-4) & (np.abs(z - 0.01) < 5e-4) & (y < 0)
    assert y[centre].max() == pytest.approx(-(radius - dent.depth_m), abs=1e-5)


def test_skin_surface_lies_on_the_dented_mesh() -> None:
    radius, half, pos, zaxis = 0.07, 0.12, (0.9, -0.4, 1.2), (1.0, 0.0, 0.0)
    dent = SkinDent(angle_rad=0.3, height_m=0.02, depth_m=0.008, radius_m=0.046)
    rotation = local_rotation(zaxis)
    centre = np.array([radius * math.cos(0.3), radius * math.sin(0.3), 0.02])
    point, normal = skin_surface(dent, radius, pos, zaxis, tuple(rotation @ centre + np.asarray(pos)))
    expected = rotation @ (centre * np.array([1 - dent.depth_m / radius] * 2 + [1.0])) + np.asarray(pos)
    assert point == pytest.approx(expected, abs=1e-12)
    assert normal == pytest.approx(rotation @ np.array([math.cos(0.3), math.sin(0.3), 0.0]), abs=1e-12)
    # off the dent the skin is round and untouched
    far = np.array([radius, 0.0, -0.1])
    point, normal = skin_surface(dent, radius, pos, zaxis, tuple(rotation @ far + np.asarray(pos)))
    assert point == pytest.approx(rotation @ far + np.asarray(pos)) and normal == pytest.approx(
        rotation[:, 0]
    )
    placed = dent_on_skin(radius, half, pos, zaxis, tuple(point), depth_m=0.2, radius_m=0.5)
    assert placed.depth_m == pytest.approx(0.5 * radius) and placed.radius_m < half
