"""Seed §2.1-2.3: camera model, ambient-light compensation, image registration, and image files.

- :mod:`~rsi.imaging.camera` the linear CCD with its noise (seed §2.1): :func:`expose`, :class:`Frame`;
- :mod:`~rsi.imaging.compensation` strobe minus ambient (seed §2.2): :func:`compensate_interlaced`,
  :func:`compensate_field_pair`, :class:`Compensated`;
- :mod:`~rsi.imaging.bracket` the ambient-lit image from several shutters (seed §2 further work):
  :func:`merge_ambient`, :class:`AmbientImage`;
- :mod:`~rsi.imaging.registration` Gauss-Newton registration (seed §2.3): :func:`register`;
- :mod:`~rsi.imaging.io` reading and writing grey images: :func:`read_image`, :func:`write_image`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi._lazy import lazy_getattr

if TYPE_CHECKING:
    from rsi.imaging.bracket import AmbientImage, merge_ambient
    from rsi.imaging.camera import DEFAULT_CAMERA, BadPixelMap, CameraModel, Frame, expose
    from rsi.imaging.compensation import (
        Compensated,
        compensate_field_pair,
        compensate_interlaced,
        compensate_two_frames,
    )
    from rsi.imaging.io import read_image, write_image
    from rsi.imaging.registration import (
        MODELS,
        REGISTRATION_MODELS,
        PreparedReference,
        Registration,
        prepare_reference,
        register,
    )

# public names, loaded on first use so that importing the package stays cheap (PEP 562)
_LAZY = {
    "AmbientImage": "rsi.imaging.bracket",
    "merge_ambient": "rsi.imaging.bracket",
    "DEFAULT_CAMERA": "rsi.imaging.camera",
    "BadPixelMap": "rsi.imaging.camera",
    "CameraModel": "rsi.imaging.camera",
    "Frame": "rsi.imaging.camera",
    "expose": "rsi.imaging.camera",
    "Compensated": "rsi.imaging.compensation",
    "compensate_field_pair": "rsi.imaging.compensation",
    "compensate_interlaced": "rsi.imaging.compensation",
    "compensate_two_frames": "rsi.imaging.compensation",
    "read_image": "rsi.imaging.io",
    "write_image": "rsi.imaging.io",
    "MODELS": "rsi.imaging.registration",
    "REGISTRATION_MODELS": "rsi.imaging.registration",
    "PreparedReference": "rsi.imaging.registration",
    "Registration": "rsi.imaging.registration",
    "prepare_reference": "rsi.imaging.registration",
    "register": "rsi.imaging.registration",
}


__getattr__ = lazy_getattr(__name__, _LAZY)


__all__ = [
    "DEFAULT_CAMERA",
    "MODELS",
    "REGISTRATION_MODELS",
    "AmbientImage",
    "BadPixelMap",
    "CameraModel",
    "Compensated",
    "Frame",
    "PreparedReference",
    "Registration",
    "compensate_field_pair",
    "compensate_interlaced",
    "compensate_two_frames",
    "expose",
    "merge_ambient",
    "prepare_reference",
    "read_image",
    "register",
    "write_image",
]
