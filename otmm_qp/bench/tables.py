"""The Markdown tables of a benchmark result."""

from __future__ import annotations

from typing import Any

from otmm_qp.output.markdown import Table, table_markdown

STEP_DEFINITION = (
    "floor: the robot's kinematics + Jacobian + one dgesdd, nothing else; "
    "otmm-qp: KinematicState.compute (kinematics + Jacobian + SVD) + Controller.step; "
    "pink / mink / Drake / OInK: the registered adapter's public solve(state, ẋ, q̇_prev) "
    "(the peer's configuration update, task, limits and QP / DiffIK)."
)


def _scenario_lines(scenario: dict[str, Any]) -> list[str]:
    lines = [
        f"### {scenario['name']}",
        "",
        f"{scenario['description']}; a joint bound was active on "
        f"{scenario['bounded_fraction']:.0%} of the recording run's steps.",
        "",
    ]
    headers = ["pipeline", "median µs", "p10 µs", "p90 µs", "p99 µs", "× pink (daqp)", "× floor"]
    cells = [
        [row["pipeline"], *(f"{row[k]:.1f}" for k in ("median_us", "p10_us", "p90_us", "p99_us"))]
        + [f"{row['ratio_to_pink_daqp']:.2f}", f"{row.get('ratio_to_floor', float('nan')):.2f}"]
        for row in sorted(scenario["rows"], key=lambda r: r["median_us"])
    ]
    lines += table_markdown(Table(headers, cells, "lrrrrrr"))
    if scenario["targets"]:
        targets = [
            [check["target"], f"{check['value_us']:.1f}", f"{check['limit_us']:.1f}"]
            + ["yes" if check["met"] else "**no**"]
            for check in scenario["targets"]
        ]
        headers = ["target (medians, same run)", "µs", "limit µs", "met"]
        lines += ["", *table_markdown(Table(headers, targets, "lrrl"))]
    lines += [f"\n_{note}_" for note in scenario["notes"]]
    lines.append("")
    return lines


def markdown(result: dict[str, Any]) -> str:
    """The Markdown tables of a :func:`~otmm_qp.bench.run.run_bench` result."""
    info = result["machine"]
    versions = ", ".join(f"{k} {v}" for k, v in info["versions"].items() if v)
    lines = [
        f"Command: `{result['command']}`  ",
        f"Machine: {info['cpu']}, {info['cores']} cores, load average "
        f"{' / '.join(str(v) for v in info['load_average_1_5_15'])} (1/5/15 min) at the start, "
        f"{' / '.join(str(v) for v in result['load_average_end'])} at the end, "
        f"Python {info['python']}  ",
        f"Libraries: {versions}  ",
        f"One step: {result['step_definition']}  ",
        f"Samples: {result['rounds']} rounds × the state sequence per pipeline, interleaved in "
        f"blocks of {result['block']} consecutive states.",
        "",
    ]
    for scenario in result["scenarios"]:
        lines += _scenario_lines(scenario)
    return "\n".join(lines)
