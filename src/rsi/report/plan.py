"""The mission report's plan section: the plan's points, what they cover of the CAD, what was left (issue 15).

Draws the records only (:class:`rsi.mission.coverage.Coverage`, read by attribute): the plan's table, the
coverage by kind of surface, the coverage map (every sample of the inspectable surface projected into the
overview, green where a plan point covers it at the stated resolution, red where none does) and the
uncovered surfaces.
"""

from __future__ import annotations

import html
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.report.figures import figure_png

if TYPE_CHECKING:
    from rsi.mission.records import MissionResult

COVERED_COLOUR, UNCOVERED_COLOUR = "#1a9850", "#d73027"
MAX_PICTURE_PIXELS = 2**26  # the image reader's default limit (docs/reliability.md)
UNCOVERED_ROWS = 15  # the worst surfaces listed; the rest summed in a last line


def _e(value: object) -> str:
    return html.escape(str(value), quote=True)


def _rows_html(headers: Sequence[str], rows: Sequence[Sequence[object]]) -> str:
    head = "".join(f"<th>{_e(name)}</th>" for name in headers)
    body = "".join("<tr>" + "".join(f"<td>{_e(cell)}</td>" for cell in row) + "</tr>" for row in rows)
    return f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody></table>"


def coverage_png(picture: NDArray[np.uint8], pose: Any, points_m: NDArray[np.float64], covered: Any) -> bytes:
    """The overview `picture` with the samples `points_m` as dots, green covered and red not (`pose`
    projects world points into it: a :class:`rsi.sim.render.CameraPose`)."""
    from matplotlib.figure import Figure

    picture, points_m, covered = _map_inputs(picture, pose, points_m, covered)
    xy, depth = pose.project(points_m)
    rows, cols = picture.shape[:2]
    inside = (depth > 0) & (xy[:, 0] >= 0) & (xy[:, 0] < cols) & (xy[:, 1] >= 0) & (xy[:, 1] < rows)
    if inside.any():
        (x0, y0), (x1, y1) = xy[inside].min(axis=0) - 30, xy[inside].max(axis=0) + 30
    else:
        x0, y0, x1, y1 = 0.0, 0.0, float(cols), float(rows)
    x0, y0, x1, y1 = max(x0, 0.0), max(y0, 0.0), min(x1, cols - 1.0), min(y1, rows - 1.0)
    figure = Figure(figsize=(8.0, 8.0 * (y1 - y0) / max(x1 - x0, 1.0)), dpi=72)
    axes = figure.add_axes((0.0, 0.0, 1.0, 1.0))
    axes.imshow(picture, alpha=0.6)
    for mask, colour in ((covered & inside, COVERED_COLOUR), (~covered & inside, UNCOVERED_COLOUR)):
        axes.scatter(xy[mask, 0], xy[mask, 1], s=2.0 if colour == COVERED_COLOUR else 6.0, c=colour, lw=0)
    axes.set_xlim(x0, x1)
    axes.set_ylim(y1, y0)
    axes.set_axis_off()
    return figure_png(figure)


def _map_inputs(
    picture: object, pose: object, points_m: object, covered: object
) -> tuple[NDArray[np.uint8], NDArray[np.float64], NDArray[np.bool_]]:
    """coverage_png's arguments checked: an RGB or grey picture, a CameraPose, N points and N flags."""
    if not (
        isinstance(picture, np.ndarray)
        and picture.dtype == np.uint8
        and picture.ndim in (2, 3)
        and min(picture.shape[:2]) >= 1
        and picture.size <= MAX_PICTURE_PIXELS * 3
    ):
        raise InputError(
            f"picture must be a uint8 image (rows, cols) or (rows, cols, 3) of at most {MAX_PICTURE_PIXELS} "
            "pixels, as World.overview_picture gives."
        )
    v.record_named(pose, "pose", "CameraPose")
    points = v.as_float_array(points_m, "points_m")
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise InputError(
            f"points_m must be an (N, 3) array of finite world points; got shape {points.shape}."
        )
    flags = covered if isinstance(covered, np.ndarray) else None
    if flags is None or flags.dtype != np.bool_ or flags.shape != (len(points),):
        raise InputError(f"covered must be a bool array of shape ({len(points)},), one flag per point.")
    return picture, points, flags


def _reached(result: MissionResult, name: str) -> str:
    moves = [transit for transit in result.transits if transit.label == name]
    if not moves:
        return "free camera" if not result.transits else "not visited"
    return "arm" if all(transit.reached for transit in moves) else "free camera (out of reach)"


def plan_rows(result: MissionResult) -> list[tuple[object, ...]]:
    """Per plan point: name, vista, door opening (deg), the jaws' opening (mm; a second frame behind another
    opening's jaws says so), samples it covers, new area it adds (cm^2), how it was taken."""
    v.record_named(result, "result", "MissionResult")
    measured = result.plan_coverage
    if measured is None:
        raise InputError(
            "result has no plan coverage (plan_coverage is None): there are no plan rows to list."
        )
    area = measured.samples.area_m2
    rows: list[tuple[object, ...]] = []
    for number, point in enumerate(result.plan):
        new_cm2 = float(area[measured.first_seen == number].sum()) * 1e4
        seen = measured.seen_counts[number] if number < len(measured.seen_counts) else 0
        door = f"{np.degrees(point.door_angle_rad):.0f}"
        jaws = f"{point.jaw_opening_m * 1e3:.0f}"
        if point.behind_jaws_at_m is not None:
            jaws += f" (behind {point.behind_jaws_at_m * 1e3:.0f})"
        reached = _reached(result, point.name)
        rows.append((point.name, point.vista, door, jaws, seen, f"{new_cm2:.1f}", reached))
    return rows


def uncovered_rows(measured: Any) -> list[tuple[object, ...]]:
    """The worst uncovered surfaces: name, kind, uncovered cm^2, its area cm^2 (the rest in one line)."""
    v.record_named(measured, "measured", "Coverage")
    listed = measured.uncovered()
    rows: list[tuple[object, ...]] = [
        (name, kind, f"{missing * 1e4:.2f}", f"{total * 1e4:.2f}")
        for name, kind, missing, total in listed[:UNCOVERED_ROWS]
    ]
    if len(listed) > UNCOVERED_ROWS:
        rest = sum(row[2] for row in listed[UNCOVERED_ROWS:]) * 1e4
        rows.append((f"{len(listed) - UNCOVERED_ROWS} more", "", f"{rest:.2f}", ""))
    return rows


def plan_section(result: MissionResult) -> str:
    """The plan's points, its coverage of the inspectable surface by kind, the coverage map and what was
    left uncovered (issue 15)."""
    v.record_named(result, "result", "MissionResult")
    measured = result.plan_coverage
    if measured is None:
        return "<h2>The plan and its coverage</h2>\n<p>No coverage was measured for this run.</p>"
    rules = measured.rules
    head = (
        f"<p id='plan-coverage'>{len(result.plan)} plan points ({_e(result.settings.plan)} plan) cover "
        f"{100 * measured.fraction:.1f} % of the {measured.total_area_m2 * 1e4:.0f} cm<sup>2</sup> of "
        f"inspectable surface at &le; {rules.max_pixel_m * 1e3:.2f} mm per pixel and &le; "
        f"{rules.max_incidence_deg:.0f} deg incidence, measured from the CAD by ray casting (less what the "
        "ISEE's jaws hide in the frames the arm takes).</p>\n"
    )
    kinds = _rows_html(
        ("surface kind", "covered %"),
        [(kind, f"{100 * share:.1f}") for kind, share in measured.by_kind().items()],
    )
    points = _rows_html(
        ("plan point", "vista", "door deg", "jaws mm", "samples covered", "new cm^2", "taken by"),
        plan_rows(result),
    )
    parts = [f"<h2>The plan and its coverage</h2>\n{head}{points}\n{kinds}\n"]
    if result.overview_rgb is not None and result.overview_pose is not None:
        png = coverage_png(
            result.overview_rgb, result.overview_pose, measured.samples.points_m, measured.covered
        )
        parts.append(
            f'<img alt="coverage map: the inspectable surface, green covered, red not" '
            f'src="data:image/png;base64,{_b64(png)}">\n'
        )
    missing = uncovered_rows(measured)
    if missing:
        parts.append(
            "<p>Left uncovered:</p>\n"
            + _rows_html(("surface", "kind", "uncovered cm^2", "area cm^2"), missing)
        )
    else:
        parts.append("<p>Nothing left uncovered.</p>")
    return "".join(parts)


def _b64(png: bytes) -> str:
    import base64

    return base64.b64encode(png).decode("ascii")


__all__ = ["coverage_png", "plan_rows", "plan_section", "uncovered_rows"]
