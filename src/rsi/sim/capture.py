"""What the ISEE gives the robot for one visit (seed §3 D, §2.2), and nothing the simulator alone knows.

A :class:`~rsi.sim.world.View` is the simulator's whole record of a visit: the frame, and the truth behind
it (rendered depth, the anomalies' masks, the true camera pose, the light falling on every pixel). The
mission must not see that truth, only what the robot's sensors and its own model give. A :class:`Capture`
is that: the two interlaced frames with the strobe in opposite fields, the stereo pair's frames and its
calibration, the pose the robot *believes* (commanded, read through its encoders: the flexure and thermal
error is not in it), and the robot's CAD model projected from that believed pose. Truth stays on the View,
for scoring and tests.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

from rsi.errors import InputError
from rsi.imaging.camera import CameraModel, Frame
from rsi.imaging.stereo import StereoRig
from rsi.sim.render import CadView, CameraPose
from rsi.sim.scene import STEREO_BASELINE_M
from rsi.sim.world import View, World


@dataclass(frozen=True)
class Capture:
    """One visit as the ISEE gives it (seed §3 D): frames, stereo pair, believed pose, the CAD expectation.

    Attributes
    ----------
    vista : str
        The vista point the robot was sent to.
    frames : (Frame, Frame)
        Two consecutive frames of the main camera, the strobe in the odd and then the even field (seed §2.2).
    stereo : (Frame, Frame)
        The calibrated pair's left (the main camera) and right frames, strobe in the odd field.
    rig : StereoRig
        The pair's calibration.
    believed_pose : CameraPose
        Commanded pose through the joint encoders (not the true pose: seed §2.3's flexure is not in it).
    cad : CadView
        The CAD model projected from `believed_pose`.
    camera : CameraModel
        The camera's calibration (gain, black level, bits): what turns DN into light.
    model : callable or None
        The robot's CAD model drawn from any pose it believes, ``model(pose) -> CadView``
        (:meth:`rsi.sim.world.World.cad_projection`: the pristine mock-up, the door and arm as commanded,
        the ISEE's own body where the arm's ISEE took the frame), for a pose the robot corrects from what it
        sees (seed §2.3); None where no model can be drawn.
    """

    vista: str
    frames: tuple[Frame, Frame]
    stereo: tuple[Frame, Frame]
    rig: StereoRig
    believed_pose: CameraPose
    cad: CadView
    camera: CameraModel
    model: Callable[[CameraPose], CadView] | None = field(default=None, compare=False, repr=False)


def capture(world: World, view: View, *, cad: CadView | None = None) -> Capture:
    """What the robot receives from `view`'s visit: its sensors' data and its model's expectation.

    `view` must come from :meth:`World.render` or :meth:`World.render_from_tool` with ``stereo=True``; the
    second frame (the strobe in the other field) is taken here, from the same pose. `cad`: the model's
    projection from the same believed pose when already made (a frame taken again from the same pose).
    """
    if not isinstance(view, View) or view.stereo is None or view.believed_pose is None:
        raise InputError(
            "view must be a View from World.render or World.render_from_tool with stereo=True; "
            f"got {type(view).__name__} (a View without its stereo pair when it is one)."
        )
    other = "even" if view.frame.lit_field == "odd" else "odd"
    second = world.next_frame(view, lit_field=other)
    frames = (view.frame, second) if view.frame.lit_field == "odd" else (second, view.frame)
    pose = view.believed_pose
    return Capture(
        vista=view.vista,
        frames=frames,
        stereo=view.stereo,
        rig=StereoRig(pose.focal_px, pose.shape, STEREO_BASELINE_M),
        believed_pose=pose,
        cad=world.cad_projection(pose, own_body=view.carried) if cad is None else cad,
        camera=world.camera,
        # the free camera (the arm's fallback) carries no jaws: its model draws none
        model=partial(world.cad_projection, own_body=view.carried),
    )


__all__ = ["CadView", "Capture", "capture"]
