"""Studies that size themselves: ``decide: {budget_tasks: N, batch: M}`` instead of a count.

The generators' ``count`` s become weights: ``N`` tasks per robot are split over them in
proportion (at least one each, largest remainders, :func:`split`). The tasks are run in
batches: after batch ``k`` the first ``split(min(k·M, N))`` tasks of each generator are
stored, and each robot is judged on **all** its tasks — the study's task mix, the one answer
for the arm — by the anytime-valid test of :mod:`otmm_qp.studies.sequential` (a row that
beats every other on success, whatever the number of looks). Batching stops as soon as every
robot is decided, the budget is spent, or the run is interrupted; which of the three is
printed and written to ``decision.md``, with a breakdown per generator and the tasks that
could not be generated. ``budget_tasks`` and ``batch`` are not part of the study's identity
(:func:`otmm_qp.studies.storage.study_id`): raising the budget resumes from the stored
episodes, lowering it judges their prefix. A task's seed depends on its index only, so
batches extend one sequence of tasks: a rerun resumes and takes the same decisions.
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from otmm_qp.paths import atomic_write_text
from otmm_qp.studies import sequential, verdicts
from otmm_qp.studies.limit_keeping import limit_breaks
from otmm_qp.studies.rows import task_of
from otmm_qp.studies.schema import DecideRule
from otmm_qp.studies.sequential import SequentialVerdict

if TYPE_CHECKING:
    from otmm_qp.studies.execute import ProgressHook, StudyOutcome
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
    ``total``. At ``total = sum(weights)`` the share is ``weights`` itself, so a study's
    last batch (weights: :func:`budget_config`'s counts) runs every task of its budget.
    """
    if total == sum(weights):
        return list(weights)
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


#: Columns the judgement reads (not the whole folder through the report).
JUDGED_COLUMNS = [
    "controller",
    "robot",
    "generator",
    "generator_params",
    "task_index",
    "task_id",
    "loop_mode",
    "success",
    "status",
    "error_message",
    "failure_causes",
]
#: Prefix of the ``error_message`` of a task its generator could not build.
GENERATION = "task generation:"


def decided(group_rows: list[dict[str, object]]) -> str | None:
    """The row that beats every other on success by the anytime test (:func:`judge_rows`)."""
    return sequential.pick(success_flags(group_rows)).pick


def is_generation_failure(row: dict[str, Any]) -> bool:
    """The row of a task its generator could not build (an error row with its reason)."""
    return str(row.get("error_message") or "").startswith(GENERATION)


@dataclass
class Decision:
    """Where batching stopped and the decision for each arm.

    Attributes:
        tasks: Tasks per robot run.
        budget: ``budget_tasks``.
        arms: ``robot → decision`` over all of its tasks (the task mix of the generators'
            weights): the one answer for the arm, and the stopping rule's.
        kinds: ``(robot, generator) → decision`` on that generator's tasks: the breakdown
            (the same test, descriptive: no stopping rule is on it).
        generation_failures: ``robot → tasks its generators could not build``.
        limit_breaks: ``robot → (pick's episodes breaking the arm's limits, its episodes)``.
        stop: ``"decided"``, ``"group"`` (:meth:`settled` without a pick on some robot),
            ``"budget"`` or ``"interrupted"``.
        seconds_per_task: Wall time per task per robot of the last batch [s] (the progress
            line's estimate; not in ``decision.md``, which a rerun reproduces).
    """

    tasks: int
    budget: int
    arms: dict[str, SequentialVerdict] = field(default_factory=dict)
    kinds: dict[tuple[str, str], SequentialVerdict] = field(default_factory=dict)
    generation_failures: dict[str, int] = field(default_factory=dict)
    limit_breaks: dict[str, tuple[int, int]] = field(default_factory=dict)
    stop: str = "budget"
    seconds_per_task: float = math.nan

    @property
    def done(self) -> bool:
        """Every robot has a decided arm verdict."""
        return bool(self.arms) and all(v.decided for v in self.arms.values())

    def settled(self, robot: str) -> bool:
        """Decided, or a group beats every other row and the budget is not expected to split it.

        The group's claims are the pick's family (anytime-valid); stopping for futility —
        no estimate, or one past the budget — changes no error rate, only saves tasks.
        """
        verdict = self.arms[robot]
        if verdict.decided:
            return True
        needed = self.needed(robot)
        return len(verdict.group) > 1 and (needed is None or needed > self.budget)

    @property
    def all_settled(self) -> bool:
        """Every robot is :meth:`settled`."""
        return bool(self.arms) and all(self.settled(r) for r in self.arms)

    def head(self) -> str:
        """The first line: how the batching stopped."""
        if self.stop == "interrupted":
            return (
                f"Interrupted after {self.tasks} of {self.budget} tasks per robot "
                "(rerun to resume: every stored episode is kept)."
            )
        if self.done:
            return f"Decided after {self.tasks} tasks per robot (budget {self.budget})."
        if self.stop == "group":
            return (
                f"Stopped after {self.tasks} tasks per robot (budget {self.budget}): on every "
                "robot a row, or a group of rows, beats every other row, and the budget is not "
                "expected to separate the group."
            )
        return (
            f"Budget spent: {self.tasks} of {self.budget} tasks per robot run; "
            "no decision for "
            + ", ".join(r for r, v in sorted(self.arms.items()) if not v.decided)
            + "."
        )

    def needed(self, robot: str) -> int | None:
        """About how many tasks in all ``robot``'s decision needs (None: no estimate)."""
        verdict = self.arms[robot]
        if verdict.decided or not verdict.evidence:
            return None
        counts = [sequential.tasks_to_decide(ev) for ev in verdict.evidence if not ev.beaten]
        return (
            None if any(c is None for c in counts) else max((c for c in counts if c), default=None)
        )

    def arm_line(self, robot: str) -> str:
        """The decision for ``robot`` in plain words (no bold pick unless decided and kept)."""
        return arm_sentence(
            robot, self.arms[robot], self.limit_breaks.get(robot), self.needed(robot)
        )

    def estimate(self, robot: str, pace: bool = False) -> str:
        """`` Still needed: about N more tasks.`` when undecided (``pace``: and the minutes)."""
        needed = self.needed(robot)
        if needed is None or self.arms[robot].decided:
            return ""
        more = max(needed - self.tasks, 0)
        minutes = more * self.seconds_per_task / 60
        at = f" ({minutes:.2g} min at the last batch's pace)" * (pace and math.isfinite(minutes))
        return f" Still needed: about {more} more tasks{at}."

    def lines(self) -> list[str]:
        """The Markdown lines of ``decision.md``."""
        out = [self.head(), ""]
        for robot in sorted(self.arms):
            out.append(f"- {self.arm_line(robot)}{self.estimate(robot)}")
            for (r, kind), verdict in sorted(self.kinds.items()):
                if r == robot:
                    out.append(f"  - {kind_sentence(kind, verdict)}")
            failures = self.generation_failures.get(robot, 0)
            if failures:
                out.append(
                    f"  - {failures} task(s) could not be generated: recorded as error rows "
                    "with their reason, counted in the budget, left out of the paired counts."
                )
        return [*out, "", GUARANTEE, BREAKDOWN]


#: What the decision guarantees (the same sentence in decision.md and the report).
GUARANTEE = (
    "The decision is the anytime-valid mixture test on the tasks only one of two rows "
    "succeeds on (Bonferroni over every ordered pair of rows, α = 0.05): the chance that it "
    "ever names a row not truly better than every other is at most 5 %, whenever the study "
    "stops (after any batch, or at the budget; docs/studies.md, 'Deciding')."
)
#: What the per-generator lines of decision.md are.
BREAKDOWN = (
    "The per-generator lines (the task mix, known before a task is run) use the same test as "
    "a breakdown: no stopping rule is on them."
)


def _pct(rate: float) -> str:
    return f"{100 * rate:.0f} %"


def _claim(ev: sequential.PairEvidence) -> str:
    low, high = ev.share
    return (
        f"{ev.leader} alone succeeds on {ev.leader_only} tasks, {ev.other} alone on "
        f"{ev.other_only} (E = {ev.e_value:.3g}, needs ≥ {ev.needed:.3g}; anytime p = "
        f"{ev.p_anytime:.2g}; {ev.leader}'s share of those tasks {low:.2f}–{high:.2f})"
    )


def arm_sentence(
    robot: str,
    verdict: SequentialVerdict,
    breaks: tuple[int, int] | None = None,
    needed: int | None = None,
) -> str:
    """One sentence: the controller to run on ``robot`` for the study's task mix, or why not.

    A pick that breaks the arm's limits on most of its episodes (``breaks``) is said, not
    bolded.
    """
    head = f"**{robot}** (all {verdict.tasks} tasks, the study's task mix): "
    if verdict.leader is None:
        return head + "no rows."
    rates = ", ".join(
        f"{n} {_pct(verdict.rates[n])}"
        for n in sorted(verdict.rates, key=lambda n: (-verdict.rates[n], n))
    )
    closest = verdict.evidence[0] if verdict.evidence else None
    if verdict.pick is not None and closest is not None:
        broken, total = breaks or (0, 0)
        if total and 2 * broken > total:
            return head + (
                f"{verdict.pick} beats every other row on success but breaks the arm's limits "
                f"on {broken} of {total} episodes: no row to run is named (success {rates})."
            )
        return head + (
            f"run **{verdict.pick}**: it beats every other row on success ({rates}); against "
            f"the closest, {closest.other}, {_claim(closest)}."
        )
    if closest is None:
        return head + f"only {verdict.leader} ran ({rates})."
    lacking = [ev for ev in verdict.evidence if not ev.beaten]
    if len(verdict.group) > 1:
        differ = ", ".join(
            f"{ev.other} on {ev.leader_only + ev.other_only}"
            for ev in verdict.evidence
            if ev.other in verdict.group
        )
        return head + (
            f"undecided between {', '.join(verdict.group)}: each beats every other row on "
            f"success, not each other ({rates}); {verdict.leader} differs from {differ} of "
            f"{verdict.tasks} tasks. Any of them is a valid choice over the other rows; more "
            "tasks only choose among them."
            + (f" About {needed} tasks in all would, if these rates hold." if needed else "")
        )
    return head + (
        f"undecided — the leader {verdict.leader} does not yet beat "
        + ", ".join(ev.other for ev in lacking)
        + f" ({rates}); against {lacking[0].other}, {_claim(lacking[0])}."
        + (f" About {needed} tasks in all would decide, if these rates hold." if needed else "")
    )


def kind_sentence(kind: str, verdict: SequentialVerdict) -> str:
    """The breakdown line of one generator's tasks (the same test, descriptive)."""
    rates = ", ".join(
        f"{n} {_pct(verdict.rates[n])}"
        for n in sorted(verdict.rates, key=lambda n: (-verdict.rates[n], n))
    )
    best = [n for n, r in verdict.rates.items() if r == max(verdict.rates.values(), default=0)]
    if verdict.pick:
        state = f"{verdict.pick} beats every other row"
    elif len(verdict.group) > 1:
        state = f"{', '.join(verdict.group)} beat every other row, not each other"
    else:
        state = "undecided" + (f" (highest rate {best[0]})" if len(best) == 1 else "")
    return f"{kind} ({verdict.tasks} tasks): {state}; {rates}."


def success_flags(rows: Sequence[dict[str, Any]]) -> dict[str, dict[tuple[object, ...], bool]]:
    """``controller → {task key → success}`` of the competitor rows, generation failures out."""
    return verdicts.success_flags([r for r in rows if not is_generation_failure(r)])


def judge_rows(rows: Sequence[dict[str, Any]], tasks: int, budget: int) -> Decision:
    """The decision on ``rows`` (a pure function of the rows: the simulation's rule per arm)."""
    decision = Decision(tasks, budget)
    for robot in sorted({str(r["robot"]) for r in rows}):
        own = [r for r in rows if r["robot"] == robot]
        verdict = sequential.pick(success_flags(own))
        decision.arms[robot] = verdict
        for generator in sorted({str(r["generator"]) for r in own}):
            chosen = [r for r in own if r["generator"] == generator]
            decision.kinds[(robot, generator)] = sequential.pick(success_flags(chosen))
        failed = {task_of(r) for r in own if is_generation_failure(r)}
        decision.generation_failures[robot] = len(failed)
        if verdict.pick is not None:
            decision.limit_breaks[robot] = limit_breaks(own, verdict.pick)
    return decision


def judge(out: Path, tasks: int, budget: int) -> Decision:
    """The decision on the study stored in ``out`` (only the judged columns are read)."""
    from otmm_qp.studies.storage import read_episodes

    table = read_episodes(out, JUDGED_COLUMNS)
    rows = [] if table is None else table.to_pylist()
    return judge_rows(rows, tasks, budget)


#: What a batch run reports: finished, or stopped by an interrupt.
BatchStatus = Literal["ok", "interrupted"]


def run_decided(
    config: StudyConfig,
    rule: DecideRule,
    out: Path,
    run_batch: Callable[[StudyConfig, int, list[int]], BatchStatus],
) -> Decision:
    """Run batches until every arm is decided, the budget is spent or the run is interrupted.

    Args:
        config: The study at its full budget (:func:`budget_config`).
        rule: The ``decide`` block.
        out: The study folder.
        run_batch: Runs the first ``limits[g]`` tasks of each generator ``g`` (``batch`` is
            the batch number from 1); ``"interrupted"`` stops the batching (failed episodes
            do not: they are rows, a task that cannot be generated too).

    Batching also stops when every robot is decided or has a group of rows that each beat
    every other row and that the budget is not expected to separate (:meth:`Decision.settled`).

    Returns:
        The last judgement (also written to ``out/decision.md``).
    """
    weights = [g.count for g in config.generators]
    batches = math.ceil(rule.budget_tasks / min(rule.batch, rule.budget_tasks))
    decision = Decision(0, rule.budget_tasks)
    for batch in range(1, batches + 1):
        tic = time.perf_counter()
        tasks = min(batch * rule.batch, rule.budget_tasks)
        try:
            status = run_batch(config, batch, split(tasks, weights))
            if status != "interrupted":
                decision = judge(out, tasks, rule.budget_tasks)
        except KeyboardInterrupt:  # between the batches' stored parts: the same as inside
            status = "interrupted"
        if status == "interrupted":
            decision.stop = "interrupted"
            break
        previous = min((batch - 1) * rule.batch, rule.budget_tasks)
        decision.seconds_per_task = (time.perf_counter() - tic) / max(tasks - previous, 1)
        undecided = [r for r, v in sorted(decision.arms.items()) if not v.decided]
        estimate = " ".join(
            decision.estimate(r, pace=True).strip()
            or f"{r}: no estimate (a rival level with or ahead of the leader)"
            for r in undecided
        )
        print(
            f"batch {batch}: {tasks} tasks per robot; "
            + (f"undecided: {', '.join(undecided)}. {estimate}" if undecided else "decided"),
            file=sys.stderr,
            flush=True,
        )
        if decision.all_settled:
            decision.stop = "decided" if decision.done else "group"
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
    where: tuple[int | None, str | None],
    force: bool,
    progress: ProgressHook | None = None,
) -> StudyOutcome:
    """:func:`run_decided` over ``run_study`` on one executor: the batches summed into one.

    ``where`` is ``(workers, scheduler)``; one Dask client serves every batch (none with
    one worker). ``force`` applies to the first batch only (later batches extend the same
    study); each notice about ignored stored parts is printed once per run (stored rows past
    a batch's tasks are the next batches', not a notice).
    """
    from contextlib import ExitStack

    from otmm_qp.studies.execute import StudyOutcome, dask_client, run_study

    total = StudyOutcome(total=0, skipped_stored=0)
    # a batch's plan holds its own tasks only: the later batches' stored rows are not news
    notices: set[str] = {"rows of episodes not in this study's plan"}
    workers, scheduler = where
    with ExitStack() as stack:

        def run_batch(_: StudyConfig, batch: int, limits: list[int]) -> BatchStatus:
            client = clients[0] if clients else None
            if client is None and not (workers == 1 and scheduler is None):
                clients.append(stack.enter_context(dask_client(workers, scheduler)))
                client = clients[0]
            outcome = run_study(
                batch_plan(plan, limits),
                out,
                source,
                workers,
                scheduler,
                force and batch == 1,
                progress=progress,
                client=client,
                notices=notices,
            )
            total.total = outcome.total
            total.ran += outcome.ran
            # stored before this run: the batch found them, this run's earlier batches aside
            total.skipped_stored = outcome.skipped_stored + outcome.ran - total.ran
            total.failed += outcome.failed
            total.steps += outcome.steps
            total.seconds += outcome.seconds
            total.compute_seconds += outcome.compute_seconds
            total.interrupted = outcome.interrupted
            return "interrupted" if outcome.interrupted else "ok"

        clients: list[Any] = []
        decision = run_decided(plan.config, rule, out, run_batch)
    total.interrupted = total.interrupted or decision.stop == "interrupted"
    print(decision.head())
    for robot in sorted(decision.arms):
        print(f"  {decision.arm_line(robot)}{decision.estimate(robot)}".replace("**", ""))
    return total
