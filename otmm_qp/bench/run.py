"""``otmm-qp bench``: time every pipeline on recorded states and write the tables."""

from __future__ import annotations

import json
import warnings
from pathlib import Path
from typing import Any

from qpsolvers.warnings import SparseConversionWarning

from otmm_qp.bench.pipelines import build_steps
from otmm_qp.bench.scenarios import Scenario, panda_scenario, planar_scenario
from otmm_qp.bench.tables import STEP_DEFINITION, markdown
from otmm_qp.bench.timing import (
    BLOCK,
    check_targets,
    load_average,
    machine,
    summarise,
    time_pipelines,
)
from otmm_qp.exceptions import ParameterError
from otmm_qp.output.folders import claim_folder
from otmm_qp.paths import atomic_write_text

ROUNDS = 5
#: Fewest replayed states accepted (the percentiles need a few samples per round).
MIN_STEPS = 10
#: Most replayed states accepted (each is recorded up front: ~0.1 MB per state on the Panda).
MAX_STEPS = 100_000
#: Most timing rounds accepted.
MAX_ROUNDS = 1_000


def bench_scenario(scenario: Scenario, full: bool, rounds: int) -> dict[str, Any]:
    """Time every pipeline on ``scenario``; its rows, targets and notes."""
    steps, notes = build_steps(scenario, full)
    rows = summarise(time_pipelines(steps, scenario.steps, rounds))
    return {
        "name": scenario.name,
        "description": scenario.description,
        "bounded_fraction": scenario.bounded_fraction,
        "rows": rows,
        "targets": check_targets(rows),
        "notes": notes,
    }


def run_bench(out: Path, steps: int, rounds: int = ROUNDS, planar_only: bool = False) -> int:
    """Time all pipelines, write ``bench.json`` and ``bench.md`` into ``out``, print the table.

    Args:
        out: Output directory (created).
        steps: Replayed states per scenario (control steps per pass), >= :data:`MIN_STEPS`.
        rounds: Interleaved timing rounds, >= 1.
        planar_only: Time the planar scenario only (a quick check).

    Returns:
        0 (the exit status; unmet targets are reported in the table, not as a failure).

    Raises:
        ParameterError: ``steps`` or ``rounds`` out of range.
        OutputPathError: ``out`` is not a usable bench folder (checked before any timing).
    """
    if not MIN_STEPS <= steps <= MAX_STEPS:
        raise ParameterError("--steps", f"must be in [{MIN_STEPS}, {MAX_STEPS}], got {steps}")
    if not 1 <= rounds <= MAX_ROUNDS:
        raise ParameterError("--rounds", f"must be in [1, {MAX_ROUNDS}], got {rounds}")
    out = Path(out)
    with claim_folder(out, "bench"):
        return _run_claimed(out, steps, rounds, planar_only)


def _run_claimed(out: Path, steps: int, rounds: int, planar_only: bool) -> int:
    """:func:`run_bench` in the claimed (locked, writable) folder ``out``."""
    info = machine()
    with warnings.catch_warnings():
        # qpsolvers warns on every dense-to-sparse conversion for OSQP (pink's path too):
        # the cost is part of what is measured, the repeated text is not useful.
        warnings.simplefilter("ignore", SparseConversionWarning)
        # osqp 1.x warns that solve()'s raise_error default will change (qpsolvers calls it).
        warnings.simplefilter("ignore", PendingDeprecationWarning)
        scenarios = [] if planar_only else [bench_scenario(panda_scenario(steps), True, rounds)]
        scenarios.append(bench_scenario(planar_scenario(steps), False, rounds))
    command = f"otmm-qp bench --out {out} --steps {steps}"
    if rounds != ROUNDS:
        command += f" --rounds {rounds}"
    result = {
        "command": command + (" --planar-only" if planar_only else ""),
        "step_definition": STEP_DEFINITION,
        "rounds": rounds,
        "block": BLOCK,
        "steps": steps,
        "machine": info,
        "load_average_end": load_average(),
        "scenarios": scenarios,
    }
    atomic_write_text(out / "bench.json", json.dumps(result, indent=2) + "\n")
    table = markdown(result)
    atomic_write_text(out / "bench.md", table + "\n")
    print(table)
    return 0
