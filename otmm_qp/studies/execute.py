"""Run a study in-process, on an embedded Dask ``LocalCluster`` or on an existing scheduler.

``workers=1`` runs without Dask; results stream into the Parquet dataset chunk by chunk.

The driver alone writes the dataset. A chunk's rows are written once, when its future
completes; Dask re-runs the chunk of a worker that dies, and the driver still receives one
result per chunk, so every episode is stored exactly once.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
import time
from collections.abc import Callable, Generator, Iterator
from contextlib import closing, contextmanager, suppress
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from otmm_qp import interrupt
from otmm_qp.studies.columns import task_reference
from otmm_qp.studies.episodes import ChunkResult, WorkUnit, run_chunk
from otmm_qp.studies.reach_store import store_reaches
from otmm_qp.studies.scheduler import SchedulerUnreachable, probe_scheduler
from otmm_qp.studies.spec import StudyPlan
from otmm_qp.studies.storage import (
    EPISODES,
    PartWriter,
    prepare_directory,
    read_study,
    stored_keys,
    study_id,
    write_marker,
)
from otmm_qp.studies.task import PlannedEpisode, StudyTask

#: Seconds allowed to connect to an external scheduler.
CONNECT_TIMEOUT = 10.0
#: Dask settings of the embedded LocalCluster's workers: no stack profiler or GIL monitor, and
#: event-loop housekeeping at 1-2 s instead of 20-500 ms (each wake-up takes the GIL from the
#: running episode). See docs/studies.md for the measured effect of each.
QUIET_WORKERS = {
    "distributed.worker.profile.enabled": False,
    "distributed.admin.system-monitor.gil.enabled": False,
    "distributed.admin.tick.interval": "1s",
    "distributed.admin.system-monitor.interval": "2s",
    "distributed.worker.memory.monitor-interval": "1s",
}


@dataclass
class StudyOutcome:
    """What a study run did.

    Attributes:
        total: Episodes in the study.
        skipped_stored: Episodes already in the dataset (not rerun).
        ran: Episodes run and stored now.
        failed: Of those, episodes with ``status != "ok"``.
        steps: Control steps simulated now.
        seconds: Wall time of the run [s].
        compute_seconds: Sum of the chunks' compute times on their workers [s].
        interrupted: Stopped by Ctrl-C / SIGTERM.
    """

    total: int
    skipped_stored: int
    ran: int = 0
    failed: int = 0
    steps: int = 0
    seconds: float = 0.0
    compute_seconds: float = 0.0
    interrupted: bool = False


def make_chunks(
    plan: StudyPlan,
    done: set[str],
    references: dict[StudyTask, tuple[tuple[str, Any], ...]] | None = None,
) -> list[list[WorkUnit]]:
    """Group the missing episodes by task, then tasks into chunks of ``chunk_size``.

    Tasks are ordered by index first (round-robin over robots and generators). A task whose
    reference row is stored already carries its ``reference.*`` columns (``references``,
    from :func:`stored_references`), so its new rows are judged with the stored reference.
    """
    config = plan.config
    by_task: dict[StudyTask, list[PlannedEpisode]] = {}
    for episode in plan.episodes:
        if episode.key not in done:
            by_task.setdefault(episode.task, []).append(episode)
    references = references or {}
    units = [
        WorkUnit(
            task,
            tuple(episodes),
            time_series=task.index < config.time_series.tasks,
            reference=references.get(task),
        )
        for task, episodes in by_task.items()
    ]
    # Round-robin over robots and generators, so a partial dataset covers all of them.
    units.sort(key=lambda u: (u.task.index, u.task.robot, u.task.generator))
    size = config.chunk_size
    return [units[i : i + size] for i in range(0, len(units), size)]


def stored_references(
    plan: StudyPlan, done: set[str], out: Path, ident: str
) -> dict[StudyTask, tuple[tuple[str, Any], ...]]:
    """``task → reference.* columns`` of the tasks with a stored reference and missing rows.

    Their new rows are judged with the stored reference (``--resume``).
    """
    missing = {e.task for e in plan.episodes if e.key not in done}
    tasks = {e.key: e.task for e in plan.episodes if e.is_reference and e.key in done}
    wanted = {key for key, task in tasks.items() if task in missing}
    if not wanted:
        return {}
    data = read_study(out, EPISODES, ident, wanted)
    rows = [] if data.table is None else data.table.to_pylist()
    return {tasks[r["episode_key"]]: tuple(sorted(task_reference(r).items())) for r in rows}


def payload_of(plan: StudyPlan) -> dict[str, Any]:
    """Payload sent with each chunk (config + controllers + a digest for worker caches)."""
    payload = plan.payload()
    text = json.dumps(payload, sort_keys=True, default=str)
    payload["digest"] = hashlib.sha256(text.encode()).hexdigest()
    return payload


ProgressHook = Callable[[int, int], None]


def _serial(payload: dict[str, Any], chunks: list[list[WorkUnit]]) -> Iterator[ChunkResult]:
    for chunk in chunks:
        yield run_chunk(payload, chunk)


@contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A Dask client: to ``scheduler`` or to a fresh ``LocalCluster`` of ``workers`` processes.

    Raises:
        SchedulerUnreachable: No scheduler answers at ``scheduler`` within
            :data:`CONNECT_TIMEOUT`.
    """
    import dask
    from distributed import Client

    if scheduler is not None:
        try:
            with dask.config.set({"distributed.comm.timeouts.connect": f"{CONNECT_TIMEOUT}s"}):
                client = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError, ValueError) as error:
            raise SchedulerUnreachable(
                f"--scheduler: cannot reach a Dask scheduler at {scheduler!r} within "
                f"{CONNECT_TIMEOUT:g} s ({type(error).__name__})"
            ) from None
        try:
            yield client
        finally:
            client.close()
        return
    with _local_cluster(workers) as client:
        yield client


#: Preload module of the embedded cluster's workers (they ignore SIGINT; the driver stops them).
WORKER_PRELOAD = "otmm_qp.studies.worker_signals"


@contextmanager
def _local_cluster(workers: int | None) -> Iterator[Any]:
    """A client of a fresh ``LocalCluster``, started and closed with stop signals deferred.

    SIGTERM/SIGINT while the cluster starts or closes is acted on once it is fully up or
    fully closed (a KeyboardInterrupt inside ``LocalCluster`` start-up printed an ``atexit``
    AssertionError); the workers ignore SIGINT (:data:`WORKER_PRELOAD`), so Ctrl-C in a
    terminal is one line from the driver, not a traceback per worker; a worker it kills while
    still starting makes the start an interrupt.
    """
    import dask
    from distributed import Client, LocalCluster

    cluster: Any = None
    client: Any = None
    settings = {**QUIET_WORKERS, "distributed.worker.preload": [WORKER_PRELOAD]}
    try:
        with interrupt.deferred_stop_signals(spawning=True):
            try:
                with dask.config.set(settings):  # the Nanny hands it to the workers it spawns
                    cluster = LocalCluster(
                        n_workers=workers or os.cpu_count() or 1,
                        threads_per_worker=1,
                        processes=True,
                        dashboard_address=":0",  # never the shared default 8787
                        silence_logs=50,
                    )
                client = Client(cluster)
            except Exception:
                # Ctrl-C reaches a worker still starting, before its preload ignores SIGINT:
                # it dies and the cluster fails to start ("Nanny failed to start") — an
                # interrupt, not an error (the watcher records the stop as the signal lands).
                if interrupt.requested():
                    raise KeyboardInterrupt from None
                raise
        yield client
    finally:
        with suppress(KeyboardInterrupt), interrupt.deferred_stop_signals():
            if client is not None:
                client.close()
            if cluster is not None:
                cluster.close()


def _distributed(
    client: Any, payload: dict[str, Any], chunks: list[list[WorkUnit]]
) -> Generator[ChunkResult, None, None]:
    from distributed import as_completed

    # In a list, so the payload is one object under a fresh key: a scattered *dict* becomes
    # one future per value, keyed by the dict's own keys ("config", ...), and a second study on
    # the same client then raced the release of the first one's (lost dependencies).
    shared = client.scatter([payload], broadcast=True, hash=False)[0]
    futures = [
        client.submit(
            run_chunk, shared, chunk, pure=False, retries=3, key=f"chunk-{i}-{time.time_ns()}"
        )
        for i, chunk in enumerate(chunks)
    ]
    try:
        for future in as_completed(futures):
            yield future.result()
    finally:
        with suppress(Exception):  # the client may already be closing (Ctrl-C)
            client.cancel(futures)


def run_study(
    plan: StudyPlan,
    out: Path,
    source: str,
    workers: int | None = None,
    scheduler: str | None = None,
    force: bool = False,
    progress: ProgressHook | None = None,
    client: Any = None,
    notices: set[str] | None = None,
) -> StudyOutcome:
    """Run the episodes of ``plan`` not yet stored in ``out``.

    Args:
        plan: The validated study.
        out: Output directory.
        source: Study file (recorded in ``study.json``).
        workers: Worker processes; 1 runs in this process without Dask; None = cores.
        scheduler: Address of an existing Dask scheduler (``tcp://host:port``).
        force: Replace the dataset of another study in ``out``.
        progress: Called with ``(episodes finished now, failures now)`` after each chunk.
        client: An open Dask client to use instead of starting one (benchmarks reuse one).
        notices: Reasons of "resume ignored" notices printed already in this run (each is
            printed once; updated).

    Returns:
        The outcome; an interrupt (Ctrl-C, SIGTERM) returns with ``interrupted = True``
        after every finished chunk is stored.
    """
    from otmm_qp.output.folders import claim_folder

    if scheduler is not None and client is None:
        scheduler = probe_scheduler(scheduler, CONNECT_TIMEOUT)  # before the folder is touched
    with claim_folder(out, "study", force):
        return _run_claimed(
            plan, out, source, force, client, (workers, scheduler), progress, notices
        )


def _run_claimed(
    plan: StudyPlan,
    out: Path,
    source: str,
    force: bool,
    client: Any,
    where: tuple[int | None, str | None],
    progress: ProgressHook | None,
    notices: set[str] | None = None,
) -> StudyOutcome:
    """:func:`run_study` in the claimed (locked) folder ``out``."""
    config = plan.config
    dumped = config.model_dump(mode="json")
    prepare_directory(out, dumped, force)
    ident = study_id(dumped)
    keys = {e.key for e in plan.episodes}
    stored = stored_keys(out, ident, keys)
    done = set() if stored.table is None else set(stored.table.column("episode_key").to_pylist())
    shown = set() if notices is None else notices
    for line in stored.ignored:
        reason = line.split(" ", 1)[-1]  # "<count> <reason>": once per reason
        if reason not in shown:
            print(f"otmm-qp: resume ignored {line}", file=sys.stderr)
        shown.add(reason)
    outcome = StudyOutcome(total=len(plan.episodes), skipped_stored=len(done))
    written: set[str] = set(done)
    tic = time.perf_counter()
    # From the marker on, a stop signal is an interrupted study (every finished episode
    # stored), also while the chunks are made (reading the stored references takes a while).
    try:
        with interrupt.handle_stop_signals():  # the one stop-signal path (nested in the CLI's)
            _write_study_marker(out, plan, source, ident)
            store_reaches(config, out)  # stored with the study, before any episode runs
            chunks = make_chunks(plan, done, stored_references(plan, done, out, ident))
            payload = payload_of(plan)
            writer = PartWriter(out, ident, plan.task_columns)

            def consume(results: Iterator[ChunkResult]) -> None:
                _store_results(results, writer, written, outcome, progress)

            _feed_chunks(consume, payload, chunks, where[0], where[1], client)
            interrupt.check()  # a stop that library code swallowed: the study still stopped
    except KeyboardInterrupt:
        outcome.interrupted = True
    outcome.seconds = time.perf_counter() - tic
    return outcome


def _write_study_marker(out: Path, plan: StudyPlan, source: str, ident: str) -> None:
    """Write ``study.json``: the study, its id, source, config, controllers and episode keys."""
    config = plan.config
    write_marker(
        out,
        {
            "study": config.name,
            "study_id": ident,
            "episode_keys": sorted(e.key for e in plan.episodes),
            "source": source,
            "config": config.model_dump(mode="json"),
            "controllers": [c.name for c in plan.controllers],
            "skipped_controllers": [{"name": n, "reason": r} for n, r in plan.skipped],
            "episodes": len(plan.episodes),
        },
    )


def _store_results(
    results: Iterator[ChunkResult],
    writer: PartWriter,
    written: set[str],
    outcome: StudyOutcome,
    progress: ProgressHook | None,
) -> None:
    """Write each chunk's episodes not yet in ``written`` and count them into ``outcome``."""
    for result in results:
        rows = [r for r in result.rows if r["episode_key"] not in written]
        written.update(r["episode_key"] for r in rows)
        fresh = {r["episode_key"] for r in rows}
        series = [s for s in result.series if s["episode_key"] and s["episode_key"][0] in fresh]
        writer.write(rows, series)
        failed = sum(1 for r in rows if r.get("status") != "ok")
        outcome.ran += len(rows)
        outcome.compute_seconds += result.seconds
        outcome.failed += failed
        outcome.steps += sum(int(r.get("steps") or 0) for r in rows)
        if progress is not None:
            progress(len(rows), failed)
        interrupt.check()  # a stop Python dropped (raised in a finaliser) ends the study here


def _feed_chunks(
    consume: Callable[[Iterator[ChunkResult]], None],
    payload: dict[str, Any],
    chunks: list[list[WorkUnit]],
    workers: int | None,
    scheduler: str | None,
    client: Any,
) -> None:
    """Run ``chunks`` on ``client``, in this process, or on a new Dask client; ``consume`` them."""
    if client is not None:
        with closing(_distributed(client, payload, chunks)) as results:
            consume(results)
    elif scheduler is None and workers == 1:
        consume(_serial(payload, chunks))
    elif chunks or scheduler is not None:
        with dask_client(workers, scheduler) as client:
            # closed (its futures cancelled) before the client is, also on Ctrl-C
            with closing(_distributed(client, payload, chunks)) as results:
                consume(results)
