"""A screw on a swapped component (seed §4: swaps and removed screws are planted independently) is judged
against the comparison that holds its head: a found swap's pixels leave the frame's photometric fit
(seed §2.3), and a screw on that component must not leave with them."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.mission import MissionSettings, run_mission, score_mission


def test_a_screw_removed_from_a_repainted_panel_is_found() -> None:
    # truss world of mission seed 2240 in space: the solar panel repainted, its screw_C_1 removed and seen
    # only from C_panel_west_back; with the panel's pixels out of the comparison none of its disc was left
    # to judge, and the removal was missed
    result = run_mission(
        2240, repeatability="space", settings=MissionSettings(plan="hand", vistas=("C_panel_west_back",))
    )
    truth = result.truth.anomalies
    score = score_mission(result)
    screws = [k for k, a in enumerate(truth) if a.KIND == "missing_screw" and a.site == "screw_C_1"]
    swaps = [k for k, a in enumerate(truth) if a.KIND == "swapped_component" and a.site == "C_panel"]
    assert len(screws) == 1 and len(swaps) == 1
    assert {screws[0], swaps[0]} <= set(score.matches.values())
    assert score.false_findings == 0
