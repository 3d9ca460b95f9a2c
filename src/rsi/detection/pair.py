"""One inspection of a reference/inspection pair, scored against ground truth (seed §2.3-2.4).

:func:`inspect_pair` is the pipeline glue of seed §2: register the reference to the inspection image
(§2.3), then difference and test every pixel against the flaw model at a chosen false-alarm probability
(§2.4). :func:`score_flaws` scores found flaws against known flaw centres.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

if TYPE_CHECKING:
    from rsi.detection.detect import Detection, Flaw
    from rsi.imaging.compensation import Compensated
    from rsi.imaging.registration import Registration

FloatArray = NDArray[np.floating[Any]]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.integer[Any]]

MATCH_TOLERANCE_PX = 2
"""A truth flaw counts as found when its centre lies within this many pixels of a detected flaw's box."""


@dataclass(frozen=True)
class PairResult:
    """One registered and tested reference/inspection pair.

    Attributes
    ----------
    reference, inspection : ndarray of shape (M, N)
        The images that were compared (the compensated estimates when compensation ran).
    detection : Detection
        Score maps, the decision mask, the flaws (strongest first) and the registration used.
    elapsed_s : float
        Wall time of registration plus detection, seconds.
    """

    reference: FloatArray
    inspection: FloatArray
    detection: Detection
    elapsed_s: float

    @property
    def registration(self) -> Registration | None:
        """The reference-to-inspection registration the detector used (None when it ran unregistered)."""
        return self.detection.registration

    @property
    def flaws(self) -> tuple[Flaw, ...]:
        """Found flaws, strongest first."""
        return self.detection.flaws


def inspect_pair(
    reference: FloatArray | Compensated,
    inspection: FloatArray | Compensated,
    *,
    flaw_model: str = "single",
    size: int = 3,
    p_false_alarm: float = 1e-5,
    polarity: str = "both",
    registration_model: str = "translation",
    method: str = "lrt",
    noise_sigma: float | None = None,
    misregistration_std_px: float = 0.0,
) -> PairResult:
    """Register the reference to the inspection image, then detect flaws (seed §2.3-2.4).

    Parameters
    ----------
    reference, inspection : ndarray of shape (M, N) or Compensated
        The earlier reference and the new inspection image. ``Compensated`` inputs (seed §2.2) carry their
        own noise variance and valid mask, which the detector uses.
    flaw_model : {"single", "uniform", "disc", "peak"}
        Seed §2.4 flaw model the likelihood-ratio test is matched to.
    size : int
        Side of the flaw window in pixels (odd); ignored by the single-pixel model.
    p_false_alarm : float
        Per-pixel false-alarm probability the threshold is set for, in (0, 1).
    polarity : {"both", "dark", "bright"}
        Which sign of change counts as a flaw.
    registration_model : str
        One of ``rsi.imaging.registration.MODELS``.
    method : {"lrt", "erosion"}
        Optimal weighted-sum test or its sub-optimal morphological-erosion version (seed §2.4).
    noise_sigma : float, optional
        Noise standard deviation of one image, in image units; estimated from the data when omitted.
    misregistration_std_px : float
        Floor on the residual shift std of the noise model (see :func:`rsi.detection.detect.detect`).

    Returns
    -------
    PairResult
    """
    from rsi.detection.detect import detect
    from rsi.imaging.registration import register

    start_s = time.perf_counter()
    reference_image, reference_valid = _image_and_valid(reference, "reference")
    inspection_image, _ = _image_and_valid(inspection, "inspection")
    registration = register(reference_image, inspection_image, model=registration_model, mask=reference_valid)
    detection = detect(
        reference,
        inspection,
        flaw_model=flaw_model,
        size=size,
        method=method,
        p_false_alarm=p_false_alarm,
        polarity=polarity,
        noise_sigma=noise_sigma,
        registration=registration,
        misregistration_std_px=misregistration_std_px,
    )
    return PairResult(reference_image, inspection_image, detection, time.perf_counter() - start_s)


def _image_and_valid(image: object, name: str) -> tuple[FloatArray, BoolArray | None]:
    from rsi.imaging.compensation import Compensated

    if isinstance(image, Compensated):
        return image.image, image.valid
    return v.as_image(image, name), None


@dataclass(frozen=True)
class Score:
    """Found flaws matched against ground truth.

    Attributes
    ----------
    truth_count : int
        Seeded flaws inside the valid (registered, unsaturated) region.
    found_count : int
        Seeded flaws inside the valid region that some detected flaw covers.
    false_alarms : int
        Detected flaws that cover no seeded flaw.
    is_true : tuple of bool
        For each detected flaw (strongest first): whether it covers a seeded flaw.
    """

    truth_count: int
    found_count: int
    false_alarms: int
    is_true: tuple[bool, ...]

    @property
    def recall(self) -> float:
        """Fraction of seeded flaws found (1.0 when there are none)."""
        return self.found_count / self.truth_count if self.truth_count else 1.0

    @property
    def precision(self) -> float:
        """Fraction of detected flaws that are real (1.0 when nothing was detected)."""
        detected = len(self.is_true)
        return (detected - self.false_alarms) / detected if detected else 1.0


def _centres(centres_rc: object) -> IntArray:
    values = v.as_float_array(centres_rc, "centres_rc")
    if values.size % 2 or not np.isfinite(values).all() or (values != np.round(values)).any():
        raise InputError(
            f"centres_rc must be (row, col) integer pairs, shape (K, 2); got shape {values.shape}."
        )
    if values.size and np.abs(values).max() > 2**31:
        raise InputError("centres_rc holds a centre beyond 2**31 pixels; pass pixel (row, col) pairs.")
    return values.astype(np.int64).reshape(-1, 2)


def score_flaws(
    flaws: tuple[Flaw, ...],
    centres_rc: IntArray,
    *,
    valid: BoolArray | None = None,
    tolerance_px: int = MATCH_TOLERANCE_PX,
) -> Score:
    """Match detected flaws to seeded flaw centres.

    Parameters
    ----------
    flaws : tuple of Flaw
        Detected flaws; `bbox` is (row0, col0, row1, col1), half-open.
    centres_rc : ndarray of shape (K, 2), int
        (row, col) of each seeded flaw.
    valid : ndarray of bool, shape (M, N), optional
        Pixels the detector could test; seeded flaws outside it are not counted.
    tolerance_px : int
        A flaw's box is grown by this much before testing whether it covers a centre.

    Returns
    -------
    Score
    """
    if isinstance(flaws, (str, bytes)) or not isinstance(flaws, (tuple, list)):
        raise InputError(f"flaws must be a tuple of Flaw (Detection.flaws); got {type(flaws).__name__}.")
    for index, flaw in enumerate(flaws):
        bbox = getattr(flaw, "bbox", None)
        if (
            not isinstance(bbox, (tuple, list))
            or len(bbox) != 4
            or not all(isinstance(side, (int, np.integer)) and not isinstance(side, bool) for side in bbox)
        ):
            raise InputError(
                f"flaws[{index}] must have a bbox of four integers (row0, col0, row1, col1), as a Flaw has; "
                f"got {type(flaw).__name__}."
            )
    tolerance_px = v.positive_int(tolerance_px, "tolerance_px", minimum=0, maximum=2**31)
    centres = _centres(centres_rc)
    if valid is not None:
        mask = v.as_mask(valid, "valid", np.shape(valid)) if isinstance(valid, np.ndarray) else None
        if mask is None or mask.ndim != 2:
            raise InputError(f"valid must be a 2-D bool array (rows, cols); got {type(valid).__name__}.")
        outside = (centres < 0).any(axis=1) | (centres >= mask.shape).any(axis=1)
        if outside.any():
            raise InputError(
                f"centres_rc has a centre outside valid's shape {mask.shape}: {centres[outside][0]}."
            )
        centres = centres[mask[centres[:, 0], centres[:, 1]]]
    covers = np.zeros((len(flaws), len(centres)), dtype=bool)
    for index, flaw in enumerate(flaws):
        row0, col0, row1, col1 = flaw.bbox
        rows, cols = centres[:, 0], centres[:, 1]
        covers[index] = (
            (rows >= row0 - tolerance_px)
            & (rows < row1 + tolerance_px)
            & (cols >= col0 - tolerance_px)
            & (cols < col1 + tolerance_px)
        )
    is_true = tuple(bool(hit) for hit in np.atleast_1d(covers.any(axis=1)))
    return Score(
        truth_count=len(centres),
        found_count=int(covers.any(axis=0).sum()),
        false_alarms=is_true.count(False),
        is_true=is_true,
    )


__all__ = ["MATCH_TOLERANCE_PX", "PairResult", "Score", "inspect_pair", "score_flaws"]
