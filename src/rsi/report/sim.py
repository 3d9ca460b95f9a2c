"""Pictures and tables of simulator records: the solar simulator's lamp trajectory along an orbit."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rsi import _validate as v
from rsi._files import writable_folder
from rsi.errors import InputError
from rsi.report.figures import _title, _uint8_picture, encode_png, figure_png
from rsi.report.writers import csv_text, to_json, write_files

if TYPE_CHECKING:
    from rsi.sim.orbit import SunPath

SUN_PATH_COLUMNS = (
    "time_s",
    "orbit_angle_deg",
    "sunlit",
    "sun_world_x",
    "sun_world_y",
    "sun_world_z",
    "rho_m",
    "theta_deg",
    "phi_deg",
    "lambda_m",
    "gamma_m",
    "intensity_lux",
    "direction_error_deg",
    "clipped",
)
"""Columns of sun_path.csv: angles in degrees at this edge, SI inside."""


def sun_path_rows(path: SunPath) -> list[dict[str, float | bool]]:
    """One row per sample of `path` with the columns of :data:`SUN_PATH_COLUMNS`."""
    v.record_named(path, "path", "SunPath")
    trajectory, clipped = path.trajectory, path.clipped
    rows: list[dict[str, float | bool]] = []
    for index, time_s in enumerate(path.time_s):
        sun = path.sun_world[index]
        rows.append(
            {
                "time_s": float(time_s),
                "orbit_angle_deg": math.degrees(path.orbit_angle_rad[index]),
                "sunlit": bool(path.sunlit[index]),
                "sun_world_x": float(sun[0]),
                "sun_world_y": float(sun[1]),
                "sun_world_z": float(sun[2]),
                "rho_m": float(trajectory.rho_m[index]),
                "theta_deg": math.degrees(trajectory.theta_rad[index]),
                "phi_deg": math.degrees(trajectory.phi_rad[index]),
                "lambda_m": float(trajectory.lambda_m[index]),
                "gamma_m": float(trajectory.gamma_m[index]),
                "intensity_lux": float(path.intensity_lux[index]),
                "direction_error_deg": math.degrees(path.direction_error_rad[index]),
                "clipped": bool(clipped[index]),
            }
        )
    return rows


def sun_path_png(path: SunPath, *, title: str) -> bytes:
    """Plot the lamp joints, the spot intensity and the direction error against orbit time (seed §4.1)."""
    v.record_named(path, "path", "SunPath")
    _title(title)
    from matplotlib.figure import Figure

    minutes = np.asarray(path.time_s) / 60.0
    trajectory = path.trajectory
    figure = Figure(figsize=(8.0, 7.0), dpi=100)
    joints, light, error = figure.subplots(3, 1, sharex=True)
    joints.plot(minutes, np.degrees(trajectory.theta_rad), label="theta (pan), deg")
    joints.plot(minutes, np.degrees(trajectory.phi_rad), label="phi (tilt), deg")
    joints.plot(minutes, 100.0 * np.asarray(trajectory.lambda_m), label="lambda (rail), cm")
    joints.set(title=title, ylabel="joint")
    light.plot(minutes, path.intensity_lux, label="spot intensity")
    light.axhline(path.target_intensity_lux, color="grey", linestyle="--", label="1.5% of the sun")
    light.set(ylabel="lux")
    error.plot(minutes, np.degrees(path.direction_error_rad), label="light direction error")
    error.set(xlabel="orbit time, min", ylabel="deg")
    for axes in (joints, light, error):
        _shade(axes, minutes, ~np.asarray(path.sunlit), "black", "eclipse")
        _shade(axes, minutes, np.asarray(path.clipped) & np.asarray(path.sunlit), "red", "not reproduced")
        axes.grid(True, alpha=0.3)
        axes.legend(loc="upper right", fontsize="small")
    return figure_png(figure)


def _shade(axes: Any, minutes: np.ndarray, where: np.ndarray, colour: str, label: str) -> None:
    if where.any():
        transform = axes.get_xaxis_transform()  # x in data, y in axes units: a full-height band
        axes.fill_between(
            minutes, 0, 1, where=where, color=colour, alpha=0.12, transform=transform, label=label
        )


def write_sun_report(out_dir: Path | str, path: SunPath, *, title: str) -> dict[str, Path]:
    """Write sun_path.csv, sun_path.png and sun_path.json (summary: eclipse, exposure, clipped share)."""
    writable_folder(out_dir, "out_dir")
    v.record_named(path, "path", "SunPath")
    _title(title)
    summary = {
        "samples": len(path.time_s),
        "sunlit_fraction": float(np.mean(path.sunlit)),
        "reproduced_fraction_of_sunlit": (
            float(np.mean(~path.clipped[path.sunlit])) if path.sunlit.any() else 0.0
        ),
        "target_intensity_lux": path.target_intensity_lux,
        "lab_exposure_s": path.exposure.lab_exposure_s,
    }
    contents = {
        "sun_path.csv": csv_text(SUN_PATH_COLUMNS, sun_path_rows(path)).encode(),
        "sun_path.png": sun_path_png(path, title=title),
        "sun_path.json": to_json(summary).encode(),
    }
    return write_files(out_dir, contents)


def write_overview(out_dir: Path | str, picture_rgb: np.ndarray) -> dict[str, Path]:
    """Write overview.png: the whole mock-up from the overview camera with numbered anomaly markers."""
    writable_folder(out_dir, "out_dir")
    _rgb(picture_rgb)
    bgr = np.ascontiguousarray(np.asarray(picture_rgb, dtype=np.uint8)[..., ::-1])
    return write_files(out_dir, {"overview.png": encode_png(bgr)})


def _rgb(picture_rgb: object) -> None:
    shape: tuple[int, ...] = tuple(getattr(picture_rgb, "shape", ()))
    if len(shape) != 3 or shape[2] != 3 or getattr(picture_rgb, "dtype", None) != np.uint8:
        raise InputError(
            f"picture_rgb must be a uint8 (M, N, 3) RGB picture (rsi.sim render output); got "
            f"{type(picture_rgb).__name__} {getattr(picture_rgb, 'dtype', '')} {shape}."
        )
    _uint8_picture(picture_rgb, "picture_rgb")
