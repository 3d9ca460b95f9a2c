"""A look read again under another light, from the same viewpoint (seed §2 further work, §2.5): the sun's
(the ambient-lit image, "exploited and used to supplement the image information in the compensated image")
and the ISEE's other strobe ("selection of different illuminator/camera combinations to get more data").

Every visit takes its ambient alone at several shutters (:func:`rsi.mission.exposure.ambient_bracket`),
merged into one image of high dynamic range (:func:`rsi.imaging.bracket.merge_ambient`), and its frames again
with the other strobe, below the lens (:meth:`rsi.sim.world.World.other_strobe_frames`). A look the strobe
comparison found is read in each against the reference pass's image under the same light. The echoes go
into each finding's record (``MissionFinding.ambient_score``, ``other_strobe_score``) and decide nothing:
taken from the first look's viewpoint, they share every artefact it made (door-edge points confirmed at
6.5-16 sigma under either light where a second visit had rejected them, held-out seeds 2105 and 2134).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from rsi.imaging.compensation import Compensated
from rsi.mission.evidence import (
    CLUTTER_REACH_PX,
    FOLLOW_HALF_PX,
    Echo,
    Look,
    follow_window,
    second_look_score,
)
from rsi.mission.settings import MissionSettings

if TYPE_CHECKING:
    from rsi.detection.pair import PairResult
    from rsi.imaging.bracket import AmbientImage
    from rsi.imaging.registration import Registration


# registered pixels below which a translation, gain and bias are not fitted: a flaw kernel's few hundred
_MIN_FIT_PX = 200
# a place is lit when it reads 10 times its noise: the ambient bracket's own bound on a shadow
# (rsi.mission.exposure: 8-bit steps and read noise >= 10 % of the reading)
_LIT_SNR = 10.0
# the crop about a look in which the two images are registered and compared: the followed window
# (FOLLOW_HALF_PX) and the ring a blob is judged against beyond it
_ECHO_HALF_PX = FOLLOW_HALF_PX + CLUTTER_REACH_PX


def ambient_echo(
    reference: AmbientImage, inspection: AmbientImage, look: Look, settings: MissionSettings
) -> Echo | None:
    """The look read again in the ambient-lit images of its two passes (seed §2 further work: "the
    information in the ambient lit image needs to be exploited"): the same place under the sun, for free.

    The strobe rides with the camera and the sun does not (seed §2.2): what one strobe frame made (its glare
    moved with the viewpoint, its shadow beside an edge) is not in the ambient, and the sun's own change
    between the passes is smooth over a plain face (a gain, fitted) and a moved shadow edge is no
    millimetre spot (:func:`rsi.mission.evidence.spot_score` widens the noise by the ring's spread).
    """
    return echo_in(_as_image(reference), _as_image(inspection), look, settings)


def echo_in(
    reference: Compensated, inspection: Compensated, look: Look, settings: MissionSettings
) -> Echo | None:
    """The look read again in two passes' images under one other light (:class:`Echo`). None where either
    image does not read the place (in shadow, clipped, or the crop at the frame's edge leaves too few
    pixels to register)."""
    from rsi.detection.detect import detect
    from rsi.detection.pair import PairResult

    images, at = _crops(reference, inspection, look)
    kernel = settings.flaw_size_px
    near = [slice(max(round(value) - kernel, 0), round(value) + kernel + 1) for value in at]
    here = (near[0], near[1])
    if not all(image.valid[here].all() and _lit(image, here) for image in images):
        return None
    fit = _registered_about(images, at)
    if fit is None:
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
    score = _signed_at(pair, at, second_look_score(pair, at, kernel))
    level = float(np.median(images[1].image[here]))
    noise = math.sqrt(
        float(np.median(images[1].variance[here])) + fit.gain**2 * float(np.median(images[0].variance[here]))
    )
    # the flaw kernel's sum over its noise: a 3x3 change of `contrast` at this level (seed §2.4)
    return Echo(score, look.contrast * max(level, 0.0) * kernel / max(noise, 1e-6))


def _crops(
    reference: Compensated, inspection: Compensated, look: Look
) -> tuple[list[Compensated], tuple[float, float]]:
    """Both images cropped about the look (``_ECHO_HALF_PX``), and the look's place in the crop."""
    rows, cols = inspection.image.shape
    row, col = (round(value) for value in look.at_px)
    top, left = max(row - _ECHO_HALF_PX, 0), max(col - _ECHO_HALF_PX, 0)
    crop = (slice(top, min(row + _ECHO_HALF_PX + 1, rows)), slice(left, min(col + _ECHO_HALF_PX + 1, cols)))
    images = [
        Compensated(
            image=image.image[crop],
            valid=image.valid[crop] & np.isfinite(image.variance[crop]),
            variance=image.variance[crop],
            interpolation_variance=image.interpolation_variance[crop],
            row_step=1,
        )
        for image in (reference, inspection)
    ]
    return images, (look.at_px[0] - top, look.at_px[1] - left)


def _registered_about(images: list[Compensated], at: tuple[float, float]) -> Registration | None:
    """The reference crop registered on the inspection crop by a translation, gain and bias, over the
    followed window about `at` (seed §2.3: a small mis-registration is locally a translation); None where
    too few pixels or no convergence."""
    from rsi.imaging.registration import register

    mask = follow_window(images[0].image.shape, at) & images[0].valid
    if int(mask.sum()) < _MIN_FIT_PX:
        return None
    fit = register(images[0].image, images[1].image, model="translation", mask=mask)
    return fit if fit.converged else None


def _lit(image: Compensated, here: tuple[slice, slice]) -> bool:
    """Whether `image` reads `here` with its noise under ``1 / _LIT_SNR`` of it: where its light does not
    reach (the sun's shadow, the strobe's beyond its beam) it has nothing to say."""
    level = float(np.median(image.image[here]))
    return level > _LIT_SNR * math.sqrt(float(np.median(image.variance[here])))


def _as_image(ambient: AmbientImage) -> Compensated:
    """An ambient-lit image as the comparison reads an image: its values, variance and valid pixels."""
    return Compensated(
        image=ambient.image,
        valid=ambient.valid,
        variance=ambient.variance,
        interpolation_variance=np.zeros_like(ambient.variance),
        row_step=1,
    )


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
