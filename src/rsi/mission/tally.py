"""Many scored missions tallied: recall per type and per stratum with 95 % Wilson intervals, false findings
per run by kind, and the runs with no anomaly that counts scored on their own (issue 13 item 3).

One mission becomes a :class:`RunTally` (:func:`tally_run`: each ground-truth anomaly's stratum and whether
a finding matched it, each false finding's kind); a :class:`Tally` holds the runs of many seeds, merges with
another (a resumed or split benchmark) and round-trips through JSON (:meth:`Tally.to_dict`,
:meth:`Tally.from_dict`). Pure: no simulator, no renderer. ``benchmarks/mission_recall.py`` prints it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from statistics import NormalDist
from typing import TYPE_CHECKING, Any, NamedTuple

from rsi import _validate as v
from rsi.errors import InputError
from rsi.mission.records import (
    IMPACT_MIN_SIZE_M,
    SCORED_TYPES,
    MissionResult,
    counts_towards_recall,
    scored_type,
)

if TYPE_CHECKING:
    from rsi.mission.score import MissionScore
    from rsi.sim.anomalies import Anomaly

CONFIDENCE = 0.95
# the kinds a finding (and a ground-truth anomaly) can have: rsi.sim.anomalies.ANOMALY_KINDS
FINDING_KINDS: tuple[str, ...] = (
    "impact",
    "missing_screw",
    "swapped_component",
    "hot_spot",
    "cold_spot",
    "gas_leak",
)
# seed §2: ~1 mm flaws are what the inspection must find; the bands show how recall falls towards that size
IMPACT_BAND_EDGES_M: tuple[float, ...] = (IMPACT_MIN_SIZE_M, 2e-3, 4e-3)
SIZE_BANDS: tuple[str, ...] = ("<1 mm", "1-2 mm", "2-4 mm", ">=4 mm", "n/a")
_SCHEMA = "rsi.mission.tally/1"


# ------------------------------------------------------------------------------------------ intervals


def _z(confidence: object) -> float:
    level = v.in_range(confidence, "confidence", low=0.0, high=1.0, low_inclusive=False, high_inclusive=False)
    return NormalDist().inv_cdf(0.5 + level / 2.0)


def wilson_interval(successes: int, trials: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson's score interval for a binomial proportion `successes` / `trials`.

    Wilson (1927), "Probable inference, the law of succession, and statistical inference", JASA 22:209-212;
    recommended over the Wald interval for small counts and proportions near 0 or 1 by Agresti & Coull
    (1998), "Approximate is better than 'exact' for interval estimation of binomial proportions", Am. Stat.
    52:119-126. ``(0.0, 1.0)`` when `trials` is 0 (nothing measured).

    Raises
    ------
    InputError
        If `successes` or `trials` is not an integer >= 0, `successes` > `trials`, or `confidence` is not in
        (0, 1).
    """
    found = v.positive_int(successes, "successes", minimum=0)
    total = v.positive_int(trials, "trials", minimum=0)
    z = _z(confidence)
    if found > total:
        raise InputError(f"successes must be <= trials; got successes={found}, trials={total}.")
    if total == 0:
        return (0.0, 1.0)
    p = found / total
    denominator = 1.0 + z * z / total
    centre = (p + z * z / (2.0 * total)) / denominator
    half = z / denominator * math.sqrt(p * (1.0 - p) / total + z * z / (4.0 * total * total))
    # the bounds are exactly 0 and 1 at the ends: rounding must not leave a 1e-17 above zero
    low = 0.0 if found == 0 else max(0.0, centre - half)
    high = 1.0 if found == total else min(1.0, centre + half)
    return (low, high)


def poisson_rate_interval(events: int, runs: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Score interval for a Poisson rate: `events` counted over `runs` runs, per run.

    The Wilson construction applied to a Poisson count X with mean n*lambda: the lambdas with
    (X - n lambda)^2 <= z^2 n lambda, i.e. (X + z^2/2 +- z sqrt(X + z^2/4)) / n (the score interval of
    Brown, Cai & DasGupta (2003), "Interval estimation in exponential families", Statistica Sinica
    13:19-49). ``(0.0, inf)`` when `runs` is 0.

    Raises
    ------
    InputError
        If `events` or `runs` is not an integer >= 0, or `confidence` is not in (0, 1).
    """
    # counts beyond 2**53 have no exact float, and no batch of runs comes near
    count = v.positive_int(events, "events", minimum=0, maximum=2**53)
    total = v.positive_int(runs, "runs", minimum=0, maximum=2**53)
    z = _z(confidence)
    if total == 0:
        return (0.0, math.inf)
    spread = z * math.sqrt(count + z * z / 4.0)
    middle = count + z * z / 2.0
    return (max(0.0, (middle - spread) / total), (middle + spread) / total)


# ------------------------------------------------------------------------------------------ strata


def _anomaly(value: object) -> Anomaly:
    from rsi.sim.anomalies import Anomaly

    return v.instance_of(value, "anomaly", Anomaly, none_allowed=False)


def size_band(anomaly: Anomaly) -> str:
    """An impact's diameter band (``"<1 mm"``, ``"1-2 mm"``, ``"2-4 mm"``, ``">=4 mm"``); ``"n/a"`` else.

    Raises
    ------
    InputError
        If `anomaly` is not an :class:`rsi.sim.anomalies.Anomaly`.
    """
    if _anomaly(anomaly).kind != "impact":
        return "n/a"
    below = sum(anomaly.size_m >= edge for edge in IMPACT_BAND_EDGES_M)
    return SIZE_BANDS[below]


def subtype_of(anomaly: Anomaly) -> str:
    """The anomaly's subtype for stratified scoring (:attr:`rsi.sim.anomalies.Anomaly.subtype`).

    Raises
    ------
    InputError
        If `anomaly` is not an :class:`rsi.sim.anomalies.Anomaly`.
    """
    return _anomaly(anomaly).subtype


class Stratum(NamedTuple):
    """A stratum: scored type, subtype, surface material and size band."""

    type: str
    subtype: str
    surface: str
    size_band: str


# ------------------------------------------------------------------------------------------ one run


def _text(value: object, name: str) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} must be a non-empty string; got {value!r}.")
    return value


def _flag(value: object, name: str) -> bool:
    if not isinstance(value, bool):
        raise InputError(f"{name} must be True or False; got {value!r}.")
    return value


@dataclass(frozen=True)
class Outcome:
    """One ground-truth anomaly of a run: its stratum, whether it counts towards recall and was found.

    Attributes
    ----------
    type : str
        One of :data:`SCORED_TYPES` (hot and cold spots are ``thermal_spot``).
    subtype, surface : str
        :func:`subtype_of` and the surface material it sits on.
    size_band : str
        One of :data:`SIZE_BANDS`.
    counts : bool
        :func:`rsi.mission.counts_towards_recall`.
    found : bool
        A finding of its kind matched it.
    error_m : float or None
        Distance of that finding from the truth, metres; None when not found.
    """

    type: str
    subtype: str
    surface: str
    size_band: str
    counts: bool
    found: bool
    error_m: float | None = None

    def __post_init__(self) -> None:
        v.choice(self.type, "type", SCORED_TYPES)
        _text(self.subtype, "subtype")
        _text(self.surface, "surface")
        v.choice(self.size_band, "size_band", SIZE_BANDS)
        _flag(self.counts, "counts")
        _flag(self.found, "found")
        if (self.error_m is None) == self.found:
            raise InputError(
                f"error_m must be a distance >= 0 when found and None when not; got found={self.found}, "
                f"error_m={self.error_m!r}."
            )
        if self.error_m is not None:
            object.__setattr__(self, "error_m", v.in_range(self.error_m, "error_m", low=0.0))

    @property
    def stratum(self) -> Stratum:
        """(type, subtype, surface, size band)."""
        return Stratum(self.type, self.subtype, self.surface, self.size_band)


@dataclass(frozen=True)
class RunTally:
    """One scored mission, reduced to what a benchmark adds up.

    Attributes
    ----------
    seed : int
        The mission's seed.
    outcomes : tuple of Outcome
        Every ground-truth anomaly, in the truth's order.
    false_by_kind : dict of str to int
        False findings (matching no anomaly) per finding kind, every kind of :data:`FINDING_KINDS` present.
    mission_s : float
        Wall time of the mission (informative: not compared, two runs of a seed are the same run).
    """

    seed: int
    outcomes: tuple[Outcome, ...]
    false_by_kind: Mapping[str, int]
    mission_s: float = field(default=0.0, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "seed", v.positive_int(self.seed, "seed", minimum=0))
        if not isinstance(self.outcomes, tuple) or not all(isinstance(o, Outcome) for o in self.outcomes):
            raise InputError(f"outcomes must be a tuple of Outcome; got {self.outcomes!r}.")
        if not isinstance(self.false_by_kind, Mapping) or set(self.false_by_kind) - set(FINDING_KINDS):
            raise InputError(
                f"false_by_kind must map finding kinds ({', '.join(FINDING_KINDS)}) to counts; got "
                f"{self.false_by_kind!r}."
            )
        counts = {
            kind: v.positive_int(self.false_by_kind.get(kind, 0), f"false_by_kind[{kind!r}]", minimum=0)
            for kind in FINDING_KINDS
        }
        object.__setattr__(self, "false_by_kind", counts)
        object.__setattr__(self, "mission_s", v.in_range(self.mission_s, "mission_s", low=0.0))

    @property
    def anomaly_free(self) -> bool:
        """No anomaly that counts towards recall (an impact under 1 mm alone leaves the run free)."""
        return not any(outcome.counts for outcome in self.outcomes)

    @property
    def false_findings(self) -> int:
        """False findings of every kind."""
        return sum(self.false_by_kind.values())

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``seed``, ``outcomes`` (dicts), ``false_by_kind``, ``mission_s``."""
        return {
            "seed": self.seed,
            "outcomes": [asdict(outcome) for outcome in self.outcomes],
            "false_by_kind": dict(self.false_by_kind),
            "mission_s": self.mission_s,
        }


def tally_run(result: MissionResult, score: MissionScore, *, mission_s: float = 0.0) -> RunTally:
    """One mission's :class:`RunTally` from its result and :func:`rsi.mission.score_mission`'s score.

    Raises
    ------
    InputError
        If `result` is not a MissionResult, `score` not a MissionScore, or `score.matches` names a finding or
        an anomaly the result does not have (a score of another run).
    """
    from rsi.mission.score import MissionScore

    v.instance_of(result, "result", MissionResult, none_allowed=False)
    v.instance_of(score, "score", MissionScore, none_allowed=False)
    anomalies, findings = result.truth.anomalies, result.findings
    if any(i >= len(findings) or k >= len(anomalies) for i, k in score.matches.items()):
        raise InputError(
            f"score must be score_mission(result) of this result; its matches {score.matches!r} name "
            f"findings or anomalies beyond the result's {len(findings)} findings, {len(anomalies)} anomalies."
        )
    matched = {k: i for i, k in score.matches.items()}
    outcomes = []
    for k, anomaly in enumerate(anomalies):
        finding = findings[matched[k]] if k in matched else None
        error = None if finding is None else math.dist(finding.position_m, anomaly.position_m)
        outcomes.append(
            Outcome(
                type=scored_type(anomaly.kind),
                subtype=subtype_of(anomaly),
                surface=anomaly.surface,
                size_band=size_band(anomaly),
                counts=counts_towards_recall(anomaly),
                found=finding is not None,
                error_m=error,
            )
        )
    false = [finding.kind for i, finding in enumerate(findings) if i not in score.matches]
    by_kind = {kind: false.count(kind) for kind in FINDING_KINDS}
    return RunTally(result.seed, tuple(outcomes), by_kind, mission_s=mission_s)


# ------------------------------------------------------------------------------------------ many runs


@dataclass(frozen=True)
class Recall:
    """`found` of `truth` with its Wilson interval at the tally's confidence."""

    found: int
    truth: int
    low: float
    high: float

    @classmethod
    def of(cls, found: int, truth: int, confidence: float = CONFIDENCE) -> Recall:
        """The proportion and its :func:`wilson_interval`."""
        low, high = wilson_interval(found, truth, confidence)
        return cls(found, truth, low, high)

    @property
    def recall(self) -> float:
        """found / truth; nan when there was nothing to find."""
        return self.found / self.truth if self.truth else math.nan


@dataclass(frozen=True)
class Rate:
    """`events` over `runs` runs, per run, with its :func:`poisson_rate_interval`."""

    events: int
    runs: int
    low: float
    high: float

    @classmethod
    def of(cls, events: int, runs: int, confidence: float = CONFIDENCE) -> Rate:
        """The rate and its score interval."""
        low, high = poisson_rate_interval(events, runs, confidence)
        return cls(events, runs, low, high)

    @property
    def per_run(self) -> float:
        """events / runs; nan without runs."""
        return self.events / self.runs if self.runs else math.nan


@dataclass(frozen=True)
class AnomalyFree:
    """The runs with no anomaly that counts: every finding in them is a false alarm.

    Attributes
    ----------
    runs : int
    false_findings : Rate
        False findings per anomaly-free run (Poisson score interval).
    runs_with_false : Recall
        Anomaly-free runs with at least one false finding, of all anomaly-free runs (Wilson interval): the
        chance that a clean platform raises an alarm.
    """

    runs: int
    false_findings: Rate
    runs_with_false: Recall


def _run_from_dict(entry: Mapping[str, Any]) -> RunTally:
    return RunTally(
        seed=entry["seed"],
        outcomes=tuple(Outcome(**outcome) for outcome in entry["outcomes"]),
        false_by_kind=entry["false_by_kind"],
        mission_s=entry.get("mission_s", 0.0),
    )


@dataclass(frozen=True)
class Tally:
    """The runs of many seeds (one per seed, in seed order).

    Raises
    ------
    InputError
        If `runs` is not a sequence of RunTally or two runs share a seed.
    """

    runs: tuple[RunTally, ...] = ()

    def __post_init__(self) -> None:
        runs = self.runs
        if not isinstance(runs, (tuple, list)):
            raise InputError(f"runs must be a tuple of RunTally; got {type(runs).__name__}.")
        runs = tuple(runs)
        if not all(isinstance(run, RunTally) for run in runs):
            raise InputError(f"runs must hold only RunTally (from tally_run); got {runs!r}.")
        seeds = [run.seed for run in runs]
        if len(set(seeds)) != len(seeds):
            twice = sorted({seed for seed in seeds if seeds.count(seed) > 1})
            raise InputError(f"runs has seeds {twice} more than once; give each seed one run (merge() them).")
        object.__setattr__(self, "runs", tuple(sorted(runs, key=lambda run: run.seed)))

    @property
    def seeds(self) -> tuple[int, ...]:
        """The seeds tallied, increasing."""
        return tuple(run.seed for run in self.runs)

    def merge(self, other: Tally) -> Tally:
        """Both tallies' runs; a seed in both must be the same run (determinism by seed), kept once.

        Raises
        ------
        InputError
            If `other` is not a Tally, or a seed in both has different outcomes or false findings.
        """
        v.instance_of(other, "other", Tally, none_allowed=False)
        mine = {run.seed: run for run in self.runs}
        for run in other.runs:
            if run.seed in mine and mine[run.seed] != run:
                raise InputError(
                    f"other has seed {run.seed} with another result than this tally's; tallies of different "
                    "settings (size, repeatability, active, sun) cannot be merged."
                )
            mine.setdefault(run.seed, run)
        return Tally(tuple(mine.values()))

    def per_type(self, confidence: float = CONFIDENCE) -> dict[str, Recall]:
        """Recall of each :data:`SCORED_TYPES` over the anomalies that count."""
        counted = [o for run in self.runs for o in run.outcomes if o.counts]
        return {
            name: Recall.of(
                sum(o.found for o in counted if o.type == name),
                sum(o.type == name for o in counted),
                confidence,
            )
            for name in SCORED_TYPES
        }

    def per_stratum(self, confidence: float = CONFIDENCE) -> dict[Stratum, Recall]:
        """Recall in each stratum present, sorted; impacts under 1 mm included (band ``"<1 mm"``)."""
        _z(confidence)  # checked even when there is no run
        found: dict[Stratum, list[int]] = {}
        for outcome in (o for run in self.runs for o in run.outcomes):
            entry = found.setdefault(outcome.stratum, [0, 0])
            entry[0] += outcome.found
            entry[1] += 1
        return {key: Recall.of(hit, total, confidence) for key, (hit, total) in sorted(found.items())}

    def localisation_error_m(self) -> dict[str, float]:
        """Mean distance of the matched findings from their truth per type, over the anomalies that count
        (as :class:`rsi.mission.TypeScore`); nan where none matched."""
        errors: dict[str, list[float]] = {name: [] for name in SCORED_TYPES}
        for outcome in (o for run in self.runs for o in run.outcomes):
            if outcome.counts and outcome.error_m is not None:
                errors[outcome.type].append(outcome.error_m)
        return {name: math.fsum(e) / len(e) if e else math.nan for name, e in errors.items()}

    def false_by_kind(self, confidence: float = CONFIDENCE) -> dict[str, Rate]:
        """False findings per run of each finding kind, and ``"all"`` of them."""
        runs = len(self.runs)
        rates = {
            kind: Rate.of(sum(run.false_by_kind[kind] for run in self.runs), runs, confidence)
            for kind in FINDING_KINDS
        }
        rates["all"] = Rate.of(sum(run.false_findings for run in self.runs), runs, confidence)
        return rates

    def anomaly_free(self, confidence: float = CONFIDENCE) -> AnomalyFree:
        """The runs with no anomaly that counts, on their own (false alarms measured directly)."""
        free = [run for run in self.runs if run.anomaly_free]
        return AnomalyFree(
            runs=len(free),
            false_findings=Rate.of(sum(run.false_findings for run in free), len(free), confidence),
            runs_with_false=Recall.of(sum(run.false_findings > 0 for run in free), len(free), confidence),
        )

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: ``schema`` and ``runs`` (each :meth:`RunTally.to_dict`)."""
        return {"schema": _SCHEMA, "runs": [run.to_dict() for run in self.runs]}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Tally:
        """The tally :meth:`to_dict` wrote.

        Raises
        ------
        InputError
            If `data` is not such a dict (another schema, a missing or malformed entry).
        """
        if not isinstance(data, Mapping) or data.get("schema") != _SCHEMA:
            raise InputError(
                f"data must be a dict from Tally.to_dict (schema {_SCHEMA!r}); got {data!r:.200}."
            )
        try:
            return cls(tuple(_run_from_dict(entry) for entry in data["runs"]))
        except (KeyError, TypeError, AttributeError) as error:
            raise InputError(
                f"data must be a dict from Tally.to_dict; its runs are malformed ({error!r}); "
                f"got {data!r:.200}."
            ) from error
