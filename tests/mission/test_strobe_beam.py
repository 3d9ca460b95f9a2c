"""The strobe's beam edge (seed §2.1 strobe beside the lens): pixels near it leave the inspection region."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest

from rsi.mission.settings import MissionSettings
from rsi.mission.views import within_strobe_beam
from rsi.sim.render import CameraPose
from rsi.sim.scene import CAMERA_FOVY_DEG, STROBE_CUTOFF_DEG, STROBE_OFFSET_M

SHAPE = (480, 640)


@dataclass(frozen=True)
class _Seen:
    """What :func:`within_strobe_beam` reads of a visit: the believed pose and the surface's range."""

    believed_pose: CameraPose
    surface_m: np.ndarray


def _plate(distance_m: float) -> _Seen:
    pose = CameraPose(np.zeros(3), np.eye(3), math.radians(CAMERA_FOVY_DEG), SHAPE)
    return _Seen(pose, np.full(SHAPE, distance_m, np.float32))


@pytest.mark.parametrize("distance_m", [0.2, 0.24, 0.3])
def test_a_plate_facing_the_camera_keeps_the_disc_about_the_strobes_axis(distance_m: float) -> None:
    settings = MissionSettings()
    seen = _plate(distance_m)
    kept = within_strobe_beam(seen, settings)  # type: ignore[arg-type]
    focal = seen.believed_pose.focal_px
    # the strobe's axis meets the plate above the lens's (the strobe sits 3 cm up): a disc of radius
    # Z tan(cut-off - margin) about that foot, in pixels
    foot_row = (SHAPE[0] - 1) / 2 - focal * STROBE_OFFSET_M[1] / distance_m
    radius_px = focal * math.tan(math.radians(STROBE_CUTOFF_DEG - settings.strobe_beam_margin_deg))
    row, col = np.mgrid[0 : SHAPE[0], 0 : SHAPE[1]]
    from_foot = np.hypot(row - foot_row, col - (SHAPE[1] - 1) / 2)
    assert kept[from_foot < radius_px - 0.5].all()
    assert not kept[from_foot > radius_px + 0.5].any()
    # the bottom corners go first: they lie farthest from the strobe
    assert not kept[-1, 0] and not kept[-1, -1]
    assert kept[0, 0] == kept[0, -1]


def test_at_the_hand_plans_standoff_only_the_bottom_corners_leave() -> None:
    # seed §2.1: 0.5 m; the frame's corners lie 27.7 deg off the lens's axis, 29.4 deg off the strobe's
    kept = within_strobe_beam(_plate(0.5), MissionSettings())  # type: ignore[arg-type]
    assert 0.0 < 1.0 - kept.mean() < 0.015
    assert kept[: SHAPE[0] // 2].all()  # the upper half faces the strobe


def test_sky_pixels_are_not_called_outside_the_beam() -> None:
    seen = _plate(0.2)
    sky = _Seen(seen.believed_pose, np.full(SHAPE, 20.0, np.float32))
    assert within_strobe_beam(sky, MissionSettings()).all()  # type: ignore[arg-type]


def test_a_negative_beam_margin_is_refused_by_name() -> None:
    from rsi.errors import InputError

    with pytest.raises(InputError, match="strobe_beam_margin_deg"):
        MissionSettings(strobe_beam_margin_deg=-1.0)
