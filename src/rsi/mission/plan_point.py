"""One vista point of a mission plan: where a frame is taken, with the door and the jaws as they stand.

Its own module because the plans (:mod:`rsi.mission.plan`, :mod:`rsi.mission.plan_cad`), what they cover
(:mod:`rsi.mission.coverage`), the views (:mod:`rsi.mission.views`) and the result records
(:mod:`rsi.mission.records`, which re-exports it) all name it, and the records also name the coverage.
"""

from __future__ import annotations

from dataclasses import dataclass

from rsi import _validate as v
from rsi.errors import InputError
from rsi.sim.arm import DEFAULT_JAW_OPENING_M, JAW_MAX_OPENING_M


@dataclass(frozen=True)
class PlanPoint:
    """One vista point of the mission plan.

    Attributes
    ----------
    name : str
        Unique name (the archive's vista name).
    vista : str
        The world's vista it is taken from.
    door_angle_rad : float
        Opening of the electrical ORU's door while the frame is taken.
    jaw_opening_m : float
        Opening of the gripper's jaws while the arm's ISEE takes the frame, in [0, 0.08] m: the jaws lie in
        its cameras' view (seed §3.1), and the opening sets which pixels they hide.
    behind_jaws_at_m : float or None
        None: the frame is inspected wherever it sees the mock-up. A jaw opening: the point is the second
        frame of another at the same vista, whose jaws stood at this opening, and only what they hid there
        (and a margin about it) is inspected (:func:`rsi.mission.plan.with_jaws_moved`).
    """

    name: str
    vista: str
    door_angle_rad: float = 0.0
    jaw_opening_m: float = DEFAULT_JAW_OPENING_M
    behind_jaws_at_m: float | None = None

    def __post_init__(self) -> None:
        opening = v.in_range(self.jaw_opening_m, "jaw_opening_m", low=0.0, high=JAW_MAX_OPENING_M)
        object.__setattr__(self, "jaw_opening_m", opening)
        if self.behind_jaws_at_m is None:
            return
        behind = v.in_range(self.behind_jaws_at_m, "behind_jaws_at_m", low=0.0, high=JAW_MAX_OPENING_M)
        if behind == opening:
            raise InputError(
                f"behind_jaws_at_m={behind} is the point's own jaw_opening_m: the jaws would hide what the "
                "frame is to look behind; give another opening, or None."
            )
        object.__setattr__(self, "behind_jaws_at_m", behind)


__all__ = ["PlanPoint"]
