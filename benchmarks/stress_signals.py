"""Stress the stop-signal path: interrupt studies with SIGINT and SIGTERM at random times.

Each run starts ``otmm-qp study`` (``--workers 1``; every fifth run ``--workers 2``, an
embedded Dask cluster) on a small planar study with the offline reference and an
OSQP row (tasks generated, controllers run, references solved, parts and the report written),
sends SIGINT (to the process group, as Ctrl-C in a terminal) or SIGTERM (to the process, as a
batch system) at a uniformly random time over ``--span`` × a run's length (measured once at the
start, an embedded cluster's taken as twice that), and checks:

* the answer: exit 130 and exactly one line (``otmm-qp: interrupted…``), no traceback — or
  exit 0 when the study had already finished (every episode stored);
* the dataset: no temporary file, every part readable, no episode key twice;
* then a resume run (no signal) exits 0 and stores every episode exactly once (none lost).

Usage (one core; ~15 min for 50 runs on a loaded 2-core machine)::

    python benchmarks/stress_signals.py --runs 50 --seed 3 --span 0.7 > stress.txt
"""

from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import pyarrow.parquet as pq
import yaml

STUDY = {
    "name": "stress",
    "seed": 1,
    "dt": 0.02,
    "loop_modes": ["clik"],
    "clik_gain": 10.0,
    "duration": {"extra": 0.5},
    "chunk_size": 1,
    "robots": [{"name": "planar2", "robot": {"type": "planar", "link_lengths": [1.0, 0.8]}}],
    "generators": [
        {"type": "near_singular", "count": 2, "distance": [0.0, 0.1]},
        {"type": "joint_path", "count": 1},
    ],
    "controllers": [
        {"name": "pinv", "backend": {"type": "pinv"}},
        {"name": "dls", "backend": {"type": "dls", "damping": 0.05}},
        {"name": "qp-osqp", "backend": {"type": "qp", "solver": "osqp"}},
    ],
    "reference": {"time_budget": 2.0},
}
#: In-process runs; every fifth run on an embedded Dask cluster of two workers.
WORKERS = (1, 2)
LINES = (
    ["otmm-qp: interrupted; every finished episode is stored (rerun to resume)"],
    ["otmm-qp: interrupted"],
)


def _study(config: Path, out: Path, workers: int = 1) -> list[str]:
    command = [sys.executable, "-m", "otmm_qp.cli", "study", str(config), "--out", str(out)]
    return [*command, "--workers", str(workers)]


def _stored(out: Path) -> tuple[list[str], list[str]]:
    """(episode keys of every part, problems: temporary files, unreadable parts)."""
    problems = [f"temporary file {p.name}" for p in out.rglob("*.tmp")]
    keys: list[str] = []
    for part in sorted((out / "episodes").glob("**/*.parquet")):
        try:
            keys += pq.read_table(part, columns=["episode_key"]).column(0).to_pylist()
        except Exception as error:  # noqa: BLE001 - a half-written part is what we look for
            problems.append(f"unreadable {part.name}: {type(error).__name__}")
    return keys, problems


def main() -> int:
    """Run the stress test; print one line per run and a summary; exit 1 on any failure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--span", type=float, default=1.1, help="signal times: uniform over span × baseline"
    )
    args = parser.parse_args()
    rng = random.Random(args.seed)
    work = Path(tempfile.mkdtemp(prefix="otmm-stress-"))
    config = work / "stress.yaml"
    config.write_text(yaml.safe_dump(STUDY))
    lengths = {}
    for workers in WORKERS[:1]:
        tic = time.perf_counter()
        out = work / f"baseline{workers}"
        baseline = subprocess.run(_study(config, out, workers), capture_output=True, text=True)
        lengths[workers] = time.perf_counter() - tic
        total = len(set(_stored(out)[0]))
        print(
            f"baseline --workers {workers}: exit {baseline.returncode}, {total} episodes, "
            f"{lengths[workers]:.1f} s",
            flush=True,
        )
        if baseline.returncode != 0:
            print(baseline.stderr[-2000:])
            return 1
    lengths[WORKERS[1]] = 2.0 * lengths[WORKERS[0]]  # a cluster's start-up: about as long again
    tally: Counter[str] = Counter()
    for run in range(args.runs):
        signum = (signal.SIGINT, signal.SIGTERM)[run % 2]
        workers = WORKERS[1] if run % 5 == 4 else WORKERS[0]
        out = work / f"run{run}"
        delay = rng.uniform(0.0, args.span * lengths[workers])
        process = subprocess.Popen(
            _study(config, out, workers), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            start_new_session=True,
        )  # fmt: skip
        time.sleep(delay)
        if process.poll() is None:
            if signum == signal.SIGINT:
                os.killpg(process.pid, signum)  # Ctrl-C: the whole foreground group
            else:
                process.send_signal(signum)
        _, err = process.communicate(timeout=300)
        keys, problems = _stored(out)
        lines = err.strip().splitlines()
        finished = len(set(keys)) == total
        if "Traceback" in err:
            problems.append("traceback")
        if len(keys) != len(set(keys)):
            problems.append(f"{len(keys) - len(set(keys))} duplicated episodes")
        if process.returncode == 130:
            outcome = "interrupted"
            if lines not in LINES:
                problems.append(f"stderr {lines[:3]!r}")
        elif process.returncode == 0 and finished:
            outcome = "finished"
        else:
            outcome = f"exit {process.returncode}"
            problems.append(f"exit {process.returncode} with {len(set(keys))}/{total} stored")
        resume = subprocess.run([*_study(config, out), "--no-report"], capture_output=True)
        after, resumed_problems = _stored(out)
        problems += [f"after resume: {p}" for p in resumed_problems]
        if resume.returncode != 0 or sorted(after) != sorted(set(after)) or len(after) != total:
            problems.append(f"resume: exit {resume.returncode}, {len(after)} rows of {total}")
        if problems:
            (work / f"run{run}.stderr").write_text(err)
            print("    " + "\n    ".join(lines[-12:]), flush=True)
        tally[outcome] += 1
        tally["failed runs"] += bool(problems)
        name = signal.Signals(signum).name
        print(
            f"run {run:2d} {name} --workers {workers} at {delay:5.2f} s: {outcome}, "
            f"{len(set(keys))}/{total} stored; {'; '.join(problems) or 'ok'}",
            flush=True,
        )
    print(
        f"runs {args.runs}: interrupted {tally['interrupted']}, finished {tally['finished']}, "
        f"failed {tally['failed runs']}"
    )
    return 1 if tally["failed runs"] else 0


if __name__ == "__main__":
    sys.exit(main())
