"""Seed §4: the orbital environment simulator (truss mock-up, anomalies, fields, solar simulator, frames).

- :mod:`rsi.sim.mockup`           geometry of the one-third-scale truss mock-up, in metres (pure)
- :mod:`rsi.sim.anomalies`        seeded anomalies with ground truth (pure)
- :mod:`rsi.sim.fields`           surface temperature and ammonia plume fields (pure)
- :mod:`rsi.sim.solar_simulator`  the robotic lamp's kinematics and optics (seed §4.1, pure)
- :mod:`rsi.sim.orbit`            sun path in low Earth orbit and the compensating exposure (pure)
- :mod:`rsi.sim.scene`            MJCF of the mock-up (MuJoCo)
- :mod:`rsi.sim.render`           OpenGL backend, basis images, depth and segmentation (MuJoCo)
- :mod:`rsi.sim.world`            the World: state, read-outs, frames, fields
- :mod:`rsi.sim.arm`              the K1207-style arm on its rail with the ISEE (in the World: ``arm=True``)
- :mod:`rsi.sim.proximity_loop`   the §3.1 44 Hz proximity loop on the arm (Fig. 4), stepped or run
- :mod:`rsi.sim.clearance`        the arm's smallest distance to the mock-up (MuJoCo geom distances)

The front door is :func:`load`; :data:`LAYOUTS` names the mock-up's layouts it builds ("truss", the seed's,
and "truss-b", issue 15's second arrangement). Importing ``rsi.sim`` does not import MuJoCo: it loads on
first use.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from rsi.sim.mockup import LAYOUT_NAMES as LAYOUTS

if TYPE_CHECKING:
    from rsi.sim.world import World

__all__ = ["LAYOUTS", "load"]


def load(scene: str = "truss", **kwargs: Any) -> World:
    """Build a seeded world; see :func:`rsi.sim.world.load` (``rsi.sim.load("truss-b", seed=7)``)."""
    from rsi.sim.world import load as load_world

    return load_world(scene, **kwargs)
