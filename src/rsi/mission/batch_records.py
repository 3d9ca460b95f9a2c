"""What one pair's task returns (:func:`rsi.mission.batch.inspect_item`): its flaws with their confidence,
or the error that stopped it. Plain data: it crosses the cluster's processes and the archive writer
(:mod:`rsi.mission.batch_store`) reads it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from rsi import _validate as v
from rsi.mission.batch_manifest import POLARITIES

if TYPE_CHECKING:
    from rsi.detection.detect import Flaw

__all__ = ["PairRecord", "flaw_confidence"]


def flaw_confidence(score: float, polarity: str) -> float:
    """``1 - P_F(score)``: one minus the per-pixel false-alarm probability of a flaw's peak score.

    seed §2.4: under the null the likelihood-ratio statistic is a standard normal, so the tail is
    ``erfc(score / sqrt 2) / 2``, doubled for the two-sided test (polarity "both"). For the erosion test
    this is a lower bound (the eroded score's null tail is thinner).

    Parameters
    ----------
    score : float
        The flaw's peak score, in noise sigmas.
    polarity : {"both", "dark", "bright"}
        Polarity of the test that found it.

    Returns
    -------
    float
        In [0, 1].
    """
    score = v.finite_number(score, "score")
    v.choice(polarity, "polarity", POLARITIES)
    tail = 0.5 * math.erfc(score / math.sqrt(2.0))
    return 1.0 - min(1.0, 2.0 * tail if polarity == "both" else tail)


@dataclass(frozen=True)
class PairRecord:
    """What one pair's task returned: its flaws, or the error that stopped it. Never raised, always returned.

    Attributes
    ----------
    pair_id : str
        The pair's id.
    status : {"ok", "failed"}
        Whether the pair was inspected.
    flaws : tuple of rsi.detection.detect.Flaw
        The detector's flaws, strongest first (empty when failed).
    shape : (int, int) or None
        (rows, cols) of the inspection image.
    threshold : float or None
        Score threshold of the requested per-pixel false-alarm probability.
    translation_xy : (float, float) or None
        Registration's (dx, dy), pixels.
    converged : bool or None
        Whether registration converged.
    error : str or None
        ``"<ErrorType>: <message>"`` for a failed pair.
    stage : str or None
        Where a failed pair stopped: ``"read"`` (an image), ``"inspect"`` (registration or detection) or
        ``"worker"`` (the task itself was lost, e.g. its worker process died).
    tested_polarity : {"both", "dark", "bright"} or None
        Polarity of the test that ran (the pair's setting); None when failed.
    read_s, inspect_s : float
        Seconds spent reading both images and inspecting them (not compared between records).
    worker : str
        ``host:pid`` of the process that ran it (not compared).
    """

    pair_id: str
    status: str
    flaws: tuple[Flaw, ...] = ()
    shape: tuple[int, int] | None = None
    threshold: float | None = None
    translation_xy: tuple[float, float] | None = None
    converged: bool | None = None
    error: str | None = None
    stage: str | None = None
    tested_polarity: str | None = None
    read_s: float = field(default=0.0, compare=False)
    inspect_s: float = field(default=0.0, compare=False)
    worker: str = field(default="", compare=False)

    @property
    def ok(self) -> bool:
        """True when the pair was inspected."""
        return self.status == "ok"

    @property
    def confidences(self) -> tuple[float, ...]:
        """:func:`flaw_confidence` of each flaw, in the order of :attr:`flaws` (empty when failed)."""
        polarity = self.tested_polarity or "both"
        return tuple(flaw_confidence(flaw.score, polarity) for flaw in self.flaws)
