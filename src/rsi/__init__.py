"""rsi: robotic surface inspection of space platforms.

After Volpe & Balaram, "Technology for Robotic Surface Inspection in Space" (JPL). Table of contents:

- :mod:`rsi.imaging`    seed §2.1-2.3: camera model, ambient-light compensation, registration
- :mod:`rsi.detection`  seed §2.4: flaw models, noise model, likelihood-ratio tests, ROC
- :mod:`rsi.datasets`   real pair datasets (DeepPCB) and the synthetic flaw-pattern generator
- :mod:`rsi.cli`        the ``rsi`` command

The front door: :func:`rsi.register` and :func:`rsi.detect`. Importing rsi stays cheap: the heavy modules
load on first use.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

__version__ = "0.1.0"

_LAZY = {
    "register": "rsi.imaging.registration",
    "Registration": "rsi.imaging.registration",
    "detect": "rsi.detection.detect",
    "Detection": "rsi.detection.detect",
    "Flaw": "rsi.detection.detect",
    "InputError": "rsi.errors",
    "RsiError": "rsi.errors",
}

__all__ = ["Detection", "Flaw", "InputError", "Registration", "RsiError", "__version__", "detect", "register"]

if TYPE_CHECKING:
    from rsi.detection.detect import Detection, Flaw, detect
    from rsi.errors import InputError, RsiError
    from rsi.imaging.registration import Registration, register


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'rsi' has no attribute {name!r}")
