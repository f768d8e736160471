"""Header stamps read without ROS: any object with integer ``sec`` and ``nanosec`` fields
(``builtin_interfaces/Time`` of an rclpy message, of a message decoded from a bag, or a test's
stand-in).

A stamp names a message's world generation across the graph (docs/spec.md section 6): the
nodes compare stamps by :func:`stamp_key`, the bag tools order them by :func:`stamp_ns`, the
planner reports them as :func:`stamp_text`, the designer page shows :func:`stamp_seconds`.
Only the standard library is imported, so the bag tools can use it on a machine without ROS.
"""

from __future__ import annotations

from typing import Any

__all__ = ["stamp_key", "stamp_ns", "stamp_seconds", "stamp_text"]


def stamp_key(stamp: Any) -> tuple[int, int]:
    """``(sec, nanosec)``: equal exactly when the stamps are equal; orders as time does."""
    return int(stamp.sec), int(stamp.nanosec)


def stamp_ns(stamp: Any) -> int:
    """Nanoseconds since the epoch (exact)."""
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def stamp_seconds(stamp: Any) -> float:
    """Seconds since the epoch as a float (for display; not exact)."""
    return int(stamp.sec) + int(stamp.nanosec) * 1e-9


def stamp_text(stamp: Any) -> str:
    """``<sec>.<nanosec>`` with the nanoseconds zero-padded to 9 digits (exact)."""
    return f"{int(stamp.sec)}.{int(stamp.nanosec):09d}"
