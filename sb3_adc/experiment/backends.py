"""
How a benchmark's runs are carried out: :func:`run_one` trains, resumes or skips one run and reads its results;
:func:`run_local` runs many in a process pool (Ctrl-C and SIGTERM checkpoint runs in progress), :func:`run_ray` on Ray.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
import os
import signal
import threading
import traceback
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from types import FrameType
from typing import TYPE_CHECKING, Any

from sb3_adc.experiment.layout import RunLayout
from sb3_adc.experiment.results import Row, episode_rows, evaluation_rows, final_row

if TYPE_CHECKING:
    from sb3_adc.experiment.benchmark import BenchmarkSettings, RunSpec

#: A run and the settings of its grid: the unit the local and Ray backends schedule.
Job = tuple["RunSpec", "BenchmarkSettings"]


@dataclass
class RunOutcome:
    """
    What a run of the grid produced.

    :param spec: The run
    :param status: ``skipped`` (finished before), ``resumed``, ``trained`` or ``failed``
    :param evaluations: Its evaluation-curve rows
    :param episodes: Its training-episode rows
    :param final: Its final-evaluation row (``None`` if it failed)
    :param error: The traceback of a failed run
    :param log_folder: The log folder of the run's grid (which grid it belongs to when several share a pool)
    """

    spec: RunSpec
    status: str
    evaluations: list[Row] = field(default_factory=list)
    episodes: list[Row] = field(default_factory=list)
    final: Row | None = None
    error: str = ""
    log_folder: str = ""

    @classmethod
    def read(cls, spec: RunSpec, status: str, log_folder: str) -> RunOutcome:
        """
        The outcome of a run with its results read from its folder.

        :param spec: The run
        :param status: Its status
        :param log_folder: Its grid's log folder
        """
        layout = RunLayout(spec.run_dir(log_folder), spec.env_id)
        evaluations, episodes = evaluation_rows(layout, spec.algo, spec.seed), episode_rows(layout, spec.algo, spec.seed)
        return cls(spec, status, evaluations, episodes, final_row(layout, spec.algo, spec.seed), log_folder=log_folder)


def run_one(spec: RunSpec, settings: BenchmarkSettings) -> RunOutcome:
    """
    Train, resume or skip one run, and read back its results. Never raises: a failure is an outcome.

    :param spec: The run
    :param settings: The grid's settings
    """
    from sb3_adc.experiment.training import resume, train

    run_dir = spec.run_dir(settings.log_folder)
    layout = RunLayout(run_dir, spec.env_id)
    try:
        if layout.is_finished():
            status = "skipped"
        elif os.path.isfile(layout.args):
            resume(run_dir, progress_bar=False)
            status = "resumed"
        else:
            train(settings.train_settings(spec))
            status = "trained"
        return RunOutcome.read(spec, status, settings.log_folder)
    except Exception:  # a failed run must not stop the grid
        return RunOutcome(spec, "failed", error=traceback.format_exc(), log_folder=settings.log_folder)


#: In a worker of the local pool: whether a run is in progress, and whether the worker was interrupted (no run starts).
_IN_RUN = threading.Event()
_WORKER_INTERRUPTED = threading.Event()


def _init_worker(handle_signals: bool = False) -> None:
    """
    One torch thread per process (one process per run). With ``handle_signals`` (the local pool; Ray stops its workers
    with SIGTERM itself): Ctrl-C and SIGTERM go to :func:`_interrupt_worker`.
    """
    import torch as th

    th.set_num_threads(1)
    if handle_signals:
        signal.signal(signal.SIGINT, _interrupt_worker)
        signal.signal(signal.SIGTERM, _interrupt_worker)


def _interrupt_worker(signum: int, frame: FrameType | None) -> None:
    """
    Ctrl-C or SIGTERM in a local worker: the run in progress stops as with Ctrl-C (its SIGINT handler saves a
    checkpoint), and no other run starts. An idle worker only takes note (a dead worker would break the pool).
    """
    if signum == signal.SIGTERM and _WORKER_INTERRUPTED.is_set():
        return  # a SIGTERM passed on by the parent after the scheduler's own (Slurm signals every process)
    _WORKER_INTERRUPTED.set()
    handler = signal.getsignal(signal.SIGINT)
    if _IN_RUN.is_set() and callable(handler) and handler is not _interrupt_worker:
        handler(signal.SIGINT, frame)
    elif _IN_RUN.is_set():
        raise KeyboardInterrupt


def _run_local_job(spec: RunSpec, settings: BenchmarkSettings) -> RunOutcome:
    """:func:`run_one` in a worker of the local pool, unless it was interrupted (a ``KeyboardInterrupt`` that pickles)."""
    if _WORKER_INTERRUPTED.is_set():
        raise KeyboardInterrupt(f"{spec}: not started, the worker was interrupted")
    _IN_RUN.set()
    try:
        return run_one(spec, settings)
    except KeyboardInterrupt as error:
        _WORKER_INTERRUPTED.set()
        raise KeyboardInterrupt(str(error)) from None
    finally:
        _IN_RUN.clear()


def run_local(jobs: Sequence[Job], workers: int) -> Iterator[RunOutcome]:
    """
    Run the jobs in a pool of ``workers`` processes; outcomes come as runs finish.

    :param jobs: The runs, each with its grid's settings (one grid or several sharing the pool)
    :param workers: Number of processes (1: in this process, one after the other)
    """
    if workers <= 1:
        for spec, settings in jobs:
            yield run_one(spec, settings)
        return
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(workers, context, _init_worker, (True,)) as pool:
        futures = [pool.submit(_run_local_job, spec, settings) for spec, settings in jobs]
        try:
            for future in concurrent.futures.as_completed(futures):
                yield future.result()
        except KeyboardInterrupt:
            _stop_pool(pool, futures)
            raise


def _stop_pool(pool: concurrent.futures.ProcessPoolExecutor, futures: Sequence[concurrent.futures.Future[Any]]) -> None:
    """
    After Ctrl-C or SIGTERM: no run starts, the runs in progress save a checkpoint and the workers exit. Ctrl-C (and
    Slurm's SIGTERM) reaches the whole process group; a SIGTERM to this process alone (``kill PID``) is passed on.
    """
    from sb3_adc.experiment.training import sigterm_received

    started = [future for future in futures if not future.cancel()]
    if sigterm_received():
        # The pool's processes (a private attribute: the executor has no public way to signal its workers).
        for process in list((getattr(pool, "_processes", None) or {}).values()):
            if process.is_alive():
                process.terminate()  # SIGTERM, handled as Ctrl-C
    concurrent.futures.wait(started)
    pool.shutdown(wait=True, cancel_futures=True)


def run_ray(jobs: Sequence[Job], address: str | None = None) -> Iterator[RunOutcome]:
    """
    Run the jobs as Ray tasks (one CPU each); outcomes come as runs finish. Uses the connected Ray instance, else
    ``ray.init(address)``. Tasks return their rows: no shared file system is needed, but resuming needs one.

    :param jobs: The runs, each with its grid's settings
    :param address: Address of the Ray cluster (``ray.init(address=...)``)
    """
    import ray

    if not ray.is_initialized():
        ray.init(address=address)
    task = ray.remote(num_cpus=1)(_ray_run_one)
    pending = [task.remote(spec, settings) for spec, settings in jobs]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        yield ray.get(done[0])


def _ray_run_one(spec: RunSpec, settings: BenchmarkSettings) -> RunOutcome:
    _init_worker()
    return run_one(spec, settings)
