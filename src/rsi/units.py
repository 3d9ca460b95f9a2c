"""Unit conversions used only at the edges (CLI, web); everything inside is SI."""

from __future__ import annotations

from rsi._validate import finite_number

KELVIN_AT_0_C = 273.15


def fahrenheit_to_kelvin(temperature_f: float) -> float:
    """Degrees Fahrenheit to kelvin (seed §3 quotes the pyrometer range in degF)."""
    return (finite_number(temperature_f, "temperature_f") - 32.0) * 5.0 / 9.0 + KELVIN_AT_0_C


def kelvin_to_fahrenheit(temperature_k: float) -> float:
    """Kelvin to degrees Fahrenheit."""
    return (finite_number(temperature_k, "temperature_k") - KELVIN_AT_0_C) * 9.0 / 5.0 + 32.0


def mm_to_m(length_mm: float) -> float:
    """Millimetres to metres."""
    return finite_number(length_mm, "length_mm") / 1000.0


def m_to_mm(length_m: float) -> float:
    """Metres to millimetres."""
    return finite_number(length_m, "length_m") * 1000.0
