"""Cost of the offline-optimal reference: per task, per generator, and its share of a study.

    python benchmarks/bench_reference.py --tasks 40 [--config configs/studies/arms.yaml]
    python benchmarks/bench_reference.py --tasks 0 --workers 2     # the whole study

Scales the study's generator counts to about ``--tasks`` tasks in total (0: the study as
shipped), runs it into a fresh directory (``--workers 1``: in-process; more: an embedded
Dask LocalCluster) and reports, from the stored rows and the run's outcome:

* per robot × generator: tasks, reference status counts, median / p90 / max wall time of one
  reference [s] (the ``reference.seconds`` column);
* the study's compute (sum of the chunks' compute times on their workers [s]), the
  references' part of it and their share (target: ≤ 30 % on ``configs/studies/arms.yaml``).
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from otmm_qp.studies.execute import run_study  # noqa: E402
from otmm_qp.studies.schema import StudyConfig  # noqa: E402
from otmm_qp.studies.spec import load_study, plan_study  # noqa: E402
from otmm_qp.studies.storage import read_episodes  # noqa: E402

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "configs" / "studies" / "arms.yaml"


def scaled(config_path: Path, tasks: int) -> StudyConfig:
    """The study with its generator counts scaled to about ``tasks`` tasks (0: unchanged)."""
    config = load_study(config_path)
    data = config.model_dump(mode="json")
    data["time_series"] = {"tasks": 0, "stride": 5}
    if tasks > 0:
        total = sum(g.count for g in config.generators) * len(config.robots)
        factor = tasks / total
        generators = [
            dict(g.model_dump(exclude_none=True), count=max(1, round(g.count * factor)))
            for g in config.generators
        ]
        data["generators"] = generators
    return config.model_validate(data)


def summarise(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per robot × generator: tasks, status counts and reference wall times [s]."""
    groups: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for row in rows:
        groups[f"{row['robot']}/{row['generator']}"].append(row)
    table: dict[str, Any] = {}
    for name, group in sorted(groups.items()):
        seconds = [float(r["reference.seconds"]) for r in group if r.get("reference.seconds")]
        statuses: dict[str, int] = defaultdict(int)
        for r in group:
            statuses[str(r["reference.status"])] += 1
        table[name] = {
            "tasks": len(group),
            "status": dict(statuses),
            "median_s": statistics.median(seconds) if seconds else float("nan"),
            "p90_s": float(np.percentile(seconds, 90)) if seconds else float("nan"),
            "max_s": max(seconds) if seconds else float("nan"),
            "total_s": sum(seconds),
        }
    return table


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (and optionally write) its numbers."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--tasks", type=int, default=40, help="about this many tasks; 0: all")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    args = parser.parse_args(argv)
    plan = plan_study(scaled(args.config, args.tasks), str(args.config))
    with tempfile.TemporaryDirectory() as scratch:
        out = Path(scratch) / "study"
        outcome = run_study(plan, out, "bench", workers=args.workers)
        table = read_episodes(out)
        rows = [
            r
            for r in (table.to_pylist() if table is not None else [])
            if r["controller"] == "oracle"
        ]
    reference_s = sum(float(r.get("reference.seconds") or 0.0) for r in rows)
    results: dict[str, Any] = {
        "config": str(args.config),
        "tasks": len(rows),
        "episodes": outcome.ran,
        "workers": args.workers,
        "wall_s": outcome.seconds,
        "compute_s": outcome.compute_seconds,
        "reference_s": reference_s,
        "reference_share": reference_s / outcome.compute_seconds
        if outcome.compute_seconds
        else 0.0,
        "per_task_s": reference_s / len(rows) if rows else float("nan"),
        "groups": summarise(rows),
    }
    print(f"{args.config.name}: {results['tasks']} tasks, {outcome.ran} episodes, "
          f"workers {args.workers}, wall {outcome.seconds:.1f} s")  # fmt: skip
    print("| robot/generator | tasks | feasible / infeasible / failed | median s | p90 s | max s |")
    print("|---|---|---|---|---|---|")
    for name, group in results["groups"].items():
        status = group["status"]
        counts = "/".join(str(status.get(s, 0)) for s in ("feasible", "infeasible", "failed"))
        print(f"| {name} | {group['tasks']} | {counts} | {group['median_s']:.3f} | "
              f"{group['p90_s']:.3f} | {group['max_s']:.3f} |")  # fmt: skip
    print(f"reference {reference_s:.1f} s of {outcome.compute_seconds:.1f} s compute "
          f"= {100 * results['reference_share']:.1f} % "
          f"({results['per_task_s']:.3f} s per task)")  # fmt: skip
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
