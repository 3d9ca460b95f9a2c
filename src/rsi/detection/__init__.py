"""Seed §2.4: flaw models, noise model, likelihood-ratio flaw detection, ROC analysis, and the §2.3-2.4
nuisances that raise the noise.

- :mod:`~rsi.detection.detect` the test and its flaws: :func:`detect`, :class:`Detection`, :class:`Flaw`;
- :mod:`~rsi.detection.flaw_models` single-pixel, uniform and peak/adjacent models: :func:`flaw_kernel`;
- :mod:`~rsi.detection.roc` P_D against P_F, theory and measured: :func:`theoretical_roc`,
  :func:`empirical_roc`, :func:`thresholds`;
- :mod:`~rsi.detection.nuisance` extra variance of mis-registration, parallax, sampling phase and shadow
  edges;
- :mod:`~rsi.detection.pair` one pair registered then tested: :func:`inspect_pair`, :func:`score_flaws`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi._lazy import lazy_getattr

if TYPE_CHECKING:
    from rsi.detection.detect import Detection, Flaw, detect
    from rsi.detection.flaw_models import FLAW_MODELS, flaw_kernel
    from rsi.detection.nuisance import (
        half_pixel_shifted,
        nuisance_scale,
        pair_excess,
        parallax_scale,
        shadow_edge_variance,
        shared_interpolation,
    )
    from rsi.detection.pair import PairResult, Score, inspect_pair, score_flaws
    from rsi.detection.roc import RocCurve, empirical_roc, theoretical_roc, thresholds

# public names, loaded on first use so that importing the package stays cheap (PEP 562)
_LAZY = {
    "Detection": "rsi.detection.detect",
    "Flaw": "rsi.detection.detect",
    "detect": "rsi.detection.detect",
    "FLAW_MODELS": "rsi.detection.flaw_models",
    "flaw_kernel": "rsi.detection.flaw_models",
    "half_pixel_shifted": "rsi.detection.nuisance",
    "nuisance_scale": "rsi.detection.nuisance",
    "pair_excess": "rsi.detection.nuisance",
    "parallax_scale": "rsi.detection.nuisance",
    "shadow_edge_variance": "rsi.detection.nuisance",
    "shared_interpolation": "rsi.detection.nuisance",
    "PairResult": "rsi.detection.pair",
    "Score": "rsi.detection.pair",
    "inspect_pair": "rsi.detection.pair",
    "score_flaws": "rsi.detection.pair",
    "RocCurve": "rsi.detection.roc",
    "empirical_roc": "rsi.detection.roc",
    "theoretical_roc": "rsi.detection.roc",
    "thresholds": "rsi.detection.roc",
}


__getattr__ = lazy_getattr(__name__, _LAZY)


__all__ = [
    "FLAW_MODELS",
    "Detection",
    "Flaw",
    "PairResult",
    "RocCurve",
    "Score",
    "detect",
    "empirical_roc",
    "flaw_kernel",
    "half_pixel_shifted",
    "inspect_pair",
    "nuisance_scale",
    "pair_excess",
    "parallax_scale",
    "score_flaws",
    "shadow_edge_variance",
    "shared_interpolation",
    "theoretical_roc",
    "thresholds",
]
