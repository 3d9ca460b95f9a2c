"""One world for the simulator tests: building and rendering cost seconds, so share it per module."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")

from rsi.sim.world import World, load

SEED = 16  # five impacts on the solar panel, a missing screw and a swapped tank (D_tank_0)


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    built = load("truss", seed=SEED)
    yield built
    built.close()
