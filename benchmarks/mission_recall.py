"""Recall, false findings and localisation error per anomaly type over seeded missions (issue 5 acceptance).

Each seed runs :func:`rsi.mission.run_mission` (reference pass, inspection pass, pyrometer, gas) with
active inspection on and off, and scores it with :func:`rsi.mission.score_mission`. The issue's target:
recall >= 0.95 for each type (impacts >= 1 mm, missing screws, swapped components, hot/cold spots, the
active leak) with at most 1 false finding per run.

Run: ``MUJOCO_GL=egl .venv/bin/python benchmarks/mission_recall.py [--seeds 20] [--size 480 640]``
"""

from __future__ import annotations

import argparse
import math
import time

from rsi.mission import SCORED_TYPES, run_mission, score_mission


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=20)
    parser.add_argument("--size", type=int, nargs=2, default=(480, 640))
    parser.add_argument("--repeatability", default="lab", choices=("lab", "space"))
    args = parser.parse_args()
    size = (args.size[0], args.size[1])
    for active in (True, False):
        totals = {name: [0, 0, 0, 0.0, 0] for name in SCORED_TYPES}  # found, truth, false, error sum, n
        seconds: list[float] = []
        looks = confirmed = 0
        for seed in range(args.seeds):
            start = time.perf_counter()
            result = run_mission(seed, size=size, active=active, repeatability=args.repeatability)
            seconds.append(time.perf_counter() - start)
            score = score_mission(result)
            looks += sum(visit.second_looks for visit in result.visits)
            confirmed += sum(visit.confirmed for visit in result.visits)
            for name, entry in score.per_type.items():
                row = totals[name]
                row[0] += entry.found
                row[1] += entry.truth
                row[2] += entry.false_findings
                if not math.isnan(entry.localisation_error_m):
                    row[3] += entry.localisation_error_m * entry.found
                    row[4] += entry.found
        runs = args.seeds
        print(
            f"\nactive={active}  seeds 0..{runs - 1}  size {size[0]}x{size[1]}  {args.repeatability}  "
            f"mission {sum(seconds) / runs:.1f} s mean, {max(seconds):.1f} s max  "
            f"second looks {looks / runs:.1f}/run, confirmed {confirmed / runs:.1f}/run"
        )
        print(f"| {'type':<18} | found/truth | recall | false findings/run | localisation error mm |")
        print("| --- | --- | --- | --- | --- |")
        for name, (found, truth, false, error_sum, matched) in totals.items():
            recall = found / truth if truth else 1.0
            error = f"{1e3 * error_sum / matched:.1f}" if matched else "-"
            print(
                f"| {name:<18} | {found:>4}/{truth:<4} | {recall:6.3f} | {false / runs:18.2f} | {error:>5} |"
            )
        false_total = sum(row[2] for row in totals.values())
        print(f"| all types | | | {false_total / runs:.2f} | |")


if __name__ == "__main__":
    main()
