"""Retired: the names :mod:`rsi.mission.mission` still imports from here, until its split re-points them.

Transits live in :mod:`rsi.mission.transit`, the orbit's sun on the lamp in :mod:`rsi.mission.sun`. Import
from those; this module goes when ``mission.py`` does (issue 11).
"""

from __future__ import annotations

from rsi.mission.sun import SunSetting, pass_starts
from rsi.mission.tour import Tour
from rsi.mission.transit import Transit

__all__ = ["SunSetting", "Tour", "Transit", "pass_starts"]
