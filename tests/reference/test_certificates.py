"""bench_reference's certificate output: kinds per group, recomputed from their definition."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from otmm_qp.studies.execute import run_study
from otmm_qp.studies.spec import parse_study, plan_study
from tests.factories import load_script, reference_study

STUDY = reference_study(
    "bench-certificates",
    seed=4,
    chunk_size=4,
    generators=[
        {"type": "beyond_reach", "count": 2, "duration": [1.0, 1.5]},
        {"type": "random_reachable", "count": 1, "duration": [1.0, 1.5]},
    ],
    controllers=[{"name": "dls", "backend": {"type": "dls"}}],
)


def _bench_reference() -> Any:
    return load_script("benchmarks/bench_reference.py")


def test_stored_certificates_recompute_exactly(tmp_path: Path) -> None:
    out = tmp_path / "study"
    run_study(plan_study(parse_study(STUDY)), out, "test", workers=1)
    numbers_path = tmp_path / "numbers.json"
    module = _bench_reference()
    argv = ["--stored", str(out), "--certificates", "5", "--json", str(numbers_path)]
    assert module.main(argv) == 0
    numbers = json.loads(numbers_path.read_text())
    unachievable = sum(g["status"].get("unachievable", 0) for g in numbers["groups"].values())
    certified = sum(sum(g["certificates"].values()) for g in numbers["groups"].values())
    assert unachievable >= 1 and certified == unachievable  # every label carries its kind
    check = numbers["certificates"]
    assert check["tasks"] >= 1
    assert check["exact"] == check["tasks"]


def test_bench_coupled_planar_labels_every_task(capsys: Any) -> None:
    module = load_script("benchmarks/bench_coupled_planar.py")
    assert module.main(["--tasks", "3"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for line in lines[1:3]:  # without / with: the three tasks, each labelled once
        assert sum(int(part.split()[-1]) for part in line.split(":")[1].split(",")) == 3
