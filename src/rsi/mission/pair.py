"""One inspection pass over a reference/inspection pair, scored against ground truth, and the synthetic demo.

:func:`inspect_pair` is the pipeline glue of seed §2: register the reference to the inspection image
(§2.3), then difference and test every pixel against the flaw model at a chosen false-alarm probability
(§2.4). :func:`simulate_demo` builds a scene whose truth is known and runs the whole chain through the camera
model: interlaced strobe/ambient frames (§2.1), intra-frame ambient compensation (§2.2), registration and
detection; the results folder is written by :mod:`rsi.report` (the CLI joins the two).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

if TYPE_CHECKING:
    from rsi.detection.detect import Detection, Flaw
    from rsi.detection.roc import RocCurve
    from rsi.imaging.camera import Frame
    from rsi.imaging.compensation import Compensated
    from rsi.imaging.registration import Registration

FloatArray = NDArray[np.floating[Any]]
BoolArray = NDArray[np.bool_]
IntArray = NDArray[np.integer[Any]]

ProgressFn = Callable[[str, int, int], None]
"""Called as ``progress(description, completed, total)`` after each stage of a multi-stage run."""

# --- the demo scene (seed §2.1-2.4) -------------------------------------------------------------------
DEMO_FIELD_SHAPE = (240, 320)
"""(rows, cols) of the compensated field images; the camera frame has twice the rows (2:1 interlace)."""
DEMO_SHIFT_XY = (5.4, -3.3)
"""Viewpoint change between reference and inspection, field pixels (seed §2.3: 1-2 px in the lab, more
in space from arm flexibility and thermal expansion)."""
SUN_LUX = 130_000.0  # seed §2.1: solar illuminance in Earth orbit
STROBE_LUX_S = 13.0  # seed §2.1: 1.3 lm s over a 0.1 m^2 scene
REFERENCE_AMBIENT_LUX = SUN_LUX
INSPECTION_AMBIENT_LUX = 0.6 * SUN_LUX  # the orbit has moved on: the sun is lower on the surface
SHADOW_AMBIENT_FRACTION = 0.1  # earthlight left inside the shadow of a strut
PENUMBRA_PX = 4.0  # seed §2.2: a penumbra wider than 2 px is interpolated accurately
REFLECTANCE_RANGE = (0.1, 0.6)  # keeps sun + strobe under the full well (camera.py: saturates above ~0.77)
FLAW_SIZE_PX = 3  # seed §2: ~1 mm micro-meteoroid impacts span a few pixels
FLAW_SPACING_PX = 40
# Reflectance lost at a flaw (dark, like the mock-up's tape impact sites, seed §4): ~4 noise sigmas a pixel,
# so at P_F = 1e-5 the single-pixel test finds about half, the 3x3 uniform model all (seed §2.4).
FLAW_DEPTH = 0.05
DEMO_FLAW_MODEL = "uniform"
DEMO_P_FALSE_ALARM = 1e-5
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
    flaw_model : {"single", "uniform", "peak"}
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


@dataclass(frozen=True)
class DemoResult:
    """Everything the synthetic demo produced, for the report to draw.

    Attributes
    ----------
    seed : int
        The seed every random draw came from.
    reference_frame, inspection_frame : Frame
        Raw interlaced frames: odd field lit by strobe plus ambient, even field ambient only (seed §2.2).
    reference_compensated, inspection_compensated : Compensated
        Strobe-only estimates at field resolution.
    pair : PairResult
        Registration and detection with the demo's flaw model.
    single_pixel : PairResult
        The same pair tested with the single-pixel model, to show what the multi-pixel model gains.
    centres_rc : ndarray of shape (K, 2), int
        Seeded flaw centres in inspection field pixels.
    truth_mask : ndarray of shape (M, N), bool
        Seeded flaw pixels in inspection field pixels.
    shift_xy : (float, float)
        True viewpoint change in field pixels: the inspection is the reference moved by this much.
    score : Score
        `pair`'s flaws matched against the truth.
    curves : tuple of RocCurve
        Theoretical and measured ROC curves for both flaw models.
    elapsed_s : float
        Wall time of the whole simulation, seconds.
    """

    seed: int
    reference_frame: Frame
    inspection_frame: Frame
    reference_compensated: Compensated
    inspection_compensated: Compensated
    pair: PairResult
    single_pixel: PairResult
    centres_rc: IntArray
    truth_mask: BoolArray
    shift_xy: tuple[float, float]
    score: Score
    curves: tuple[RocCurve, ...]
    elapsed_s: float


@dataclass(frozen=True)
class _Scene:
    reference_reflectance: FloatArray
    inspection_reflectance: FloatArray
    reference_ambient_lux: FloatArray
    inspection_ambient_lux: FloatArray
    centres_rc: IntArray
    truth_mask: BoolArray


def _build_scene(rng: np.random.Generator) -> _Scene:
    """Reflectance and ambient light at frame resolution (twice the field rows), and the flaw truth."""
    from scipy import ndimage

    from rsi.datasets.synthetic import flaw_pattern, textured_surface

    field_rows, cols = DEMO_FIELD_SHAPE
    frame_shape = (2 * field_rows, cols)
    low, high = REFLECTANCE_RANGE
    surface = low + (high - low) * textured_surface(frame_shape, rng=rng)
    shift_x, shift_y = DEMO_SHIFT_XY
    # The surface moves by shift_y field rows, i.e. twice that in frame rows (2:1 interlace, seed §2.2).
    moved = ndimage.shift(surface, (2.0 * shift_y, shift_x), order=3, mode="reflect")
    pattern = flaw_pattern(
        DEMO_FIELD_SHAPE,
        size_px=FLAW_SIZE_PX,
        spacing_px=FLAW_SPACING_PX,
        strength=FLAW_DEPTH,
        polarity="dark",
        rng=rng,
    )
    # One field row stands for two frame rows (2:1 interlace): field-resolution flaws are doubled in rows.
    inspected = np.clip(moved + np.repeat(pattern.signal, 2, axis=0), 0.0, 1.0)
    return _Scene(
        reference_reflectance=surface,
        inspection_reflectance=inspected,
        reference_ambient_lux=REFERENCE_AMBIENT_LUX * surface,
        inspection_ambient_lux=INSPECTION_AMBIENT_LUX * _shadow(frame_shape) * inspected,
        centres_rc=np.asarray(pattern.centres_rc, dtype=np.int64),
        truth_mask=np.asarray(pattern.truth_mask, dtype=bool),
    )


def _shadow(frame_shape: tuple[int, int]) -> FloatArray:
    """Ambient attenuation of a straight shadow edge across the frame with a linear penumbra (seed §2.2)."""
    rows, cols = np.indices(frame_shape, dtype=np.float64)
    # Signed distance in frame pixels from a line running diagonally through the lower half of the frame.
    distance = (rows - 0.6 * frame_shape[0]) * np.cos(0.3) - (cols - 0.5 * frame_shape[1]) * np.sin(0.3)
    lit = np.clip(0.5 - distance / PENUMBRA_PX, 0.0, 1.0)
    attenuation: FloatArray = SHADOW_AMBIENT_FRACTION + (1.0 - SHADOW_AMBIENT_FRACTION) * lit
    return attenuation


_STAGES = ("scene", "expose", "compensate", "register + detect", "score")


def simulate_demo(*, seed: int = 0, progress: ProgressFn | None = None) -> DemoResult:
    """Build the synthetic scene, image it through the camera model and inspect it.

    The reference and inspection frames are each one interlaced strobe/ambient frame (seed §2.1-2.2) under
    different ambient light: full sun for the reference; for the inspection a lower sun and the soft shadow of
    a strut across the view. The inspection viewpoint is shifted by :data:`DEMO_SHIFT_XY` and dark ~1 mm
    flaws (3x3 field pixels) are seeded on it. Both frames are compensated, registered and tested at
    P_F = 1e-5 per pixel, and the found flaws are scored against the truth.

    Parameters
    ----------
    seed : int
        Seed of every random draw (texture, flaw positions, sensor noise); the same seed, the same run.
    progress : callable, optional
        Called as ``progress(stage, completed, total)`` after each of the five stages.

    Returns
    -------
    DemoResult
    """
    from rsi.imaging.camera import expose
    from rsi.imaging.compensation import compensate_interlaced

    seed = v.positive_int(seed, "seed", minimum=0)
    report = _progress_reporter(progress, _STAGES)
    start_s = time.perf_counter()
    rng = np.random.default_rng(seed)
    scene = _build_scene(rng)
    report()
    reference_frame = expose(scene.reference_ambient_lux, STROBE_LUX_S * scene.reference_reflectance, rng=rng)
    inspection_frame = expose(
        scene.inspection_ambient_lux, STROBE_LUX_S * scene.inspection_reflectance, rng=rng
    )
    report()
    reference = compensate_interlaced(reference_frame)
    inspection = compensate_interlaced(inspection_frame)
    report()
    pair = inspect_pair(
        reference, inspection, flaw_model=DEMO_FLAW_MODEL, size=FLAW_SIZE_PX, p_false_alarm=DEMO_P_FALSE_ALARM
    )
    single = _single_pixel(pair, reference, inspection)
    report()
    score = score_flaws(pair.flaws, scene.centres_rc, valid=pair.detection.valid)
    curves = _roc_curves((pair, single), scene.truth_mask, strength_sigma=_flaw_strength_sigma(pair))
    report()
    return DemoResult(
        seed=seed,
        reference_frame=reference_frame,
        inspection_frame=inspection_frame,
        reference_compensated=reference,
        inspection_compensated=inspection,
        pair=pair,
        single_pixel=single,
        centres_rc=scene.centres_rc,
        truth_mask=scene.truth_mask,
        shift_xy=DEMO_SHIFT_XY,
        score=score,
        curves=curves,
        elapsed_s=time.perf_counter() - start_s,
    )


def _progress_reporter(progress: ProgressFn | None, stages: tuple[str, ...]) -> Callable[[], None]:
    done = iter(range(1, len(stages) + 1))

    def report() -> None:
        completed = next(done)
        if progress is not None:
            progress(stages[completed - 1], completed, len(stages))

    return report


def _single_pixel(pair: PairResult, reference: Compensated, inspection: Compensated) -> PairResult:
    """Re-test the registered pair with the single-pixel model (seed §2.4) for the ROC comparison."""
    from rsi.detection.detect import detect

    start_s = time.perf_counter()
    detection = detect(
        reference,
        inspection,
        flaw_model="single",
        p_false_alarm=DEMO_P_FALSE_ALARM,
        registration=pair.registration,
    )
    return PairResult(pair.reference, pair.inspection, detection, time.perf_counter() - start_s)


def _flaw_strength_sigma(pair: PairResult) -> float:
    """Seeded flaw contrast in units of the difference image's noise sigma, for the theoretical ROC.

    The compensated image is the strobe-lit estimate (seed §2.2), so a flaw that removes ``FLAW_DEPTH`` of
    reflectance removes ``FLAW_DEPTH * STROBE_LUX_S`` lux s of exposure, converted here to DN.
    """
    from rsi.imaging.camera import DEFAULT_CAMERA

    contrast_e = FLAW_DEPTH * STROBE_LUX_S * DEFAULT_CAMERA.electrons_per_lux_s
    contrast_dn = contrast_e / DEFAULT_CAMERA.gain_e_per_dn
    sigma = np.asarray(pair.detection.sigma, dtype=np.float64)
    valid = np.broadcast_to(np.asarray(pair.detection.valid, dtype=bool), sigma.shape) if sigma.ndim else None
    typical_sigma = float(np.median(sigma[valid])) if valid is not None else float(sigma)
    return contrast_dn / typical_sigma


def _roc_curves(
    pairs: tuple[PairResult, ...], truth_mask: BoolArray, *, strength_sigma: float
) -> tuple[RocCurve, ...]:
    """Theory (seed §2.4) next to what the score maps measured on this scene, for each flaw model."""
    from dataclasses import replace

    from rsi.detection.roc import empirical_roc, theoretical_roc

    curves: list[RocCurve] = []
    for pair in pairs:
        detection = pair.detection
        model = detection.flaw_model
        theory = theoretical_roc(model, strength_sigma=strength_sigma, size=FLAW_SIZE_PX, polarity="dark")
        measured = empirical_roc(detection.score, truth_mask, valid=detection.valid)
        curves.append(replace(theory, label=f"{model}: theory"))
        curves.append(replace(measured, label=f"{model}: measured"))
    return tuple(curves)
