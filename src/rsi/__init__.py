"""rsi: robotic surface inspection of space platforms.

After Volpe & Balaram, "Technology for Robotic Surface Inspection in Space" (JPL). Table of contents:

Core (numpy, scipy, OpenCV; no simulator):

- :mod:`rsi.imaging`    seed §2.1-2.3: camera model, ambient-light compensation, registration, image files
- :mod:`rsi.detection`  seed §2.4: flaw models, noise and nuisance models, likelihood-ratio tests, ROC
- :mod:`rsi.sensors`    seed §3: proximity, pyrometer, MOS gas, force/torque, lamps and strobes
- :mod:`rsi.control`    seed §3.1: the proximity velocity law (regions A-F) and the Fig. 4 blend

Above the core, each room importing only the rooms below it:

- :mod:`rsi.sim`        seed §4: the MuJoCo truss mock-up, anomalies, fields, solar simulator, orbit, arm
- :mod:`rsi.datasets`   real pair datasets (DeepPCB), the synthetic flaw patterns and demo pair, rendered
                        samples
- :mod:`rsi.archive`    references, runs, findings and flaw history in SQL
- :mod:`rsi.mission`    the inspection mission as a list of steps, its settings, records and score; batch
- :mod:`rsi.report`     result records to pictures, plots, tables and the HTML report
- :mod:`rsi.cli`        the ``rsi`` command
- :mod:`rsi.constants`  the paper's numbers used by several rooms; :mod:`rsi.errors` the error types

The front door: :func:`rsi.register` and :func:`rsi.detect`. Importing rsi stays cheap: the heavy modules
load on first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from rsi._lazy import lazy_getattr

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


__getattr__ = lazy_getattr(__name__, _LAZY)
