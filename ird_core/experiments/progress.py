"""Progress of long command-line runs, one mechanism: a tqdm bar on stderr.

The computations never import tqdm: long core calls take a plain ``progress(step, total)``
callback (``ird_core.mcmc.ProgressFn``); :func:`step_progress` turns a bar into such a callback.
tqdm is imported only inside the functions that draw a bar, so importing any ``ird_core`` module
never loads it. On a terminal the bar redraws in place. Off a terminal (logs, CI) it is ASCII,
refreshed at most every 10 s, and every refresh is its own line: tqdm's carriage returns would
otherwise pile every refresh onto one endless log line.
"""

from __future__ import annotations

import sys
from contextlib import contextmanager
from typing import TYPE_CHECKING, Callable, Iterator, TextIO

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["progress_bar", "step_progress"]


class _LogLines:
    """A text stream for tqdm that writes each refresh as one line (carriage returns dropped)."""

    def __init__(self, stream: TextIO) -> None:
        self._stream = stream

    def write(self, text: str) -> None:
        line = text.replace("\r", "").rstrip()
        if line:
            self._stream.write(line + "\n")

    def flush(self) -> None:
        self._stream.flush()


def progress_bar(total: int | None, desc: str, unit: str = "it") -> "tqdm":
    """A tqdm bar on stderr: redrawn in place on a terminal, one line per refresh otherwise."""
    from tqdm import tqdm

    if sys.stderr.isatty():
        return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, dynamic_ncols=True, mininterval=0.5)
    return tqdm(total=total, desc=desc, unit=unit, file=_LogLines(sys.stderr), ascii=True, ncols=100,
                mininterval=10.0)


@contextmanager
def step_progress(desc: str, unit: str = "step") -> Iterator[Callable[[int, int], None]]:
    """A ``progress(step, total)`` callback for ``ird_core`` that drives a bar, closed on exit.

    The bar is created at the first call, when the total is known; ``step`` is the number of
    steps done so far (cumulative), as ``ird_core`` reports it.
    """
    bar: "tqdm | None" = None

    def progress(step: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = progress_bar(total, desc, unit)
        bar.update(step - bar.n)

    try:
        yield progress
    finally:
        if bar is not None:
            bar.close()
