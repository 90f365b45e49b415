"""Cost of the offline-optimal reference: per task, per generator, and its share of a study.

    python benchmarks/bench_reference.py --tasks 40 [--config configs/studies/arms.yaml]
    python benchmarks/bench_reference.py --tasks 0 --workers 2     # the whole study
    python benchmarks/bench_reference.py --tasks 200 --check 20    # + independent re-solve
    python benchmarks/bench_reference.py --stored DIR --check 40   # check a stored study only
    python benchmarks/bench_reference.py --stored DIR --compare BASE  # verdicts of DIR vs BASE
    python benchmarks/bench_reference.py --stored DIR --certificates 40  # recompute 40 certificates

Scales the study's generator counts to about ``--tasks`` tasks in total (0: the study as
shipped), runs it into a fresh directory (``--workers 1``: in-process; more: an embedded
Dask LocalCluster) and reports, from the stored rows and the run's outcome:

* per robot × generator: tasks, reference labels (achievable / unachievable / undecided /
  failed), the median gap ``upper − lower`` [tolerances], median / p90 / max wall time of one
  reference [s] (the ``reference.seconds`` column);
* the study's compute (sum of the chunks' compute times on their workers [s]), the
  references' part of it and their share (target: ≤ 35 % on ``configs/studies/arms.yaml``);
* with ``--check N``: an independent re-solve of ``N`` sampled tasks (every ``k``-th oracle row)
  by a second method (:func:`otmm_qp.reference.independent.slsqp_upper`, SLSQP from the
  damped-IK start and from the stored reference's best start), and how many it improves by
  more than 5 % (target: ≤ 5 % of them);
* per robot × generator, the certificates of its unachievable tasks by kind (``reach``,
  ``travel``, ``turn``, ``search``, ``coupled``: :mod:`otmm_qp.reference.certificates`);
  with ``--certificates N``: ``N`` sampled certificates recomputed from their definition,
  and how many give the stored lower bound to the last bit;
* with ``--compare BASE``: what the study's references change against a stored study ``BASE``
  of the same tasks and controllers (another polish cap, another solver), judged as the report
  judges (:func:`compare`).
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

from otmm_qp.reference import LABELS  # noqa: E402
from otmm_qp.studies.execute import run_study  # noqa: E402
from otmm_qp.studies.schema import StudyConfig  # noqa: E402
from otmm_qp.studies.spec import load_study, plan_study  # noqa: E402
from otmm_qp.studies.storage import read_episodes  # noqa: E402

#: Up to this many joint variables SLSQP takes every sample as a knot; above, every 5th.
KNOT_VARIABLES = 300
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
        kinds: dict[str, int] = defaultdict(int)
        for r in group:
            statuses[str(r["reference.status"])] += 1
            if r["reference.status"] == "unachievable":
                kinds[str(r.get("reference.certificate") or "none").split("@")[0]] += 1
        gaps = [
            float(r["reference.upper"]) - float(r["reference.lower"])
            for r in group
            if r.get("reference.upper") is not None and r.get("reference.lower") is not None
        ]
        table[name] = {
            "tasks": len(group),
            "status": dict(statuses),
            "certificates": dict(sorted(kinds.items())),
            "median_gap": statistics.median(gaps) if gaps else float("nan"),
            "median_s": statistics.median(seconds) if seconds else float("nan"),
            "p90_s": float(np.percentile(seconds, 90)) if seconds else float("nan"),
            "max_s": max(seconds) if seconds else float("nan"),
            "total_s": sum(seconds),
        }
    return table


def certificate_check(
    config: StudyConfig, rows: list[dict[str, Any]], count: int
) -> dict[str, Any]:
    """Recompute ``count`` stored certificates (every ``k``-th task that has one) from their
    definition (:func:`otmm_qp.reference.certificates.recompute`); count exact matches."""
    from otmm_qp.reference.certificates import recompute
    from otmm_qp.reference.problem import TrackingProblem
    from otmm_qp.studies.oracle import reference_settings
    from otmm_qp.studies.tradeoff import rebuild_task

    held = [r for r in rows if str(r.get("reference.certificate") or "none") != "none"]
    if count <= 0 or not held:
        return {"tasks": 0, "exact": 0, "kinds": {}}
    chosen = held[:: max(1, len(held) // count)][:count]
    exact = 0
    kinds: dict[str, int] = defaultdict(int)
    for row in chosen:
        robot, _, task, duration = rebuild_task(config, row)
        problem = TrackingProblem(
            robot, task.trajectory, task.q0, config.dt, duration, reference_settings(config)
        )
        exact += recompute(problem, str(row["reference.certificate"])) == row["reference.lower"]
        kinds[str(row["reference.certificate"]).split("@")[0]] += 1
    return {"tasks": len(chosen), "exact": exact, "kinds": dict(sorted(kinds.items()))}


def independent_check(
    config: StudyConfig, rows: list[dict[str, Any]], count: int
) -> dict[str, Any]:
    """Re-solve ``count`` evenly sampled tasks by SLSQP; how often it beats ``upper`` by > 5 %.

    Also counted: improvements by more than 5 % *and* more than ``SETTLE`` = 0.01 tolerances
    (the resolution the reference refines to: below it no verdict changes), and those on the
    tasks not ``achievable``, the only ones whose upper end is optimised (an achievable task
    keeps the first path that meets every tolerance: a lower upper changes nothing there).

    Each task is rebuilt as the study built it; SLSQP starts from the damped-IK path and from
    the task's own joint path when it has one (the best of the two is kept), with a knot at
    every sample up to :data:`KNOT_VARIABLES` joint variables, else every 5th sample.
    """
    from otmm_qp.reference.independent import slsqp_upper
    from otmm_qp.reference.problem import TrackingProblem
    from otmm_qp.reference.solve import SETTLE
    from otmm_qp.reference.warm_start import damped_ik_path, joint_path_start
    from otmm_qp.studies.oracle import reference_settings
    from otmm_qp.studies.tradeoff import rebuild_task

    sample = rows[:: max(1, len(rows) // count)][:count] if count > 0 else []
    ratios: list[float] = []
    resolved: list[bool] = []
    open_: list[bool] = []  # not achievable: the upper end matters (an achievable task's does not)
    for row in sample:
        robot, _, task, duration = rebuild_task(config, row)
        problem = TrackingProblem(
            robot, task.trajectory, task.q0, config.dt, duration, reference_settings(config)
        )
        starts = [damped_ik_path(problem)]
        given = joint_path_start(problem, task.trajectory)
        if given is not None:
            starts.append(given)
        stride = 1 if problem.samples * problem.nv <= KNOT_VARIABLES else 5
        other = min(slsqp_upper(problem, start, stride) for start in starts)
        upper = float(row["reference.upper"])
        ratios.append((upper - other) / upper if upper > 0 else 0.0)
        resolved.append(upper - other > max(0.05 * upper, SETTLE))
        open_.append(row.get("reference.status") != "achievable")
    matter = [r for r, o in zip(ratios, open_, strict=True) if o]
    return {
        "tasks": len(ratios),
        "improved": sum(r > 0.05 for r in ratios),
        "improved_beyond_resolution": sum(resolved),
        "not_achievable": len(matter),
        "improved_not_achievable": sum(r > 0.05 for r in matter),
        "largest_not_achievable": max(matter, default=0.0),
        "largest": max(ratios, default=0.0),
        "ratios": ratios,
    }


#: A stored value counts as moved when it is more than this fraction above the base's.
MOVED = 0.05


def compare(base: Path, other: Path) -> dict[str, Any]:
    """What the references of ``other`` change against those of ``base`` (same tasks, rows).

    Both studies are read as the report reads them (:func:`otmm_qp.studies.rows.load_rows`:
    success re-judged against each study's own references, oracle-relative error only
    within the limits). Counted over the tasks and controller rows both hold:

    * ``success_changed``: controller rows whose ``success`` differs (of ``rows``);
    * ``labels_changed``: tasks whose ``reference.status`` differs (of ``tasks``), and
      ``labels``: ``"base → other"`` → count;
    * ``groups_changed``: (robot, report task group) whose set of tasks differs (of
      ``groups``);
    * ``accuracy_changed``: (robot, all rows or one task group) whose first pick of the
      paired-Wilcoxon accuracy verdict differs (of ``accuracy``);
    * on the ``not_achievable`` tasks of ``base``: how often ``reference.upper`` and the
      position optimum ``reference.max_error`` [m] of ``other`` are more than :data:`MOVED`
      above the base's (``upper_moved``, ``position_moved``) and below it
      (``upper_improved``, ``position_improved``);
    * ``relative_shift``: median and largest ``|Δ oracle-relative error|`` [m] over the
      controller rows where both are defined (``relative_rows``);
    * ``unpassed``: per study (``base``, ``other``), tasks no known path passes (neither a
      controller row nor the oracle row succeeds: the report's bracket table).
    """
    from otmm_qp.studies.rows import Rows, load_rows
    from otmm_qp.studies.verdicts import accuracy_verdict, bracket_summary, task_groups

    _, rows_a = load_rows(base)
    _, rows_b = load_rows(other)

    def split(rows: Rows) -> tuple[dict[str, Any], dict[tuple[str, str], Any]]:
        oracle = {r["task_id"]: r for r in rows.rows if r["controller"] == "oracle"}
        own = {(r["task_id"], r["controller"]): r for r in rows.rows if r["controller"] != "oracle"}
        return oracle, own

    oracle_a, own_a = split(rows_a)
    oracle_b, own_b = split(rows_b)
    tasks = sorted(oracle_a.keys() & oracle_b.keys())
    keys = sorted(own_a.keys() & own_b.keys())
    success = sum(bool(own_a[k]["success"]) != bool(own_b[k]["success"]) for k in keys)
    labels: dict[str, int] = defaultdict(int)
    for task in tasks:
        was, now = oracle_a[task]["reference.status"], oracle_b[task]["reference.status"]
        if was != now:
            labels[f"{was} → {now}"] += 1
    groups = accuracy = groups_changed = accuracy_changed = 0
    for robot in rows_a.robots():
        kinds_a = {g.label: g for g in task_groups(rows_a, robot)}
        kinds_b = {g.label: g for g in task_groups(rows_b, robot)}
        oracle_rows = [r for r in rows_a.rows if r["controller"] == "oracle"]
        oracle_rows_b = [r for r in rows_b.rows if r["controller"] == "oracle"]
        selections = [(Rows(rows_a.rows), Rows(rows_b.rows))]
        for label, group in kinds_a.items():
            groups += 1
            other_group = kinds_b.get(label)
            members_b = {r["task_id"] for r in other_group.rows} if other_group else set()
            groups_changed += {r["task_id"] for r in group.rows} != members_b
            if other_group is not None:
                selections.append(
                    (Rows(group.rows + oracle_rows), Rows(other_group.rows + oracle_rows_b))
                )
        for selected_a, selected_b in selections:
            top_a = accuracy_verdict(selected_a, robot).top
            top_b = accuracy_verdict(selected_b, robot).top
            if not top_a and not top_b:
                continue
            accuracy += 1
            accuracy_changed += top_a[:1] != top_b[:1]
    hard = [t for t in tasks if oracle_a[t]["reference.status"] != "achievable"]

    def moved(column: str) -> int:
        return sum(
            float(oracle_b[t][column]) > (1.0 + MOVED) * float(oracle_a[t][column]) for t in hard
        )

    def improved(column: str) -> int:
        return sum(
            float(oracle_b[t][column]) < (1.0 - MOVED) * float(oracle_a[t][column]) for t in hard
        )

    unpassed = {
        name: sum(
            line.unpassed
            for robot in rows.robots()
            for line in bracket_summary(rows, robot)
            if line.kind == "all tasks"
        )
        for name, rows in (("base", rows_a), ("other", rows_b))
    }
    shifts = [
        abs(float(own_b[k]["oracle_relative_error"]) - float(own_a[k]["oracle_relative_error"]))
        for k in keys
        if own_a[k].get("oracle_relative_error") is not None
        and own_b[k].get("oracle_relative_error") is not None
    ]
    return {
        "tasks": len(tasks),
        "rows": len(keys),
        "success_changed": success,
        "labels_changed": sum(labels.values()),
        "labels": dict(labels),
        "groups": groups,
        "groups_changed": groups_changed,
        "accuracy": accuracy,
        "accuracy_changed": accuracy_changed,
        "not_achievable": len(hard),
        "upper_moved": moved("reference.upper"),
        "position_moved": moved("reference.max_error"),
        "upper_improved": improved("reference.upper"),
        "position_improved": improved("reference.max_error"),
        "relative_rows": len(shifts),
        "relative_shift_median": statistics.median(shifts) if shifts else 0.0,
        "relative_shift_max": max(shifts, default=0.0),
        "unpassed": unpassed,
    }


def _print_compare(numbers: dict[str, Any], base: Path) -> None:
    print(f"against {base}: success changed on {numbers['success_changed']} of "
          f"{numbers['rows']} rows; labels changed on {numbers['labels_changed']} of "
          f"{numbers['tasks']} tasks {numbers['labels'] or ''}; task groups changed "
          f"{numbers['groups_changed']} of {numbers['groups']}; accuracy first pick changed "
          f"{numbers['accuracy_changed']} of {numbers['accuracy']}; on the "
          f"{numbers['not_achievable']} tasks not achievable upper / position optimum "
          f"> {100 * MOVED:.0f} % higher on {numbers['upper_moved']} / "
          f"{numbers['position_moved']}, > {100 * MOVED:.0f} % lower on "
          f"{numbers['upper_improved']} / {numbers['position_improved']}; "
          f"|Δ oracle-relative error| median "
          f"{numbers['relative_shift_median']:.3g} m, largest "
          f"{numbers['relative_shift_max']:.3g} m ({numbers['relative_rows']} rows); tasks no "
          f"known path passes: {numbers['unpassed']['base']} (base) / "
          f"{numbers['unpassed']['other']}")  # fmt: skip


def _check_stored(
    out: Path, count: int, target: Path | None, base: Path | None = None, certificates: int = 0
) -> int:
    """The labels table and the independent checks of the study stored in ``out``."""
    from otmm_qp.studies.storage import read_study_folder

    config, _ = read_study_folder(out)
    table = read_episodes(out)
    rows = [
        r for r in (table.to_pylist() if table is not None else []) if r["controller"] == "oracle"
    ]
    check = independent_check(config, rows, count)
    recomputed = certificate_check(config, rows, certificates)
    groups = summarise(rows)
    print(f"{out}: {len(rows)} tasks (stored)")
    _print_check(check)
    _print_certificates(groups, recomputed)
    numbers: dict[str, Any] = {"groups": groups, "check": check, "certificates": recomputed}
    if base is not None:
        numbers["compare"] = compare(base, out)
        _print_compare(numbers["compare"], base)
    if target is not None:
        target.write_text(json.dumps(numbers, indent=2))
    return 0


def _print_check(check: dict[str, Any]) -> None:
    if check["tasks"]:
        print(f"independent SLSQP re-solve of {check['tasks']} tasks: improves upper by > 5 % "
              f"on {check['improved']} ({100 * check['improved'] / check['tasks']:.0f} %; "
              f"{check['improved_beyond_resolution']} also by > 0.01 tolerances), "
              f"largest improvement {100 * check['largest']:.1f} %; on the "
              f"{check['not_achievable']} not achievable (where the upper end matters; an "
              f"achievable task stops at its first path within tolerance): "
              f"{check['improved_not_achievable']}, largest "
              f"{100 * check['largest_not_achievable']:.1f} %")  # fmt: skip


def _print_certificates(groups: dict[str, Any], check: dict[str, Any]) -> None:
    kinds: dict[str, int] = defaultdict(int)
    for group in groups.values():
        for kind, count in group["certificates"].items():
            kinds[kind] += count
    listed = ", ".join(f"{kind} {count}" for kind, count in sorted(kinds.items()))
    print(f"certificates of unachievable tasks: {listed or 'none'}")
    if check["tasks"]:
        print(f"certificates recomputed from their definition: {check['exact']} of "
              f"{check['tasks']} give the stored bound exactly ({check['kinds']})")  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark and print (and optionally write) its numbers."""
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--tasks", type=int, default=40, help="about this many tasks; 0: all")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    parser.add_argument("--check", type=int, default=0, help="re-solve this many tasks by SLSQP")
    parser.add_argument(
        "--certificates", type=int, default=0, help="recompute this many stored certificates"
    )
    parser.add_argument("--out", type=Path, help="keep the study here (default: a temp dir)")
    parser.add_argument(
        "--stored", type=Path, help="read this stored study instead of running one (--check only)"
    )
    parser.add_argument(
        "--compare", type=Path, help="a stored study of the same tasks to compare verdicts with"
    )
    args = parser.parse_args(argv)
    if args.stored is not None:
        return _check_stored(args.stored, args.check, args.json, args.compare, args.certificates)
    if args.compare is not None and args.out is None:
        parser.error("--compare needs --out (the run is read back from it)")
    config = scaled(args.config, args.tasks)
    plan = plan_study(config, str(args.config))
    with tempfile.TemporaryDirectory() as scratch:
        out = args.out if args.out is not None else Path(scratch) / "study"
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
        "check": independent_check(config, rows, args.check),
        "certificates": certificate_check(config, rows, args.certificates),
    }
    if args.compare is not None and args.out is not None:
        results["compare"] = compare(args.compare, args.out)
    print(f"{args.config.name}: {results['tasks']} tasks, {outcome.ran} episodes, "
          f"workers {args.workers}, wall {outcome.seconds:.1f} s")  # fmt: skip
    print("| robot/generator | tasks | achievable / unachievable / undecided / failed "
          "| median gap | median s | p90 s | max s |")  # fmt: skip
    print("|---|---|---|---|---|---|---|")
    for name, group in results["groups"].items():
        status = group["status"]
        counts = "/".join(str(status.get(s, 0)) for s in LABELS)
        gap, times = group["median_gap"], (group[k] for k in ("median_s", "p90_s", "max_s"))
        print(f"| {name} | {group['tasks']} | {counts} | {gap:.3g} | "
              + " | ".join(f"{t:.3f}" for t in times) + " |")  # fmt: skip
    _print_check(results["check"])
    _print_certificates(results["groups"], results["certificates"])
    print(f"reference {reference_s:.1f} s of {outcome.compute_seconds:.1f} s compute "
          f"= {100 * results['reference_share']:.1f} % "
          f"({results['per_task_s']:.3f} s per task)")  # fmt: skip
    if args.compare is not None:
        _print_compare(results["compare"], args.compare)
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
