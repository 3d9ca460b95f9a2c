"""Seed §2.1: a linear CCD camera with an electronic shutter, a strobe that lights one field, and its noise.

The camera turns an illuminance image into digital numbers (DN)::

    electrons = Poisson(k * (E_ambient * t_exposure + H_strobe * lit_rows)) + dark
    DN        = clip(round(black + (min(electrons, full_well) + read) / gain), 0, max_DN)

with `k` = ``electrons_per_lux_s``, `gain` = ``full_well_e / (max_DN - black)`` so that a full well reads
exactly ``max_DN`` (a full well always reads ``max_DN``: the digitiser range ends there), and read noise
Gaussian. The response is linear (unity gamma, seed §2.1), which is what
lets ambient-light subtraction (seed §2.2) be computed on DN directly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.floating[Any]]
BoolArray = NDArray[np.bool_]
RawArray = NDArray[np.unsignedinteger[Any]]

LIT_FIELDS = ("odd", "even", "both", "none")

# A hot pixel's dark current fills this fraction of the well during a frame: bright, not always clipped.
HOT_DARK_FRACTION = 0.5
# Shot noise is Poisson; from 100 electrons up its Normal approximation (skewness 1/sqrt(mean) <= 0.1) is what
# no frame can tell from it: the ADC's step (78 electrons a DN by default) is eight of its sigmas there.
SHOT_NORMAL_E = 100.0
_MAX_BITS = 16
_QUANTISATION_VARIANCE_DN2 = 1.0 / 12.0  # uniform rounding error of one DN step


@dataclass(frozen=True)
class CameraModel:
    """A linear (unity-gamma) camera: sensitivity, well depth, read noise and digitiser.

    The defaults expose the seed's orbital scene sensibly (seed §2.1): at the default 1/10000 s shutter,
    sunlight (130000 lux) and the laboratory strobe (1.3 lm s over 0.1 m^2 = 13 lux s) each put
    13000 e- on a white pixel, so a mid-reflectance (0.5) surface lit by both fills 65 % of the well, and
    only surfaces brighter than reflectance ~0.77 saturate when both illuminate them.

    Parameters
    ----------
    electrons_per_lux_s : float
        Photo-electrons per lux second of (reflectance-weighted) illuminance on a pixel, > 0.
    full_well_e : float
        Well capacity in electrons, > 0; the signal clips here and reads ``max_dn``.
    read_noise_e : float
        Standard deviation of the Gaussian read noise in electrons, >= 0.
    bits : int
        Digitiser depth in bits, 1..16 (seed §2.1: 8-bit luminance).
    black_level_dn : float
        DN read by an unlit pixel, in [0, max_dn); an offset keeps the read noise of dark pixels unclipped.
    """

    electrons_per_lux_s: float = 1000.0
    full_well_e: float = 20000.0
    read_noise_e: float = 20.0
    bits: int = 8
    black_level_dn: float = 4.0

    def __post_init__(self) -> None:
        checks = {
            "electrons_per_lux_s": v.in_range(
                self.electrons_per_lux_s, "electrons_per_lux_s", low=0.0, low_inclusive=False
            ),
            "full_well_e": v.in_range(self.full_well_e, "full_well_e", low=0.0, low_inclusive=False),
            "read_noise_e": v.in_range(self.read_noise_e, "read_noise_e", low=0.0),
            "bits": v.positive_int(self.bits, "bits"),
        }
        if checks["bits"] > _MAX_BITS:
            raise InputError(
                f"bits must be in 1..{_MAX_BITS} (raw frames are uint8 or uint16); got {self.bits!r}."
            )
        max_dn = 2 ** checks["bits"] - 1
        checks["black_level_dn"] = v.in_range(
            self.black_level_dn, "black_level_dn", low=0.0, high=float(max_dn), high_inclusive=False
        )
        v.store_checked(self, checks)

    @property
    def max_dn(self) -> int:
        """Largest digital number the digitiser returns, ``2**bits - 1``."""
        return int(2**self.bits - 1)

    @property
    def gain_e_per_dn(self) -> float:
        """Electrons per DN, chosen so that a full well reads exactly ``max_dn``."""
        return self.full_well_e / (self.max_dn - self.black_level_dn)

    @property
    def raw_dtype(self) -> type[np.unsignedinteger[Any]]:
        """dtype of raw frames: uint8 up to 8 bits, uint16 above."""
        return np.uint8 if self.bits <= 8 else np.uint16

    def noise_variance_dn(self, image_dn: FloatArray | RawArray) -> NDArray[np.float32]:
        """Expected noise variance of a pixel reading `image_dn`, in DN^2.

        Parameters
        ----------
        image_dn : ndarray of any shape
            Raw readings in DN (black level included).

        Returns
        -------
        ndarray of the same shape, float32
            Shot + read + quantisation variance in DN^2.

        Notes
        -----
        Shot noise is Poisson in electrons, so its variance in DN^2 is ``signal_e / gain^2 =
        (DN - black) / gain``; read noise adds ``(read_noise_e / gain)^2`` and rounding ``1/12``.
        """
        floor = np.float32((self.read_noise_e / self.gain_e_per_dn) ** 2 + _QUANTISATION_VARIANCE_DN2)
        # in place on one float32 buffer: this runs on every frame of the pipeline
        variance: NDArray[np.float32] = np.subtract(image_dn, self.black_level_dn, dtype=np.float32)
        np.maximum(variance, 0, out=variance)
        variance *= np.float32(1.0 / self.gain_e_per_dn)
        variance += floor
        return variance


DEFAULT_CAMERA = CameraModel()


@dataclass(frozen=True)
class BadPixelMap:
    """Defective sensor pixels: hot (high dark signal), dead (read 0) and stuck (read a fixed value).

    Parameters
    ----------
    hot, dead, stuck : ndarray of shape (M, N), bool
        True where a pixel has that defect.
    stuck_value_dn : float
        DN a stuck pixel reads (clipped to the camera's ``max_dn``), >= 0.
    """

    hot: BoolArray
    dead: BoolArray
    stuck: BoolArray
    stuck_value_dn: float = 128.0

    def __post_init__(self) -> None:
        if not isinstance(self.hot, np.ndarray) or self.hot.ndim != 2:
            raise InputError(
                f"hot must be a 2-D numpy bool array of shape (rows, cols); got {type(self.hot).__name__} "
                f"with shape {getattr(self.hot, 'shape', None)}."
            )
        for name in ("hot", "dead", "stuck"):
            object.__setattr__(self, name, v.as_mask(getattr(self, name), name, self.hot.shape))
        object.__setattr__(self, "stuck_value_dn", v.in_range(self.stuck_value_dn, "stuck_value_dn", low=0.0))

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the sensor."""
        return (int(self.hot.shape[0]), int(self.hot.shape[1]))

    @property
    def defective(self) -> BoolArray:
        """True where a pixel is hot, dead or stuck (its reading must not be used)."""
        return self.hot | self.dead | self.stuck

    @classmethod
    def random(
        cls,
        shape: tuple[int, int],
        *,
        fraction: float = 1e-4,
        rng: np.random.Generator | int | None = None,
        stuck_value_dn: float = 128.0,
    ) -> BadPixelMap:
        """Draw a map where each pixel is defective with probability `fraction`, a third of each kind.

        Parameters
        ----------
        shape : (int, int)
            (rows, cols) of the sensor.
        fraction : float
            Probability in [0, 1] that a pixel is defective.
        rng : numpy.random.Generator, int or None
            Source of randomness; identical seeds give identical maps.
        stuck_value_dn : float
            DN the stuck pixels read.
        """
        rows, cols = _shape(shape)
        probability = v.in_range(fraction, "fraction", low=0.0, high=1.0)
        generator = v.as_rng(rng)
        defective = generator.random((rows, cols)) < probability
        kind = generator.integers(0, 3, size=(rows, cols))
        return cls(
            hot=defective & (kind == 0),
            dead=defective & (kind == 1),
            stuck=defective & (kind == 2),
            stuck_value_dn=stuck_value_dn,
        )


def _shape(shape: object) -> tuple[int, int]:
    if not isinstance(shape, tuple) or len(shape) != 2:
        raise InputError(f"shape must be a (rows, cols) tuple; got {shape!r}.")
    return (v.positive_int(shape[0], "shape[0]"), v.positive_int(shape[1], "shape[1]"))


@dataclass(frozen=True)
class Frame:
    """One raw camera frame and how it was taken.

    Parameters
    ----------
    raw : ndarray of shape (M, N), uint8 (bits <= 8) or uint16
        Digital numbers read out, black level included.
    saturated : ndarray of shape (M, N), bool
        True where the well filled or the digitiser clipped at ``max_dn``.
    lit_field : {"odd", "even", "both", "none"}
        Rows the strobe lit: "odd" = rows 1, 3, 5...; "even" = rows 0, 2, 4...; "both" = a whole flash frame;
        "none" = ambient only.
    exposure_s : float
        Electronic shutter time in seconds.
    camera : CameraModel
        The camera that took it.
    bad_pixels : BadPixelMap or None
        The sensor's known defects, if any.
    """

    raw: RawArray
    saturated: BoolArray
    lit_field: str
    exposure_s: float
    camera: CameraModel = field(default_factory=CameraModel)
    bad_pixels: BadPixelMap | None = None

    def __post_init__(self) -> None:
        _check_camera(self.camera)
        dtype = np.dtype(self.camera.raw_dtype)
        if not isinstance(self.raw, np.ndarray) or self.raw.ndim != 2 or self.raw.dtype != dtype:
            raise InputError(
                f"raw must be a 2-D {dtype.name} array for a {self.camera.bits}-bit camera; "
                f"got {type(self.raw).__name__} {getattr(self.raw, 'dtype', '')} "
                f"with shape {getattr(self.raw, 'shape', None)}. Build frames with expose() or cast raw."
            )
        object.__setattr__(self, "saturated", v.as_mask(self.saturated, "saturated", self.raw.shape))
        v.choice(self.lit_field, "lit_field", LIT_FIELDS)
        object.__setattr__(
            self, "exposure_s", v.in_range(self.exposure_s, "exposure_s", low=0.0, low_inclusive=False)
        )
        _check_bad_pixels(self.bad_pixels, self.raw.shape)


def _check_camera(camera: object) -> None:
    if not isinstance(camera, CameraModel):
        raise InputError(f"camera must be a CameraModel; got {type(camera).__name__}. Try CameraModel().")


def _check_bad_pixels(bad_pixels: object, shape: tuple[int, ...]) -> None:
    if bad_pixels is None:
        return
    if not isinstance(bad_pixels, BadPixelMap):
        raise InputError(f"bad_pixels must be a BadPixelMap or None; got {type(bad_pixels).__name__}.")
    if bad_pixels.shape != shape:
        raise InputError(
            f"bad_pixels must have the image's shape {shape}; got {bad_pixels.shape}. "
            "Build the map for this sensor, e.g. BadPixelMap.random(image.shape)."
        )


def _lit_rows(shape: tuple[int, ...], lit_field: str) -> BoolArray:
    """Bool column of shape (M, 1): True on the rows the strobe lights for `lit_field` (seed §2.2)."""
    rows = np.arange(shape[0])[:, None]
    parity: dict[str, BoolArray] = {
        "odd": rows % 2 == 1,
        "even": rows % 2 == 0,
        "both": rows >= 0,
        "none": rows < 0,
    }
    return parity[v.choice(lit_field, "lit_field", LIT_FIELDS)]


def expose(
    ambient_lux: FloatArray,
    strobe_lux_s: FloatArray,
    *,
    exposure_s: float = 1e-4,
    camera: CameraModel = DEFAULT_CAMERA,
    lit_field: str = "odd",
    rng: np.random.Generator | int | None = None,
    bad_pixels: BadPixelMap | None = None,
) -> Frame:
    """Take one interlaced frame of a scene under ambient light and a strobe (seed §2.1).

    Parameters
    ----------
    ambient_lux : ndarray of shape (M, N)
        Reflectance-weighted ambient illuminance on each pixel in lux (sunlight is ~130000 lux), >= 0.
        It is integrated over the shutter time.
    strobe_lux_s : ndarray of shape (M, N)
        Reflectance-weighted strobe exposure in lux seconds, >= 0. The ~20 us flash fits inside the shutter,
        so the shutter does not cut it (seed §2.1).
    exposure_s : float
        Electronic shutter time in seconds, > 0 (seed §2.1: 1/10000 s).
    camera : CameraModel
        The camera (default ``CameraModel()``).
    lit_field : {"odd", "even", "both", "none"}
        Rows the strobe lights: one field of the interlaced frame (seed §2.2), the whole frame ("both", the
        lit frame of two-frame compensation) or none (the ambient frame).
    rng : numpy.random.Generator, int or None
        Source of shot and read noise; identical seeds give identical frames.
    bad_pixels : BadPixelMap or None
        Defects to imprint: hot pixels gain a dark signal of half the well, dead read 0, stuck a fixed DN.

    Returns
    -------
    Frame
        Raw DN (uint8 for bits <= 8, else uint16) with the saturation mask.
    """
    _check_camera(camera)
    ambient = _exposure_image(ambient_lux, "ambient_lux")
    strobe = _exposure_image(strobe_lux_s, "strobe_lux_s")
    v.same_shape(ambient, strobe, ("ambient_lux", "strobe_lux_s"))
    seconds = v.in_range(exposure_s, "exposure_s", low=0.0, low_inclusive=False)
    _check_bad_pixels(bad_pixels, ambient.shape)
    generator = v.as_rng(rng)
    with np.errstate(over="ignore"):  # an overflow to inf only saturates the pixel (clipped just below)
        lux_s = ambient * seconds + strobe * _lit_rows(ambient.shape, lit_field)
        electrons = camera.electrons_per_lux_s * lux_s
    if bad_pixels is not None:
        electrons = electrons + HOT_DARK_FRACTION * camera.full_well_e * bad_pixels.hot
    # A mean 40 sigma over the full well fills the well whatever the shot noise draws: clipping there
    # changes no frame, and keeps the Poisson draw within numpy's range however bright the scene (1e16 lux s
    # and up would otherwise fail inside numpy).
    electrons = np.minimum(electrons, camera.full_well_e + 40.0 * math.sqrt(camera.full_well_e) + 40.0)
    # The well clips first (seed §2.2: ambient plus strobe must not saturate), then read noise, then the ADC.
    collected = np.minimum(_shot(electrons, generator), np.float32(camera.full_well_e))
    well_full = collected >= camera.full_well_e
    if camera.read_noise_e > 0:
        read = generator.standard_normal(collected.shape, dtype=np.float32)
        collected += np.float32(camera.read_noise_e) * read
    dn = np.clip(np.rint(camera.black_level_dn + collected / camera.gain_e_per_dn), 0, camera.max_dn)
    dn[well_full] = camera.max_dn  # the ADC range ends at the full well, so a full well reads max DN
    if bad_pixels is not None:
        dn, well_full = _imprint_fixed_defects(dn, well_full, bad_pixels, camera)
    raw = dn.astype(camera.raw_dtype)
    return Frame(
        raw=raw,
        saturated=well_full | (raw >= camera.max_dn),
        lit_field=lit_field,
        exposure_s=seconds,
        camera=camera,
        bad_pixels=bad_pixels,
    )


def _shot(electrons: FloatArray, generator: np.random.Generator) -> NDArray[np.float32]:
    """Photo-electrons collected, Poisson about `electrons`: drawn as the Normal of the same mean and
    variance from :data:`SHOT_NORMAL_E` up (numpy's Poisson draw took half of a frame's simulation)."""
    mean = electrons.astype(np.float32)
    collected = mean + np.sqrt(mean) * generator.standard_normal(mean.shape, dtype=np.float32)
    faint = mean < SHOT_NORMAL_E
    if faint.any():
        collected[faint] = generator.poisson(electrons[faint])
    return np.maximum(np.rint(collected, out=collected), np.float32(0.0), out=collected)


def _imprint_fixed_defects(
    dn: FloatArray, well_full: BoolArray, bad_pixels: BadPixelMap, camera: CameraModel
) -> tuple[FloatArray, BoolArray]:
    """Dead pixels read 0 and stuck pixels a fixed DN whatever the light; neither reports a full well."""
    dn = np.where(bad_pixels.dead, 0.0, dn)
    dn = np.where(bad_pixels.stuck, min(bad_pixels.stuck_value_dn, camera.max_dn), dn)
    return dn, well_full & ~(bad_pixels.dead | bad_pixels.stuck)


def _exposure_image(image: object, name: str) -> FloatArray:
    array = v.as_image(image, name)
    if (array < 0).any():
        raise InputError(
            f"{name} must be >= 0 everywhere (light cannot be negative); got min {array.min()!r}."
        )
    return array
