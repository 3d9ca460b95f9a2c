"""Direct tests of the checks added for the hostile suite whose messages the generated cases may not reach
(issue 17): each asserts the argument, the value or the fix is named."""

from __future__ import annotations

import pytest

from rsi.errors import InputError
from rsi.sim.mockup import vista


def test_a_vista_needs_a_name() -> None:
    with pytest.raises(InputError, match="name must be a non-empty string; got ''"):
        vista("", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, 1.0, 0.0), 0.5)


def test_a_vista_refuses_an_up_along_its_normal() -> None:
    with pytest.raises(InputError, match=r"up=\(0, 0, 2\) is parallel to normal=\(0, 0, 1\)"):
        vista("A_door", (0.0, 0.0, 0.0), (0, 0, 1), (0, 0, 2), 0.5)


def test_a_vista_is_built_from_checked_vectors() -> None:
    view = vista("A_door", (1, 2, 3), (0, 0, 2), (0, 1, 0), 0.5)
    assert view.position_m == (1.0, 2.0, 3.5)
    assert view.forward == (0.0, 0.0, -1.0)
