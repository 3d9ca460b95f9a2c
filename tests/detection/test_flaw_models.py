"""Flaw models (seed §2.4): shapes, normalisation and every input error."""

from __future__ import annotations

import numpy as np
import pytest

from rsi.detection.flaw_models import FLAW_MODELS, flaw_kernel
from rsi.errors import InputError


def test_models_have_unit_peak_and_odd_sides() -> None:
    for model in FLAW_MODELS:
        kernel = np.ones((3, 5)) * 2.0 if model == "kernel" else None
        weights = flaw_kernel(model, size=5, kernel=kernel)
        assert np.max(np.abs(weights)) == 1.0
        assert weights.shape[0] % 2 == 1 and weights.shape[1] % 2 == 1


def test_shapes_of_the_seed_models() -> None:
    assert flaw_kernel("single").shape == (1, 1)
    np.testing.assert_array_equal(flaw_kernel("uniform", size=3), np.ones((3, 3)))
    peak = flaw_kernel("peak", size=5, peak_ratio=4.0)
    assert peak[2, 2] == 1.0
    assert np.count_nonzero(peak == 0.25) == 24
    plus = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]])
    np.testing.assert_array_equal(flaw_kernel("disc", size=3), plus)
    # radius 2: the centre, its 8 neighbours (within sqrt 2) and the 4 pixels 2 px out along the axes
    disc = flaw_kernel("disc", size=5)
    assert np.count_nonzero(disc) == 13 and disc[0, 2] == 1.0 and disc[0, 1] == 0.0 and disc[1, 1] == 1.0


def test_the_erosion_test_finds_a_round_bite_that_no_square_fits() -> None:
    from rsi.detection.detect import detect

    rng = np.random.default_rng(2)
    reference = (100.0 + rng.normal(0.0, 1.0, (40, 40))).astype(np.float32)
    inspection = (reference + rng.normal(0.0, 1.0, reference.shape)).astype(np.float32)
    inspection[19:22, 20] -= 40.0  # a plus 3 px across: the smallest round bite with a centre pixel
    inspection[20, 19:22] -= 40.0
    found = {
        model: detect(
            reference, inspection, flaw_model=model, method="erosion", noise_sigma=1.4, registration=None
        )
        for model in ("uniform", "disc")
    }
    assert not found["uniform"].flaws
    (flaw,) = found["disc"].flaws
    assert (round(flaw.row), round(flaw.col)) == (20, 20)


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"flaw_model": "blob"}, "flaw_model"),
        ({"flaw_model": "uniform", "size": 4}, "size"),
        ({"flaw_model": "uniform", "size": 0}, "size"),
        ({"flaw_model": "peak", "peak_ratio": 0.5}, "peak_ratio"),
        ({"flaw_model": "kernel"}, "kernel"),
        ({"flaw_model": "kernel", "kernel": np.ones(3)}, "kernel"),
        ({"flaw_model": "kernel", "kernel": np.ones((2, 3))}, "kernel"),
        ({"flaw_model": "kernel", "kernel": np.full((3, 3), np.nan)}, "kernel"),
        ({"flaw_model": "kernel", "kernel": np.zeros((3, 3))}, "kernel"),
        ({"flaw_model": "uniform", "kernel": np.ones((3, 3))}, "kernel"),
    ],
)
def test_bad_arguments_are_named(kwargs: dict[str, object], argument: str) -> None:
    model = kwargs.pop("flaw_model")
    with pytest.raises(InputError, match=argument):
        flaw_kernel(model, **kwargs)  # type: ignore[arg-type]
