"""The mock-up's geometry and its MJCF: parts, candidates, vistas, anomaly groups, cheap import."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sim.anomalies import AnomalySet, AnomalySettings, seed_anomalies
from rsi.sim.dent import local_rotation
from rsi.sim.mockup import BAY_M, BAYS, truss_mockup
from rsi.sim.scene import ANOMALY_GROUP, MESHED_BOX_M, PRISTINE_GROUP, build_model, scene_mjcf


def test_importing_rsi_sim_does_not_import_mujoco() -> None:
    code = "import sys, rsi.sim; print('mujoco' in sys.modules)"
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "False"


def test_mockup_has_the_seed_components_and_enough_candidates() -> None:
    mockup = truss_mockup()
    components = {part.component for part in mockup.parts}
    assert {"truss", "A", "A_door", "B", "C", "D"} <= components
    assert len(mockup.candidates.peltier_sites) >= 4
    assert len(mockup.candidates.leak_sites) == 3
    assert len(mockup.candidates.screw_sites) >= 16
    assert {"A_door", "A_kapton", "B_tank", "C_panel", "D_tubing", "overview"} <= set(mockup.vistas)
    span = [part.pos[0] for part in mockup.parts if part.component == "truss"]
    assert min(span) >= -0.05 and max(span) <= BAY_M * BAYS + 0.05


def test_vistas_look_at_their_target_from_the_standoff() -> None:
    for vista in truss_mockup().vistas.values():
        offset = np.asarray(vista.target_m) - np.asarray(vista.position_m)
        assert np.linalg.norm(offset) == np.float64(vista.standoff_m) or np.isclose(
            np.linalg.norm(offset), vista.standoff_m
        )
        assert np.allclose(offset / np.linalg.norm(offset), vista.forward)
        assert abs(np.dot(vista.forward, vista.up)) < 1e-12


def test_anomalies_go_to_their_geom_groups() -> None:
    mockup = truss_mockup()
    settings = replace(AnomalySettings.seed_mockup(), missing_screw_count=2, impact_count_range=(3, 3))
    anomalies = seed_anomalies(mockup.candidates, rng=5, settings=settings)
    model, index = build_model(mockup, anomalies)
    import mujoco

    def group(name: str) -> int:
        return int(model.geom_group[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)])

    kinds = [anomaly.kind for anomaly in anomalies.anomalies]
    for position, kind in enumerate(kinds):
        if kind in ("impact", "missing_screw", "swapped_component"):
            assert all(group(name) == ANOMALY_GROUP for name in index.flaw_geoms[position])
        if kind in ("missing_screw", "swapped_component"):
            assert all(group(name) == PRISTINE_GROUP for name in index.pristine_geoms[position])
    assert sum(kind == "impact" for kind in kinds) == 3


def test_mjcf_has_no_emission_and_spot_lamp() -> None:
    mockup = truss_mockup()
    xml, assets, _ = scene_mjcf(mockup, seed_anomalies(mockup.candidates, rng=0))
    assert 'emission="0"' in xml and 'type="directional"' in xml  # only the room's ambient is directional
    assert 'name="solar_lamp" mode="fixed" type="spot"' in xml
    assert set(assets) == {"brushed.png", "grain.png", "cells.png"}


def test_no_two_box_faces_overlap_in_one_plane() -> None:
    """Coplanar faces facing the same way z-fight: their pixels flicker with the pose, and a reference and
    an inspection frame then differ there like a flaw (seen at the ORU rims before they were trimmed)."""
    from rsi.sim.dent import local_rotation

    faces = []
    for part in (p for p in truss_mockup().parts if p.shape == "box"):
        rotation, half = local_rotation(part.zaxis), np.asarray(part.size)
        for axis in range(3):
            for sign in (1, -1):
                normal = sign * rotation[:, axis]
                others = [k for k in range(3) if k != axis]
                centre = np.asarray(part.pos) + normal * half[axis]
                faces.append((part.name, normal, centre, [(rotation[:, k], half[k]) for k in others]))
    clashes = []
    for i, (name, normal, centre, extent) in enumerate(faces):
        for other, normal_b, centre_b, extent_b in faces[i + 1 :]:
            same_plane = np.dot(normal, normal_b) > 1 - 1e-9 and abs(np.dot(centre_b - centre, normal)) < 1e-9
            if other == name or not same_plane:
                continue
            offset = centre_b - centre
            if all(
                abs(np.dot(offset, axis)) < half + sum(abs(np.dot(axis, b)) * h for b, h in extent_b) - 1e-9
                for axis, half in extent
            ):
                clashes.append((name, other))
    assert clashes == []


def test_rays_to_a_grid_mesh_s_face_meet_it_borders_included() -> None:
    # rays from 0.3 m to points on every large box's face, its borders included (the CAD coverage's
    # samples lie there): the grid mesh drawn for the lighting is met there or in front (a part touching
    # it), never passed through
    import mujoco

    built = truss_mockup()
    model, _ = build_model(built, AnomalySet(()))  # the CAD: no replacement's dent in the way
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    met, expected = _face_hits(model, data, built)
    assert (met >= 0).all()
    assert np.all(met <= expected + 2e-6)
    assert np.mean(np.abs(met - expected) < 2e-6) > 0.5


def _face_hits(model: object, data: object, built: object) -> tuple[np.ndarray, np.ndarray]:
    """Distance met and distance to the face of rays to a 5 x 5 grid on each large box's +z face."""
    import mujoco

    met, expected = [], []
    for part in built.parts:  # type: ignore[attr-defined]
        if part.shape != "box" or 2 * max(part.size) <= MESHED_BOX_M:
            continue
        rotation = local_rotation(part.zaxis)  # a mesh geom's own frame is its inertia's: the part's is kept
        for u in np.linspace(-1.0, 1.0, 5):
            for w in np.linspace(-1.0, 1.0, 5):
                local = np.array([u * part.size[0], w * part.size[1], part.size[2]])
                target = np.asarray(part.pos) + rotation @ local
                start = target + rotation[:, 2] * 0.3 + rotation[:, 0] * 0.05
                direction = (target - start) / np.linalg.norm(target - start)
                found = np.array([-1], dtype=np.int32)
                met.append(mujoco.mj_ray(model, data, start, direction, None, 1, -1, found))
                expected.append(np.linalg.norm(target - start))
    return np.array(met), np.array(expected)


def test_grid_meshes_must_be_a_bool() -> None:
    built = truss_mockup()
    anomalies = seed_anomalies(built.candidates, rng=np.random.default_rng(0), settings=AnomalySettings())
    with pytest.raises(InputError, match="grid_meshes must be True or False"):
        scene_mjcf(built, anomalies, grid_meshes="yes")  # type: ignore[arg-type]
