"""scripts/bootstrap.sh shows progress: progress lines while uv, pip and cmake run (read from their
own output, scripts/lib/bootstrap_progress.sh), and its total time on its last line."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

PIP_AND_CMAKE = """\
Collecting numpy==2.4.6 (from -r requirements.txt (line 30))
  Downloading numpy-2.4.6-cp311-cp311-manylinux_2_28_x86_64.whl (16.4 MB)
""" + "".join(f"Collecting pkg{i}==1.0 (from -r requirements.txt (line {i}))\n" for i in range(2, 51)) + """\
Processing /opt/wheels/mdurl-0.1.2-py3-none-any.whl (from markdown-it-py)
Installing collected packages: a, b, c
Successfully installed a-1 b-2 c-3
-- Configuring done (1.2s)
[  2%] Generating C code
[ 10%] Building C object
[ 27%] Building C object
[ 60%] Building C object
[100%] Built target ird_msgs
"""


def _progress(text: str) -> list[str]:
    done = subprocess.run(["bash", "-c", "source scripts/lib/bootstrap_progress.sh && ird_bootstrap_progress step"],
                          cwd=ROOT, input=text, capture_output=True, text=True, check=True)
    return [re.sub(r" \[\d+s\]$", "", line) for line in done.stdout.splitlines()]


def test_pip_and_cmake_output_becomes_a_few_progress_lines() -> None:
    assert _progress(PIP_AND_CMAKE) == [
        "[bootstrap]   step: 1 package collected, latest numpy==2.4.6",
        "[bootstrap]   step: 25 packages collected, latest pkg25==1.0",
        "[bootstrap]   step: 50 packages collected, latest pkg50==1.0",
        "[bootstrap]   step: installing 3 packages",
        "[bootstrap]   step: installed 3 packages",
        "[bootstrap]   step: configured",
        "[bootstrap]   step: 2%",
        "[bootstrap]   step: 27%",
        "[bootstrap]   step: 60%",
        "[bootstrap]   step: 100%",
    ]


UV = """\
Using Python 3.11.7 environment at: .venv
Resolved 188 packages in 1.21s
Prepared 188 packages in 2.87s
Installed 188 packages in 410ms
 + numpy==2.4.6
 + ros-jazzy-rclpy==7.1.6
"""


def test_uv_output_becomes_its_three_summary_lines() -> None:
    assert _progress(UV) == [
        "[bootstrap]   step: resolved 188 packages in 1.21s",
        "[bootstrap]   step: prepared 188 packages in 2.87s",
        "[bootstrap]   step: installed 188 packages in 410ms",
    ]


def test_other_output_stays_in_the_log() -> None:
    assert _progress("Requirement already satisfied: numpy\n  Downloading x.whl\nwarning: something\n") == []


def test_the_last_line_gives_the_total_time() -> None:
    done = subprocess.run(["bash", "scripts/bootstrap.sh"], cwd=ROOT, capture_output=True, text=True, timeout=1800)
    assert done.returncode == 0, done.stderr[-3000:]
    last = done.stdout.strip().splitlines()[-1]
    assert re.fullmatch(r"\[bootstrap\] ready: \S+/\.venv/bin/python \(set-up took \d+\.\d s\)", last), last


def test_the_installed_packages_come_with_their_bytecode() -> None:
    # uv compiles no bytecode unless asked (--compile-bytecode); with PYTHONDONTWRITEBYTECODE set,
    # as on CI machines, every process would compile numpy, scipy and rclpy from source again.
    import importlib.util

    import numpy
    import rclpy
    import scipy.special

    for module in (numpy, scipy.special, rclpy):
        source = module.__file__
        assert source is not None
        assert Path(importlib.util.cache_from_source(source)).is_file(), f"no bytecode for {source}"
