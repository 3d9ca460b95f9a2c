"""Seeded anomalies of the mock-up (seed §4): determinism, counts, ranges, truth records, every raise."""

from __future__ import annotations

import dataclasses
import doctest
import json
import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import rsi.sim.anomalies as anomalies_module
from rsi.errors import InputError
from rsi.sim.anomalies import (
    ANOMALY_KINDS,
    AnomalySet,
    AnomalySettings,
    Candidates,
    CylinderPatch,
    GasLeak,
    Impact,
    MissingScrew,
    Patch,
    Site,
    SwappedComponent,
    ThermalSpot,
    seed_anomalies,
)

TOLERANCE_M = 1e-12  # positions are sums of a few metre-scale floats


def _candidates(
    peltier: int = 6, leaks: int = 3, screws: int = 12, patches: int = 2, components: int = 3
) -> Candidates:
    """A small mock-up: Peltier sites on a panel at z=0, leaks on a tank, screws, two tilted patches."""
    return Candidates(
        peltier_sites=tuple(
            Site(f"peltier_{k}", (0.2 * k, 0.0, 0.0), (0, 0, 1), "kapton", 0.05) for k in range(peltier)
        ),
        leak_sites=tuple(
            Site(f"leak_{k}", (1.0, 0.1 * k, 0.5), (1, 0, 0), "aluminium") for k in range(leaks)
        ),
        screw_sites=tuple(
            Site(f"screw_{k}", (0.05 * k, 0.3, 0.0), (0, 0, 1), "aluminium", 0.006) for k in range(screws)
        ),
        impact_patches=tuple(
            Patch(
                f"panel_{k}", (0.0, 1.0 + k, 0.2), (0, 1, 1), (1, 0, 0), (0.1, 0.05 + 0.05 * k), "solar_cell"
            )
            for k in range(patches)
        ),
        component_sites=tuple(
            Site(f"tank_{k}", (2.0, 0.3 * k, 0.0), (0, 0, 1), "aluminium", 0.3) for k in range(components)
        ),
    )


CANDIDATES = _candidates()
SEED_MOCKUP = AnomalySettings.seed_mockup()


# ------------------------------------------------------------------------------------------ determinism


def test_same_seed_gives_the_same_anomalies() -> None:
    first = seed_anomalies(CANDIDATES, rng=42)
    second = seed_anomalies(CANDIDATES, rng=np.random.default_rng(42))
    assert first == second
    assert first.to_dict() == second.to_dict()


def test_different_seeds_give_different_anomalies() -> None:
    worlds = [json.dumps(seed_anomalies(CANDIDATES, rng=seed).to_dict()) for seed in range(6)]
    assert len(set(worlds)) == len(worlds)


def test_seed_mockup_preset_follows_the_seed_paper() -> None:
    world = seed_anomalies(CANDIDATES, rng=3, settings=SEED_MOCKUP)
    counts = world.counts()
    # seed §4: two Peltier modules on at a time, one of three leaks; issue 3: 0.5-3 mm impacts.
    assert counts["hot_spot"] + counts["cold_spot"] == 2
    assert counts["gas_leak"] == 1
    assert counts["impact"] == 5
    assert counts["swapped_component"] == 1
    assert sorted(counts) == sorted(ANOMALY_KINDS)
    for spot in world.thermal_spots:
        assert abs(spot.delta_k) == 30.0
        assert spot.radius_m == anomalies_module.KAPTON_RADIUS_M
    assert len({spot.site for spot in world.thermal_spots}) == 2
    (leak,) = world.gas_leaks
    assert 0.0 <= leak.start_time_s <= 30.0
    assert leak.hole_diameter_m == 1e-3
    assert leak.site in {site.name for site in CANDIDATES.leak_sites}
    assert leak.exit_ppm == 5000.0
    for impact in world.of_kind("impact"):
        assert isinstance(impact, Impact)
        assert impact.polarity == "dark" and 0.3 <= impact.darkening <= 0.7 and impact.size_m <= 3e-3


@pytest.mark.parametrize(("probability", "kind"), [(1.0, "hot_spot"), (0.0, "cold_spot")])
def test_current_direction_sets_hot_or_cold(probability: float, kind: str) -> None:
    chosen = dataclasses.replace(SEED_MOCKUP, hot_probability=probability)
    world = seed_anomalies(CANDIDATES, rng=0, settings=chosen)
    assert [spot.kind for spot in world.thermal_spots] == [kind, kind]
    assert all((spot.delta_k > 0) == (kind == "hot_spot") for spot in world.thermal_spots)


@pytest.mark.parametrize(("probability", "expected"), [(0.0, 0), (1.0, 12)])
def test_screw_probability_extremes(probability: float, expected: int) -> None:
    chosen = dataclasses.replace(SEED_MOCKUP, missing_screw_probability=probability)
    assert seed_anomalies(CANDIDATES, rng=1, settings=chosen).counts()["missing_screw"] == expected


def test_missing_screw_truth_is_the_site() -> None:
    world = seed_anomalies(
        CANDIDATES, rng=5, settings=dataclasses.replace(SEED_MOCKUP, missing_screw_count=4)
    )
    screws = world.of_kind("missing_screw")
    sites = {site.name: site for site in CANDIDATES.screw_sites}
    assert len({screw.site for screw in screws}) == 4
    for screw in screws:
        assert isinstance(screw, MissingScrew)
        assert screw.position_m == sites[screw.site].position_m
        assert screw.size_m == 0.006


# ----------------------------------------------------------------------------------------- properties


def _in_patch(impact: Impact, patch: Patch) -> tuple[float, float, float]:
    offset = np.asarray(impact.position_m) - np.asarray(patch.centre_m)
    return (
        float(offset @ np.asarray(patch.u_axis)),
        float(offset @ np.asarray(patch.v_axis)),
        float(offset @ np.asarray(patch.normal)),
    )


def _pair(low: float, high: float) -> st.SearchStrategy[tuple[float, float]]:
    return st.tuples(st.floats(low, high), st.floats(low, high)).map(lambda pair: (min(pair), max(pair)))


def _counts(low: int, high: int) -> st.SearchStrategy[tuple[int, int]]:
    return st.tuples(st.integers(low, high), st.integers(low, high)).map(lambda pair: (min(pair), max(pair)))


SETTINGS = st.builds(
    AnomalySettings,
    anomaly_free_probability=st.just(0.0),
    active_peltier_count=st.integers(0, 6),
    peltier_delta_range_k=_pair(0.5, 80.0),
    active_leak_count_range=_counts(0, 3),
    leak_start_window_s=_pair(0.0, 100.0),
    leak_exit_ppm_range=_pair(10.0, 1e5),
    missing_screw_count=st.one_of(st.none(), st.integers(0, 12)),
    impact_count_range=_counts(0, 25),
    impact_diameter_range_m=_pair(0.5e-3, 3e-3),
    impact_profiles=st.sampled_from([("uniform",), ("crater",), ("uniform", "crater")]),
    impact_bright_probability=st.floats(0.0, 1.0),
    impact_contrast_range=_pair(0.0, 1.0),
    swapped_component_count_range=_counts(0, 3),
    component_defects=st.sampled_from([("dented",), ("discoloured",), ("dented", "discoloured")]),
    discolour_patch_probability=st.floats(0.0, 1.0),
    discolour_brighter_probability=st.floats(0.0, 1.0),
)


@settings(max_examples=60, deadline=None)
@given(chosen=SETTINGS, seed=st.integers(0, 2**32 - 1))
def test_counts_and_ranges_are_respected(chosen: AnomalySettings, seed: int) -> None:
    peltier, screws = chosen.active_peltier_count, chosen.missing_screw_count
    diameter_m, window_s = chosen.impact_diameter_range_m, chosen.leak_start_window_s
    world = seed_anomalies(CANDIDATES, rng=seed, settings=chosen)
    counts = world.counts()
    assert counts["hot_spot"] + counts["cold_spot"] == peltier
    assert chosen.active_leak_count_range[0] <= counts["gas_leak"] <= chosen.active_leak_count_range[1]
    if screws is not None:
        assert counts["missing_screw"] == screws
    assert chosen.impact_count_range[0] <= counts["impact"] <= chosen.impact_count_range[1]
    low, high = chosen.swapped_component_count_range
    assert low <= counts["swapped_component"] <= high
    assert len(world) == sum(counts.values())
    for record_type in (ThermalSpot, GasLeak, MissingScrew, SwappedComponent):
        names = [item.site for item in world.anomalies if isinstance(item, record_type)]
        assert len(names) == len(set(names)), f"a {record_type.__name__} site was chosen twice"
    for spot in world.thermal_spots:
        assert chosen.peltier_delta_range_k[0] <= abs(spot.delta_k) <= chosen.peltier_delta_range_k[1]
    for leak in world.gas_leaks:
        assert window_s[0] <= leak.start_time_s <= window_s[1]
        assert chosen.leak_exit_ppm_range[0] <= leak.exit_ppm <= chosen.leak_exit_ppm_range[1]
    patches = {patch.name: patch for patch in CANDIDATES.impact_patches}
    for impact in world.of_kind("impact"):
        assert isinstance(impact, Impact)
        assert diameter_m[0] <= impact.size_m <= diameter_m[1]
        assert impact.profile in chosen.impact_profiles
        assert impact.subtype == f"{impact.polarity}-{impact.profile}"
        assert chosen.impact_contrast_range[0] <= impact.darkening <= chosen.impact_contrast_range[1]
        if impact.profile == "crater":
            # seed §2.4: the crater's centre is stronger than the uniform surround.
            assert impact.centre_darkening >= impact.darkening
            assert impact.centre_diameter_m < impact.size_m
        else:
            assert impact.centre_darkening == impact.darkening
            assert impact.centre_diameter_m == impact.size_m
        patch = patches[impact.site]
        u_m, v_m, n_m = _in_patch(impact, patch)
        radius_m = impact.size_m / 2.0
        assert abs(u_m) <= patch.half_extent_m[0] - radius_m + TOLERANCE_M
        assert abs(v_m) <= patch.half_extent_m[1] - radius_m + TOLERANCE_M
        assert abs(n_m) < TOLERANCE_M
        assert impact.normal == patch.normal
    for swapped in world.of_kind("swapped_component"):
        assert isinstance(swapped, SwappedComponent)
        assert swapped.defect in chosen.component_defects
        if swapped.defect == "dented":
            assert 1e-3 <= swapped.dent_depth_m <= 10e-3
            assert swapped.reflectance_factor == 1.0 and swapped.subtype == "dent"
        else:
            darker, brighter = chosen.reflectance_factor_range, chosen.brightening_factor_range
            factor = swapped.reflectance_factor
            assert darker[0] <= factor <= darker[1] or brighter[0] <= factor <= brighter[1]
            assert swapped.dent_depth_m == 0.0
            # the test components have no dent patches: a discoloured one changes as a whole
            assert swapped.subtype in ("discolour-whole-darker", "discolour-whole-brighter")


# ---------------------------------------------------------------------------------------------- truth


def test_truth_is_json_ready_and_round_trips() -> None:
    world = seed_anomalies(
        CANDIDATES, rng=11, settings=dataclasses.replace(SEED_MOCKUP, missing_screw_count=2)
    )
    truth = json.loads(json.dumps(world.to_dict()))
    assert truth["schema"] == "rsi.sim.anomalies/1"
    assert sum(truth["counts"].values()) == len(truth["anomalies"]) == len(world)
    first = truth["anomalies"][0]
    assert first["kind"] in ("hot_spot", "cold_spot")
    assert len(first["position_m"]) == 3
    assert {"site", "size_m", "surface", "delta_k", "radius_m", "subtype"} <= set(first)
    assert [entry["subtype"] for entry in truth["anomalies"]] == [item.subtype for item in world.anomalies]
    assert AnomalySet.from_dict(truth) == world


def test_patch_axes_are_orthonormal() -> None:
    patch = Patch("p", (0, 0, 0), (0, 0, 2), (1, 0, 1), (0.1, 0.1))
    axes = np.array([patch.u_axis, patch.v_axis, patch.normal])
    np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-15)
    assert patch.area_m2 == pytest.approx(0.04)


def test_docstring_examples_run() -> None:
    assert doctest.testmod(anomalies_module).failed == 0


# --------------------------------------------------------------------------------------------- raises


@pytest.mark.parametrize(
    ("setting", "count", "argument"),
    [
        ("active_peltier_count", 7, "active_peltier_count"),
        ("active_leak_count_range", (0, 4), "active_leak_count_range"),
        ("missing_screw_count", 13, "missing_screw_count"),
        ("swapped_component_count_range", (1, 4), "swapped_component_count_range"),
    ],
)
def test_counts_beyond_candidates_raise(setting: str, count: object, argument: str) -> None:
    chosen = dataclasses.replace(SEED_MOCKUP, **{setting: count})
    with pytest.raises(InputError, match=argument):
        seed_anomalies(CANDIDATES, rng=0, settings=chosen)


def test_impacts_without_patches_raise() -> None:
    with pytest.raises(InputError, match="impact_patches"):
        seed_anomalies(_candidates(patches=0), rng=0, settings=SEED_MOCKUP)


def test_patch_too_small_for_the_largest_impact_raises() -> None:
    tiny = dataclasses.replace(
        CANDIDATES, impact_patches=(Patch("chip", (0, 0, 0), (0, 0, 1), (1, 0, 0), (0.01, 0.001)),)
    )
    with pytest.raises(InputError, match="impact_patches"):
        seed_anomalies(tiny, rng=0, settings=SEED_MOCKUP)


@pytest.mark.parametrize(
    ("changes", "argument"),
    [
        ({"active_peltier_count": -1}, "active_peltier_count"),
        ({"active_peltier_count": True}, "active_peltier_count"),
        ({"active_leak_count_range": (1.5, 2)}, "active_leak_count_range"),
        ({"active_leak_count_range": (2, 1)}, "active_leak_count_range"),
        ({"active_leak_count_range": (-1, 1)}, "active_leak_count_range"),
        ({"active_leak_count_range": 1}, "active_leak_count_range"),
        ({"peltier_delta_range_k": (0.0, 1.0)}, "peltier_delta_range_k"),
        ({"peltier_delta_range_k": (40.0, 2.0)}, "peltier_delta_range_k"),
        ({"peltier_delta_range_k": (1.0, float("nan"))}, "peltier_delta_range_k"),
        ({"anomaly_free_probability": 1.1}, "anomaly_free_probability"),
        ({"anomaly_free_probability": -0.1}, "anomaly_free_probability"),
        ({"hot_probability": 1.5}, "hot_probability"),
        ({"peltier_radius_m": -0.01}, "peltier_radius_m"),
        ({"leak_start_window_s": (5.0, 1.0)}, "leak_start_window_s"),
        ({"leak_start_window_s": (-1.0, 1.0)}, "leak_start_window_s"),
        ({"leak_start_window_s": 3.0}, "leak_start_window_s"),
        ({"leak_hole_diameter_m": 0.0}, "leak_hole_diameter_m"),
        ({"leak_exit_velocity_m_s": -1.0}, "leak_exit_velocity_m_s"),
        ({"leak_exit_ppm_range": (0.0, 10.0)}, "leak_exit_ppm_range"),
        ({"leak_exit_ppm_range": (5e4, 5e2)}, "leak_exit_ppm_range"),
        ({"leak_turn_on_time_s": 0.0}, "leak_turn_on_time_s"),
        ({"missing_screw_count": -2}, "missing_screw_count"),
        ({"missing_screw_probability": -0.1}, "missing_screw_probability"),
        ({"impact_count_range": (-1, 3)}, "impact_count_range"),
        ({"impact_count_range": (8, 0)}, "impact_count_range"),
        ({"impact_count_range": (0, True)}, "impact_count_range"),
        ({"impact_diameter_range_m": (0.0, 1e-3)}, "impact_diameter_range_m"),
        ({"impact_diameter_range_m": (4e-3, 5e-4)}, "impact_diameter_range_m"),
        ({"impact_profiles": ("uniform", "peak")}, "impact_profiles"),
        ({"impact_profiles": ()}, "impact_profiles"),
        ({"impact_profiles": "crater"}, "impact_profiles"),
        ({"impact_bright_probability": 2.0}, "impact_bright_probability"),
        ({"impact_contrast_range": (0.5, 1.5)}, "impact_contrast_range"),
        ({"impact_contrast_range": (0.8, 0.1)}, "impact_contrast_range"),
        ({"impact_crater_extra_range": (0.9, 0.1)}, "impact_crater_extra_range"),
        ({"impact_core_fraction": 0.0}, "impact_core_fraction"),
        ({"swapped_component_count_range": (-1, 0)}, "swapped_component_count_range"),
        ({"swapped_component_count_range": (2, 0)}, "swapped_component_count_range"),
        ({"defect_off_centre": "yes"}, "defect_off_centre"),
        ({"discolour_patch_probability": -0.5}, "discolour_patch_probability"),
        ({"discolour_brighter_probability": 1.5}, "discolour_brighter_probability"),
        ({"discolour_patch_radius_range_m": (0.0, 0.01)}, "discolour_patch_radius_range_m"),
        ({"discolour_patch_radius_range_m": (0.04, 0.01)}, "discolour_patch_radius_range_m"),
        ({"brightening_factor_range": (0.9, 1.2)}, "brightening_factor_range"),
        ({"brightening_factor_range": (1.2, 2.0)}, "brightening_factor_range"),
        ({"component_defects": ("melted",)}, "component_defects"),
        ({"dent_depth_range_m": (-1e-3, 1e-3)}, "dent_depth_range_m"),
        ({"dent_depth_range_m": (1e-2, 1e-3)}, "dent_depth_range_m"),
        ({"reflectance_factor_range": (0.5, 2.0)}, "reflectance_factor_range"),
    ],
)
def test_bad_settings_raise_naming_the_setting(changes: dict[str, Any], argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        AnomalySettings(**changes)


@pytest.mark.parametrize(
    ("arguments", "argument"),
    [
        ({"name": "", "position_m": (0, 0, 0), "normal": (0, 0, 1)}, "name"),
        ({"name": "s", "position_m": (0, 0), "normal": (0, 0, 1)}, "position_m"),
        ({"name": "s", "position_m": "xyz", "normal": (0, 0, 1)}, "position_m"),
        ({"name": "s", "position_m": (0, float("nan"), 0), "normal": (0, 0, 1)}, "position_m"),
        ({"name": "s", "position_m": (0, 0, 0), "normal": (0, 0, 0)}, "normal"),
        ({"name": "s", "position_m": (0, 0, 0), "normal": (0, 0, 1), "surface": ""}, "surface"),
        ({"name": "s", "position_m": (0, 0, 0), "normal": (0, 0, 1), "size_m": -1.0}, "size_m"),
    ],
)
def test_bad_site_raises(arguments: dict[str, Any], argument: str) -> None:
    with pytest.raises(InputError, match=argument):
        Site(**arguments)


@pytest.mark.parametrize(
    ("arguments", "argument"),
    [
        ({"u_axis": (0, 0, 3)}, "u_axis"),
        ({"half_extent_m": (0.1, 0.0)}, "half_extent_m"),
        ({"half_extent_m": 0.1}, "half_extent_m"),
        ({"centre_m": (0, 0, 0, 0)}, "centre_m"),
    ],
)
def test_bad_patch_raises(arguments: dict[str, Any], argument: str) -> None:
    base: dict[str, Any] = {
        "name": "p",
        "centre_m": (0, 0, 0),
        "normal": (0, 0, 1),
        "u_axis": (1, 0, 0),
        "half_extent_m": (0.1, 0.1),
    }
    with pytest.raises(InputError, match=argument):
        Patch(**(base | arguments))


def test_bad_candidates_raise() -> None:
    site = Site("a", (0, 0, 0), (0, 0, 1))
    with pytest.raises(InputError, match="leak_sites"):
        Candidates(leak_sites=site)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="impact_patches"):
        Candidates(impact_patches=(site,))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="screw_sites"):
        Candidates(screw_sites=(site, site))


def test_bad_call_arguments_raise() -> None:
    with pytest.raises(InputError, match="candidates"):
        seed_anomalies([CANDIDATES], rng=0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="settings"):
        seed_anomalies(CANDIDATES, rng=0, settings={"impact_count_range": (1, 1)})  # type: ignore[arg-type]
    with pytest.raises(InputError, match="rng"):
        seed_anomalies(CANDIDATES, rng="seven")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="kind"):
        seed_anomalies(CANDIDATES, rng=0).of_kind("meteor")
    with pytest.raises(InputError, match="anomalies"):
        AnomalySet(("hot",))  # type: ignore[arg-type]


def test_bad_records_raise() -> None:
    common: dict[str, Any] = {"site": "s", "position_m": (0, 0, 0), "normal": (0, 0, 1), "size_m": 0.001}
    with pytest.raises(InputError, match="delta_k"):
        ThermalSpot(**common, surface="kapton", delta_k=0.0)
    with pytest.raises(InputError, match="radius_m"):
        ThermalSpot(**common, surface="kapton", delta_k=1.0, radius_m=0.0)
    with pytest.raises(InputError, match="start_time_s"):
        GasLeak(**common, surface="aluminium", start_time_s=-1.0)
    with pytest.raises(InputError, match="profile"):
        Impact(**common, surface="aluminium", profile="dimple", centre_diameter_m=0.001)
    with pytest.raises(InputError, match="polarity"):
        Impact(**common, surface="aluminium", polarity="grey")
    with pytest.raises(InputError, match="defect_radius_m"):
        SwappedComponent(**common, surface="tank", defect="discoloured", defect_radius_m=-0.01)
    with pytest.raises(InputError, match="defect_normal"):
        SwappedComponent(**common, surface="tank", defect_normal=(0, 0, 0))
    with pytest.raises(InputError, match="defect_centre_m"):
        SwappedComponent(**common, surface="tank", defect_centre_m=(0, 0))
    with pytest.raises(InputError, match="centre_darkening"):
        Impact(**common, surface="aluminium", darkening=0.5, centre_darkening=0.4)
    with pytest.raises(InputError, match="centre_diameter_m"):
        Impact(**common, surface="aluminium", centre_diameter_m=0.002)
    with pytest.raises(InputError, match="defect"):
        SwappedComponent(**common, surface="aluminium", defect="melted")
    with pytest.raises(InputError, match="reflectance_factor"):
        SwappedComponent(**common, surface="aluminium", defect="discoloured", reflectance_factor=1.6)
    with pytest.raises(InputError, match="dent_depth_m"):
        SwappedComponent(**common, surface="aluminium", dent_depth_m=-0.001)
    with pytest.raises(InputError, match="size_m"):
        MissingScrew(**(common | {"size_m": -1.0}), surface="aluminium")


def test_bad_truth_raises() -> None:
    truth = seed_anomalies(CANDIDATES, rng=2, settings=SEED_MOCKUP).to_dict()
    with pytest.raises(InputError, match="schema"):
        AnomalySet.from_dict({"anomalies": []})
    entries: list[dict[str, Any]] = truth["anomalies"]  # type: ignore[assignment]
    with pytest.raises(InputError, match="kind"):
        AnomalySet.from_dict(truth | {"anomalies": [entries[0] | {"kind": "meteor"}]})
    without_delta = {key: value for key, value in entries[0].items() if key != "delta_k"}
    with pytest.raises(InputError, match="delta_k"):
        AnomalySet.from_dict(truth | {"anomalies": [without_delta]})
    flipped = "cold_spot" if entries[0]["kind"] == "hot_spot" else "hot_spot"
    with pytest.raises(InputError, match="kind"):
        AnomalySet.from_dict(truth | {"anomalies": [entries[0] | {"kind": flipped}]})


# ------------------------------------------------------------------------------------ the wide draw


def test_wide_draw_spreads_counts_kinds_and_strengths() -> None:
    """Issue 13: 0-8 impacts, 0-2 swaps and leaks, 2-40 K, leaks over two decades, ~1 run in 10 empty."""
    from rsi.sim.mockup import SURFACES, truss_mockup

    candidates = truss_mockup().candidates
    worlds = [seed_anomalies(candidates, rng=seed) for seed in range(300)]
    empty = sum(len(world) == 0 for world in worlds)
    assert 15 <= empty <= 45  # binomial(300, 0.1): 30 +- 5
    counts = [world.counts() for world in worlds if len(world)]
    assert {c["impact"] for c in counts} == set(range(9))
    assert {c["swapped_component"] for c in counts} == {0, 1, 2}
    assert {c["gas_leak"] for c in counts} == {0, 1, 2}
    records = [item for world in worlds for item in world.anomalies]
    deltas = [abs(item.delta_k) for item in records if isinstance(item, ThermalSpot)]
    assert 2.0 <= min(deltas) < 4.0 and 38.0 < max(deltas) <= 40.0
    ppm = np.log10([item.exit_ppm for item in records if isinstance(item, GasLeak)])
    assert ppm.min() < np.log10(700) and ppm.max() > np.log10(35000)
    impacts = [item for item in records if isinstance(item, Impact)]
    assert {item.surface for item in impacts} == set(SURFACES)
    assert {item.subtype for item in impacts} == {
        "dark-uniform",
        "dark-crater",
        "bright-uniform",
        "bright-crater",
    }
    bright = np.mean([item.polarity == "bright" for item in impacts])
    assert 0.18 < bright < 0.32
    contrast = [item.darkening for item in impacts]
    assert min(contrast) < 0.12 and max(contrast) > 0.78
    sizes = [item.size_m for item in impacts]
    assert min(sizes) < 0.6e-3 and max(sizes) > 3.9e-3
    swaps = [item for item in records if isinstance(item, SwappedComponent)]
    assert {item.subtype for item in swaps} == {
        "dent",
        "discolour-whole-darker",
        "discolour-whole-brighter",
        "discolour-patch-darker",
        "discolour-patch-brighter",
    }
    depths = [item.dent_depth_m for item in swaps if item.defect == "dented"]
    assert min(depths) < 2e-3 and max(depths) > 9e-3


def test_impacts_lie_on_their_surface_and_follow_the_area() -> None:
    from rsi.sim.mockup import truss_mockup

    candidates = truss_mockup().candidates
    patches = {patch.name: patch for patch in candidates.impact_patches}
    chosen = dataclasses.replace(SEED_MOCKUP, impact_count_range=(400, 400))
    impacts = seed_anomalies(candidates, rng=1, settings=chosen).of_kind("impact")
    for impact in impacts:
        patch = patches[impact.site]
        assert isinstance(impact, Impact)
        if isinstance(patch, CylinderPatch):
            offset = np.asarray(impact.position_m) - np.asarray(patch.centre_m)
            along = float(offset @ np.asarray(patch.axis))
            radial = offset - along * np.asarray(patch.axis)
            # on the skin, the normal radial, inside the window a radius clear of its edges
            assert float(np.linalg.norm(radial)) == pytest.approx(patch.radius_m, abs=1e-12)
            assert np.asarray(impact.normal) == pytest.approx(radial / patch.radius_m, abs=1e-12)
            assert abs(along) <= patch.half_length_m - impact.size_m / 2 + TOLERANCE_M
            angle = math.acos(min(1.0, float(np.asarray(impact.normal) @ np.asarray(patch.front))))
            assert angle <= patch.half_angle_rad - impact.size_m / 2 / patch.radius_m + 1e-9
    # micrometeoroid flux is uniform per unit area: the panel (about half the area) takes about half
    area = {name: patch.area_m2 for name, patch in patches.items()}
    share = area["C_cells"] / sum(area.values())
    on_panel = np.mean([impact.site == "C_cells" for impact in impacts])
    assert abs(on_panel - share) < 4 * math.sqrt(share * (1 - share) / len(impacts))


@pytest.mark.parametrize("layout", ["truss", "truss-b"])
def test_no_impact_lies_under_a_screw_head(layout: str) -> None:
    # a head stands 2 mm proud of its plate: a spot painted under it shows from nowhere (truss mission seed
    # 2269: a 2.2 mm spot 2.9 mm from screw_B_1's axis showed one pixel); the spots still cover the plates
    from rsi.sim.mockup import mockup

    candidates = mockup(layout).candidates
    chosen = dataclasses.replace(SEED_MOCKUP, impact_count_range=(400, 400))
    # 0.2-0.3 % of the spots fell under a head before this rule: several of these 4,000
    impacts = [
        spot
        for seed in range(10)
        for spot in seed_anomalies(candidates, rng=seed, settings=chosen).of_kind("impact")
    ]
    heads = candidates.screw_sites
    for impact in impacts:
        for head in heads:
            assert math.dist(impact.position_m, head.position_m) > (impact.size_m + head.size_m) / 2
    plates = {head.surface for head in heads}
    assert sum(impact.surface in plates for impact in impacts) >= 2000


def test_cylinder_patch_places_points_on_its_skin() -> None:
    patch = CylinderPatch("tank", (0, 0, 0), (0, 0, 2), (0, -1, 0.5), 0.05, 0.1, math.pi / 3)
    assert patch.front == pytest.approx((0, -1, 0))
    assert patch.area_m2 == pytest.approx(4 * 0.05 * math.pi / 3 * 0.1)
    middle, normal = patch.place((0.5, 0.5), 0.0)
    assert middle == pytest.approx((0, -0.05, 0)) and normal == pytest.approx((0, -1, 0))
    corner, normal = patch.place((1.0, 0.0), 0.0)
    assert corner[2] == pytest.approx(-0.1) and math.acos(-normal[1]) == pytest.approx(math.pi / 3)
    assert patch.fits(0.05) and not patch.fits(0.06)  # 60 deg of a 5 cm radius: 52 mm of arc


@pytest.mark.parametrize(
    ("arguments", "argument"),
    [
        ({"front": (0, 0, 1)}, "front"),
        ({"radius_m": 0.0}, "radius_m"),
        ({"half_length_m": -1.0}, "half_length_m"),
        ({"half_angle_rad": 4.0}, "half_angle_rad"),
        ({"axis": (0, 0, 0)}, "axis"),
    ],
)
def test_bad_cylinder_patch_raises(arguments: dict[str, Any], argument: str) -> None:
    base: dict[str, Any] = {
        "name": "tank",
        "centre_m": (0, 0, 0),
        "axis": (0, 0, 1),
        "front": (0, -1, 0),
        "radius_m": 0.05,
        "half_length_m": 0.1,
        "half_angle_rad": 1.0,
    }
    with pytest.raises(InputError, match=argument):
        CylinderPatch(**(base | arguments))


def test_defects_sit_on_the_component_s_visible_surfaces() -> None:
    from rsi.sim.mockup import truss_mockup

    candidates = truss_mockup().candidates
    chosen = dataclasses.replace(AnomalySettings(), anomaly_free_probability=0.0)
    swaps = [
        item
        for seed in range(60)
        for item in seed_anomalies(candidates, rng=seed, settings=chosen).anomalies
        if isinstance(item, SwappedComponent) and item.subtype != "discolour-whole-darker"
    ]
    centred = 0
    for swap in swaps:
        centre, _ = swap.defect_at
        if swap.subtype.startswith("discolour-whole"):
            assert centre == swap.position_m and swap.defect_radius_m == 0.0
            continue
        (patch,) = candidates.dent_patches[swap.site]
        middle, _ = patch.place((0.5, 0.5), 0.0)
        centred += centre == middle
        # the whole dent (rim) or patch lies inside the visible surface
        if isinstance(patch, Patch):
            offset = np.asarray(centre) - np.asarray(patch.centre_m)
            reach = np.abs([offset @ np.asarray(patch.u_axis), offset @ np.asarray(patch.v_axis)])
            assert np.all(reach <= np.asarray(patch.half_extent_m) - swap.defect_radius_m + 1e-12)
    assert centred == 0  # issue 13: off centre
    fixed = seed_anomalies(candidates, rng=4, settings=SEED_MOCKUP).of_kind("swapped_component")
    for swap in fixed:  # the seed mock-up's dent at the middle of the visible face
        assert isinstance(swap, SwappedComponent)
        (patch,) = candidates.dent_patches[swap.site]
        assert swap.subtype in ("dent", "discolour-whole-darker")
        if swap.defect == "dented":
            assert swap.defect_at[0] == patch.place((0.5, 0.5), 0.0)[0]


def test_no_defect_is_centred_under_a_kapton_circle() -> None:
    # the circle lies over the ORU's fill face: a patch centred under it shows a crescent at most (held-out
    # truss mission seed 2243); 21-29 % of the centres the face allows lie under the four circles
    from rsi.sim.mockup import truss_mockup

    candidates = truss_mockup().candidates
    chosen = dataclasses.replace(
        AnomalySettings(), anomaly_free_probability=0.0, discolour_patch_probability=1.0
    )
    circles = [(np.asarray(site.position_m), 0.5 * site.size_m) for site in candidates.peltier_sites]
    on_face = [
        item
        for seed in range(120)
        for item in seed_anomalies(candidates, rng=seed, settings=chosen).anomalies
        if isinstance(item, SwappedComponent) and item.site == "A_oru" and item.defect_radius_m > 0.0
    ]
    assert len(on_face) >= 20
    for swap in on_face:
        centre = np.asarray(swap.defect_at[0])
        assert all(np.linalg.norm(centre - middle) >= radius for middle, radius in circles)


def test_dent_patches_all_under_kapton_raise() -> None:
    covered = Patch("covered", (0.0, 0.0, 0.0), (0, 0, 1), (1, 0, 0), (0.02, 0.02))
    candidates = dataclasses.replace(CANDIDATES, dent_patches={"tank_0": (covered,)})
    chosen = dataclasses.replace(
        AnomalySettings(),
        anomaly_free_probability=0.0,
        swapped_component_count_range=(3, 3),
        component_defects=("dented",),
    )
    with pytest.raises(InputError, match="dent_patches of component 'tank_0'"):
        seed_anomalies(candidates, rng=0, settings=chosen)


def test_a_run_may_be_free_of_anomalies() -> None:
    chosen = dataclasses.replace(SEED_MOCKUP, anomaly_free_probability=1.0)
    assert len(seed_anomalies(CANDIDATES, rng=0, settings=chosen)) == 0


def test_subtypes_of_every_kind() -> None:
    common: dict[str, Any] = {"site": "s", "position_m": (0, 0, 0), "normal": (0, 0, 1), "size_m": 0.002}
    assert ThermalSpot(**common, surface="kapton", delta_k=-3.0).subtype == "cold"
    assert ThermalSpot(**common, surface="kapton", delta_k=3.0).subtype == "hot"
    bands = [GasLeak(**common, surface="tubing", exit_ppm=ppm).subtype for ppm in (600.0, 5000.0, 40000.0)]
    assert bands == ["weak", "medium", "strong"]
    assert MissingScrew(**common, surface="plate").subtype == "screw"
    spot = Impact(**common, surface="door", profile="crater", polarity="bright", centre_diameter_m=0.001)
    assert spot.subtype == "bright-crater"
    patch = SwappedComponent(
        **common, surface="panel", defect="discoloured", reflectance_factor=1.3, defect_radius_m=0.02
    )
    assert patch.subtype == "discolour-patch-brighter"


def test_truth_written_before_subtypes_still_reads() -> None:
    """Older truth: no subtype, no polarity, no defect centre, and the crater profile called "peak"."""
    world = seed_anomalies(CANDIDATES, rng=2, settings=SEED_MOCKUP)
    truth = json.loads(json.dumps(world.to_dict()))
    new_fields = {"subtype", "polarity", "defect_centre_m", "defect_normal", "defect_radius_m"}
    entries = [{k: v for k, v in entry.items() if k not in new_fields} for entry in truth["anomalies"]]
    for entry in entries:
        if entry.get("profile") == "crater":
            entry["profile"] = "peak"
    old = AnomalySet.from_dict(truth | {"anomalies": entries})
    assert [item.subtype for item in old.anomalies] == [item.subtype for item in world.anomalies]
    assert all(item.polarity == "dark" for item in old.of_kind("impact"))  # type: ignore[attr-defined]


def test_settings_from_a_dict_and_presets() -> None:
    assert anomalies_module.preset("wide") == AnomalySettings()
    assert anomalies_module.preset("seed-mockup") == SEED_MOCKUP
    chosen = AnomalySettings.from_dict({"preset": "seed-mockup", "impact_count_range": [2, 3]})
    assert chosen == dataclasses.replace(SEED_MOCKUP, impact_count_range=(2, 3))
    assert AnomalySettings.from_dict({}) == AnomalySettings()
    with pytest.raises(InputError, match="unknown fields"):
        AnomalySettings.from_dict({"impact_count": 3})
    with pytest.raises(InputError, match="JSON object"):
        AnomalySettings.from_dict([1, 2])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="preset"):
        anomalies_module.preset("narrow")
    with pytest.raises(InputError, match="impact_count_range"):
        AnomalySettings.from_dict({"impact_count_range": [3, 1]})


def test_bad_dent_patches_raise() -> None:
    patch = Patch("p", (0, 0, 0), (0, 0, 1), (1, 0, 0), (0.1, 0.1))
    with pytest.raises(InputError, match="dent_patches"):
        dataclasses.replace(CANDIDATES, dent_patches={"no_such_tank": (patch,)})
    with pytest.raises(InputError, match="dent_patches"):
        dataclasses.replace(CANDIDATES, dent_patches=[patch])  # type: ignore[arg-type]
    with pytest.raises(InputError, match="dent_patches"):
        dataclasses.replace(CANDIDATES, dent_patches={"tank_0": (CANDIDATES.screw_sites[0],)})
