"""False decisions and power of a ``decide`` study's rule, simulated (issue 36).

    python benchmarks/bench_decide.py [--studies 2000] [--seed 0] [--json FILE]

Synthetic paired successes (:mod:`otmm_qp.studies.decide_simulation`) through the anytime
rule studies use (:func:`otmm_qp.studies.sequential.pick_from_counts`) and, on the same
draws, the fixed-sample rule used before (exact McNemar + Holm at every look,
:func:`~otmm_qp.studies.sequential.fixed_sample_pick`), with a look after every batch as the
loop makes them (``decide: {budget_tasks, batch}``) or after every task. Prints a Markdown
table: per scenario and rule, the false-decision rate with its Clopper-Pearson 95 %
Monte-Carlo interval, the right-decision rate (power) and the mean tasks at the stop. The
table in docs/studies.md ("Deciding") is this command's output with the defaults.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from otmm_qp.studies.decide_simulation import Rule, looks, simulate
from otmm_qp.studies.sequential import fixed_sample_pick, pick_from_counts

#: (label, success rates, budget, batch (0: a look after every task), shared share)
SCENARIOS: list[tuple[str, tuple[float, ...], int, int, float]] = [
    ("equal 0.6/0.6, batch 10 of 200", (0.6, 0.6), 200, 10, 0.0),
    ("equal 0.6/0.6, batch 60 of 600", (0.6, 0.6), 600, 60, 0.0),
    ("equal 0.6/0.6, every task of 600", (0.6, 0.6), 600, 1, 0.0),
    ("equal 4 × 0.6, batch 60 of 600", (0.6, 0.6, 0.6, 0.6), 600, 60, 0.0),
    ("equal 0.6/0.6 correlated (half shared), batch 60 of 600", (0.6, 0.6), 600, 60, 0.5),
    ("small: 0.60 vs 0.66, batch 60 of 600", (0.6, 0.66), 600, 60, 0.0),
    ("large: 0.5 vs 0.7, batch 60 of 600", (0.5, 0.7), 600, 60, 0.0),
    ("large: 0.5 vs 0.7, every task of 600", (0.5, 0.7), 600, 1, 0.0),
    ("3 rows 0.5/0.5/0.7, batch 60 of 600", (0.5, 0.5, 0.7), 600, 60, 0.0),
    ("correlated 0.52 vs 0.56 (arms study), batch 60 of 600", (0.52, 0.56), 600, 60, 0.8),
]

RULES: dict[str, Rule] = {
    "anytime (mixture e-process, Bonferroni)": pick_from_counts,
    "fixed-sample McNemar + Holm (before)": fixed_sample_pick,
}


def _rate(count: int, studies: int, interval: tuple[float, float]) -> str:
    return f"{100 * count / studies:.1f} % [{100 * interval[0]:.1f}, {100 * interval[1]:.1f}]"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--studies", type=int, default=2000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    args = parser.parse_args(argv)
    print(
        f"{args.studies} simulated studies per scenario, seed {args.seed}; false = a named row "
        "not strictly better than every other (α = 0.05)\n"
    )
    print("| scenario | rule | false decisions [95 % MC] | right decisions | mean tasks |")
    print("|---|---|---|---|---|")
    results = []
    tic = time.perf_counter()
    for label, rates, budget, batch, shared in SCENARIOS:
        for name, rule in RULES.items():
            s = simulate(rule, rates, looks(budget, batch), args.studies, args.seed, shared)
            right = _rate(s.right, s.studies, s.interval(s.right)) if len(set(rates)) > 1 else "–"
            print(
                f"| {label} | {name} | {_rate(s.false, s.studies, s.interval(s.false))} | "
                f"{right} | {s.mean_tasks:.0f} |",
                flush=True,
            )
            results.append(
                {
                    "scenario": label,
                    "rule": name,
                    "studies": s.studies,
                    "false": s.false,
                    "right": s.right,
                    "mean_tasks": s.mean_tasks,
                }
            )
    print(f"\n{time.perf_counter() - tic:.0f} s")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2), encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
