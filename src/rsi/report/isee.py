"""Pictures and figures of the ISEE proximity demo (seed §3.1, Figs 3, 6, 7; issue 4): a view only.

Every number drawn or written here sits in the :class:`rsi.mission.proximity_records.ProximityDemoResult`
already; this module computes nothing about the loop. Plots are bare matplotlib ``Figure`` objects on the
Agg canvas (no pyplot, no GUI backend, no global state).
"""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rsi import _validate as v
from rsi._files import writable_folder
from rsi.report.figures import figure_png
from rsi.report.writers import to_json, write_files

if TYPE_CHECKING:
    from rsi.control.proximity_law import ProximityLaw
    from rsi.mission.proximity_records import ContourScan, LawResponse, ProximityDemoResult, Scenario

PICTURES = (
    "fig3_readings_vs_position.png",
    "fig6_avoidance_velocity.png",
    "fig7_servo_velocity.png",
    "a_full_push.png",
    "b_servo.png",
    "c_follow_stepped.png",
    "c_follow_curved.png",
    "d_contour.png",
    "f_lamp.png",
)
"""The plots :func:`write_proximity_report` draws (one per follow scenario under ``c_``)."""


def _new_figure(rows: int = 1, *, height: float = 4.0) -> tuple[Any, Any]:
    from matplotlib.figure import Figure

    figure = Figure(figsize=(7.0, height), dpi=100)
    axes = figure.subplots(rows, 1, sharex=True, squeeze=False)[:, 0]
    for each in axes:
        each.grid(True, alpha=0.3)
    return figure, axes


def fig3_png(result: ProximityDemoResult) -> bytes:
    """Seed Fig. 3: filtered readings of both sensors against the arm position during the sweep."""
    trace = result.sweep.trace
    position = result.sweep_arm_position_m
    figure, (axes,) = _new_figure()
    for index, label in enumerate(("left", "right")):
        shown = np.where(trace.out_of_range[:, index], np.nan, trace.reading_m[:, index])
        axes.plot(position, shown, ".", markersize=2.5, label=f"{label} sensor, filtered")
    axes.plot(position, position - result.surface_position_m, "k--", linewidth=0.8, label="true distance")
    axes.set(
        xlabel=f"arm position, m (surface at {result.surface_position_m:g} m)",
        ylabel="filtered reading, m",
        title="Fig. 3: filtered proximity readings versus arm position",
    )
    axes.legend(fontsize="small")
    return figure_png(figure)


def law_png(response: LawResponse) -> bytes:
    """Seed Fig. 6 (avoidance) or 7 (servo): commanded x_ps against measured proximity, over the law."""
    figure, (axes,) = _new_figure()
    axes.plot(response.law_distance_m, response.law_velocity_m_s, "k-", linewidth=0.8, label="law")
    axes.plot(response.measured_m, response.commanded_m_s, ".", markersize=3, label="commanded x_ps")
    for edge in response.breakpoints_m:
        axes.axvline(edge, color="grey", linewidth=0.5, linestyle=":")
    number, what = ("6", "repulsion (avoidance)") if response.mode == "avoidance" else ("7", "distance servo")
    axes.set(
        xlabel="measured proximity, m",
        ylabel="commanded velocity x_ps, m/s",
        title=f"Fig. {number}: commanded {what} velocity versus measured proximity",
    )
    axes.legend(fontsize="small")
    return figure_png(figure)


def time_png(scenario: Scenario, law: ProximityLaw, title: str) -> bytes:
    """True and filtered distances, and the commanded velocity with its proximity term, against time."""
    trace = scenario.trace
    figure, (distance, velocity) = _new_figure(2, height=6.0)
    for index, label in enumerate(("left", "right")):
        distance.plot(trace.time_s, trace.true_m[:, index], linewidth=1.0, label=f"{label} true")
        distance.plot(trace.time_s, trace.reading_m[:, index], ".", markersize=2, label=f"{label} filtered")
    distance.axhline(law.standoff_m, color="green", linestyle="--", linewidth=0.8, label="standoff")
    distance.axhline(law.hold_distance_m, color="orange", linestyle="--", linewidth=0.8, label="C|D (hold)")
    distance.axhline(law.avoidance_start_m, color="red", linestyle="--", linewidth=0.8, label="B|C")
    distance.set(ylabel="distance, m", title=title, ylim=(0.0, law.max_distance_m + 0.05))
    distance.legend(fontsize="x-small", ncol=3)
    velocity.plot(trace.time_s, trace.command_m_s, label="commanded (sum, Fig. 4)")
    velocity.plot(trace.time_s, trace.proximity_m_s, label="proximity term x_ps")
    velocity.set(xlabel="time, s", ylabel="velocity, m/s (+ toward surface)")
    velocity.legend(fontsize="x-small")
    return figure_png(figure)


def contour_png(contours: tuple[ContourScan, ...]) -> bytes:
    """Scenario d: each rebuilt profile over the true one, one panel per surface."""
    figure, axes = _new_figure(len(contours), height=3.2 * len(contours))
    for each, contour in zip(axes, contours, strict=True):
        each.plot(
            contour.profile_tangential_m, contour.profile_depth_m, "k-", linewidth=0.8, label="true surface"
        )
        rebuilt = "rebuilt: arm pose + filtered reading"
        each.plot(contour.tangential_m, contour.depth_m, ".", markersize=2, label=rebuilt)
        each.invert_yaxis()
        each.set(ylabel="depth from home tip, m", title=f"contour: {contour.name}")
        each.legend(fontsize="x-small")
    axes[-1].set(xlabel="along the scan, m")
    return figure_png(figure)


def lamp_png(result: ProximityDemoResult) -> bytes:
    """Scenario f: the regulated lamps' relative illumination error against time, with the +-1 % band."""
    figure, (axes,) = _new_figure()
    axes.plot(result.lamp_time_s, 100.0 * result.lamp_error, linewidth=0.8)
    axes.axvline(result.lamp_settle_s, color="grey", linestyle=":", label="settled")
    axes.axhline(1.0, color="red", linestyle="--", linewidth=0.8, label="+-1 %")
    axes.axhline(-1.0, color="red", linestyle="--", linewidth=0.8)
    axes.set(
        xlabel="time, s",
        ylabel="illumination error, %",
        ylim=(-3, 3),
        title="Regulated halogen lamps under supply wander, sag and ageing",
    )
    axes.legend(fontsize="small")
    return figure_png(figure)


def scenario_details(result: ProximityDemoResult) -> dict[str, Any]:
    """scenarios.json content: the seed, the law used, per-surface figures, and scenario e's task error."""
    v.record_named(result, "result", "ProximityDemoResult")
    law = result.law
    return {
        "seed": result.seed,
        "law": asdict(law) | {"standoff_m": law.standoff_m, "peak_distance_m": law.peak_distance_m},
        "surfaces": {name: asdict(figures) for name, figures in result.surfaces.items()},
        "recovery_s": result.recovery_s,
        "filter_delay_s": result.filter_delay_s,
        "arm_path": result.arm_path,
        "additional_task_error_deg": result.additional_task_error_deg,
    }


def write_proximity_report(out_dir: Path | str, result: ProximityDemoResult) -> dict[str, Path]:
    """Write the demo's plots (:data:`PICTURES`), figures.json and scenarios.json, each atomically.

    Parameters
    ----------
    out_dir : path
        Results folder (created if missing).
    result : ProximityDemoResult
        From :func:`rsi.mission.proximity_demo.simulate_proximity_demo`.

    Returns
    -------
    dict of str to Path
        File name -> written path.
    """
    writable_folder(out_dir, "out_dir")
    v.record_named(result, "result", "ProximityDemoResult")
    law = result.law
    contents = {
        "fig3_readings_vs_position.png": fig3_png(result),
        "fig6_avoidance_velocity.png": law_png(result.avoidance_response),
        "fig7_servo_velocity.png": law_png(result.servo_response),
        "a_full_push.png": time_png(result.push, law, "a: full joystick push toward a wall, avoidance mode"),
        "b_servo.png": time_png(result.servo, law, "b: distance servo from 0.6 m"),
        **{
            f"c_{scenario.name}.png": time_png(
                scenario,
                law,
                f"c: sideways over a {scenario.name.removeprefix('follow_')} surface, servo mode",
            )
            for scenario in result.follows
        },
        "d_contour.png": contour_png(result.contours),
        "f_lamp.png": lamp_png(result),
        "scenarios.json": to_json(scenario_details(result)).encode(),
        "figures.json": to_json(result.figures.to_dict()).encode(),
    }
    return write_files(out_dir, contents)


__all__ = ["PICTURES", "scenario_details", "write_proximity_report"]
