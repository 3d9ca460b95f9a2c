"""One seed, many independent random streams: each stream is spawned from the one before it, never re-derived.

numpy's :class:`~numpy.random.SeedSequence` spawns children that are independent of each other and of
their parent's other children; a room that needs streams receives a sequence (or the user's integer seed)
and spawns its own from it, so no two rooms can pick the same stream by choosing the same integer tag.
"""

from __future__ import annotations

import zlib

import numpy as np

from rsi.errors import InputError

SeedLike = int | np.integer | np.random.SeedSequence


def seed_sequence(seed: object, name: str = "seed") -> np.random.SeedSequence:
    """`seed` as a SeedSequence: an integer >= 0 seeds a new one, a SeedSequence is taken as it is.

    Raises
    ------
    InputError
        Naming `name`, for anything else (a bool, a float, a negative integer).
    """
    if isinstance(seed, np.random.SeedSequence):
        return seed
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"{name} must be an integer >= 0 or a numpy SeedSequence; got {seed!r}.")
    return np.random.SeedSequence(int(seed))


def keyed(parent: np.random.SeedSequence, key: str) -> np.random.SeedSequence:
    """The stream of one named event (a visit) under `parent`: the same `key` gives the same stream
    whatever else was drawn before it, and distinct keys independent streams.

    A simulated mission draws each visit's viewpoint error and camera noise from its visit's own stream,
    so that one visit more or fewer (a second look) leaves every other visit's draws as they were; drawn
    in sequence instead, a changed second look re-drew every later visit and an A/B comparison of two
    versions of the detector compared different missions. The key enters the spawn key as its CRC-32 after
    a marker word, which no spawned child's key (the parent's key and one small index) can equal.
    """
    if not isinstance(key, str) or not key:
        raise InputError(f"key must be a non-empty string naming the event; got {key!r}.")
    return np.random.SeedSequence(
        parent.entropy,
        spawn_key=(*parent.spawn_key, _KEYED_MARK, zlib.crc32(key.encode("utf-8"))),
        pool_size=parent.pool_size,
    )


# a spawn-key word no spawned child's index reaches (SeedSequence.spawn counts from 0)
_KEYED_MARK = 0xC0FFEE


def seed_number(seed: SeedLike) -> int:
    """The integer a seed or sequence was made from (its entropy), for records and reports."""
    entropy = seed.entropy if isinstance(seed, np.random.SeedSequence) else seed
    return int(entropy)  # type: ignore[arg-type]
