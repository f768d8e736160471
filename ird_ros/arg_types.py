"""Argument types shared by the command lines (``ird`` verbs, ``launch_graph.py``): seconds.

A bad value raises ``argparse.ArgumentTypeError``, which argparse reports naming the option
(exit status 2) before the program does anything. ``inf`` is accepted (wait without a limit);
NaN and non-numbers are not.
"""

from __future__ import annotations

import argparse

__all__ = ["seconds", "seconds_or_zero"]


def seconds(text: str) -> float:
    """Seconds ``> 0``."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not value > 0:
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}")
    return value


def seconds_or_zero(text: str) -> float:
    """Seconds ``>= 0``."""
    try:
        value = float(text)
    except ValueError:
        value = -1.0
    if not value >= 0:
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text!r}")
    return value
