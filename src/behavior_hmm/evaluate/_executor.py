"""One executor for all batch work: in this process, in local processes, or on Ray.

Every batch job (the cases of an evaluation, the rows of an experiment, the seeds of a
report) is a list of independent tasks, each a picklable ``(function, argument)`` whose
seed comes from the run's seed and the task's identity, never from shared state. So the
results are identical whatever runs them: :class:`SerialExecutor` (one after another),
:class:`ProcessExecutor` (``--workers N`` local processes, the default) or
:class:`RayExecutor` (``--executor ray [--address ADDR]``; ``pip install
'behavior-hmm[ray]'``; Ray is imported only here, only when asked for). ``map`` returns
the results in task order and reports progress as tasks finish, whichever worker ran them.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Protocol, TypeVar

from behavior_hmm.errors import ConfigError

T = TypeVar("T")
R = TypeVar("R")
Progress = Callable[[int, int], None]

#: Environment variables that cap the BLAS / OpenMP threads of a worker process.
_THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: Executor names of ``--executor``.
EXECUTORS = ("local", "ray")


class Executor(Protocol):
    """Runs independent tasks; results in task order."""

    workers: int

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], progress: Progress | None = None
    ) -> list[R]:
        """``[fn(task) for task in tasks]``, progress reported as tasks finish."""
        ...


class SerialExecutor:
    """Every task in this process, one after another (``--workers 1``)."""

    workers = 1

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], progress: Progress | None = None
    ) -> list[R]:
        out = []
        for done, task in enumerate(tasks, start=1):
            out.append(fn(task))
            if progress is not None:
                progress(done, len(tasks))
        return out


class ProcessExecutor:
    """Tasks in ``workers`` local processes (``--workers N``; fresh interpreters, "spawn").

    A function and its tasks must be picklable (module-level functions, data and
    fitted models are). One task or one worker runs in this process instead.
    """

    def __init__(self, workers: int | None = None) -> None:
        self.workers = default_workers() if workers is None else check_workers(workers)

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], progress: Progress | None = None
    ) -> list[R]:
        if self.workers == 1 or len(tasks) <= 1:
            return SerialExecutor().map(fn, tasks, progress)
        import multiprocessing

        out: list[Any] = [None] * len(tasks)
        context = multiprocessing.get_context("spawn")  # no forked MuJoCo or Ray state
        # one BLAS thread per worker: N workers each running OpenBLAS's own threads would
        # oversubscribe the cores (measured: no faster than one process); the children
        # read these when they import numpy
        saved = {key: os.environ.get(key) for key in _THREAD_VARIABLES}
        os.environ.update(dict.fromkeys(_THREAD_VARIABLES, "1"))
        try:
            with ProcessPoolExecutor(
                max_workers=min(self.workers, len(tasks)), mp_context=context
            ) as pool:
                futures = {pool.submit(fn, task): i for i, task in enumerate(tasks)}
                for done, future in enumerate(as_completed(futures), start=1):
                    out[futures[future]] = future.result()
                    if progress is not None:
                        progress(done, len(tasks))
        finally:
            for key, value in saved.items():
                if value is None:
                    os.environ.pop(key, None)
                else:
                    os.environ[key] = value
        return out


class RayExecutor:
    """Tasks on a Ray cluster (``address``) or a local Ray started here (no address)."""

    def __init__(self, address: str | None = None, workers: int | None = None) -> None:
        try:
            import ray
        except ImportError:
            raise ConfigError("--executor ray needs Ray: pip install 'behavior-hmm[ray]'") from None
        self._ray = ray
        if not ray.is_initialized():
            options: dict[str, Any] = {
                "include_dashboard": False,
                "log_to_driver": False,
                "configure_logging": False,
            }
            # one BLAS thread per task, as for local processes
            options["runtime_env"] = {"env_vars": dict.fromkeys(_THREAD_VARIABLES, "1")}
            if address:
                options["address"] = address
            elif workers is not None:
                options["num_cpus"] = check_workers(workers)
            try:
                ray.init(**options)
            except Exception as err:  # an unreachable address, a bad cluster: one line
                raise ConfigError(
                    f"cannot start or reach Ray ({address or 'local'}): {err}"
                ) from None
        self.workers = int(ray.cluster_resources().get("CPU", 1))

    def map(
        self, fn: Callable[[T], R], tasks: Sequence[T], progress: Progress | None = None
    ) -> list[R]:
        ray = self._ray
        remote = ray.remote(fn)
        refs = [remote.remote(task) for task in tasks]
        pending, done = list(refs), 0
        while pending:
            ready, pending = ray.wait(pending, num_returns=1)
            done += len(ready)
            if progress is not None:
                progress(done, len(tasks))
        return list(ray.get(refs))


def map_largest_first(
    executor: Executor,
    fn: Callable[[T], R],
    tasks: Sequence[T],
    sizes: Sequence[float],
    progress: Progress | None = None,
) -> list[R]:
    """``executor.map(fn, tasks, progress)`` with the tasks handed out largest first.

    Workers take tasks in the order given; a large task handed out last runs on alone
    while the other workers idle. ``sizes`` are estimates of the tasks' costs (any
    comparable numbers; equal sizes keep their order). Results come back in task order
    and do not depend on the sizes: every task's seed comes from its identity.
    """
    order = sorted(range(len(tasks)), key=lambda i: -sizes[i])
    done = executor.map(fn, [tasks[i] for i in order], progress)
    by_task = dict(zip(order, done, strict=True))
    return [by_task[i] for i in range(len(tasks))]


#: Environment variable that overrides ``--workers``' default (e.g. 1 in a test session or
#: on a shared login node).
WORKERS_VARIABLE = "BEHAVIOR_HMM_WORKERS"


def default_workers() -> int:
    """What ``--workers`` defaults to: ``$BEHAVIOR_HMM_WORKERS``, else this machine's cores."""
    value = os.environ.get(WORKERS_VARIABLE, "").strip()
    if value:
        workers = int(value) if value.isdigit() else 0
        if not 1 <= workers <= 1024:
            raise ConfigError(f"{WORKERS_VARIABLE} must be an integer in [1, 1024], got {value!r}")
        return workers
    return max(
        1, len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    )


def check_workers(workers: int) -> int:
    """Refuse a worker count below 1 or beyond 1024."""
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= 1024:
        raise ConfigError(f"--workers must be an integer in [1, 1024], got {workers!r}")
    return workers


def make_executor(
    name: str = "local", *, workers: int | None = None, address: str | None = None
) -> Executor:
    """The executor ``--executor NAME [--workers N] [--address ADDR]`` asks for."""
    if name == "local":
        if address:
            raise ConfigError("--address is for --executor ray")
        return ProcessExecutor(workers)
    if name == "ray":
        return RayExecutor(address, workers)
    raise ConfigError(f"unknown executor '{name}'; choose one of {', '.join(EXECUTORS)}")
