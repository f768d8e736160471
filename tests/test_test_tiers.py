"""The test tiers' lists in tests/conftest.py name tests that exist (a renamed test would silently
leave the fast tier or the timing group), and scripts/test.sh runs in parallel by default."""

from __future__ import annotations

import re
from pathlib import Path

import conftest

ROOT = Path(__file__).resolve().parents[1]


def test_every_slow_test_named_in_conftest_exists() -> None:
    for name in sorted(conftest.SLOW_TESTS):
        path, function = name.split("::")
        assert re.search(rf"^(async )?def {function}\(", (ROOT / path).read_text(encoding="utf-8"), re.M), name


def test_every_ros_timing_module_exists() -> None:
    for stem in sorted(conftest.ROS_TIMING_MODULES):
        assert (ROOT / "tests" / "ros" / f"{stem}.py").is_file(), stem


def test_parallel_work_units() -> None:
    assert conftest.xdist_unit("tests/ros/test_burst.py::test_a[1]") == "ros-timing"
    assert conftest.xdist_unit("tests/ros/test_stalls.py::test_b") == "ros-timing"
    assert conftest.xdist_unit("tests/ros/test_client.py::test_c") == "tests/ros/test_client.py"
    assert conftest.xdist_unit("tests/core/test_mdp.py::test_d") is None
    assert conftest.xdist_unit("tests/test_docs_site.py::test_f") == "tests/test_docs_site.py"  # builds the site once
    assert conftest.xdist_unit("tests/test_readme.py::test_e[tests/ros/x]") is None


def test_the_test_command_runs_on_workers_and_has_a_fast_tier() -> None:
    script = (ROOT / "scripts" / "test.sh").read_text(encoding="utf-8")
    assert 'workers="${IRD_TEST_WORKERS:-2}"' in script and "--dist loadgroup" in script
    assert '-m "not slow and not ros"' in script
    assert re.search(r"^pytest-xdist==", (ROOT / "requirements.txt").read_text(encoding="utf-8"), re.M)
