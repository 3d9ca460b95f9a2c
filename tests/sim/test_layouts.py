"""The mock-up's layouts (issue 15): "truss" pinned to the seed mock-up as it was built before layouts
existed, and "truss-b", the same kinds of component arranged differently on four bays (bad input here too).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rsi.errors import InputError
from rsi.sim import LAYOUTS
from rsi.sim.anomalies import AnomalySettings, SwappedComponent, seed_anomalies
from rsi.sim.dent import local_rotation
from rsi.sim.mockup import (
    BAY_M,
    Layout,
    Mockup,
    Part,
    Placement,
    build_mockup,
    mockup,
    truss_mockup,
)
from rsi.sim.render import SceneRenderer
from rsi.sim.scene import scene_mjcf
from rsi.sim.world import SCENES, World, arm_home_tool_tip_m, load

DATA = Path(__file__).parent / "data"
DECIMALS = 9  # 1 nm: far below a pixel, above the last-bit noise of re-ordered float sums
SMALL = (48, 64)
# Every kind at once, several of each: what the wide draw plants over many runs
EVERY_KIND = AnomalySettings(
    anomaly_free_probability=0.0,
    active_peltier_count=2,
    active_leak_count_range=(2, 2),
    impact_count_range=(8, 8),
    missing_screw_count=4,
    swapped_component_count_range=(2, 2),
)


# ------------------------------------------------------------------------------------------ helpers


def _canonical(value: Any) -> Any:
    """Dataclasses, mappings and sequences as plain JSON values, floats rounded to DECIMALS."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        fields = {f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}
        return {"__type__": type(value).__name__, **fields}
    if isinstance(value, dict):
        return {str(key): _canonical(item) for key, item in value.items()}
    if isinstance(value, (tuple, list, np.ndarray)):
        return [_canonical(item) for item in value]
    if isinstance(value, (bool, str)) or value is None:
        return value
    if isinstance(value, (int, np.integer)):
        return int(value)
    number = round(float(value), DECIMALS)
    return 0.0 if number == 0.0 else number


def _geometry(built: Mockup) -> dict[str, Any]:
    """What the snapshot in tests/sim/data/truss_mockup.json holds, as JSON would give it back."""
    geometry = {
        "parts": _canonical(built.parts),
        "door_hinge_m": _canonical(built.door.hinge_m),
        "candidates": _canonical(built.candidates),
        "vistas": _canonical(built.vistas),
        "components": _canonical(built.components),
    }
    loaded: dict[str, Any] = json.loads(json.dumps(geometry))
    return loaded


def _box(part: Part) -> tuple[np.ndarray, np.ndarray]:
    """Axis-aligned bounds of a part in the world (exact for the mock-up's axis-aligned primitives)."""
    rotation = local_rotation(part.zaxis)
    if part.shape == "box":
        half = np.abs(rotation) @ np.asarray(part.size)
    elif part.shape == "sphere":
        half = np.full(3, part.size[0])
    else:  # a cylinder's or capsule's extent: its disc across the axis plus its length along it
        radius, length = part.size[0], part.size[1] + (part.size[0] if part.shape == "capsule" else 0.0)
        axis = np.abs(np.asarray(part.zaxis))
        half = radius * np.sqrt(np.clip(1.0 - axis**2, 0.0, 1.0)) + length * axis
    centre = np.asarray(part.pos)
    return centre - half, centre + half


def _owner(part: Part) -> str:
    """The component letter a part belongs to ("truss" for the frame): a screw is its plate's."""
    if part.component == "truss":
        return "truss"
    if part.component.startswith("screw_"):
        return part.component.split("_")[1]
    return part.component.split("_")[0]


def _surface_distance_m(part: Part, point: np.ndarray) -> float:
    """Distance from `point` to the surface of a part (signed distance function, absolute value)."""
    local = local_rotation(part.zaxis).T @ (point - np.asarray(part.pos))
    if part.shape == "sphere":
        return abs(float(np.linalg.norm(local)) - part.size[0])
    if part.shape == "capsule":
        along = np.clip(local[2], -part.size[1], part.size[1])
        return abs(float(np.linalg.norm(local - [0.0, 0.0, along])) - part.size[0])
    if part.shape == "box":
        q = np.abs(local) - np.asarray(part.size)
    else:  # cylinder: radial and axial
        q = np.array([np.hypot(local[0], local[1]) - part.size[0], abs(local[2]) - part.size[1]])
    return abs(float(np.linalg.norm(np.maximum(q, 0.0)) + min(float(q.max()), 0.0)))


@pytest.fixture(scope="module")
def truss_b() -> Mockup:
    return mockup("truss-b")


@pytest.fixture(scope="module")
def world_b() -> Iterator[World]:
    built = load("truss-b", seed=5, arm=True)
    yield built
    built.close()


# ------------------------------------------------------------------------------------------- truss


def test_truss_is_the_seed_mockup_as_built_before_layouts() -> None:
    # taken from the code before the refactor; the plates' material "plate" (which the scene used to give
    # them by name) is the one change
    assert _geometry(truss_mockup()) == json.loads((DATA / "truss_mockup.json").read_text())
    assert _geometry(mockup("truss")) == _geometry(truss_mockup())


def test_truss_gives_byte_identical_mjcf_for_the_draws_taken_before_layouts() -> None:
    # pinned before layouts; pinned again once when the large boxes became grid meshes (issue 15: a
    # fifth of the renderer's geometry, the same lighting, tests/sim/test_render.py)
    pinned = json.loads((DATA / "truss_mjcf_sha256.json").read_text())
    built = truss_mockup()
    for key, digest in pinned.items():
        seed, draw = key.split("-")
        settings = AnomalySettings() if draw == "wide" else AnomalySettings.seed_mockup()
        anomalies = seed_anomalies(built.candidates, rng=np.random.default_rng(int(seed)), settings=settings)
        xml, _, _ = scene_mjcf(built, anomalies)
        assert hashlib.sha256(xml.encode()).hexdigest() == digest, key


def test_the_layouts_are_exported_and_the_arm_rail_is_centred_on_each_truss() -> None:
    assert LAYOUTS == SCENES == ("truss", "truss-b")
    for name, bays in (("truss", 3), ("truss-b", 4)):
        built = mockup(name)
        assert built.layout == name and built.length_m == pytest.approx(bays * BAY_M)
        assert arm_home_tool_tip_m(built)[0] == pytest.approx(bays * BAY_M / 2)
        assert built.centre_m[0] == pytest.approx(bays * BAY_M / 2)


# ----------------------------------------------------------------------------------------- truss-b


def test_every_part_of_truss_b_lies_in_its_world(truss_b: Mockup) -> None:
    lows, highs = zip(*(_box(part) for part in truss_b.parts), strict=True)
    low, high = np.min(lows, axis=0), np.max(highs, axis=0)
    # the truss spans x = 0..2.4 m (its nodes 28 mm round), the ORUs hang in front, the panel stands on top
    np.testing.assert_allclose(low[0], -0.028, atol=1e-9)
    np.testing.assert_allclose(high[0], 4 * BAY_M + 0.028, atol=1e-9)
    assert low[1] > -0.5 and high[1] < 0.33
    assert low[2] > 0.87 and high[2] < 1.6


def test_no_two_components_of_truss_b_overlap(truss_b: Mockup) -> None:
    boxes: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for part in truss_b.parts:
        owner = _owner(part)
        if owner == "truss":
            continue
        low, high = _box(part)
        if owner in boxes:
            low, high = np.minimum(boxes[owner][0], low), np.maximum(boxes[owner][1], high)
        boxes[owner] = (low, high)
    assert set(boxes) == {"A", "B", "C", "D", "E"}
    for (first, (low_a, high_a)), (second, (low_b, high_b)) in itertools.combinations(boxes.items(), 2):
        overlap = np.minimum(high_a, high_b) - np.maximum(low_a, low_b)
        assert (overlap <= 0).any(), (first, second)
    # bays permuted: tubing on bay 0, tank on 1 (panel on top), electrical ORU on 2, second tubing on 3
    bays = {owner: int((low[0] + high[0]) / 2 // BAY_M) for owner, (low, high) in boxes.items()}
    assert bays == {"D": 0, "B": 1, "C": 1, "A": 2, "E": 3}


def test_the_truss_b_door_is_hinged_on_its_right_edge_and_swings_out(world_b: World) -> None:
    door = world_b.mockup.door
    part = next(p for p in world_b.mockup.parts if p.name == door.body)
    assert door.hinge_m[0] == pytest.approx(part.pos[0] + part.size[0])  # the right edge, seen from the front
    assert (door.body, door.joint, door.vista) == ("A_door", "A_door_hinge", "A_door")
    assert world_b.vista(door.vista).target_m[0] == pytest.approx(part.pos[0])  # it looks at the door
    geom = world_b.model.geom(door.body).id
    closed = world_b.data.geom_xpos[geom].copy()
    world_b.set_door(np.pi / 2)
    try:
        opened = world_b.data.geom_xpos[geom].copy()
        assert world_b.door_angle_rad == pytest.approx(np.pi / 2)
        assert world_b.readouts()["door_angle_rad"] == pytest.approx(np.pi / 2)
    finally:
        world_b.set_door(0.0)
    # at 90 deg the door stands out of the face at its hinge: half its width out towards the robot (-y)
    np.testing.assert_allclose(opened - closed, [part.size[0], -part.size[0], 0.0], atol=1e-9)
    seed_door = truss_mockup().door
    assert seed_door.axis == (0.0, 0.0, -1.0) and door.axis == (0.0, 0.0, 1.0)  # opposite hands


def test_a_spot_on_the_truss_b_door_rides_on_it() -> None:
    built = mockup("truss-b")
    settings = dataclasses.replace(EVERY_KIND, impact_count_range=(8, 8))
    for seed in range(40):
        anomalies = seed_anomalies(built.candidates, rng=np.random.default_rng(seed), settings=settings)
        on_door = [a for a in anomalies.anomalies if a.kind == "impact" and a.surface == "door"]
        if on_door:
            break
    else:  # pragma: no cover - 320 impacts over ~0.1 m^2 of the mock-up's ~0.8 m^2 of patches
        pytest.fail("no impact on the door in 40 draws")
    xml, _, index = scene_mjcf(built, anomalies)
    door_body = xml[xml.index('<body name="A_door"') : xml.index("</body>", xml.index('<body name="A_door"'))]
    spot = anomalies.anomalies.index(on_door[0])
    assert f'name="{index.flaw_geoms[spot][0]}"' in door_body


def test_the_truss_b_panel_is_turned_a_quarter_on_bay_1(truss_b: Mockup) -> None:
    seed_panel = next(p for p in truss_mockup().parts if p.name == "C_panel")
    panel = next(p for p in truss_b.parts if p.name == "C_panel")
    assert panel.size == (seed_panel.size[1], seed_panel.size[0], seed_panel.size[2])  # long side along y
    assert panel.pos[0] == pytest.approx(1.5 * BAY_M) and panel.pos[2] == seed_panel.pos[2]
    cells = next(p for p in truss_b.candidates.impact_patches if p.name == "C_cells")
    assert cells.u_axis == pytest.approx((0.0, 1.0, 0.0))  # type: ignore[union-attr]
    posts = [p for p in truss_b.parts if p.name.startswith("C_post_")]
    screws = [s for s in truss_b.candidates.screw_sites if s.name.startswith("screw_C_")]
    for point in [p.pos for p in posts] + [s.position_m for s in screws]:  # all under or on the panel
        assert abs(point[0] - panel.pos[0]) < panel.size[0] and abs(point[1]) < panel.size[1]


def test_truss_b_has_two_tubing_oru_each_with_three_leak_holes_on_its_tubing(truss_b: Mockup) -> None:
    assert truss_b.tubing_leaks == (("leak_0", "leak_1", "leak_2"), ("leak_3", "leak_4", "leak_5"))
    assert truss_b.instrument_vistas == {"pyrometer": ("A_kapton",), "gas": ("D_tubing", "E_tubing")}
    sites = {site.name: site for site in truss_b.candidates.leak_sites}
    tubes = {p.name: p for p in truss_b.parts if "_tube_" in p.name}
    for letter, names in zip("DE", truss_b.tubing_leaks, strict=True):
        for name in names:
            point = np.asarray(sites[name].position_m)
            nearest = min(
                _surface_distance_m(tube, point) for tube in tubes.values() if tube.name[0] == letter
            )
            assert nearest < 1e-9, name
    components = {site.name for site in truss_b.candidates.component_sites}
    assert components == {"A_oru", "B_tank", "C_panel", "D_tank_0", "E_tank_0"}
    assert set(truss_b.candidates.dent_patches) == components


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4, 5])
def test_anomalies_drawn_on_truss_b_land_on_its_surfaces(truss_b: Mockup, seed: int) -> None:
    anomalies = seed_anomalies(truss_b.candidates, rng=np.random.default_rng(seed), settings=EVERY_KIND)
    kinds = {anomaly.kind for anomaly in anomalies.anomalies}
    assert {"impact", "missing_screw", "gas_leak", "swapped_component"} <= kinds
    assert kinds & {"hot_spot", "cold_spot"}
    parts = [part for part in truss_b.parts if _owner(part) != "truss"]
    for anomaly in anomalies.anomalies:
        point = np.asarray(anomaly.position_m)
        if isinstance(anomaly, SwappedComponent):
            assert anomaly.site in truss_b.components
            if anomaly.defect_radius_m == 0.0:  # the whole component: its site (a tank's stands 5 mm off)
                continue
            point = np.asarray(anomaly.defect_at[0])
        nearest = min(_surface_distance_m(part, point) for part in parts)
        assert nearest < 1e-6, (anomaly.kind, anomaly.site)


def _segments(world: World, name: str) -> tuple[np.ndarray, dict[int, str]]:
    point = world.vista(name)
    world.place_camera(point.position_m, point.forward, point.up)
    renderer = SceneRenderer(world.model, *SMALL)
    try:
        _, segments = renderer.depth_and_segments(world.data, "isee", state="reference")
    finally:
        renderer.close()
    owners = {world.model.geom(part.name).id: _owner(part) for part in world.mockup.parts}
    return segments, owners


def test_each_hand_vista_of_truss_b_shows_its_component(world_b: World) -> None:
    for name in world_b.vistas:
        if name == "overview":
            continue
        segments, owners = _segments(world_b, name)
        letter = name[0]
        seen = np.vectorize(lambda geom, known=owners: known.get(int(geom), "other"))(segments)
        assert seen[SMALL[0] // 2, SMALL[1] // 2] == letter, name  # the component at the image centre
        assert np.mean(seen == letter) > 0.3, name
        # the mock-up fills most of the frame; the open truss shows the dark room above and below an ORU's
        # plate (0.64-0.77 of the pixels hit the mock-up in the same views on truss)
        assert np.mean(segments >= 0) > 0.6, name
    segments, owners = _segments(world_b, "overview")
    seen = {owners.get(int(geom)) for geom in np.unique(segments)}
    assert {"A", "B", "C", "D", "E", "truss"} <= seen  # the whole mock-up in the overview


def test_the_arm_on_its_rail_reaches_every_front_vista_of_truss_b(world_b: World) -> None:
    from rsi.mission.viewing import reach

    rails = []
    for name in ("D_tubing", "B_tank", "A_door", "A_kapton", "E_tubing"):
        reached = reach(world_b, name)
        assert reached.reachable and reached.shortfall_m < -0.2, name  # as on truss: 20 cm inside
        rails.append(reached.rail_m)
    assert min(rails) < -0.8 and max(rails) > 0.8  # the rail's travel spans both ends of the longer truss
    # as on truss, a camera over the panel on top is beyond the arm on its rail: a plan flags it
    assert not reach(world_b, "C_panel").reachable


def test_the_arm_takes_the_isee_to_the_far_end_of_truss_b(world_b: World) -> None:
    from rsi.mission.transit import ARRIVAL_TOLERANCE_M, transit

    moved = transit(world_b, "E_tubing", rng=0)
    assert moved.reached and moved.position_error_m < ARRIVAL_TOLERANCE_M
    view = world_b.render_from_tool(size=SMALL)
    assert view.component_masks["E_tank_0"].any()  # the second tubing ORU's tank in the arm's frame


# ----------------------------------------------------------------------------------------- bad input


def test_an_unknown_layout_names_the_value_and_the_layouts() -> None:
    with pytest.raises(InputError, match=r"layout='truss-c' is not known\. Choose one of 'truss', 'truss-b'"):
        mockup("truss-c")
    with pytest.raises(InputError, match=r"scene='truss-c' is not known"):
        load("truss-c", seed=0)
    with pytest.raises(InputError, match=r"layout must be an rsi\.sim\.mockup\.Layout"):
        build_mockup("truss-b")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="mockup"):
        arm_home_tool_tip_m("truss-b")  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ({"kind": "radiator"}, "kind='radiator' is not known"),
        ({"letter": "ab"}, "letter must be one capital letter"),
        ({"bay": -1}, "bay"),
        ({"face": "back"}, "face='back' is not known"),
        ({"face": "top"}, "a tank_oru goes on the 'front' face"),
        ({"rotation_deg": 90}, "rotation_deg=90 is not possible for a tank_oru"),
        ({"kind": "solar_panel", "face": "top", "rotation_deg": 45}, "rotation_deg=45"),
        ({"hinge": "up"}, "hinge='up' is not known"),
        ({"hinge": "right"}, "hinge='right' is for the electrical ORU's door"),
    ],
)
def test_a_bad_placement_names_what_to_change(arguments: dict[str, Any], match: str) -> None:
    with pytest.raises(InputError, match=match):
        Placement(**{"kind": "tank_oru", "letter": "B", "bay": 0, **arguments})


_DOOR = Placement("electrical_oru", "A", 0)


@pytest.mark.parametrize(
    ("arguments", "match"),
    [
        ({"name": ""}, "name must be a non-empty string"),
        ({"bays": 0}, "bays"),
        ({"bays": 9}, "bays must be at most 8"),
        ({"placements": [_DOOR]}, "placements must be a tuple of Placement"),
        ({"placements": (_DOOR, Placement("tank_oru", "B", 3))}, "B is on bay 3, but the truss has bays 0-1"),
        ({"placements": (_DOOR, Placement("tank_oru", "A", 1))}, "share a letter"),
        ({"placements": (_DOOR, Placement("tank_oru", "B", 0))}, "share a bay face"),
        ({"placements": (Placement("tank_oru", "B", 0),)}, "has 0 electrical ORUs; it needs exactly one"),
    ],
)
def test_a_bad_layout_names_what_to_change(arguments: dict[str, Any], match: str) -> None:
    with pytest.raises(InputError, match=match):
        Layout(**{"name": "mine", "bays": 2, "placements": (_DOOR,), **arguments})


def test_a_layout_of_ones_own_builds() -> None:
    built = build_mockup(Layout("mine", 1, (Placement("electrical_oru", "A", 0, hinge="right"),)))
    assert built.layout == "mine" and built.candidates.leak_sites == () and built.tubing_leaks == ()
    assert built.instrument_vistas == {"pyrometer": ("A_kapton",), "gas": ()}
