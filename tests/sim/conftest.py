"""One world for the simulator tests: building and rendering cost seconds, so share it per module."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.sim.anomalies import AnomalySettings
from rsi.sim.world import World, load

# the seed mock-up's fixed draw (seed §4): five dark impacts, four of them in the C_panel view, five missing
# screws and a discoloured tank (D_tank_0)
SEED = 101
SETTINGS = AnomalySettings.seed_mockup()


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    built = load("truss", seed=SEED, settings=SETTINGS)
    yield built
    built.close()


@pytest.fixture
def same_draw() -> Callable[[], World]:
    """A new world of the module world's draw, for a setting MuJoCo reads when a renderer is made."""
    return lambda: load("truss", seed=SEED, settings=SETTINGS)
