"""One function over many jobs, results as they finish: in this process, a local process pool, or Ray.

    for index, result, error in run_each(fn, jobs, workers=2, backend="ray", address=None): ...

The local pool (`spawn`, one simulator per worker process) is the default. `ray` runs the same function as Ray
tasks, one CPU each, on a local Ray instance started here (workers = its CPUs) or on the cluster at `address`;
Ray is an optional dependency (`pip install 'tax3d[ray]'`). A job that raises, or whose worker dies, comes back
with its error instead of stopping the others. With `fresh=True` every job runs in a process of its own, on every
backend and with one worker too: a PyBullet process carries state from one world to the next, so an episode's
outcome depends on the episodes its process ran before it, and so on how jobs fell to workers.
"""

from __future__ import annotations

import importlib.util
import multiprocessing
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from typing import Callable, Iterator, Sequence

from tax3d.errors import UsageError

BACKENDS = ("local", "ray")


def check_backend(backend: str, workers: int, address: str | None) -> None:
    if backend not in BACKENDS:
        raise UsageError(f"--backend {backend!r}: expected one of {', '.join(BACKENDS)}")
    if workers < 1:
        raise UsageError(f"--workers {workers}: expected at least 1")
    if address is not None and backend != "ray":
        raise UsageError(f"--address {address}: only used with --backend ray")
    if backend == "ray" and importlib.util.find_spec("ray") is None:
        raise UsageError("--backend ray: Ray is not installed; expected `pip install 'tax3d[ray]'`")


def run_each(fn: Callable, jobs: Sequence, workers: int = 1, backend: str = "local",
             address: str | None = None, fresh: bool = False) -> Iterator[tuple[int, object, BaseException | None]]:
    """Yield (job index, result, None) or (job index, None, error) for every job, in the order they finish; with
    `fresh`, each job in a new process."""
    check_backend(backend, workers, address)
    if backend == "ray":
        yield from _ray(fn, jobs, workers, address, fresh)
    elif workers == 1 and not fresh:
        for i, job in enumerate(jobs):
            try:
                yield i, fn(job), None
            except Exception as err:
                yield i, None, err
    else:
        pool = ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                                   max_tasks_per_child=1 if fresh else None)
        try:
            futures = {pool.submit(fn, job): i for i, job in enumerate(jobs)}
            for future in as_completed(futures):
                try:
                    yield futures[future], future.result(), None
                except BrokenProcessPool:
                    yield futures[future], None, RuntimeError("worker process died")
                except Exception as err:
                    yield futures[future], None, err
        except BaseException:  # Ctrl-C, or the caller stopped early: no job may go on behind its back
            stop(pool)
            raise
        pool.shutdown(wait=True)


def stop(pool: ProcessPoolExecutor) -> None:
    """End a pool at once: drop the jobs not started and terminate the workers, waiting until they are gone."""
    processes = list((pool._processes or {}).values())  # the executor offers no public handle on its workers
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=5)
    # Only now, and waiting: shutdown(wait=False) lets the pool's manager thread run on without its process table
    # and fail with a TypeError of its own when a worker it would replace ends.
    pool.shutdown(wait=True, cancel_futures=True)


def _call(fn: Callable, job):
    return fn(job)


def _ray(fn: Callable, jobs: Sequence, workers: int, address: str | None, fresh: bool = False):
    import ray

    started_here = not ray.is_initialized()
    if started_here:
        if address is None:  # a private local instance sized to the workers asked for
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     object_store_memory=256 * 1024**2)
        else:
            ray.init(address=address, log_to_driver=False)
    try:
        task = ray.remote(num_cpus=1, max_retries=0, **({"max_calls": 1} if fresh else {}))(_call)
        fn_ref = ray.put(fn)
        refs = {task.remote(fn_ref, job): i for i, job in enumerate(jobs)}
        pending = list(refs)
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            try:
                yield refs[done[0]], ray.get(done[0]), None
            except Exception as err:  # a RayTaskError carries the job's own exception; a dead worker raises too
                cause = getattr(err, "cause", None)
                yield refs[done[0]], None, cause if isinstance(cause, BaseException) else err
    finally:
        if started_here:
            ray.shutdown()
