"""The ambient-lit image read as a second look for free (seed §2 further work: "the information in the
ambient lit image needs to be exploited and used to supplement the image information in the compensated
image").

Every visit takes its ambient alone at several shutters (:func:`rsi.mission.exposure.ambient_bracket`),
merged into one image of high dynamic range (:func:`rsi.imaging.bracket.merge_ambient`). A look the strobe
comparison found is read there again, against the reference pass's ambient-lit image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rsi.imaging.compensation import Compensated
from rsi.mission.evidence import CLUTTER_REACH_PX, FOLLOW_HALF_PX, Look, second_look_score
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.detection.pair import PairResult
    from rsi.imaging.bracket import AmbientImage


@dataclass(frozen=True)
class AmbientEcho:
    """What the ambient-lit images of the two passes say of a look (:func:`ambient_echo`).

    Attributes
    ----------
    score : float
        The look's place compared in the ambient-lit images (a translation registered about it, gain and
        bias fitted), judged against its ring (:func:`spot_score`), in noise sigmas, either sign.
    reach : float
        The score an unchanged shape of the look's own contrast would give there: a change of reflectance
        scales every light alike (seed §4: a discoloured surface), so where the sun lights the place in both
        passes, ``reach`` is what such a change must show. A change of shape (a crater's slopes, relit by a
        sun from another angle) may show less.
    """

    score: float
    reach: float


# registered pixels below which a translation, gain and bias are not fitted: a flaw kernel's few hundred
_MIN_FIT_PX = 200
# a place is lit when its ambient reads 10 times its noise: the bracket's own bound on a shadow
# (rsi.mission.exposure: 8-bit steps and read noise >= 10 % of the reading)
_LIT_SNR = 10.0
# the crop about a look in which the ambient-lit images are registered and compared: the followed window
# (FOLLOW_HALF_PX) and the ring a blob is judged against beyond it
_ECHO_HALF_PX = FOLLOW_HALF_PX + CLUTTER_REACH_PX


def ambient_echo(
    reference: AmbientImage, inspection: AmbientImage, look: Look, settings: MissionSettings
) -> AmbientEcho | None:
    """The look read again in the ambient-lit images of its two passes (seed §2 further work: "the
    information in the ambient lit image needs to be exploited"): the same place under another light, for
    free. None where either pass's ambient is not read there (clipped, or the crop at the frame's edge
    leaves too few pixels to register).

    The strobe rides with the camera and the sun does not (seed §2.2): what one strobe frame made (its glare
    moved with the viewpoint, its shadow beside an edge) is not in the ambient, and the sun's own change
    between the passes is smooth over a plain face (a gain, fitted) and a moved shadow edge is no
    millimetre spot (:func:`spot_score` widens the noise by the ring's spread).
    """
    from rsi.detection.detect import detect
    from rsi.detection.pair import PairResult
    from rsi.imaging.registration import register

    rows, cols = inspection.image.shape
    row, col = (round(value) for value in look.at_px)
    top, left = max(row - _ECHO_HALF_PX, 0), max(col - _ECHO_HALF_PX, 0)
    crop = (slice(top, min(row + _ECHO_HALF_PX + 1, rows)), slice(left, min(col + _ECHO_HALF_PX + 1, cols)))
    images = [
        Compensated(
            image=image.image[crop],
            valid=image.valid[crop] & np.isfinite(image.variance[crop]),
            variance=image.variance[crop],
            interpolation_variance=np.zeros_like(image.variance[crop]),
            row_step=1,
        )
        for image in (reference, inspection)
    ]
    at = (look.at_px[0] - top, look.at_px[1] - left)
    kernel = settings.flaw_size_px
    near = [slice(max(round(value) - kernel, 0), round(value) + kernel + 1) for value in at]
    here = (near[0], near[1])
    if not all(image.valid[here].all() and _lit(image, here) for image in images):
        return None
    window = np.zeros(images[0].image.shape, bool)
    window[
        max(round(at[0]) - FOLLOW_HALF_PX, 0) : round(at[0]) + FOLLOW_HALF_PX + 1,
        max(round(at[1]) - FOLLOW_HALF_PX, 0) : round(at[1]) + FOLLOW_HALF_PX + 1,
    ] = True
    if int((window & images[0].valid).sum()) < _MIN_FIT_PX:
        return None
    fit = register(images[0].image, images[1].image, model="translation", mask=window & images[0].valid)
    if not fit.converged:
        return None
    found = detect(
        images[0],
        images[1],
        registration=fit,
        flaw_model=settings.flaw_model,
        size=kernel,
        p_false_alarm=settings.p_preliminary,
        polarity="both",
        misregistration_std_px=settings.misregistration_std_px,
    )
    pair = PairResult(images[0].image, images[1].image, found, 0.0)
    score = second_look_score(pair, at, kernel)
    signed = _signed_at(pair, at, score)
    level = float(np.median(images[1].image[here]))
    noise = float(
        np.sqrt(np.median(images[1].variance[here]) + fit.gain**2 * np.median(images[0].variance[here]))
    )
    reach = look.contrast * max(level, 0.0) * kernel / max(noise, 1e-6)
    return AmbientEcho(signed, reach)


def _lit(image: Compensated, here: tuple[slice, slice]) -> bool:
    """Whether the ambient reads at `here` with its noise under ``1 / _LIT_SNR`` of it: where the sun does
    not reach, the ambient-lit image has nothing to say."""
    level = float(np.median(image.image[here]))
    return level > _LIT_SNR * math.sqrt(float(np.median(image.variance[here])))


def _signed_at(pair: PairResult, at_px: tuple[float, float], score: float) -> float:
    """`score` with the sign of the statistic's strongest reading within 2 px of `at_px`."""
    r, c = round(at_px[0]), round(at_px[1])
    near = pair.detection.statistic[max(r - 2, 0) : r + 3, max(c - 2, 0) : c + 3]
    if near.size == 0:
        return score
    strongest = float(near.flat[int(np.argmax(np.abs(near)))])
    return math.copysign(score, strongest)


# run_mission's internals, no public API (PEP 8: an empty __all__): every caller is
# :func:`rsi.mission.run_mission`, with values it built and checked (docs/reliability.md).
__all__: list[str] = []
