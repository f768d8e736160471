"""Progress reporting: ird_core's ``progress(step, total)`` callback drives the command lines' tqdm bar
(ird_core.experiments.progress), and importing the core never loads tqdm or ArviZ."""

from __future__ import annotations

import io
import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def progress_module():
    from ird_core.experiments import progress

    return progress


def test_off_a_terminal_every_refresh_is_one_line(progress_module, monkeypatch: pytest.MonkeyPatch) -> None:
    log = io.StringIO()  # not a TTY, like a log file or CI
    monkeypatch.setattr(sys, "stderr", log)
    with progress_module.step_progress("MCMC") as progress:
        for step in range(1, 227):
            progress(step, 226)
    text = log.getvalue()
    assert "\r" not in text and text.endswith("\n")
    lines = text.splitlines()
    # Refreshed at most every 10 s: the opening and the closing line, not one per step.
    assert 1 <= len(lines) <= 3
    assert all(line.startswith("MCMC:") for line in lines)
    assert "226/226" in lines[-1]


def test_the_callback_follows_cumulative_steps_of_the_sampler(progress_module,
                                                             monkeypatch: pytest.MonkeyPatch) -> None:
    import numpy as np

    from ird_core import mcmc

    log = io.StringIO()
    monkeypatch.setattr(sys, "stderr", log)

    def target(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return -0.5 * np.sum(x**2, axis=1), -x

    with progress_module.step_progress("MCMC") as progress:
        mcmc.sample_chains(target, np.zeros((2, 2)) + 0.1, 5, warmup=7, thin=2, seed=0, progress=progress)
    lines = log.getvalue().splitlines()
    assert "0/17" in lines[0] and "17/17" in lines[-1]  # one bar, warm-up included, complete


def test_core_loads_neither_tqdm_nor_arviz() -> None:
    probe = (
        "import importlib, json, pkgutil, sys, ird_core\n"
        "for info in pkgutil.walk_packages(ird_core.__path__, 'ird_core.'):\n"
        "    importlib.import_module(info.name)\n"
        "print(json.dumps(sorted(m for m in ('tqdm', 'arviz', 'pandas', 'xarray') if m in sys.modules)))\n"
    )
    out = subprocess.run([sys.executable, "-c", probe], cwd=ROOT, capture_output=True, text=True, check=True)
    assert json.loads(out.stdout.strip().splitlines()[-1]) == []
