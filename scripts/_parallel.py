"""Parallel map for the experiment scripts: a local process pool or a Dask cluster, with a tqdm bar.

Import this module before numpy (the scripts do): it pins BLAS to one thread per process, since
the pool already uses every core and forked workers inherit the parent's BLAS set-up.

The mapped function must be importable by the workers (a module-level function of ``ird_core``)
and a pure function of its argument: results come back in input order, so they do not depend
on the number of workers, the scheduler or the order in which items finish. ``ird_core`` stays
free of Dask and tqdm; only the scripts use this module.
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
from concurrent.futures import ProcessPoolExecutor, as_completed  # noqa: E402
from typing import Any, Callable, Sequence, TypeVar  # noqa: E402

import _progress  # noqa: E402  (scripts/ is on sys.path: the scripts import this module from there)

__all__ = ["add_arguments", "describe", "progress_bar", "map_local", "map_dask", "parallel_map"]

T = TypeVar("T")
R = TypeVar("R")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """``--workers W`` (local processes, default = cores) and ``--scheduler tcp://HOST:PORT``."""
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--scheduler", default=None, help="Dask scheduler address, e.g. tcp://10.0.0.5:8786")


def add_trial_arguments(parser: argparse.ArgumentParser, defaults: Any) -> None:
    """The map and sampler flags both experiment scripts share, defaulting to ``defaults``'
    fields (an ``ird_core.experiments.TrialSpec`` or ``ird_core.experiments.active.ActiveSpec``)."""
    for flag, kind in (("size", int), ("horizon", int), ("obs_dim", int), ("num_samples", int),
                       ("beta", float), ("prior_sigma", float), ("num_chains", int), ("warmup", int),
                       ("thin", int), ("max_leapfrog", int)):
        parser.add_argument("--" + flag.replace("_", "-"), type=kind, default=getattr(defaults, flag))


def describe(workers: int, scheduler: str | None) -> str:
    return f"Dask {scheduler}" if scheduler else f"{workers} local worker(s)"


def progress_bar(total: int, desc: str = "trials") -> Any:
    """The scripts' one progress bar (``_progress.progress_bar``), counting trials."""
    return _progress.progress_bar(total, desc, unit="trial")


def map_local(fn: Callable[[T], R], items: Sequence[T], workers: int, progress: Any = None) -> list[R]:
    """``[fn(x) for x in items]`` in a process pool of ``workers`` (in-process if <= 1)."""
    out: list[Any] = [None] * len(items)
    if workers <= 1:
        for i, item in enumerate(items):
            out[i] = fn(item)
            if progress is not None:
                progress.update()
        return out
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for fut in as_completed(futures):
            out[futures[fut]] = fut.result()
            if progress is not None:
                progress.update()
    return out


def map_dask(fn: Callable[[T], R], items: Sequence[T], client: Any, progress: Any = None) -> list[R]:
    """``[fn(x) for x in items]`` on a Dask distributed client, in input order."""
    from distributed import as_completed as dask_completed

    futures = client.map(fn, list(items), pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    out: list[Any] = [None] * len(items)
    for fut in dask_completed(futures):
        out[index[fut.key]] = fut.result()
        if progress is not None:
            progress.update()
    return out


def parallel_map(fn: Callable[[T], R], items: Sequence[T], workers: int = 1, scheduler: str | None = None,
                 desc: str = "trials") -> list[R]:
    """Map with a progress bar: on the Dask scheduler at ``scheduler`` if given, else locally."""
    with progress_bar(len(items), desc) as progress:
        if scheduler:
            from distributed import Client

            with Client(scheduler) as client:
                return map_dask(fn, items, client, progress)
        return map_local(fn, items, workers, progress)
