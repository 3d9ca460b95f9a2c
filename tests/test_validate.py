"""The shared input checks: each rejection names the argument and the fix."""

from __future__ import annotations

import numpy as np
import pytest

from rsi import _validate as v
from rsi.errors import InputError
from rsi.units import fahrenheit_to_kelvin, kelvin_to_fahrenheit, m_to_mm, mm_to_m


def test_as_image_keeps_float_dtypes_without_copy() -> None:
    for dtype in (np.float32, np.float64):
        image = np.zeros((3, 4), dtype=dtype)
        assert v.as_image(image, "image") is image


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16, np.int32, np.bool_])
def test_as_image_turns_integers_and_bool_into_float64(dtype: type) -> None:
    assert v.as_image(np.ones((2, 2), dtype=dtype), "image").dtype == np.float64


@pytest.mark.parametrize(
    ("image", "fragment"),
    [
        ([[1.0, 2.0]], "numpy array"),
        (np.zeros((2, 2, 3)), "2-D"),
        (np.zeros((0, 5)), "at least 2x2"),
        (np.zeros((1, 1)), "at least 2x2"),
        (np.zeros((2, 2), dtype=np.complex64), "dtype=complex64"),
        (np.zeros((2, 2), dtype=np.float16), "dtype=float16"),
        (np.array([[1.0, np.nan], [0.0, 0.0]]), "NaN or inf"),
        (np.array([[1.0, np.inf], [0.0, 0.0]]), "NaN or inf"),
    ],
)
def test_as_image_rejects_bad_images_naming_the_argument(image: object, fragment: str) -> None:
    with pytest.raises(InputError, match="my_image") as caught:
        v.as_image(image, "my_image")
    assert fragment in str(caught.value)


def test_as_image_allows_nan_when_asked() -> None:
    assert np.isnan(v.as_image(np.array([[np.nan, 1.0], [1.0, 1.0]]), "image", allow_nan=True)).any()


def test_as_mask_converts_and_rejects() -> None:
    assert v.as_mask(np.ones((2, 2), dtype=np.uint8), "mask", (2, 2)).dtype == np.bool_
    with pytest.raises(InputError, match=r"mask must have shape \(2, 2\)"):
        v.as_mask(np.ones((3, 2), dtype=bool), "mask", (2, 2))
    with pytest.raises(InputError, match="mask must be a numpy bool array"):
        v.as_mask([[True]], "mask", (1, 1))
    with pytest.raises(InputError, match="mask has dtype"):
        v.as_mask(np.array([["a", "b"]]), "mask", (1, 2))


def test_same_shape_names_both_arguments() -> None:
    with pytest.raises(InputError, match="reference and inspection must have the same shape"):
        v.same_shape(np.zeros((2, 2)), np.zeros((2, 3)), ("reference", "inspection"))


def test_numbers_and_ranges() -> None:
    assert v.in_range(0.5, "p", low=0, high=1) == 0.5
    with pytest.raises(InputError, match=r"p must be in \(0, 1\); got 0"):
        v.in_range(0, "p", low=0, high=1, low_inclusive=False, high_inclusive=False)
    with pytest.raises(InputError, match="p must be a number"):
        v.in_range("x", "p", low=0)
    with pytest.raises(InputError, match="p must be a number"):
        v.finite_number(True, "p")
    with pytest.raises(InputError, match="p must be finite"):
        v.finite_number(float("nan"), "p")


def test_positive_int() -> None:
    assert v.positive_int(3, "size") == 3
    for bad in (0, -1, 2.5, True):
        with pytest.raises(InputError, match="size must be an integer >= 1"):
            v.positive_int(bad, "size")


def test_choice_lists_the_options() -> None:
    assert v.choice("a", "mode", ("a", "b")) == "a"
    with pytest.raises(InputError, match=r"mode='c' is not known\. Choose one of 'a', 'b'"):
        v.choice("c", "mode", ("a", "b"))


def test_as_rng_is_deterministic_by_seed() -> None:
    assert v.as_rng(7).random() == v.as_rng(7).random()
    generator = np.random.default_rng(1)
    assert v.as_rng(generator) is generator
    with pytest.raises(InputError, match="rng must be"):
        v.as_rng("seed")  # type: ignore[arg-type]


def test_input_error_is_a_value_error() -> None:
    assert issubclass(InputError, ValueError)


def test_unit_conversions_round_trip_and_hit_reference_points() -> None:
    assert fahrenheit_to_kelvin(32.0) == pytest.approx(273.15)
    assert fahrenheit_to_kelvin(212.0) == pytest.approx(373.15)
    # seed §3: the pyrometer covers 0-1000 degF
    assert kelvin_to_fahrenheit(fahrenheit_to_kelvin(1000.0)) == pytest.approx(1000.0)
    assert mm_to_m(m_to_mm(0.75)) == pytest.approx(0.75)


def test_positive_rejects_zero_and_negative() -> None:
    assert v.positive(0.5, "rate_hz") == 0.5
    for bad in (0.0, -1.0):
        with pytest.raises(InputError, match=r"rate_hz must be in \(0.0, inf\]"):
            v.positive(bad, "rate_hz")


def test_store_checked_writes_onto_a_frozen_dataclass() -> None:
    from dataclasses import FrozenInstanceError, dataclass

    @dataclass(frozen=True)
    class Settings:
        rate_hz: float

        def __post_init__(self) -> None:
            v.store_checked(self, {"rate_hz": v.positive(self.rate_hz, "rate_hz")})

    assert isinstance(Settings(rate_hz=np.int64(44)).rate_hz, float)  # type: ignore[arg-type]
    with pytest.raises(FrozenInstanceError):
        Settings(rate_hz=44.0).rate_hz = 1.0  # type: ignore[misc]
