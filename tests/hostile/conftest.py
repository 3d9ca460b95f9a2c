"""The hostile suite runs under a memory cap: an unbounded allocation fails there as a MemoryError (a defect
the rule catches) instead of growing the test process until the kernel kills it."""

from __future__ import annotations

import resource
from collections.abc import Iterator

import pytest

from rsi.sim.world import World

CAP_HEADROOM_BYTES = 3 * 2**30
"""Address space allowed above what the process already maps: ample for every bounded input (the largest
default image, 8192 x 8192, needs about 1 GiB), far below what an unbounded one asks (74.5 GiB, 24 GB)."""


def _mapped_bytes() -> int:
    with open("/proc/self/status", encoding="ascii") as status:
        for line in status:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize in /proc/self/status")


@pytest.fixture(autouse=True, scope="module")
def memory_cap() -> Iterator[int]:
    """RLIMIT_AS lowered to the current mapping plus the headroom for the module, then restored."""
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    cap = _mapped_bytes() + CAP_HEADROOM_BYTES
    if hard != resource.RLIM_INFINITY:
        cap = min(cap, hard)
    resource.setrlimit(resource.RLIMIT_AS, (cap, hard))
    try:
        yield cap
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))


@pytest.fixture(scope="module")
def world() -> Iterator[World]:
    """One truss world with the arm, loaded once per module (the world and console suites call into it)."""
    import rsi.sim

    loaded = rsi.sim.load("truss", seed=0, arm=True)
    try:
        yield loaded
    finally:
        loaded.close()
