"""One seed, many independent random streams: each stream is spawned from the one before it, never re-derived.

numpy's :class:`~numpy.random.SeedSequence` spawns children that are independent of each other and of
their parent's other children; a room that needs streams receives a sequence (or the user's integer seed)
and spawns its own from it, so no two rooms can pick the same stream by choosing the same integer tag.
"""

from __future__ import annotations

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


def seed_number(seed: SeedLike) -> int:
    """The integer a seed or sequence was made from (its entropy), for records and reports."""
    entropy = seed.entropy if isinstance(seed, np.random.SeedSequence) else seed
    return int(entropy)  # type: ignore[arg-type]
