"""Seed §3.1, Figs 4-7: the proximity velocity law, commanded velocity as a function of sensed distance.

Sign convention: velocities are along the proximity sensors' axis, **positive toward the surface** (the
direction a joystick push moves the arm), so repulsion is negative. Distances are sensed distances from
the sensor face in metres.

Shape (continuous and piecewise linear; regions from near to far, seed §3.1 and Fig. 5)::

    v
    +Vp ·                       ___                      servo only (dashed in Fig. 5)
     0  ·              standoff/   \\____________ F ______  out of range beyond max: 0, flagged
   -Vjs ·             _____/
    -Vc ·        ____/   C
    -Vr ·___A___/ B
          d_min  d_c   d_hold  d_peak  d_end     d_max

    A  d < d_min          the sensor cannot see this close: keep retreating at -Vr
    B  d_min .. d_c       quick retreat, -Vr to -Vc: bounded slope and magnitude, no asymptote (a 44 Hz
                          loop near an asymptote would command huge, rapidly changing velocities)
    C  d_c .. d_hold      collision avoidance, -Vc to -Vjs: with Vc > Vjs every value is <= -Vjs, so even
                          a full joystick push (+Vjs) nets a velocity <= 0: it cannot be overridden
    D  d_hold .. d_peak   the line of C continued with C's slope (equal acceleration to the servo point),
                          crossing zero at the standoff and rising to the servo peak +Vp < Vjs, so a full
                          negative joystick command always pulls the arm away
    E  d_peak .. d_end    back to zero, for continuity
    F  d_end .. d_max     the sensor sees the surface; no command

The two functions of the seed "are identical except that the [servoing one] has positive values", so the
avoidance law is ``min(servo law, 0)``: in D it repels down to the standoff and is zero beyond. The
standoff and the peak's distance follow from matching D's slope to C's; they are derived, not set.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.constants import PROXIMITY_SAMPLE_RATE_HZ
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

REGIONS = ("A", "B", "C", "D", "E", "F")
OUT_OF_RANGE_LABEL = "-"
MODES: dict[str, Callable[[FloatArray], FloatArray]] = {
    "servo": lambda velocity: velocity,
    # seed §3.1: the avoidance function is the servoing one without its positive (dashed) part
    "avoidance": lambda velocity: np.minimum(velocity, 0.0),
}
# A discrete loop x[k+1] = x[k] + v(x[k]) dt settles on a zero of v without overshoot while
# |slope| dt < 1; half of that leaves room for the sensors' filter lag (seed §3.1: low sampling rate).
_MAX_SLOPE_TIMES_STEP = 0.5


@dataclass(frozen=True)
class ProximityLaw:
    """Breakpoints and speeds of the proximity law (seed §3.1, Fig. 5); see the module sketch.

    Parameters
    ----------
    joystick_speed_m_s : float
        ``Vjs``, the largest speed the joysticks command, > 0 m/s.
    retreat_speed_m_s : float
        ``Vr``, retreat speed in A and at the near end of B, >= ``avoidance_speed_m_s``.
    avoidance_speed_m_s : float
        ``Vc``, retreat speed at the near end of C, > ``joystick_speed_m_s`` (the non-override property).
    servo_peak_speed_m_s : float
        ``Vp``, the servo law's peak attraction, in (0, ``joystick_speed_m_s``).
    min_distance_m : float
        A|B: the sensors' minimum distance, > 0 m.
    avoidance_start_m : float
        B|C, > ``min_distance_m``.
    hold_distance_m : float
        C|D, where the law is ``-Vjs`` (a full joystick push holds the arm here), > ``avoidance_start_m``.
    servo_end_m : float
        E|F, where the servo law returns to zero; must lie beyond the derived peak distance.
    max_distance_m : float
        F|out of range: the sensors' maximum distance, > ``servo_end_m`` (seed §3: about 0.75 m).
    sample_rate_hz : float
        Rate of the loop that evaluates the law, > 0 Hz (seed §3.1: 44 Hz); bounds every slope.
    """

    joystick_speed_m_s: float = 0.05
    retreat_speed_m_s: float = 0.12
    avoidance_speed_m_s: float = 0.08
    servo_peak_speed_m_s: float = 0.03
    min_distance_m: float = 0.08
    avoidance_start_m: float = 0.12
    hold_distance_m: float = 0.20
    servo_end_m: float = 0.45
    max_distance_m: float = 0.75
    sample_rate_hz: float = PROXIMITY_SAMPLE_RATE_HZ

    def __post_init__(self) -> None:
        checks = {
            name: v.positive(getattr(self, name), name)
            for name in (
                "joystick_speed_m_s",
                "retreat_speed_m_s",
                "avoidance_speed_m_s",
                "servo_peak_speed_m_s",
                "min_distance_m",
                "avoidance_start_m",
                "hold_distance_m",
                "servo_end_m",
                "max_distance_m",
                "sample_rate_hz",
            )
        }
        v.store_checked(self, checks)
        self._check_speeds()
        self._check_breakpoints()
        self._check_slopes()

    def _check_speeds(self) -> None:
        if self.avoidance_speed_m_s <= self.joystick_speed_m_s:
            raise InputError(
                f"avoidance_speed_m_s={self.avoidance_speed_m_s!r} must exceed joystick_speed_m_s="
                f"{self.joystick_speed_m_s!r}, or a full joystick push overrides region C (seed §3.1)."
            )
        if self.retreat_speed_m_s < self.avoidance_speed_m_s:
            raise InputError(
                f"retreat_speed_m_s={self.retreat_speed_m_s!r} must be >= avoidance_speed_m_s="
                f"{self.avoidance_speed_m_s!r}: region B retreats at least as fast as C."
            )
        if self.servo_peak_speed_m_s >= self.joystick_speed_m_s:
            raise InputError(
                f"servo_peak_speed_m_s={self.servo_peak_speed_m_s!r} must be below joystick_speed_m_s="
                f"{self.joystick_speed_m_s!r} so the operator can pull the arm away (seed §3.1)."
            )

    def _check_breakpoints(self) -> None:
        order = ("min_distance_m", "avoidance_start_m", "hold_distance_m", "servo_end_m", "max_distance_m")
        for nearer, farther in itertools.pairwise(order):
            if getattr(self, farther) <= getattr(self, nearer):
                raise InputError(
                    f"{farther}={getattr(self, farther)!r} must be greater than {nearer}="
                    f"{getattr(self, nearer)!r}: breakpoints run from near to far."
                )
        if self.peak_distance_m >= self.servo_end_m:
            raise InputError(
                f"servo_end_m={self.servo_end_m!r} must be beyond the servo peak at "
                f"{self.peak_distance_m:.4f} m (set by C's slope and the speeds); move it out, or steepen C."
            )

    def _check_slopes(self) -> None:
        knots = self.knots_m
        slopes = np.abs(np.diff(knots[1]) / np.diff(knots[0]))
        limit = _MAX_SLOPE_TIMES_STEP * self.sample_rate_hz
        setters = ("avoidance_start_m", "hold_distance_m", "hold_distance_m", "servo_end_m")
        for setter, slope in zip(setters, slopes, strict=True):
            if slope > limit:
                raise InputError(
                    f"{setter}={getattr(self, setter)!r} makes a segment of slope {slope:.3g} /s, steeper "
                    f"than {limit:.3g} /s (= {_MAX_SLOPE_TIMES_STEP} x sample_rate_hz): a "
                    f"{self.sample_rate_hz:g} Hz loop would overshoot. "
                    "Spread the breakpoints or lower the speeds."
                )

    @property
    def avoidance_slope_per_s(self) -> float:
        """Slope of region C (and D), (m/s) per m."""
        return (self.avoidance_speed_m_s - self.joystick_speed_m_s) / (
            self.hold_distance_m - self.avoidance_start_m
        )

    @property
    def standoff_m(self) -> float:
        """Distance the servo law holds: its zero crossing in D."""
        return self.hold_distance_m + self.joystick_speed_m_s / self.avoidance_slope_per_s

    @property
    def peak_distance_m(self) -> float:
        """D|E: where the servo law peaks at ``servo_peak_speed_m_s``."""
        rise_m_s = self.joystick_speed_m_s + self.servo_peak_speed_m_s
        return self.hold_distance_m + rise_m_s / self.avoidance_slope_per_s

    @property
    def breakpoints_m(self) -> tuple[float, float, float, float, float, float]:
        """Region boundaries A|B, B|C, C|D, D|E, E|F, F|out of range, metres."""
        return (
            self.min_distance_m,
            self.avoidance_start_m,
            self.hold_distance_m,
            self.peak_distance_m,
            self.servo_end_m,
            self.max_distance_m,
        )

    @property
    def knots_m(self) -> tuple[FloatArray, FloatArray]:
        """(distances in m, servo-law velocities in m/s) at A|B .. E|F; the law interpolates them."""
        distances = np.array(self.breakpoints_m[:5])
        velocities = np.array(
            [
                -self.retreat_speed_m_s,
                -self.avoidance_speed_m_s,
                -self.joystick_speed_m_s,
                self.servo_peak_speed_m_s,
                0.0,
            ]
        )
        return distances, velocities


@dataclass(frozen=True)
class ProximityCommand:
    """The law's output for each sensed distance.

    Attributes
    ----------
    velocity_m_s : ndarray
        Commanded velocity along the sensor axis, m/s, positive toward the surface.
    region : ndarray of str
        ``"A"`` .. ``"F"``, or ``"-"`` where out of range.
    out_of_range : ndarray of bool
        True beyond the sensors' maximum distance (the velocity there is 0).
    """

    velocity_m_s: FloatArray
    region: NDArray[np.str_]
    out_of_range: BoolArray


def as_sensed_distances_m(distance_m: object, name: str) -> FloatArray:
    """Sensed distances as float64; ``+inf`` (no return) is allowed, NaN and negatives are not."""
    values = v.as_float_array(distance_m, name)
    if np.isnan(values).any():
        raise InputError(f"{name} contains NaN; pass distances in metres, or inf for no return.")
    if (values < 0).any():
        raise InputError(f"{name} must be >= 0 m; got minimum {values.min()!r}.")
    return values


def proximity_velocity(
    distance_m: object, law: ProximityLaw | None = None, *, mode: str = "avoidance"
) -> ProximityCommand:
    """Commanded velocity for sensed distances (seed §3.1, Fig. 5), vectorised.

    Parameters
    ----------
    distance_m : array_like
        Sensed distances in metres, >= 0; ``inf`` (no return) is out of range.
    law : ProximityLaw, optional
        Breakpoints and speeds.
    mode : {"avoidance", "servo"}
        Collision avoidance only, or distance servoing to the standoff.

    Returns
    -------
    ProximityCommand

    Examples
    --------
    >>> command = proximity_velocity([0.05, 0.3, 0.6, 1.0], mode="servo")
    >>> command.region.tolist(), command.out_of_range.tolist()
    (['A', 'D', 'F', '-'], [False, False, False, True])
    """
    settings = ProximityLaw() if law is None else v.instance_of(law, "law", ProximityLaw)
    shape = MODES[v.choice(mode, "mode", MODES)]
    distance = as_sensed_distances_m(distance_m, "distance_m")
    knots, speeds = settings.knots_m
    out_of_range = distance > settings.max_distance_m
    # np.interp holds the end values outside the knots: -Vr in A, 0 in F
    velocity = np.where(out_of_range, 0.0, shape(np.interp(distance, knots, speeds)))
    inside = np.array(REGIONS)[np.searchsorted(knots, distance, side="right")]
    region = np.where(out_of_range, OUT_OF_RANGE_LABEL, inside)
    return ProximityCommand(velocity_m_s=velocity, region=region, out_of_range=out_of_range)


__all__: list[str] = [
    "MODES",
    "REGIONS",
    "ProximityCommand",
    "ProximityLaw",
    "as_sensed_distances_m",
    "proximity_velocity",
]
