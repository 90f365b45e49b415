"""Study execution overhead and scaling: serial vs an embedded Dask LocalCluster.

    python benchmarks/bench_study.py --tasks 100 [--config configs/studies/arms.yaml]

Scales the study's generator counts to about ``--tasks`` tasks in total (generators whose
share rounds to zero are left out), runs it (1) in-process without Dask and (2) on a LocalCluster of
``--workers`` processes (default 2), each into a fresh directory, and reports:

* episode compute: the sum of the chunks' compute times on their workers [s];
* scheduling + storage overhead of the serial run: (wall − compute) / compute;
* Dask overhead: (workers × wall − compute) / compute, with and without the cluster start;
* throughput [episodes/s] of both and the speed-up Dask / serial (same study, same run).
"""

from __future__ import annotations

from otmm_qp.blas_threads import prefer_single_threaded_blas

prefer_single_threaded_blas()  # before NumPy loads: one BLAS thread, as the CLI runs

import argparse  # noqa: E402
import json  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from otmm_qp.studies.execute import dask_client, run_study  # noqa: E402
from otmm_qp.studies.schema import StudyConfig  # noqa: E402
from otmm_qp.studies.spec import load_study, plan_study  # noqa: E402

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "configs" / "studies" / "arms.yaml"


def scaled(config_path: Path, tasks: int) -> StudyConfig:
    config = load_study(config_path)
    total = sum(g.count for g in config.generators) * len(config.robots)
    factor = tasks / total
    generators = [
        dict(g.model_dump(), count=round(g.count * factor))
        for g in config.generators
        if round(g.count * factor) > 0
    ] or [dict(config.generators[0].model_dump(), count=1)]
    data = config.model_dump(mode="json")
    data["generators"] = generators
    data["time_series"] = {"tasks": 0, "stride": 5}
    return config.model_validate(data)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", type=int, default=100)
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--json", type=Path, help="also write the numbers here")
    args = parser.parse_args(argv)
    plan = plan_study(scaled(args.config, args.tasks), str(args.config))
    results: dict[str, object] = {
        "config": str(args.config),
        "tasks": len({(e.robot, e.generator, e.task_index) for e in plan.episodes}),
        "episodes": len(plan.episodes),
        "chunk_size": plan.config.chunk_size,
        "workers": args.workers,
    }
    with tempfile.TemporaryDirectory() as scratch:
        serial = run_study(plan, Path(scratch) / "serial", "bench", workers=1)
        tic = time.perf_counter()
        with dask_client(args.workers, None) as client:
            startup = time.perf_counter() - tic
            client.run(lambda: None)
            distributed = run_study(
                plan, Path(scratch) / "dask", "bench", workers=args.workers, client=client
            )
    steps = serial.steps
    results.update(
        steps=steps,
        serial_wall_s=serial.seconds,
        serial_compute_s=serial.compute_seconds,
        serial_overhead=(serial.seconds - serial.compute_seconds) / serial.compute_seconds,
        serial_episodes_per_s=serial.ran / serial.seconds,
        serial_steps_per_s=steps / serial.seconds,
        dask_startup_s=startup,
        dask_wall_s=distributed.seconds,
        dask_compute_s=distributed.compute_seconds,
        dask_overhead=(args.workers * distributed.seconds - distributed.compute_seconds)
        / distributed.compute_seconds,
        dask_episodes_per_s=distributed.ran / distributed.seconds,
        dask_steps_per_s=distributed.steps / distributed.seconds,
        speedup=serial.seconds / distributed.seconds,
        speedup_with_startup=serial.seconds / (distributed.seconds + startup),
    )
    width = max(len(k) for k in results)
    for key, value in results.items():
        shown = f"{value:.4g}" if isinstance(value, float) else str(value)
        print(f"{key:<{width}}  {shown}")
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
