"""Seeded anomalies of the mock-up (seed §4): determinism, counts, ranges, truth records, every raise."""

from __future__ import annotations

import dataclasses
import doctest
import json
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
