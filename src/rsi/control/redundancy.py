"""Seed §1 [9]: Configuration-Control-style redundancy resolution for a 7-DOF arm on a rail (pure numpy).

The seed's K1207 arm on its translating platform was "controlled by a real-time system employing
Configuration Control [9]" (Seraji 1989). Configuration control augments the end-effector task (a 6-D
twist) with *additional tasks* that use the redundancy, here the arm angle (the angle of the plane
shoulder-elbow-wrist about the shoulder-wrist line), and solves the augmented system with damped least
squares so that joint rates stay bounded near singularities. Seraji's weighted form is

    dq = argmin |J_e dq - x_e|^2 + w_c |J_c dq - x_c|^2 + lambda^2 |W^(1/2) dq|^2

which is ordinary damped least squares on the stacked, row- and column-weighted Jacobian. This module
provides the pieces as functions and the driver :func:`resolve_joint_rates`:

- :func:`damped_least_squares`, :func:`damped_pseudo_inverse`: ``J^T (J J^T + lambda^2 I)^-1`` via the SVD;
  with zero damping this is the Moore-Penrose pseudo-inverse (the inverse for a square, regular J).
- :func:`singularity_damping`: the damping grows as the smallest singular value falls below a threshold
  (Nakamura & Hanafusa 1986; Maciejewski & Klein 1988), zero elsewhere so tracking is exact away from
  singularities.
- :func:`null_space_projector`: ``I - J^+ J``; motion in it does not move the tasks.
- :func:`limit_avoidance_velocity`: a secondary joint velocity away from position limits, applied in the
  null space of the tasks (it never disturbs them).
- :func:`arm_angle_rad`, :func:`arm_angle_jacobian`: the additional task and its Jacobian.
- :func:`orientation_error`: the rotation vector taking one orientation to another (closed-loop control).

Joint position limits are met by locking a joint at its bound and re-solving with the others (the task is
kept exact while redundancy allows it), then joint-rate limits by scaling the whole joint velocity by one
factor (the direction of motion in task space is kept, only its speed drops).

Units: joint positions in rad (revolute) or m (prismatic rail); rates in rad/s or m/s; twists are
``[v (m/s), omega (rad/s)]`` in one frame (the Jacobian's).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError

FloatArray = NDArray[np.float64]
MAX_DAMPING = 1e150  # lambda^2 must stay a finite float (1e300 squared overflows)
BoolArray = NDArray[np.bool_]

# Central-difference step for the arm angle's gradient, m: the angle is smooth away from its singular sets,
# so the truncation error (~h^2) and the round-off (~eps/h) both sit near 1e-10 rad/m.
_ARM_ANGLE_STEP_M = 1e-6


def _matrix(value: object, name: str, *, rows: int | None = None, cols: int | None = None) -> FloatArray:
    if not isinstance(value, np.ndarray | list | tuple):
        raise InputError(f"{name} must be a 2-D array; got {type(value).__name__}. Try np.asarray({name}).")
    array = v.as_float_array(value, name)
    if array.ndim != 2 or array.size == 0:
        raise InputError(f"{name} must be a non-empty 2-D array (rows, joints); got shape {array.shape}.")
    if rows is not None and array.shape[0] != rows:
        raise InputError(f"{name} must have {rows} row(s); got shape {array.shape}.")
    if cols is not None and array.shape[1] != cols:
        raise InputError(f"{name} must have {cols} column(s) (one per joint); got shape {array.shape}.")
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name} contains NaN or inf; got {array!r}.")
    return array


def _vector(value: object, name: str, size: int | None = None, *, allow_inf: bool = False) -> FloatArray:
    array = v.as_float_array(value, name)
    if array.ndim == 0:
        array = array.reshape(1)
    if array.ndim != 1:
        raise InputError(f"{name} must be 1-D; got shape {array.shape}.")
    if size is not None and array.shape[0] != size:
        raise InputError(f"{name} must have {size} element(s); got shape {array.shape}.")
    bad = np.isnan(array) if allow_inf else ~np.isfinite(array)
    if np.any(bad):
        raise InputError(f"{name} must be {'not NaN' if allow_inf else 'finite'}; got {array!r}.")
    return array


# ----------------------------------------------------------------------------------------- settings


@dataclass(frozen=True)
class JointLimits:
    """Joint position and rate limits, one entry per joint (rail first, if any).

    Parameters
    ----------
    lower : ndarray of shape (n,)
        Lower position limits, rad (revolute) or m (prismatic); ``-inf`` for none.
    upper : ndarray of shape (n,)
        Upper position limits, > ``lower``; ``inf`` for none.
    max_rate : ndarray of shape (n,)
        Largest joint speed, > 0 rad/s or m/s; ``inf`` for none.
    """

    lower: FloatArray
    upper: FloatArray
    max_rate: FloatArray

    def __post_init__(self) -> None:
        lower = _vector(self.lower, "lower", allow_inf=True)
        upper = _vector(self.upper, "upper", lower.shape[0], allow_inf=True)
        max_rate = _vector(self.max_rate, "max_rate", lower.shape[0], allow_inf=True)
        if np.any(lower >= upper):
            raise InputError(f"lower must be below upper for every joint; got lower={lower}, upper={upper}.")
        if np.any(max_rate <= 0):
            raise InputError(f"max_rate must be > 0 for every joint; got {max_rate}.")
        for name, array in (("lower", lower), ("upper", upper), ("max_rate", max_rate)):
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def n_joints(self) -> int:
        """Number of joints."""
        return int(self.lower.shape[0])


@dataclass(frozen=True)
class RedundancySettings:
    """Knobs of :func:`resolve_joint_rates`.

    Parameters
    ----------
    singular_threshold : float
        ``epsilon``: damping starts when the smallest singular value of the weighted, augmented Jacobian
        falls below it, > 0 (m/rad for position rows).
    max_damping : float
        ``lambda_max``, the damping at a singularity, > 0. The joint speed is then at most
        ``|task velocity| / (2 lambda_max)`` (weighted norm).
    additional_task_weight : float
        ``w_c``, weight of the additional task's row relative to the end-effector rows, > 0.
    joint_weights : ndarray of shape (n,) or None
        ``W``, cost of each joint's speed in the minimum-norm solution, > 0 (None: all 1). A larger weight
        makes a joint (e.g. the heavy rail) move less.
    limit_margin : float
        Fraction of each joint's range, at each end, in which the limit-avoidance term acts, in (0, 0.5].
    limit_gain_per_s : float
        Gain of the limit-avoidance term, >= 0 1/s (0 switches it off).
    """

    singular_threshold: float = 0.04
    max_damping: float = 0.04
    additional_task_weight: float = 1.0
    joint_weights: FloatArray | None = None
    limit_margin: float = 0.1
    limit_gain_per_s: float = 1.0

    def __post_init__(self) -> None:
        v.in_range(self.singular_threshold, "singular_threshold", low=0.0, low_inclusive=False)
        v.in_range(self.max_damping, "max_damping", low=0.0, high=MAX_DAMPING, low_inclusive=False)
        v.in_range(self.additional_task_weight, "additional_task_weight", low=0.0, low_inclusive=False)
        v.in_range(self.limit_margin, "limit_margin", low=0.0, high=0.5, low_inclusive=False)
        v.in_range(self.limit_gain_per_s, "limit_gain_per_s", low=0.0)
        if self.joint_weights is not None:
            weights = _vector(self.joint_weights, "joint_weights")
            if np.any(weights <= 0):
                raise InputError(f"joint_weights must all be > 0; got {weights}.")
            weights.setflags(write=False)
            object.__setattr__(self, "joint_weights", weights)


@dataclass(frozen=True)
class RateResolution:
    """Joint rates resolved from task velocities.

    Attributes
    ----------
    joint_velocity : ndarray of shape (n,)
        Joint rates to command, rad/s or m/s; within the rate limits, and ``q + dq dt`` within the position
        limits.
    rate_scale : float
        Factor in (0, 1] applied to meet the rate limits (1: none needed).
    damping : float
        The damping ``lambda`` used (0 away from singularities).
    min_singular_value : float
        Smallest singular value of the weighted, augmented Jacobian.
    locked : ndarray of shape (n,), bool
        Joints held at a position limit this step.
    """

    joint_velocity: FloatArray
    rate_scale: float
    damping: float
    min_singular_value: float
    locked: BoolArray = field(default_factory=lambda: np.zeros(0, dtype=bool))


# ---------------------------------------------------------------------------------------- functions


def singularity_damping(min_singular_value: float, *, threshold: float, max_damping: float) -> float:
    """Damping that grows as the smallest singular value falls (Nakamura & Hanafusa 1986).

    ``lambda^2 = (1 - (sigma / epsilon)^2) lambda_max^2`` for ``sigma < epsilon``, else 0: zero damping, and
    so exact tracking, away from singularities; ``lambda_max`` at one.

    Parameters
    ----------
    min_singular_value : float
        ``sigma``, >= 0.
    threshold : float
        ``epsilon``, > 0.
    max_damping : float
        ``lambda_max``, >= 0.

    Returns
    -------
    float
        ``lambda``.
    """
    sigma = v.in_range(min_singular_value, "min_singular_value", low=0.0)
    epsilon = v.in_range(threshold, "threshold", low=0.0, low_inclusive=False)
    lam_max = v.in_range(max_damping, "max_damping", low=0.0, high=MAX_DAMPING)
    if sigma >= epsilon:
        return 0.0
    return float(lam_max * np.sqrt(1.0 - (sigma / epsilon) ** 2))


def _damping(damping: object) -> float:
    return v.in_range(damping, "damping", low=0.0, high=MAX_DAMPING)


def _dls_from_svd(
    u: FloatArray, s: FloatArray, vt: FloatArray, rhs: FloatArray, damping: float
) -> FloatArray:
    # sigma / (sigma^2 + lambda^2): the pseudo-inverse's 1/sigma for sigma >> lambda, never above 1/(2 lambda)
    denominator = s**2 + damping**2
    gain = np.divide(s, denominator, out=np.zeros_like(s), where=denominator > 0)
    projected = u.T @ rhs
    weighted = gain * projected if projected.ndim == 1 else gain[:, None] * projected
    result: FloatArray = vt.T @ weighted
    return result


def damped_pseudo_inverse(jacobian: object, *, damping: float = 0.0) -> FloatArray:
    """``J^T (J J^T + lambda^2 I)^-1``, computed from the SVD.

    Parameters
    ----------
    jacobian : ndarray of shape (m, n)
    damping : float
        ``lambda`` >= 0. With 0 this is the Moore-Penrose pseudo-inverse (exactly zero gain on zero
        singular values), and ``inv(J)`` for a square regular ``J``.

    Returns
    -------
    ndarray of shape (n, m)
    """
    matrix = _matrix(jacobian, "jacobian")
    lam = _damping(damping)
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    return _dls_from_svd(u, s, vt, np.eye(matrix.shape[0]), lam)


def damped_least_squares(jacobian: object, task_velocity: object, *, damping: float = 0.0) -> FloatArray:
    """Joint velocity ``J^T (J J^T + lambda^2 I)^-1 x_dot`` (minimum norm, damped).

    Parameters
    ----------
    jacobian : ndarray of shape (m, n)
    task_velocity : ndarray of shape (m,)
    damping : float
        ``lambda`` >= 0; see :func:`damped_pseudo_inverse`.

    Returns
    -------
    ndarray of shape (n,)
    """
    matrix = _matrix(jacobian, "jacobian")
    rhs = _vector(task_velocity, "task_velocity", matrix.shape[0])
    lam = _damping(damping)
    u, s, vt = np.linalg.svd(matrix, full_matrices=False)
    return _dls_from_svd(u, s, vt, rhs, lam)


def null_space_projector(jacobian: object, *, rank_tolerance: float = 1e-10) -> FloatArray:
    """Orthogonal projector ``I - J^+ J`` onto the null space of ``J``.

    Parameters
    ----------
    jacobian : ndarray of shape (m, n)
    rank_tolerance : float
        Singular values below ``rank_tolerance * sigma_max`` count as zero, > 0.

    Returns
    -------
    ndarray of shape (n, n)
        ``J @ P`` is zero to round-off: a joint velocity ``P z`` does not move the task.
    """
    matrix = _matrix(jacobian, "jacobian")
    tol = v.in_range(rank_tolerance, "rank_tolerance", low=0.0, low_inclusive=False)
    _, s, vt = np.linalg.svd(matrix, full_matrices=True)
    rank = int(np.count_nonzero(s > tol * max(float(s[0]), 1e-300))) if s.size else 0
    rows = vt[rank:]
    projector: FloatArray = rows.T @ rows
    return projector


def limit_avoidance_velocity(
    joint_positions: object, limits: JointLimits, *, margin: float = 0.1, gain_per_s: float = 1.0
) -> FloatArray:
    """Secondary joint velocity that pushes joints out of the zone near their position limits.

    Zero in the middle of each range; inside the last ``margin`` fraction at either end it grows linearly
    to ``gain_per_s * margin * range`` at the limit, pointing inward. Joints without finite limits get 0.

    Parameters
    ----------
    joint_positions : ndarray of shape (n,)
        rad or m.
    limits : JointLimits
    margin : float
        In (0, 0.5].
    gain_per_s : float
        >= 0 1/s.

    Returns
    -------
    ndarray of shape (n,)
        rad/s or m/s.
    """
    q = _vector(joint_positions, "joint_positions", v.instance_of(limits, "limits", JointLimits).n_joints)
    frac = v.in_range(margin, "margin", low=0.0, high=0.5, low_inclusive=False)
    gain = v.in_range(gain_per_s, "gain_per_s", low=0.0)
    finite = np.isfinite(limits.lower) & np.isfinite(limits.upper)
    span = np.where(finite, limits.upper - limits.lower, 1.0)
    zone = frac * span
    low_edge = np.where(finite, limits.lower + zone, -np.inf)
    high_edge = np.where(finite, limits.upper - zone, np.inf)
    push = np.clip(low_edge - q, 0.0, None) - np.clip(q - high_edge, 0.0, None)
    result: FloatArray = np.where(finite, gain * push, 0.0)
    return result


def orientation_error(rotation_desired: object, rotation_actual: object) -> FloatArray:
    """Rotation vector (axis times angle, rad) that turns ``rotation_actual`` into ``rotation_desired``.

    Both are 3x3 rotation matrices in the same frame; the result is in that frame, so ``omega = k e`` is a
    proportional orientation servo.

    Parameters
    ----------
    rotation_desired, rotation_actual : ndarray of shape (3, 3)

    Returns
    -------
    ndarray of shape (3,)
    """
    desired = _matrix(rotation_desired, "rotation_desired", rows=3, cols=3)
    actual = _matrix(rotation_actual, "rotation_actual", rows=3, cols=3)
    delta = desired @ actual.T
    cos_angle = float(np.clip((np.trace(delta) - 1.0) / 2.0, -1.0, 1.0))
    axis_sin = 0.5 * np.array(
        [delta[2, 1] - delta[1, 2], delta[0, 2] - delta[2, 0], delta[1, 0] - delta[0, 1]]
    )
    sin_angle = float(np.linalg.norm(axis_sin))
    angle = float(np.arctan2(sin_angle, cos_angle))
    if sin_angle < 1e-12:
        if cos_angle > 0:
            return axis_sin  # no rotation (small-angle limit: the skew part is the rotation vector)
        # a half turn: the axis is the eigenvector of the symmetric part
        w, vecs = np.linalg.eigh(0.5 * (delta + delta.T))
        axis: FloatArray = vecs[:, int(np.argmax(w))]
        return np.pi * axis
    result: FloatArray = axis_sin * (angle / sin_angle)
    return result


def arm_angle_rad(shoulder_m: object, elbow_m: object, wrist_m: object, *, reference: object) -> float:
    """The arm angle: rotation of the plane shoulder-elbow-wrist about the shoulder-wrist line.

    Measured from the plane through the shoulder-wrist line and ``reference`` (e.g. world up), right-handed
    about the shoulder-to-wrist direction, in (-pi, pi]. Undefined (an algorithmic singularity) when the
    elbow lies on the shoulder-wrist line (elbow straight) or the line is parallel to ``reference``.

    Parameters
    ----------
    shoulder_m, elbow_m, wrist_m : ndarray of shape (3,)
        Centres of the shoulder, elbow and wrist, m.
    reference : ndarray of shape (3,)
        The direction that defines zero, any length > 0.

    Returns
    -------
    float
        rad.
    """
    return _arm_angle(*_arm_points(shoulder_m, elbow_m, wrist_m, reference))


def _arm_points(
    shoulder_m: object, elbow_m: object, wrist_m: object, reference: object
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The three points and the reference as checked vectors, the arm angle defined by them."""
    s = _vector(shoulder_m, "shoulder_m", 3)
    e = _vector(elbow_m, "elbow_m", 3)
    w = _vector(wrist_m, "wrist_m", 3)
    r = _vector(reference, "reference", 3)
    if not _dot3(r, r) > 0:
        raise InputError(f"reference must be a non-zero direction; got {r}.")
    if not _dot3(w - s, w - s) > 0:
        raise InputError("wrist_m must differ from shoulder_m (the shoulder-wrist line is undefined).")
    return s, e, w, r


def _arm_angle(s: FloatArray, e: FloatArray, w: FloatArray, r: FloatArray) -> float:
    return float(_arm_angles(s[None], e[None], w[None], r)[0])


def _arm_angles(s: FloatArray, e: FloatArray, w: FloatArray, r: FloatArray) -> FloatArray:
    """The arm angle of each row of points (K, 3). Written out per component, not with np.dot and
    np.cross: the transits evaluate it ~20 times per 44 Hz step, where np.cross's axis handling was 40 % of
    a truss-b mission (profiled); the arithmetic is the same, so are the results, to the bit (checked on
    20,000 random points)."""
    d = w - s
    axis = d / np.sqrt(_dot3(d, d))[:, None]
    from_shoulder = e - s
    elbow_perp = from_shoulder - _dot3(from_shoulder, axis)[:, None] * axis
    ref_perp = r - _dot3(r, axis)[:, None] * axis
    angles: FloatArray = np.arctan2(_dot3(axis, _cross3(ref_perp, elbow_perp)), _dot3(ref_perp, elbow_perp))
    return angles


def _dot3(a: FloatArray, b: FloatArray) -> FloatArray:
    result: FloatArray = a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]
    return result


def _cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.stack(
        [
            a[..., 1] * b[..., 2] - a[..., 2] * b[..., 1],
            a[..., 2] * b[..., 0] - a[..., 0] * b[..., 2],
            a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0],
        ],
        axis=-1,
    )


def arm_angle_jacobian(
    shoulder_m: object,
    elbow_m: object,
    wrist_m: object,
    *,
    shoulder_jacobian: object,
    elbow_jacobian: object,
    wrist_jacobian: object,
    reference: object,
) -> FloatArray:
    """Jacobian row of the arm angle, ``d psi / dq`` (rad per rad or per m).

    Chain rule through the three points: ``J_psi = g_S J_S + g_E J_E + g_W J_W``, with the gradients
    ``g`` of :func:`arm_angle_rad` taken by central differences in the 9 point coordinates (smooth away from
    the singular sets; error ~1e-9) and the points' positional Jacobians given.

    Parameters
    ----------
    shoulder_m, elbow_m, wrist_m : ndarray of shape (3,)
        m.
    shoulder_jacobian, elbow_jacobian, wrist_jacobian : ndarray of shape (3, n)
        Positional Jacobians of the three points.
    reference : ndarray of shape (3,)

    Returns
    -------
    ndarray of shape (n,)
    """
    *points, r = _arm_points(shoulder_m, elbow_m, wrist_m, reference)
    jac_s = _matrix(shoulder_jacobian, "shoulder_jacobian", rows=3)
    n = jac_s.shape[1]
    jacobians = [
        jac_s,
        _matrix(elbow_jacobian, "elbow_jacobian", rows=3, cols=n),
        _matrix(wrist_jacobian, "wrist_jacobian", rows=3, cols=n),
    ]
    h = _ARM_ANGLE_STEP_M
    # the 9 coordinates each stepped by +h (rows 0-8) and -h (rows 9-17), all 18 angles in one call
    stacked = np.broadcast_to(np.concatenate(points), (18, 9)).copy()
    coordinate = np.arange(9)
    stacked[coordinate, coordinate] += h
    stacked[coordinate + 9, coordinate] -= h
    angles = _arm_angles(stacked[:, 0:3], stacked[:, 3:6], stacked[:, 6:9], r)
    # the angle wraps at +-pi: take the wrapped difference
    gradient = np.angle(np.exp(1j * (angles[:9] - angles[9:]))) / (2 * h)
    row = np.zeros(n)
    for which in range(3):
        row += gradient[3 * which : 3 * which + 3] @ jacobians[which]
    return row


def resolve_joint_rates(
    task_jacobian: object,
    task_velocity: object,
    *,
    joint_positions: object,
    limits: JointLimits,
    dt_s: float,
    additional_jacobian: object | None = None,
    additional_velocity: object | None = None,
    settings: RedundancySettings | None = None,
) -> RateResolution:
    """Configuration control: joint rates for an end-effector task plus an additional task.

    1. Stack ``[J_e; sqrt(w_c) J_c]`` and ``[x_e; sqrt(w_c) x_c]`` (Seraji's weighted augmented Jacobian) and
       scale columns by ``W^(-1/2)``.
    2. Damped least squares, with the damping from :func:`singularity_damping` on the smallest singular
       value; plus the limit-avoidance term projected into the null space of the stack.
    3. A joint whose rate would carry it past a position limit within ``dt_s`` is locked at the rate that
       reaches the limit, and the rest re-solve the remaining task (repeated until none would cross).
    4. If any rate exceeds its limit, the whole vector is scaled by one factor (task direction kept).

    Parameters
    ----------
    task_jacobian : ndarray of shape (m, n)
        End-effector Jacobian (m = 6 for a twist, 3 for position only).
    task_velocity : ndarray of shape (m,)
        Desired task velocity (m/s, rad/s).
    joint_positions : ndarray of shape (n,)
        Current joint positions, within ``limits``.
    limits : JointLimits
    dt_s : float
        Control period, > 0 s (positions are checked one period ahead).
    additional_jacobian : ndarray of shape (k, n) or (n,), optional
        Additional task Jacobian (e.g. the arm angle's row).
    additional_velocity : ndarray of shape (k,) or float, optional
        Desired additional task rate; required with ``additional_jacobian``.
    settings : RedundancySettings, optional

    Returns
    -------
    RateResolution
    """
    conf = settings if settings is not None else RedundancySettings()
    conf = v.instance_of(conf, "settings", RedundancySettings)
    limits = v.instance_of(limits, "limits", JointLimits)
    jac = _matrix(task_jacobian, "task_jacobian")
    n = jac.shape[1]
    xdot = _vector(task_velocity, "task_velocity", jac.shape[0])
    if limits.n_joints != n:
        raise InputError(f"limits has {limits.n_joints} joints but task_jacobian has {n} columns.")
    q = _vector(joint_positions, "joint_positions", n)
    if np.any(q < limits.lower - 1e-9) or np.any(q > limits.upper + 1e-9):
        raise InputError(
            f"joint_positions must lie within the limits; got {q} for lower={limits.lower}, "
            f"upper={limits.upper}. Clip them first."
        )
    dt = v.in_range(dt_s, "dt_s", low=0.0, low_inclusive=False)
    if (additional_jacobian is None) != (additional_velocity is None):
        raise InputError("additional_jacobian and additional_velocity must be given together (or neither).")
    if additional_jacobian is not None:
        extra = np.atleast_2d(np.asarray(additional_jacobian, dtype=np.float64))
        extra = _matrix(extra, "additional_jacobian", cols=n)
        extra_rate = _vector(additional_velocity, "additional_velocity", extra.shape[0])
        root_w = np.sqrt(conf.additional_task_weight)
        jac = np.vstack([jac, root_w * extra])
        xdot = np.concatenate([xdot, root_w * extra_rate])
    weights = conf.joint_weights if conf.joint_weights is not None else np.ones(n)
    if weights.shape[0] != n:
        raise InputError(f"settings.joint_weights must have {n} entries; got {weights.shape[0]}.")
    column_scale = 1.0 / np.sqrt(weights)
    secondary = limit_avoidance_velocity(
        q, limits, margin=conf.limit_margin, gain_per_s=conf.limit_gain_per_s
    )
    # feasible rates one period ahead; q within limits makes 0 always feasible
    low_pos = np.minimum((limits.lower - q) / dt, 0.0)
    high_pos = np.maximum((limits.upper - q) / dt, 0.0)

    locked = np.zeros(n, dtype=bool)
    dq = np.zeros(n)
    damping = 0.0
    sigma_min = 0.0
    for _ in range(n + 1):
        free = ~locked
        dq_free, damping, sigma_min = _solve_free(
            jac[:, free] * column_scale[free],
            xdot - jac[:, locked] @ dq[locked],
            secondary[free] / column_scale[free],
            conf,
        )
        dq[free] = dq_free * column_scale[free]
        over = np.maximum(dq - high_pos, low_pos - dq)
        over[locked] = -np.inf
        worst = int(np.argmax(over))
        if over[worst] <= 1e-12 or np.all(locked | (np.arange(n) == worst)):
            break
        locked[worst] = True
        dq[worst] = np.clip(dq[worst], low_pos[worst], high_pos[worst])
    dq = np.clip(dq, low_pos, high_pos)
    ratio = np.divide(np.abs(dq), limits.max_rate)
    peak = float(np.max(ratio))
    scale = 1.0 / peak if peak > 1.0 else 1.0
    joint_velocity = dq * scale
    return RateResolution(
        joint_velocity=joint_velocity,
        rate_scale=scale,
        damping=damping,
        min_singular_value=sigma_min,
        locked=locked,
    )


def _solve_free(
    jac_scaled: FloatArray, rhs: FloatArray, secondary_scaled: FloatArray, conf: RedundancySettings
) -> tuple[FloatArray, float, float]:
    if jac_scaled.shape[1] == 0:
        return np.zeros(0), 0.0, 0.0
    u, s, vt = np.linalg.svd(jac_scaled, full_matrices=True)
    rows = min(jac_scaled.shape)
    # sigma_min of the task: 0 when there are fewer joints than task rows (the task cannot be met)
    sigma_min = float(s[-1]) if jac_scaled.shape[1] >= jac_scaled.shape[0] else 0.0
    damping = singularity_damping(sigma_min, threshold=conf.singular_threshold, max_damping=conf.max_damping)
    primary = _dls_from_svd(u[:, :rows], s[:rows], vt[:rows], rhs, damping)
    rank = int(np.count_nonzero(s > 1e-10 * max(float(s[0]) if s.size else 0.0, 1e-300)))
    null_rows = vt[rank:]
    dq: FloatArray = primary + null_rows.T @ (null_rows @ secondary_scaled)
    return dq, damping, sigma_min
