"""Application layer: one inspection pass over a pair, scoring against ground truth, the synthetic demo.

Importing this package stays cheap; the algorithms load when a function runs.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi.mission.pair import (
    DemoResult,
    PairResult,
    Score,
    inspect_pair,
    score_flaws,
    simulate_demo,
)

if TYPE_CHECKING:
    from rsi.mission.mission import run_mission


def __getattr__(name: str) -> object:
    """``run_mission`` loads the mission module (scipy and the simulator) only when first asked for."""
    if name == "run_mission":
        from rsi.mission.mission import run_mission

        return run_mission
    raise AttributeError(f"module 'rsi.mission' has no attribute {name!r}")


__all__ = [
    "DemoResult",
    "PairResult",
    "Score",
    "inspect_pair",
    "run_mission",
    "score_flaws",
    "simulate_demo",
]
