"""A plan from the CAD model (issue 15): vista points that cover the inspectable surface, ordered for a short
tour.

:func:`generate_plan` works on any mock-up through its :class:`rsi.sim.mockup.Mockup` (its parts,
candidates and door), never a name or coordinate of one layout:

1. **candidates**: from targets on a grid over every inspectable surface (:mod:`rsi.mission.coverage`;
   ``TARGET_SPACING_M``) and at every site, views along the surface's normal and tilted by
   ``TILTS_DEG`` around it, at standoffs whose image centre meets the resolution (``STANDOFF_FRACTIONS``
   of the farthest), the image's up along either of the surface's own axes; each with the door closed,
   and opened too when one of its rays met the door (opening it can show the pocket behind it);
2. what each candidate covers, ray-cast on the CAD (:class:`rsi.mission.coverage.Sight`);
3. **greedy set cover** by area until ``target`` of the coverable area is seen and every coverable sample
   of a site's disc (``SITE_KINDS``: one anomaly on a few cm^2) too, a view the arm cannot
   reach counted at ``UNREACHABLE_WEIGHT`` of its gain (reachable views are preferred, an unreachable one
   is taken only where it is worth it, and flagged); then every point whose removal keeps the goal is
   dropped;
4. **reach**: each point's viewing pose checked on the arm on its rail (geometry of the chain, then a
   closed-loop IK from the home pose with the door at the point's opening and the arm's clearance from the
   mock-up): points that fail are flagged, kept (the mission takes them with the free camera, as the hand
   plan's panel views);
5. **tour**: nearest neighbour then 2-opt on the transfer time between staging poses (the rail's 0.25 m/s
   and the wrist's 0.5 rad/s of :mod:`rsi.mission.transit`), a door change costing ``DOOR_CHANGE_S`` so the
   door-open points come together.

Deterministic: no random draw anywhere. See docs/mission.md, "Plan from the CAD model".
"""

from __future__ import annotations

import itertools
import math
import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.coverage import Coverage, CoverageRules, Sight, coverage, inspectable_items
from rsi.mission.plan_point import PlanPoint
from rsi.mission.settings import MissionSettings
from rsi.sim.anomalies import CylinderPatch, Patch, Site
from rsi.sim.arm import DEFAULT_JAW_OPENING_M, JAW_MAX_OPENING_M
from rsi.sim.mockup import Mockup, Vista

if TYPE_CHECKING:
    from rsi.sim.anomalies import Surface
    from rsi.sim.world import World

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]

TARGET_SPACING_M = 0.1  # about half the short side of a frame at the 0.3 m standoff of 0.5 mm pixels
TILTS_DEG = (0.0, 15.0, 30.0)  # seed §2.1 views are near-normal; 30 deg still leaves 15 deg of incidence
AZIMUTHS = 8  # tilt directions around the normal
STANDOFF_FRACTIONS = (0.9, 0.75)  # of the farthest standoff at the image centre: the corners need less
UNREACHABLE_WEIGHT = 0.7
DOOR_CHANGE_S = 30.0  # the door swung and the exposure settled again: more than any transfer
IK_PERIOD_S = 1.0 / 44.0  # the proximity loop's period (seed §3.1)
IK_STEPS = 300
IK_SPEED_M_S, IK_TURN_RAD_S = 1.0, 2.0  # a solver's steps, not a transit's: four times the rail's limits
IK_GAIN_PER_S = 8.0
IK_TOLERANCE_M = 2e-3
IK_TOLERANCE_RAD = 5e-3
MIN_CLEARANCE_M = 0.005  # the arm may not touch the mock-up at the pose
# The jaws half open (the mission's default) and closed or wide open: at the frame's right-hand middle rows,
# its bottom or its top corner (rsi.sim.world.World.own_body_footprint)
JAW_OPENINGS_M = (DEFAULT_JAW_OPENING_M, 0.0, JAW_MAX_OPENING_M)
SITE_KINDS = ("screw", "peltier", "leak")  # each sample of these a plan must see (greedy_cover's `must`)


@dataclass(frozen=True)
class Candidate:
    """A candidate view: where the camera is, the door's opening, what it covers, whether the arm gets
    there (geometry of the chain), and the opening of the ISEE's jaws, which hide part of its frame."""

    vista: Vista
    door_angle_rad: float
    seen: NDArray[np.intp]
    reachable: bool
    surface: str
    jaw_opening_m: float = DEFAULT_JAW_OPENING_M


@dataclass(frozen=True, eq=False)
class CadPlan:
    """A plan generated from the CAD model (:func:`generate_plan`).

    Attributes
    ----------
    points : tuple of PlanPoint
        In visiting order; each names its vista (``vistas``) and the door's opening.
    vistas : tuple of Vista
        One per point, same order: add them to a world with :func:`add_plan_vistas`.
    targets : tuple of str
        The inspectable surface each point was aimed at.
    unreachable : tuple of str
        Points the arm on its rail cannot take (flagged; the free camera takes them).
    coverage : Coverage
        What the plan covers, measured from the CAD.
    coverable : float
        Fraction of the inspectable area any candidate covers (the most a plan from these candidates can).
    tour_m, tour_s : float
        Length of the staging-to-staging path from the arm's home, and its transfer time (the rail's and
        wrist's rate limits; retract and approach, the same for every point, not counted).
    candidates : int
        How many candidate views were weighed.
    generation_s : float
        Wall time of the generation.
    """

    points: tuple[PlanPoint, ...]
    vistas: tuple[Vista, ...]
    targets: tuple[str, ...]
    unreachable: tuple[str, ...]
    coverage: Coverage
    coverable: float
    tour_m: float
    tour_s: float
    candidates: int
    generation_s: float


# --------------------------------------------------------------------------------------- candidates


def _steps(half: float, spacing: float) -> FloatArray:
    """Offsets from a surface's middle, `spacing` apart, within +-`half`: the middle always one of them."""
    count = math.floor(half / spacing + 1e-9)
    steps: FloatArray = np.arange(-count, count + 1, dtype=np.float64) * spacing
    return steps


def _frames(item: Surface | Site) -> list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    """Targets on `item`: (point, normal, first axis, second axis), its middle and a grid
    ``TARGET_SPACING_M`` apart."""
    if isinstance(item, Site):
        normal = np.asarray(item.normal)
        return [(np.asarray(item.position_m), normal, *_site_axes(normal))]
    if isinstance(item, Patch):
        u_axis, v_axis, normal = (np.asarray(a) for a in (item.u_axis, item.v_axis, item.normal))
        us, vs = (_steps(half, TARGET_SPACING_M) for half in item.half_extent_m)
        centre = np.asarray(item.centre_m)
        return [(centre + a * u_axis + b * v_axis, normal, u_axis, v_axis) for a in us for b in vs]
    return _cylinder_frames(item)


def _cylinder_frames(item: CylinderPatch) -> list[tuple[FloatArray, FloatArray, FloatArray, FloatArray]]:
    axis, front = np.asarray(item.axis), np.asarray(item.front)
    side = np.cross(axis, front)
    frames = []
    for angle in _steps(item.half_angle_rad, TARGET_SPACING_M / item.radius_m):
        normal = math.cos(angle) * front + math.sin(angle) * side
        for along in _steps(item.half_length_m, TARGET_SPACING_M):
            point = np.asarray(item.centre_m) + along * axis + item.radius_m * normal
            frames.append((point, normal, axis, np.cross(normal, axis)))
    return frames


def _site_axes(normal: FloatArray) -> tuple[FloatArray, FloatArray]:
    """A site's axes: world up across its normal where it has one (an image upright), else world x."""
    for helper in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0])):
        first = helper - (helper @ normal) * normal
        if np.linalg.norm(first) > 0.1:
            first /= np.linalg.norm(first)
            return first, np.cross(normal, first)
    raise AssertionError("unreachable: x and z cannot both be parallel to a unit normal")


def _directions(normal: FloatArray, first: FloatArray, second: FloatArray) -> list[tuple[FloatArray, float]]:
    """Viewing directions (from the target to the camera) and their tilt from the normal."""
    result = [(normal, 0.0)]
    for tilt in TILTS_DEG[1:]:
        t = math.radians(tilt)
        for k in range(AZIMUTHS):
            a = 2 * math.pi * k / AZIMUTHS
            across = math.cos(a) * first + math.sin(a) * second
            result.append((math.cos(t) * normal + math.sin(t) * across, t))
    return result


def candidate_vistas(mockup: Mockup, rules: CoverageRules) -> list[tuple[Vista, str]]:
    """Every candidate vista of `mockup` (step 1 of the module notes) with the surface it aims at."""
    from rsi.sim.mockup import vista

    v.instance_of(mockup, "mockup", Mockup, none_allowed=False)
    v.instance_of(rules, "rules", CoverageRules, none_allowed=False)
    out: list[tuple[Vista, str]] = []
    for _, item in inspectable_items(mockup):
        for target, normal, first, second in _frames(item):
            for direction, tilt in _directions(normal, first, second):
                for fraction in STANDOFF_FRACTIONS:
                    standoff = fraction * rules.nominal_standoff_m * math.cos(tilt)
                    for up in (first, second):
                        if abs(float(up @ direction)) > 0.95:
                            continue
                        name = f"cand_{len(out)}"
                        point = vista(name, tuple(target), tuple(direction), tuple(up), standoff)
                        out.append((point, item.name))
    return out


def weigh_candidates(
    mockup: Mockup, sight: Sight, door_open_rad: float, arm_world: World | None
) -> list[Candidate]:
    """Step 2: what every candidate covers, door closed and (where its rays met the door) open; whether
    the arm on its rail gets there (geometry of the chain; every candidate reachable without `arm_world`).

    Where the arm reaches, its ISEE takes the frame and the jaws hide part of it (seed §3.1): the view is
    weighed at each of :data:`JAW_OPENINGS_M`, which move the jaws from the frame's bottom to its top
    right, and the cover picks the opening that leaves the most in sight. The free camera that takes a
    view out of reach holds no jaws.
    """
    from rsi.mission.viewing import reach_vistas

    v.instance_of(sight, "sight", Sight, none_allowed=False)
    door_open_rad = v.in_range(door_open_rad, "door_open_rad", low=-math.pi, high=math.pi)
    openings = _jaw_regions(sight, arm_world)
    views = candidate_vistas(mockup, sight.rules)
    reached = (
        [where.reachable for where in reach_vistas(arm_world, [point for point, _ in views])]
        if arm_world is not None
        else [True] * len(views)
    )
    result: list[Candidate] = []
    for (point, surface), reachable in zip(views, reached, strict=True):
        indices, rows, cols = sight.in_frame(point)
        if indices.size == 0:
            continue
        kept: dict[float, BoolArray | None] = openings if reachable else {DEFAULT_JAW_OPENING_M: None}
        seen, met_door = sight.cast(point, 0.0, indices)
        result += _at_openings(Candidate(point, 0.0, indices, reachable, surface), seen, rows, cols, kept)
        if met_door:
            seen_open, _ = sight.cast(point, door_open_rad, indices)
            opened = Candidate(point, door_open_rad, indices, reachable, surface)
            result += _at_openings(opened, seen_open, rows, cols, kept)
    sight.world.set_door(0.0)
    return result


def _jaw_regions(sight: Sight, arm_world: World | None) -> dict[float, BoolArray | None]:
    """Each jaw opening a view is weighed at, with the pixels its frame keeps (None: the whole frame)."""
    from rsi.mission.views import jaws_region
    from rsi.sim.world import World

    if arm_world is None:
        return {DEFAULT_JAW_OPENING_M: None}
    v.instance_of(arm_world, "arm_world", World, none_allowed=False)
    rules = sight.rules
    return {
        opening: ~jaws_region(arm_world, opening, rules.size, rules.margin_px) for opening in JAW_OPENINGS_M
    }


def _at_openings(
    view: Candidate,
    seen: BoolArray,
    rows: NDArray[np.intp],
    cols: NDArray[np.intp],
    openings: dict[float, BoolArray | None],
) -> list[Candidate]:
    """`view` (its `seen` holding every in-frame sample) once per jaw opening, with what that leaves seen."""
    result = []
    for opening, kept in openings.items():
        visible = seen if kept is None else seen & kept[rows, cols]
        if visible.any():
            result.append(replace(view, seen=view.seen[visible], jaw_opening_m=opening))
    return result


# ------------------------------------------------------------------------------------------- cover


def greedy_cover(
    candidates: list[Candidate], area: FloatArray, target: float, must: BoolArray | None = None
) -> tuple[list[int], float]:
    """Step 3: candidates chosen greedily by (weighted) new area until `target` of the coverable area,
    and until every coverable sample flagged in `must` is seen; then pruned. Returns their indices (in
    choice order) and the coverable fraction.

    `must` marks the samples a plan may not trade for area: a site's disc (a missing screw, a hot or
    cold spot, a leak) is a few square centimetres, under the 0.5 % an area cover may leave, yet a whole
    anomaly (seed §4's inspection targets) stands on it.
    """
    from scipy import sparse

    candidates, area, target = _cover_inputs(candidates, area, target)
    rows = np.concatenate([np.full(c.seen.size, k) for k, c in enumerate(candidates)])
    cols = np.concatenate([c.seen for c in candidates])
    matrix = sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(len(candidates), area.size))
    weight = np.array([1.0 if c.reachable else UNREACHABLE_WEIGHT for c in candidates])
    coverable = np.asarray(matrix.sum(axis=0)).ravel() > 0
    needed = _sample_flags(must, area.size) & coverable
    goal = _Goal(target * float(area[coverable].sum()), needed)
    covered = np.zeros(area.size, dtype=bool)
    chosen: list[int] = []
    while not goal.met(covered, area):
        gain = (matrix @ np.where(covered, 0.0, area)) * weight
        if float(area[covered].sum()) >= goal.area_m2:  # the area is in: the sites left, area breaking ties
            sites = (matrix @ (needed & ~covered).astype(np.float64)) * weight
            gain = sites * (float(gain.max()) + 1.0) + gain
        best = int(np.argmax(gain))  # the first of equals: deterministic
        if gain[best] <= 0:
            break
        chosen.append(best)
        covered[candidates[best].seen] = True
    kept = _pair_swaps(_pruned(chosen, candidates, area, goal), matrix, candidates, area, goal)
    total = float(area.sum())
    return kept, float(area[coverable].sum()) / total if total > 0.0 else 1.0


@dataclass(frozen=True)
class _Goal:
    """What a cover must reach: an area (m^2) and every sample flagged in `needed`."""

    area_m2: float
    needed: BoolArray

    def met(self, seen: BoolArray, area: FloatArray) -> bool:
        return float(area[seen].sum()) >= self.area_m2 and not (self.needed & ~seen).any()


def _sample_flags(must: object, size: int, name: str = "must") -> BoolArray:
    if must is None:
        return np.zeros(size, dtype=bool)
    flags = np.asarray(must)
    if flags.dtype != np.bool_ or flags.shape != (size,):
        raise InputError(
            f"{name} must be a boolean array of one flag per sample ({size}); got {must!r}. "
            "Leave it None to cover the whole surface by area."
        )
    return flags


def _cover_inputs(
    candidates: object, area: object, target: object
) -> tuple[list[Candidate], FloatArray, float]:
    """greedy_cover's arguments checked: candidates whose sample indices lie in `area`, areas >= 0."""
    weights = v.as_float_array(area, "area")
    if weights.ndim != 1 or weights.size == 0 or not (np.isfinite(weights) & (weights >= 0)).all():
        raise InputError(
            f"area must be a non-empty 1-D array of finite sample areas >= 0 (m^2); got {area!r}."
        )
    chosen = v.records_named(candidates, "candidates", "Candidate")
    if not chosen:
        raise InputError("candidates must hold at least one Candidate (from weigh_candidates).")
    for index, candidate in enumerate(chosen):
        seen = np.asarray(candidate.seen)
        if (
            seen.dtype.kind not in "iu"
            or seen.ndim != 1
            or (seen.size and not 0 <= seen.min() <= seen.max() < weights.size)
        ):
            raise InputError(f"candidates[{index}].seen must be sample indices in [0, {weights.size}).")
    return chosen, weights, v.in_range(target, "target", low=0.0, high=1.0, low_inclusive=False)


def _pair_swaps(
    kept: list[int], matrix: Any, candidates: list[Candidate], area: FloatArray, goal: _Goal
) -> list[int]:
    """Replace any two points by one candidate while the goal is still met (greedy's first, widest pick
    often leaves two half views where one offset view would do), until no pair can be."""
    by_sample = matrix.tocsc()  # a pair leaves few samples unseen: gains summed over those columns alone
    improved = True
    while improved and len(kept) > 1:
        improved = False
        counts = np.zeros(area.size, dtype=np.int64)
        for k in kept:
            counts[candidates[k].seen] += 1
        for a, b in itertools.combinations(range(len(kept)), 2):
            left = counts.copy()
            left[candidates[kept[a]].seen] -= 1
            left[candidates[kept[b]].seen] -= 1
            have = float(area[left > 0].sum())
            unseen = np.flatnonzero(left == 0)
            gain = by_sample[:, unseen] @ area[unseen]
            lost = unseen[goal.needed[unseen]]
            # only a candidate that sees every needed sample the pair took with it may replace the pair
            gain[(by_sample[:, lost] @ np.ones(lost.size)) < lost.size] = -1.0
            best = int(np.argmax(gain))
            if gain[best] >= 0 and have + gain[best] >= goal.area_m2:
                kept = [k for i, k in enumerate(kept) if i not in (a, b)] + [best]
                improved = True
                break
    return kept


def _pruned(chosen: list[int], candidates: list[Candidate], area: FloatArray, goal: _Goal) -> list[int]:
    """Drop, while the goal is still met, the point whose own area (seen by no other) is smallest; a
    point that alone sees a needed sample stays."""
    kept = list(chosen)
    while len(kept) > 1:
        counts = np.zeros(area.size, dtype=np.int64)
        for k in kept:
            counts[candidates[k].seen] += 1
        total = float(area[counts > 0].sum())
        own = []
        for k in kept:
            alone = candidates[k].seen[counts[candidates[k].seen] == 1]
            own.append(math.inf if goal.needed[alone].any() else float(area[alone].sum()))
        weakest = int(np.argmin(own))
        if not math.isfinite(own[weakest]) or total - own[weakest] < goal.area_m2:
            return kept
        kept.pop(weakest)
    return kept


# ------------------------------------------------------------------------------------------- reach


def ik_reaches(world: World, point: Vista, door_angle_rad: float) -> bool:
    """Step 4: closed-loop IK from the arm's home to `point`'s viewing pose (through its staging point, as
    a transit goes), the door at `door_angle_rad`; True when the pose is held and the arm clears the
    mock-up by ``MIN_CLEARANCE_M``."""
    from rsi.control.redundancy import orientation_error
    from rsi.mission.transit import APPROACH_START_M
    from rsi.mission.viewing import pose_of, world_arm
    from rsi.sim.clearance import ArmClearance

    arm = world_arm(world)
    v.instance_of(point, "point", Vista, none_allowed=False)
    arm.reset()
    world.set_door(door_angle_rad)
    pose = pose_of(world, point)
    staging = pose.tool_m - APPROACH_START_M * pose.tool_rotation[:, 2]
    for goal in (staging, pose.tool_m):
        for _ in range(IK_STEPS):
            position, rotation = arm.tool_pose()
            error, turn = goal - position, orientation_error(pose.tool_rotation, rotation)
            if np.linalg.norm(error) < IK_TOLERANCE_M and np.linalg.norm(turn) < IK_TOLERANCE_RAD:
                break
            twist = np.concatenate(
                [_capped(IK_GAIN_PER_S * error, IK_SPEED_M_S), _capped(IK_GAIN_PER_S * turn, IK_TURN_RAD_S)]
            )
            arm.step_velocity(twist, IK_PERIOD_S)
        else:
            return False
    return ArmClearance(world)() >= MIN_CLEARANCE_M


def _capped(vector: FloatArray, limit: float) -> FloatArray:
    norm = float(np.linalg.norm(vector))
    result: FloatArray = vector if norm <= limit else vector * (limit / norm)
    return result


# -------------------------------------------------------------------------------------------- tour


def _staging(point: Vista) -> FloatArray:
    from rsi.mission.transit import APPROACH_START_M

    return np.asarray(point.position_m) - APPROACH_START_M * np.asarray(point.forward)


def transfer_s(first: Vista, second: Vista) -> float:
    """Transfer time between two vistas' staging poses at the rail's and the wrist's rate limits."""
    from rsi.mission.transit import TRANSFER_SPEED_M_S, TRANSFER_TURN_RAD_S

    v.instance_of(first, "first", Vista, none_allowed=False)
    v.instance_of(second, "second", Vista, none_allowed=False)
    distance = float(np.linalg.norm(_staging(first) - _staging(second)))
    turn = math.acos(float(np.clip(np.dot(first.forward, second.forward), -1.0, 1.0)))
    return max(distance / TRANSFER_SPEED_M_S, turn / TRANSFER_TURN_RAD_S)


def _vistas(points: object, name: str) -> list[Vista]:
    if not isinstance(points, (list, tuple)):
        raise InputError(f"{name} must be a list of Vista; got {type(points).__name__}.")
    return [v.instance_of(point, f"{name}[{k}]", Vista, none_allowed=False) for k, point in enumerate(points)]


def _cost_matrix(points: list[Vista], doors: list[float]) -> FloatArray:
    n = len(points)
    cost = np.zeros((n, n))
    for i in range(n):
        for j in range(n):
            if i != j:
                cost[i, j] = transfer_s(points[i], points[j]) + DOOR_CHANGE_S * (doors[i] != doors[j])
    return cost


def tour_order(points: list[Vista], doors: list[float], start_m: FloatArray) -> list[int]:
    """Step 5: nearest neighbour from the vista nearest `start_m`, then 2-opt on the open path."""
    from rsi.mission.transit import TRANSFER_SPEED_M_S

    points, start_m = _vistas(points, "points"), np.array(v.vector3(start_m, "start_m"))
    if not isinstance(doors, (list, tuple)) or len(doors) != len(points):
        raise InputError(
            f"doors must be a list of {len(points)} door angles (rad), one per point; got {doors!r}."
        )
    doors = [v.finite_number(door, f"doors[{k}]") for k, door in enumerate(doors)]
    if not points:
        return []
    cost = _cost_matrix(points, doors)
    # from the home, a closed-door point first: the door opens once, for the points that need it
    away = [float(np.linalg.norm(_staging(p) - start_m)) / TRANSFER_SPEED_M_S for p in points]
    first = int(np.argmin([t + DOOR_CHANGE_S * (d != 0.0) for t, d in zip(away, doors, strict=True)]))
    order = [first]
    while len(order) < len(points):
        left = [k for k in range(len(points)) if k not in order]
        order.append(min(left, key=lambda k: (cost[order[-1], k], k)))
    return _two_opt(order, cost)


def _two_opt(order: list[int], cost: FloatArray) -> list[int]:
    def length(path: list[int]) -> float:
        return float(sum(cost[a, b] for a, b in itertools.pairwise(path)))

    improved = True
    while improved:
        improved = False
        for i in range(1, len(order) - 1):
            for j in range(i + 1, len(order)):
                trial = order[:i] + order[i : j + 1][::-1] + order[j + 1 :]
                if length(trial) < length(order) - 1e-9:
                    order, improved = trial, True
    return order


def tour_figures(points: list[Vista], start_m: FloatArray) -> tuple[float, float]:
    """Length (m) and transfer time (s) of visiting `points` in order from `start_m`."""
    from rsi.mission.transit import TRANSFER_SPEED_M_S

    points, start_m = _vistas(points, "points"), np.array(v.vector3(start_m, "start_m"))
    if not points:
        return 0.0, 0.0
    stops = [np.asarray(start_m, float), *(_staging(p) for p in points)]
    length = float(sum(np.linalg.norm(b - a) for a, b in itertools.pairwise(stops)))
    seconds = float(np.linalg.norm(stops[1] - stops[0])) / TRANSFER_SPEED_M_S
    seconds += sum(transfer_s(a, b) for a, b in itertools.pairwise(points))
    return length, seconds


# ------------------------------------------------------------------------------------------ the plan


def _mockup_of(source: object) -> Mockup:
    from rsi.sim.mockup import Mockup
    from rsi.sim.world import World

    if isinstance(source, World):
        return source.mockup
    if isinstance(source, Mockup):
        return source
    raise InputError(
        f"source must be an rsi.sim World or Mockup; got {type(source).__name__}. "
        "Try rsi.sim.load('truss', seed=0) or rsi.sim.mockup.truss_mockup()."
    )


def generate_plan(
    source: World | Mockup,
    settings: MissionSettings | None = None,
    rules: CoverageRules | None = None,
    *,
    target: float | None = None,
    arm: bool = True,
    covered: BoolArray | None = None,
    prefix: str = "cad",
) -> CadPlan:
    """Vista points that cover the inspectable surface of `source`'s mock-up, ordered for a short tour.

    Parameters
    ----------
    source : World or Mockup
        The mock-up (a world's mock-up: its anomalies and arm are ignored).
    settings : MissionSettings, optional
        The door's opening for views of what it hides (``door_open_rad``).
    rules : CoverageRules, optional
        When a view covers a sample; default 0.5 mm per pixel and 45 deg.
    target : float, optional
        Fraction of the coverable area, in (0, 1], at which the greedy cover stops. None: `settings`'s
        ``plan_cover`` (0.999; :class:`rsi.mission.settings.MissionSettings` says why).
    arm : bool
        Check reach by the arm on its rail (prefer reachable views, flag the others); False: any view.
    covered : ndarray of bool, optional
        Per sample of ``inspectable_samples`` at the rules' spacing, whether another plan already covers
        it (:attr:`Coverage.covered` of that plan at the same rules): the points generated then complete
        it, covering `target` of what it leaves. None: the whole surface.
    prefix : str
        The points' names: ``f"{prefix}_{k:02d}"`` in visiting order.

    Raises
    ------
    InputError
        Naming the argument: `source` not a World or Mockup, `settings` or `rules` of the wrong type,
        `target` outside (0, 1], `arm` not a bool, `covered` not one flag per sample, `prefix` not a
        name.
    """
    began = time.perf_counter()
    mockup = _mockup_of(source)
    settings = v.instance_or_default(settings, "settings", MissionSettings)
    rules = v.instance_or_default(rules, "rules", CoverageRules)
    target = settings.plan_cover if target is None else target
    target = v.in_range(target, "target", low=0.0, high=1.0, low_inclusive=False)
    if not isinstance(arm, bool):
        raise InputError(f"arm must be True or False; got {arm!r}.")
    from rsi.sim.anomalies import AnomalySet
    from rsi.sim.world import World

    if not isinstance(prefix, str) or not prefix.isidentifier():
        raise InputError(f"prefix must be a name such as 'cad'; got {prefix!r}.")
    sight = Sight(mockup, rules)
    done = _sample_flags(covered, len(sight.samples), "covered")
    arm_world = World(mockup, AnomalySet(()), seed=0, arm=True, grid_meshes=False) if arm else None
    weighed = weigh_candidates(mockup, sight, settings.door_open_rad, arm_world)
    if not weighed:
        raise InputError("source's mock-up has no inspectable surface any candidate view covers.")
    # What another plan covers already weighs nothing: the cover aims at the rest.
    area = np.where(done, 0.0, sight.samples.area_m2)
    chosen, coverable = greedy_cover(
        weighed, area, target, must=np.isin(sight.samples.kind, SITE_KINDS) & ~done
    )
    picked = [weighed[k] for k in chosen]
    reached = [c.reachable for c in picked]
    start: FloatArray = np.asarray(picked[0].vista.position_m) if picked else np.zeros(3)
    if arm_world is not None:
        reached = [
            ok and ik_reaches(arm_world, c.vista, c.door_angle_rad)
            for ok, c in zip(reached, picked, strict=True)
        ]
        arm_world.arm.reset()
        start = arm_world.arm.tool_pose()[0]
    order = tour_order([c.vista for c in picked], [c.door_angle_rad for c in picked], np.asarray(start))
    return _assembled(
        [picked[k] for k in order],
        [reached[k] for k in order],
        sight,
        coverable=coverable,
        start=np.asarray(start),
        weighed=len(weighed),
        began=began,
        prefix=prefix,
    )


def _assembled(
    picked: list[Candidate],
    reached: list[bool],
    sight: Sight,
    *,
    coverable: float,
    start: FloatArray,
    weighed: int,
    began: float,
    prefix: str,
) -> CadPlan:
    """The plan record: points named in visiting order, the coverage of the chosen views, the tour."""
    vistas = tuple(replace(c.vista, name=f"{prefix}_{k:02d}") for k, c in enumerate(picked))
    points = tuple(
        PlanPoint(p.name, p.name, c.door_angle_rad, c.jaw_opening_m)
        for p, c in zip(vistas, picked, strict=True)
    )
    length, seconds = tour_figures(list(vistas), start)
    first = np.full(len(sight.samples), -1, dtype=np.int64)
    for number, candidate in enumerate(picked):
        fresh = candidate.seen[first[candidate.seen] < 0]
        first[fresh] = number
    measured = Coverage(
        sight.rules, sight.samples, first, tuple(p.name for p in points), tuple(c.seen.size for c in picked)
    )
    return CadPlan(
        points=points,
        vistas=vistas,
        targets=tuple(c.surface for c in picked),
        unreachable=tuple(p.name for p, ok in zip(points, reached, strict=True) if not ok),
        coverage=measured,
        coverable=coverable,
        tour_m=length,
        tour_s=seconds,
        candidates=weighed,
        generation_s=time.perf_counter() - began,
    )


def add_plan_vistas(world: World, plan: CadPlan) -> tuple[PlanPoint, ...]:
    """Add `plan`'s vistas to `world` (those it lacks) and return its points, ready for a mission."""
    from rsi.sim.world import World

    v.instance_of(world, "world", World, none_allowed=False)
    v.instance_of(plan, "plan", CadPlan, none_allowed=False)
    for point in plan.vistas:
        if point.name not in world.vistas:
            world.add_vista(point)
    return plan.points


__all__ = [
    "CadPlan",
    "Candidate",
    "add_plan_vistas",
    "candidate_vistas",
    "coverage",
    "generate_plan",
    "greedy_cover",
    "ik_reaches",
    "tour_figures",
    "tour_order",
    "transfer_s",
    "weigh_candidates",
]
