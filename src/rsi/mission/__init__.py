"""Application layer: one inspection pass over a pair, scoring against ground truth, the synthetic demo.

Importing this package stays cheap; the algorithms load when a function runs.
"""

from __future__ import annotations

from rsi.mission.pair import (
    DemoResult,
    PairResult,
    Score,
    inspect_pair,
    score_flaws,
    simulate_demo,
)

__all__ = [
    "DemoResult",
    "PairResult",
    "Score",
    "inspect_pair",
    "score_flaws",
    "simulate_demo",
]
