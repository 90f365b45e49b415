"""Studies that size themselves: ``decide: {budget_tasks: N, batch: M}`` instead of a count.

The generators' ``count`` s become weights: ``N`` tasks per robot are split over them in
proportion (at least one each, largest remainders, :func:`split`), and that is the study the
folder holds (its id, its episode keys). The tasks are run in batches: after batch ``k`` the
first ``split(min(k·M, N))`` tasks of each generator are stored, every kind of task of every
robot is judged as the report judges it, and batching stops as soon as each kind that has
tasks is *decided* (:func:`decided`: one row better than every other on success, exact
McNemar, Holm) or the budget is spent; which of the two happened is printed and written to
``decision.md``. A task's seed depends on its index only, so batches extend one sequence of
tasks: a rerun resumes from the stored episodes and takes the same decisions (bit for bit, as
every study episode is reproducible).
"""

from __future__ import annotations

import math
import sys
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING

from otmm_qp.output.paths import atomic_write_text
from otmm_qp.studies.schema import DecideRule

if TYPE_CHECKING:
    from otmm_qp.studies.execute import StudyOutcome
    from otmm_qp.studies.schema import StudyConfig
    from otmm_qp.studies.spec import StudyPlan

__all__ = [
    "DecideRule",
    "Decision",
    "budget_config",
    "decided",
    "run_decided",
    "run_decided_study",
    "split",
]


def split(total: int, weights: list[int]) -> list[int]:
    """``total`` tasks over generators in proportion to ``weights`` (≥ 1 each when it can).

    One each first (while ``total`` allows), then the rest by largest remainders; sums to
    ``total``.
    """
    base = [1 if i < total else 0 for i in range(len(weights))]
    rest = total - sum(base)
    raw = [w * rest / sum(weights) for w in weights]
    counts = [b + math.floor(r) for b, r in zip(base, raw, strict=True)]
    order = sorted(range(len(raw)), key=lambda i: (raw[i] - math.floor(raw[i]), -i), reverse=True)
    for i in order[: total - sum(counts)]:
        counts[i] += 1
    return counts


def budget_config(config: StudyConfig, rule: DecideRule) -> StudyConfig:
    """The study at its full budget: each generator's count its share of ``budget_tasks``."""
    counts = split(rule.budget_tasks, [g.count for g in config.generators])
    generators = [
        g.model_copy(update={"count": c}) for g, c in zip(config.generators, counts, strict=True)
    ]
    return config.model_copy(update={"generators": generators})


def decided(group_rows: list[dict[str, object]]) -> str | None:
    """The row better than every other on success in a kind of task (Holm), or None."""
    from otmm_qp.studies.statistics import paired_ranking, paired_success
    from otmm_qp.studies.verdicts import success_flags

    flags = success_flags(group_rows)
    if len(flags) < 2:
        return None
    rates = {name: sum(f.values()) / len(f) if f else 0.0 for name, f in flags.items()}
    ranking = paired_ranking(rates, paired_success(flags), higher_is_better=True)
    top = [r for r in ranking if r.rank == 1]
    if len(top) != 1:
        return None
    best = top[0].name
    return best if all(best in r.beaten_by for r in ranking if r.name != best) else None


@dataclass
class Decision:
    """Where batching stopped: tasks per robot run, and each kind's pick (None: undecided)."""

    tasks: int
    budget: int
    picks: dict[tuple[str, str], str | None] = field(default_factory=dict)

    @property
    def done(self) -> bool:
        """Every kind of task with tasks has a decided verdict."""
        return bool(self.picks) and all(p is not None for p in self.picks.values())

    def lines(self) -> list[str]:
        """The Markdown lines of ``decision.md``."""
        head = (
            f"Decided every kind of task after {self.tasks} tasks per robot (budget {self.budget})."
            if self.done
            else f"Budget spent: {self.tasks} of {self.budget} tasks per robot run; "
            "some kinds of task are still undecided."
        )
        body = [
            f"- {robot} / {kind}: "
            + (f"**{pick}** beats every other row on success" if pick else "undecided")
            for (robot, kind), pick in sorted(self.picks.items())
        ]
        return [head, "", *body]


def judge(out: Path, tasks: int, budget: int) -> Decision:
    """Each robot's kinds of task in the stored study, decided or not."""
    from otmm_qp.studies.report import load_rows, task_groups

    _, rows = load_rows(out)
    decision = Decision(tasks, budget)
    for robot in rows.robots():
        for group in task_groups(rows, robot):
            if group.rows:
                decision.picks[(robot, group.label)] = decided(group.rows)
    return decision


def run_decided(
    config: StudyConfig,
    rule: DecideRule,
    out: Path,
    run_batch: Callable[[StudyConfig, int, list[int]], bool],
) -> Decision:
    """Run batches until every kind of task is decided or the budget is spent.

    Args:
        config: The study at its full budget (:func:`budget_config`).
        rule: The ``decide`` block.
        out: The study folder.
        run_batch: Runs the first ``limits[g]`` tasks of each generator ``g`` (``batch`` is
            the batch number from 1); False when interrupted or failed (batching stops).

    Returns:
        The last judgement (also written to ``out/decision.md``).
    """
    weights = [g.count for g in config.generators]
    batches = math.ceil(rule.budget_tasks / min(rule.batch, rule.budget_tasks))
    decision = Decision(0, rule.budget_tasks)
    for batch in range(1, batches + 1):
        tasks = min(batch * rule.batch, rule.budget_tasks)
        if not run_batch(config, batch, split(tasks, weights)):
            break
        decision = judge(out, tasks, rule.budget_tasks)
        undecided = [f"{r}/{k}" for (r, k), p in decision.picks.items() if p is None]
        print(
            f"batch {batch}: {tasks} tasks per robot; "
            + (f"undecided: {', '.join(undecided)}" if undecided else "every kind decided"),
            file=sys.stderr,
        )
        if decision.done:
            break
    atomic_write_text(out / "decision.md", "# Decision\n\n" + "\n".join(decision.lines()) + "\n")
    return decision


def batch_plan(plan: StudyPlan, limits: list[int]) -> StudyPlan:
    """``plan`` with only the episodes of each generator's first ``limits[g]`` tasks."""
    return replace(plan, episodes=[e for e in plan.episodes if e.task_index < limits[e.generator]])


def run_decided_study(
    plan: StudyPlan,
    rule: DecideRule,
    out: Path,
    source: str,
    workers: int | None,
    scheduler: str | None,
    force: bool,
) -> StudyOutcome:
    """:func:`run_decided` over ``run_study``: the batches' outcomes summed into one.

    ``force`` applies to the first batch only (later batches extend the same study).
    """
    from otmm_qp.studies.execute import StudyOutcome, run_study

    total = StudyOutcome(total=0, skipped_stored=0)

    def run_batch(_: StudyConfig, batch: int, limits: list[int]) -> bool:
        outcome = run_study(
            batch_plan(plan, limits), out, source, workers, scheduler, force and batch == 1
        )
        total.total = outcome.total
        total.skipped_stored += outcome.skipped_stored if batch == 1 else 0
        total.ran += outcome.ran
        total.failed += outcome.failed
        total.steps += outcome.steps
        total.seconds += outcome.seconds
        total.compute_seconds += outcome.compute_seconds
        total.interrupted = outcome.interrupted
        return not (outcome.interrupted or outcome.failed)

    decision = run_decided(plan.config, rule, out, run_batch)
    print(decision.lines()[0])
    return total
