r"""Per robot × generator verdict of one controller against every other row of a study.

For each group (robot, generator) and each objective (lower is better) — tracking error,
peak joint speed, largest one-step jump — the rows' medians, and paired tests of *ours*
against every other row on the same tasks (Wilcoxon signed-rank, Holm-corrected over all
tests of the group). On an objective *ours* is

* ``better`` than the best other row (lowest median) when the paired difference is negative
  with Holm p < α, ``worse`` when it is positive with Holm p < α, else ``tie``;

and the group verdict is ``dominates`` (no objective worse, at least one better),
``not worse`` (all ties), or ``loses on …``. The Pareto front over the three medians is
listed per group, with whether *ours* is on it. Run::

    python -m otmm_qp.studies.group_verdict DIR --ours NAME [--error rms_error] [--out FILE]
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from otmm_qp.exceptions import OtmmError
from otmm_qp.studies.oracle import REFERENCE_NAME
from otmm_qp.studies.report import Rows, load_rows
from otmm_qp.studies.statistics import PairedResult, holm, paired_test

#: Default objectives: (column, label, unit).
OBJECTIVES = (
    ("rms_error", "RMS error", "m"),
    ("max_joint_speed", "peak joint speed", "rad/s"),
    ("max_jump", "max one-step jump", "rad/s"),
)
#: Significance level of the Holm-corrected paired tests.
ALPHA = 0.05


@dataclass(frozen=True)
class GroupVerdict:
    """The verdict of one robot × generator group.

    Attributes:
        robot: Robot name.
        generator: Generator name.
        medians: ``{controller: (median per objective)}``.
        against_best: Per objective: (best other row, its paired result against ours, outcome).
        pareto: Controllers on the Pareto front of the medians.
        verdict: ``dominates``, ``not worse`` or ``loses on <objectives>``.
    """

    robot: str
    generator: str
    medians: dict[str, tuple[float, ...]]
    against_best: tuple[tuple[str, PairedResult, str], ...]
    pareto: tuple[str, ...]
    verdict: str


def pareto_front(points: dict[str, tuple[float, ...]]) -> list[str]:
    """Names whose points no other point weakly dominates with one strict improvement."""
    front = []
    for name, p in points.items():
        if not all(math.isfinite(v) for v in p):
            continue
        dominated = any(
            all(o <= v for o, v in zip(q, p, strict=True))
            and any(o < v for o, v in zip(q, p, strict=True))
            for other, q in points.items()
            if other != name and all(math.isfinite(v) for v in q)
        )
        if not dominated:
            front.append(name)
    return front


def _values(rows: Rows, robot: str, generator: str, metric: str) -> dict[str, dict[object, float]]:
    out: dict[str, dict[object, float]] = {}
    for row in rows.select(robot=robot, generator=generator):
        if row["controller"] == REFERENCE_NAME:  # the offline reference is not an online competitor
            continue
        value = row.get(metric)
        number = float(value) if isinstance(value, int | float) else math.nan
        if row.get("status") == "error":
            number = math.nan
        out.setdefault(row["controller"], {})[(row["task_index"], row["loop_mode"])] = number
    return out


def group_verdicts(
    rows: Rows, ours: str, objectives: Sequence[str], alpha: float = ALPHA
) -> list[GroupVerdict]:
    """Verdicts of ``ours`` for every robot × generator group (see the module docstring)."""
    if ours not in rows.controllers():
        raise OtmmError(f"--ours: no controller {ours!r} in the study; have {rows.controllers()}")
    groups = list(dict.fromkeys((r["robot"], r["generator"]) for r in rows.rows))
    verdicts = []
    for robot, generator in groups:
        per_metric = [_values(rows, robot, generator, m) for m in objectives]
        names = list(per_metric[0])
        medians = {
            name: tuple(
                float(np.nanmedian(list(v[name].values())))
                if np.isfinite(list(v[name].values())).any()
                else math.nan
                for v in per_metric
            )
            for name in names
        }
        tests: list[tuple[int, str, PairedResult]] = []
        for k, values in enumerate(per_metric):
            mine = values[ours]
            for other in names:
                if other == ours:
                    continue
                keys = sorted(set(mine) & set(values[other]), key=repr)
                a = np.array([mine[key] for key in keys])
                b = np.array([values[other][key] for key in keys])
                tests.append((k, other, paired_test(ours, other, a, b)))
        raw = [t[2].p_value if math.isfinite(t[2].p_value) else 1.0 for t in tests]
        adjusted = holm(raw)
        results = {
            (k, other): PairedResult(**{**r.__dict__, "p_holm": p})
            for (k, other, r), p in zip(tests, adjusted, strict=True)
        }
        against = []
        for k in range(len(objectives)):
            others = [n for n in names if n != ours and math.isfinite(medians[n][k])]
            if not others:
                continue
            best = min(others, key=lambda n: medians[n][k])
            result = results[(k, best)]
            if result.p_holm < alpha and result.median_difference.value < 0:
                outcome = "better"
            elif result.p_holm < alpha and result.median_difference.value > 0:
                outcome = "worse"
            else:
                outcome = "tie"
            against.append((best, result, outcome))
        worse = [objectives[k] for k, (_, _, o) in enumerate(against) if o == "worse"]
        if worse:
            verdict = "loses on " + ", ".join(worse)
        elif any(o == "better" for _, _, o in against):
            verdict = "dominates"
        else:
            verdict = "not worse"
        verdicts.append(
            GroupVerdict(
                robot, generator, medians, tuple(against), tuple(pareto_front(medians)), verdict
            )
        )
    return verdicts


def _fmt(value: float) -> str:
    return "–" if not math.isfinite(value) else f"{value:.3g}"


def render(verdicts: Sequence[GroupVerdict], ours: str, objectives: Sequence[str]) -> str:
    """Markdown: one verdict table, then the medians and Pareto front of each group."""
    lines = [
        f"# `{ours}` against every other row, per robot × generator",
        "",
        "Paired Wilcoxon signed-rank tests on the same tasks, Holm-corrected per group, "
        f"α = {ALPHA}; each objective is compared with the other row of lowest median.",
        "",
        "| robot | generator | "
        + " | ".join(f"{m}: best other (median) → ours, Holm p, outcome" for m in objectives)
        + " | verdict | ours on the Pareto front |",
        "|---|---|" + "---|" * len(objectives) + "---|---|",
    ]
    for v in verdicts:
        cells = []
        for k, (best, result, outcome) in enumerate(v.against_best):
            cells.append(
                f"{best} ({_fmt(v.medians[best][k])}) → {_fmt(v.medians[ours][k])}, "
                f"p={result.p_holm:.2g}, {outcome}"
            )
        on_front = "yes" if ours in v.pareto else "no"
        lines.append(
            f"| {v.robot} | {v.generator} | " + " | ".join(cells) + f" | {v.verdict} | {on_front} |"
        )
    lines += ["", "## Medians and Pareto fronts", ""]
    for v in verdicts:
        lines += [
            f"### {v.robot} / {v.generator}",
            "",
            "| controller | " + " | ".join(objectives) + " | Pareto |",
            "|---|" + "---|" * len(objectives) + "---|",
        ]
        for name, values in v.medians.items():
            mark = "**front**" if name in v.pareto else ""
            label = f"**{name}**" if name == ours else name
            lines.append(f"| {label} | " + " | ".join(_fmt(x) for x in values) + f" | {mark} |")
        lines.append("")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry: print (or write) the verdict report of a study folder."""
    parser = argparse.ArgumentParser(prog="python -m otmm_qp.studies.group_verdict")
    parser.add_argument("study", type=Path)
    parser.add_argument("--ours", required=True)
    parser.add_argument("--error", default="rms_error", help="error column (default rms_error)")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args(argv)
    objectives = [args.error, "max_joint_speed", "max_jump"]
    try:
        rows = load_rows(args.study)[1]
        if args.error not in rows.rows[0]:
            raise OtmmError(f"--error: no column {args.error!r} in the study's episodes")
        text = render(group_verdicts(rows, args.ours, objectives), args.ours, objectives)
    except OtmmError as error:
        print(f"group_verdict: error: {error}", file=sys.stderr)
        return 2
    if args.out is None:
        print(text)
    else:
        from otmm_qp.output.paths import atomic_write_text

        atomic_write_text(args.out, text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
