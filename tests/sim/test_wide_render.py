"""Issue 13 in pixels: every anomaly subtype renders onto its truth mask, in the right direction, and dents
are pressed into the skin a camera sees (the hidden-dent and proud-dent faults)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import numpy as np
import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.sim.anomalies import Anomaly, AnomalySet, Impact, SwappedComponent
from rsi.sim.mockup import Mockup, truss_mockup
from rsi.sim.world import View, World

SIZE = (240, 320)  # 1.3 mm a pixel at the 0.5 m standoff: a 4 mm spot covers a few pixels whole
MOCKUP = truss_mockup()
PATCHES = {patch.name: patch for patch in MOCKUP.candidates.impact_patches}
SITES = {site.name: site for site in MOCKUP.candidates.component_sites}
DEPTH_M = 0.008

# (subtype, patch, vista): every impact subtype, and every surface a camera sees
IMPACTS = (
    ("dark-uniform", "C_cells", "C_panel"),
    ("dark-crater", "A_door_face", "A_door"),
    ("bright-uniform", "A_kapton_patch_0", "A_kapton"),
    ("bright-crater", "A_face_upper", "A_kapton"),
    ("bright-crater", "B_tank_mid", "B_tank"),
    ("dark-uniform", "B_plate_top", "B_tank"),
    ("dark-crater", "D_tube_high_skin", "D_tubing"),
    ("bright-uniform", "D_tank_1_skin", "D_tubing"),
)


def _impact(subtype: str, patch_name: str) -> Impact:
    polarity, profile = subtype.split("-")
    patch = PATCHES[patch_name]
    position, normal = patch.place((0.5, 0.5), 0.0)
    return Impact(
        site=patch_name,
        position_m=position,
        normal=normal,
        size_m=4e-3,
        surface=patch.surface,
        profile=profile,
        darkening=0.7,
        centre_darkening=0.9 if profile == "crater" else 0.7,
        centre_diameter_m=4e-3 / 3 if profile == "crater" else 4e-3,
        polarity=polarity,
    )


def _swap(site: str, off_centre: tuple[float, float] = (0.5, 0.5), **defect: object) -> SwappedComponent:
    (patch,) = MOCKUP.candidates.dent_patches[site]
    record = SITES[site]
    radius = float(defect.pop("defect_radius_m", 0.03 + 2 * DEPTH_M))  # type: ignore[arg-type]
    centre, normal = patch.place(off_centre, min(radius, patch.largest_radius_m))
    return SwappedComponent(
        site=site,
        position_m=record.position_m,
        normal=record.normal,
        size_m=record.size_m,
        surface=record.surface,
        defect_centre_m=centre,
        defect_normal=normal,
        defect_radius_m=radius,
        **defect,  # type: ignore[arg-type]
    )


def _pair(world: World, vista: str) -> tuple[View, View]:
    inspection = world.render(vista, size=SIZE, state="inspection")
    reference = world.render(vista, size=SIZE, state="reference", truth=False)
    return inspection, reference


def _light(view: View) -> np.ndarray:
    """Noise-free luminance of the frame's lights (render units): the camera noise left out."""
    return sum(view.basis.values())  # type: ignore[return-value]


@pytest.fixture(scope="module")
def impacts_world() -> Iterator[World]:
    anomalies = AnomalySet(tuple(_impact(subtype, patch) for subtype, patch, _ in IMPACTS))
    built = World(MOCKUP, anomalies, seed=0)
    yield built
    built.close()


def test_every_impact_subtype_renders_onto_its_mask_in_its_direction(impacts_world: World) -> None:
    for vista in dict.fromkeys(view for _, _, view in IMPACTS):
        inspection, reference = _pair(impacts_world, vista)
        change = _light(inspection) - _light(reference)
        for index, (subtype, patch, seen_from) in enumerate(IMPACTS):
            if seen_from != vista:
                continue
            mask = inspection.flaw_masks.get(index)
            assert mask is not None and mask.any(), (subtype, patch)
            # the spot's own pixels, not the reference's misregistration around them: the strongest change
            strongest = change[mask][np.argmax(np.abs(change[mask]))]
            if subtype.startswith("dark"):
                assert strongest < 0, (subtype, patch, strongest)
            else:
                assert strongest > 0, (subtype, patch, strongest)


def _mockup_world(anomalies: tuple[Anomaly, ...], mockup: Mockup = MOCKUP) -> World:
    return World(mockup, AnomalySet(anomalies), seed=0)


@pytest.mark.parametrize(
    ("site", "vista"), [("A_oru", "A_kapton"), ("B_tank", "B_tank"), ("D_tank_0", "D_tubing")]
)
def test_a_dent_is_pressed_in_where_a_camera_sees_it(site: str, vista: str) -> None:
    """Hidden dent (issue 13): the A ORU's dent was pressed into its body's front, behind the fill plate and
    the door, so the rendered depth did not change. Proud dent: a tank's dent was a flat disc standing proud
    of the skin, nearer the camera. Now the depth at the dent's centre grows by the dent's depth."""
    dent = _swap(site, defect="dented", dent_depth_m=DEPTH_M)
    world = _mockup_world((dent,))
    try:
        inspection, reference = _pair(world, vista)
        reference_depth = world.render(vista, size=SIZE, state="reference").depth_m
    finally:
        world.close()
    assert inspection.depth_m is not None and reference_depth is not None
    (col, row), along = (value[0] for value in inspection.pose.project(np.asarray([dent.defect_at[0]])))
    row, col = round(row), round(col)
    # visible: the pristine surface at that pixel is the dent's own point
    assert abs(float(reference_depth[row, col]) - float(along)) < 1e-3
    pressed = float(inspection.depth_m[row, col] - reference_depth[row, col])
    # the pose differs between visits by the drawn error; depth along the view axis stays within 1 mm
    assert pressed == pytest.approx(DEPTH_M, abs=1.5e-3)
    assert inspection.flaw_masks[0][row, col]
    assert np.abs(_light(inspection) - _light(reference))[inspection.flaw_masks[0]].max() > 5.0


@pytest.mark.parametrize(
    ("site", "vista", "defect", "brighter"),
    [
        ("A_oru", "A_kapton", {"defect_radius_m": 0.03}, False),
        ("C_panel", "C_panel", {"defect_radius_m": 0.04}, True),
        ("D_tank_0", "D_tubing", {"defect_radius_m": 0.0}, True),
        ("B_tank", "B_tank", {"defect_radius_m": 0.0}, False),
    ],
)
def test_every_discolouring_renders_onto_its_mask(
    site: str, vista: str, defect: dict[str, float], brighter: bool
) -> None:
    factor = 1.4 if brighter else 0.6
    swap = _swap(site, defect="discoloured", reflectance_factor=factor, **defect)
    world = _mockup_world((swap,))
    try:
        inspection, reference = _pair(world, vista)
    finally:
        world.close()
    mask = inspection.flaw_masks[0]
    expected = "patch" if defect["defect_radius_m"] else "whole"
    assert swap.subtype == f"discolour-{expected}-{'brighter' if brighter else 'darker'}"
    change = np.median((_light(inspection) - _light(reference))[mask])
    assert (change > 0) == brighter and abs(change) > 1.0
