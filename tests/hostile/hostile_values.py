"""Hostile values and the rule every public entry point must keep (issue 17).

The rule: whatever it is given, a public function returns, or raises one of rsi's own errors, or a
ValueError / TypeError whose message names one of its arguments. Anything else (OverflowError, LinAlgError,
ZeroDivisionError, a numpy or OpenCV error, a MemoryError, a hang) is a defect.
"""

from __future__ import annotations

import functools
import inspect
import math
import random
import re
import signal
import time
import warnings
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from rsi.errors import RsiError

HUGE_INT = 10**400  # no float holds it: float(HUGE_INT) raises OverflowError

# Scalars that have broken rsi before: beyond the float range, not finite, subnormal, negative zero,
# huge, the wrong type altogether.
_SCALARS = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from([HUGE_INT, -HUGE_INT, 2**63, 2**64 + 1, -1, 0, 1, 99999, 10**9]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([1e200, -1e200, 1e-320, -0.0, 3.5e38, 1e16, 1e300, math.nan, math.inf, -math.inf]),
    st.text(max_size=12),
    st.sampled_from(["", " ", "nan", "1e400", "translation", "single", "both", "lrt", "x" * 300]),
    st.binary(max_size=8),
)
_ELEMENTS = {
    64: st.one_of(st.floats(width=64), st.sampled_from([0.0, 1.0, 255.0, 1e18, -1e18, 1e300, 3.5e38])),
    32: st.one_of(
        st.floats(width=32),
        st.sampled_from([0.0, 1.0, 255.0, float(np.float32(1e18)), float(np.float32(3e38))]),
    ),
}
_SHAPES = st.sampled_from(
    [(0,), (1,), (3,), (6,), (2, 2), (3, 3), (4, 5), (8, 8), (3, 3, 3), (0, 4), (16, 16)]
)


def _array(dtype: Any) -> st.SearchStrategy[np.ndarray]:
    kind = np.dtype(dtype)
    if kind.kind == "f":
        return hnp.arrays(dtype, _SHAPES, elements=_ELEMENTS[8 * kind.itemsize])
    return hnp.arrays(dtype, _SHAPES)


ARRAYS = st.one_of(
    _array(np.float64),
    _array(np.float32),
    _array(np.uint8),
    _array(np.int64),
    _array(np.bool_),
    hnp.arrays(np.complex128, st.sampled_from([(3,), (4, 4)])),
    st.just(np.empty((2, 2), dtype=object)),
    st.sampled_from([np.zeros((16, 16)), np.full((16, 16), 255.0), np.eye(3), np.eye(6), np.ones(6)]),
)
HOSTILE = st.one_of(
    _SCALARS,
    ARRAYS,
    st.lists(st.floats(allow_nan=True, allow_infinity=True), max_size=7),
    st.tuples(st.floats(), st.floats()),
    st.dictionaries(st.text(max_size=4), st.integers(), max_size=3),
    st.just(object()),
    st.just(Path("/dev/zero")),
)


def names_an_argument(message: str, names: Iterator[str] | list[str] | tuple[str, ...]) -> bool:
    """True when `message` names one of `names` as a word (``size``, ``band_m[1]``, ``rng seed``)."""
    return any(re.search(rf"(?<![A-Za-z_]){re.escape(name)}(?![A-Za-z_])", message) for name in names)


class HangError(Exception):
    """A call ran past its time limit."""


@contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`HangError` in the calling thread after `seconds` (SIGALRM; main thread only)."""

    def expire(_signum: int, _frame: object) -> None:
        raise HangError(f"no answer within {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def call_keeps_the_rule(function: Callable[..., Any], arguments: Mapping[str, Any], *, limit_s: float) -> str:
    """Call `function(**arguments)`; return "" if it kept the rule, else what went wrong."""
    names = list(arguments) or list(inspect.signature(function).parameters)
    try:
        # Warnings are not errors here (the CLI turns them into one line, tested there).
        with time_limit(limit_s), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            function(**arguments)
    except RsiError:
        return ""
    except (ValueError, TypeError) as error:
        if names_an_argument(str(error), names):
            return ""
        return f"{type(error).__name__} not naming an argument: {error}"[:400]
    except HangError as error:
        return f"hang: {error}"
    except Exception as error:
        return f"{type(error).__name__}: {error}"[:400]
    return ""


def call_tracked(
    function: Callable[..., Any], arguments: Mapping[str, Any], *, limit_s: float
) -> tuple[str, bool, float]:
    """:func:`call_keeps_the_rule`, and whether the call returned (it was not refused) and its seconds."""
    returned: list[bool] = []

    @functools.wraps(function)
    def tracked(**kwargs: Any) -> None:
        function(**kwargs)
        returned.append(True)

    start = time.perf_counter()
    problem = call_keeps_the_rule(tracked, arguments, limit_s=limit_s)
    return problem, bool(returned), time.perf_counter() - start


# The 1,000-case suites (test_hostile_world.py) draw from prebuilt values of the same kinds as HOSTILE: its
# arrays cost milliseconds each to generate, and 1,000 cases of every World method would take minutes.
_POOL = (
    None,
    True,
    False,
    HUGE_INT,
    -HUGE_INT,
    2**63,
    2**64 + 1,
    -1,
    0,
    1,
    99999,
    10**9,
    1e200,
    -1e200,
    1e-320,
    -0.0,
    3.5e38,
    1e300,
    math.nan,
    math.inf,
    -math.inf,
    "",
    " ",
    "nan",
    "1e400",
    "x" * 300,
    b"",
    b"\x00\xff",
    np.zeros(0),
    np.zeros(3),
    np.ones(6),
    np.full(3, math.nan),
    np.full(3, 1e300),
    np.eye(3),
    np.zeros((16, 16)),
    np.zeros((2, 3)),
    np.zeros((3, 3, 3)),
    np.zeros(3, dtype=np.uint8),
    np.zeros(3, dtype=np.bool_),
    np.zeros(3, dtype=np.complex128),
    np.empty((2, 2), dtype=object),
    np.float32(3e38),
    np.int64(-5),
    [],
    [1.0, math.nan],
    [1.0, 2.0, 3.0],
    [[1.0, 2.0], [3.0]],
    (1.0, 2.0),
    (0, 0),
    (16, 16),
    (-1, 5),
    (1e-320, 1.0),
    (math.inf, 1.0, 0.0),
    {"a": 1},
    {1, 2},
    object(),
    Path("/dev/zero"),
    Path("/nonexistent/x"),
    print,
)
HOSTILE_FAST = st.one_of(
    st.sampled_from(_POOL),
    st.floats(allow_nan=True, allow_infinity=True),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.text(max_size=6),
)
"""HOSTILE's kinds of values, prebuilt (beyond-float ints, NaN, inf, subnormals, text, bytes, odd arrays,
ragged lists, sets, paths, wrong objects), cheap enough for 1,000 cases of every method."""


def fast_value(draw: random.Random) -> Any:
    """One of HOSTILE_FAST's kinds of value from a hypothesis-seeded `draw` (``st.randoms()``): microseconds a
    value where a hypothesis draw costs tens of microseconds, for suites that make thousands of calls."""
    kind = draw.randrange(8)
    if kind == 0:
        return draw.choice((math.nan, math.inf, -math.inf, 0.0, -0.0, draw.uniform(-1e300, 1e300)))
    if kind == 1:
        return draw.randint(-(2**70), 2**70)
    if kind == 2:
        return "".join(draw.choice("a1 .-_/\x00\u00e9") for _ in range(draw.randrange(7)))
    return draw.choice(_POOL)
