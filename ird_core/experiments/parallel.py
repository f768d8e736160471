"""Parallel map for the experiments' command lines: a local process pool or a Dask cluster, with
a progress bar (:mod:`ird_core.experiments.progress`).

The mapped function must be importable by the workers (a module-level function of ``ird_core``)
and a pure function of its argument: results come back in input order, so they do not depend on
the number of workers, the scheduler or the order in which items finish. Dask and tqdm are
imported inside the functions that use them, so importing ``ird_core`` loads neither.

The pool's forked workers inherit the parent's BLAS set-up, and the pool already uses every
core: the command-line entry points set :data:`BLAS_THREAD_VARIABLES` to 1 before numpy loads
(one BLAS thread per process).
"""

from __future__ import annotations

import argparse
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any, Callable, Sequence, TypeVar

from ird_core.experiments import progress as progress_bars
from ird_core.experiments.journal import MISSING, Journal

__all__ = ["BLAS_THREAD_VARIABLES", "TRIAL_FLAGS", "worker_count", "add_arguments", "add_trial_arguments", "describe", "progress_bar", "map_local",
           "map_dask", "parallel_map"]

T = TypeVar("T")
R = TypeVar("R")

#: The environment variables that fix the BLAS thread count when numpy loads.
BLAS_THREAD_VARIABLES: tuple[str, ...] = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")

#: The map and sampler flags both experiments share, with their types.
TRIAL_FLAGS: tuple[tuple[str, type], ...] = (
    ("size", int), ("horizon", int), ("obs_dim", int), ("num_samples", int), ("beta", float), ("prior_sigma", float),
    ("num_chains", int), ("warmup", int), ("thin", int), ("max_leapfrog", int))


def worker_count(text: str) -> int:
    """``--workers``' type: an integer >= 1 (argparse reports the ``ArgumentTypeError`` naming the
    flag and exits with status 2)."""
    try:
        count = int(text)
    except ValueError:
        count = 0
    if count < 1:
        raise argparse.ArgumentTypeError(f"expected an integer >= 1, got {text!r}")
    return count


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--workers W`` (local processes, >= 1, default = cores) and ``--scheduler tcp://HOST:PORT``."""
    parser.add_argument("--workers", type=worker_count, default=os.cpu_count() or 1)
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://10.0.0.5:8786")


def add_trial_arguments(parser: argparse.ArgumentParser, defaults: Any) -> None:
    """The :data:`TRIAL_FLAGS`, defaulting to ``defaults``' fields of the same names (an
    ``ird_core.experiments.TrialSpec``, an ``ird_core.experiments.ActiveSpec`` or a namespace)."""
    for flag, kind in TRIAL_FLAGS:
        parser.add_argument("--" + flag.replace("_", "-"), type=kind, default=getattr(defaults, flag))


def describe(workers: int, scheduler: str | None) -> str:
    """Where the map runs, for logs and reports."""
    return f"Dask {scheduler}" if scheduler else f"{workers} local worker(s)"


def progress_bar(total: int, desc: str = "trials") -> Any:
    """The command lines' one progress bar (``progress.progress_bar``), counting trials."""
    return progress_bars.progress_bar(total, desc, unit="trial")


def map_local(fn: Callable[[T], R], items: Sequence[T], workers: int, progress: Any = None,
              done: "Callable[[int, R], None] | None" = None) -> list[R]:
    """``[fn(x) for x in items]`` in a process pool of ``workers`` (in-process if <= 1);
    ``done(i, result)`` is called in this process as each item finishes."""
    out: list[Any] = [None] * len(items)
    if workers <= 1:
        for i, item in enumerate(items):
            out[i] = fn(item)
            _finished(i, out[i], progress, done)
        return out
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for fut in as_completed(futures):
            out[futures[fut]] = fut.result()
            _finished(futures[fut], out[futures[fut]], progress, done)
    return out


def _finished(i: int, result: Any, progress: Any, done: "Callable[[int, Any], None] | None") -> None:
    if done is not None:
        done(i, result)
    if progress is not None:
        progress.update()


def map_dask(fn: Callable[[T], R], items: Sequence[T], client: Any, progress: Any = None,
             done: "Callable[[int, R], None] | None" = None) -> list[R]:
    """``[fn(x) for x in items]`` on a Dask distributed client, in input order (``done`` as in
    :func:`map_local`)."""
    from distributed import as_completed as dask_completed

    futures = client.map(fn, list(items), pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    out: list[Any] = [None] * len(items)
    for fut in dask_completed(futures):
        out[index[fut.key]] = fut.result()
        _finished(index[fut.key], out[index[fut.key]], progress, done)
    return out


def parallel_map(fn: Callable[[T], R], items: Sequence[T], workers: int = 1, scheduler: str | None = None,
                 desc: str = "trials", journal: "Journal | None" = None) -> list[R]:
    """Map with a progress bar: on the Dask scheduler at ``scheduler`` if given, else locally.

    With a ``journal`` (:class:`ird_core.experiments.journal.Journal`), items it holds are not run
    again (their kept results are returned) and every other result is kept as it arrives, so an
    interrupted run resumes where it stopped.
    """
    out: list[Any] = [MISSING if journal is None else journal.load(item) for item in items]
    todo = [i for i, result in enumerate(out) if result is MISSING]
    pending = [items[i] for i in todo]

    def done(j: int, result: Any) -> None:
        if journal is not None:
            journal.record(pending[j], result)

    with progress_bar(len(items), desc) as progress:
        progress.update(len(items) - len(todo))
        if scheduler:
            from distributed import Client

            with Client(scheduler) as client:
                fresh = map_dask(fn, pending, client, progress, done)
        else:
            fresh = map_local(fn, pending, workers, progress, done)
    for i, result in zip(todo, fresh):
        out[i] = result
    return out
