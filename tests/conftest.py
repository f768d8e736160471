"""Shared pytest set-up: every ROS test talks only inside a private ROS domain.

- The whole session runs with loopback-only DDS (``ird_ros.graph.domains.dds_env``), a private
  ROS_LOG_DIR, and (if ROS_DOMAIN_ID was not set by scripts/test.sh) a leased domain.
- In parallel runs (pytest-xdist, ``scripts/test.sh`` passes ``-n 2``) every worker leases a
  session domain of its own (the inherited ROS_DOMAIN_ID is the controller's), so two workers'
  tests never see each other's nodes. With ``--dist loadgroup`` (``pytest_xdist_make_scheduler``
  below) each ROS test module is one work unit (its module-scoped domain and graph start once,
  on one worker), and the modules that measure time or push DDS hard (``ROS_TIMING_MODULES``)
  form one unit, so they run one after another and never two of them at once: beside them runs
  at most one other worker, the load they are checked under (scripts/stress_ros_tests.sh: a busy
  process per core). A module with a module- or session-scoped fixture of its own (the docs
  site's build, a small experiments run) is one unit too, so the fixture is built once; every
  other test is a unit of its own, the largest units going first.
  (Not ``xdist_group`` marks: pytest 9 derives node IDs afresh, so xdist 3.8 cannot tag them
  with a group and ``loadgroup`` would quietly become ``load``.)
- ``ros_domain`` (module scope) leases a further domain of its own for each test module
  (see ird_ros.testing.lease_domain) and points ROS_DOMAIN_ID at it while the module runs,
  so modules never see each other's nodes.
- ``ros_ctx`` / ``ros_node`` give an rclpy context and a node in that domain.
- Tests under tests/ros/ are marked ``ros`` (``-m "not ros"`` skips them) and grouped as above
  automatically. ``slow`` marks tests of more than a few seconds (a decorator, or ``SLOW_TESTS``
  below): the fast tier is ``scripts/test.sh --fast`` (``-m "not slow and not ros"``).
"""

from __future__ import annotations

import functools
import os
import re
import tempfile
from pathlib import Path
from typing import Any, Iterator

import pytest

from ird_ros.graph.domains import DomainLease, dds_env, lease_domain, ros_context

_SESSION: dict[str, Any] = {}

#: ROS test modules that time things (stalls, bursts, limits, signals, crashes, lingering
#: answers, discovery): one xdist group, so no two of them run at once.
ROS_TIMING_MODULES = frozenset({
    "test_answer_linger", "test_battery_worker_death", "test_burst", "test_discovery", "test_limits",
    "test_navigator_bursts", "test_recorder_crash", "test_service_answer_wait", "test_shutdown_signals",
    "test_stalls",
})

#: Tests outside tests/ros that take more than a few seconds (5-20 s each on the idle 2-core
#: machine; 15-100 s each under load, issue 44's fast-tier measurement), marked ``slow`` here
#: (every parameter of each), so ``-m "not slow and not ros"`` stays within about 2 minutes.
SLOW_TESTS = frozenset({
    "tests/core/test_creased_posteriors.py::test_elliptical_kernel_samples_a_creased_target",
    "tests/core/test_creased_posteriors.py::test_elliptical_posterior_matches_quadrature_in_2d",
    "tests/core/test_creased_posteriors.py::test_the_mode_start_lets_short_chains_converge_on_a_creased_posterior",
    "tests/core/test_inference.py::test_seeded_determinism",
    "tests/core/test_lavaland_maps.py::test_mcmc_kernel_is_exact_on_a_tiny_map",
    "tests/core/test_linear_kernels.py::test_warm_up_loads_every_kernel_signature_a_real_pass_uses",
    "tests/core/test_mcmc.py::test_kernels_sample_a_correlated_gaussian",
    "tests/core/test_queries.py::test_simulated_answers_follow_the_boltzmann_probabilities",
    "tests/core/test_run_until.py::test_continuing_equals_a_longer_run",
    "tests/test_bag_repair.py::test_any_prefix_reindexes_to_the_complete_messages",
    "tests/test_entry_points.py::test_thin_scripts_print_help",
    "tests/test_experiments.py::test_chunks_merge_into_the_report_of_one_run",
    "tests/test_experiments.py::test_dask_scheduler_and_worker_processes_match_local_pool",
    "tests/test_experiments.py::test_oracle_is_optimal_under_the_true_reward",
})


def _is_xdist_worker(config: pytest.Config) -> bool:
    return hasattr(config, "workerinput")


def pytest_configure(config: pytest.Config) -> None:
    dds_env(os.environ)  # loopback-only DDS, as every entry point (ird_ros.graph.domains)
    if not os.environ.get("ROS_LOG_DIR"):
        tmp = tempfile.TemporaryDirectory(prefix="ird_pytest_ros_log_")
        _SESSION["log_tmp"] = tmp
        os.environ["ROS_LOG_DIR"] = tmp.name
    # An xdist worker inherited the controller's domain: it leases one of its own (lease_domain
    # skips the inherited ID, and the lock keeps the other workers off it).
    if not os.environ.get("ROS_DOMAIN_ID") or _is_xdist_worker(config):
        lease = lease_domain(log_dir=os.environ["ROS_LOG_DIR"])
        _SESSION["lease"] = lease
        os.environ["ROS_DOMAIN_ID"] = str(lease.domain_id)


def pytest_unconfigure(config: pytest.Config) -> None:
    lease = _SESSION.pop("lease", None)
    if lease is not None:
        lease.release()
    tmp = _SESSION.pop("log_tmp", None)
    if tmp is not None:
        tmp.cleanup()


_SHARED_FIXTURE = re.compile(r"""scope\s*=\s*["'](module|session)["']""")


@functools.cache
def _has_shared_fixture(path: str) -> bool:
    """Whether the test module ``path`` (from the repository root) has a module- or session-scoped
    fixture of its own (a site build, a run of the experiments): its tests then stay together."""
    file = Path(__file__).parent.parent / path
    return file.is_file() and bool(_SHARED_FIXTURE.search(file.read_text(encoding="utf-8")))


def xdist_unit(nodeid: str) -> str | None:
    """The work unit of a test in parallel runs: ``"ros-timing"`` for the ROS timing modules, the
    module's path for the other ROS modules and for modules with a shared fixture of their own,
    None (a unit of its own) for every other test."""
    path = nodeid.split("::", 1)[0]
    if path.startswith("tests/ros/"):
        return "ros-timing" if Path(path).stem in ROS_TIMING_MODULES else path
    return path if _has_shared_fixture(path) else None


@pytest.hookimpl(optionalhook=True)  # a hook of pytest-xdist: only called when it runs the tests
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> Any:
    if config.getvalue("dist") != "loadgroup":
        return None
    from xdist.scheduler import LoadGroupScheduling

    class Units(LoadGroupScheduling):
        def _split_scope(self, nodeid: str) -> str:
            return xdist_unit(nodeid) or super()._split_scope(nodeid)

    return Units(config, log)


@pytest.hookimpl(tryfirst=True)  # the marks must be there when -m selects
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    tests_dir = Path(__file__).parent
    ros_dir = tests_dir / "ros"
    for item in items:
        path = Path(str(item.fspath))
        if ros_dir in path.parents:
            item.add_marker(pytest.mark.ros)
        if path.is_relative_to(tests_dir):
            name = f"tests/{path.relative_to(tests_dir).as_posix()}::{item.originalname}"
            if name in SLOW_TESTS:
                item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="module")
def ros_domain() -> Iterator[DomainLease]:
    """A ROS domain leased for this test module; ROS_DOMAIN_ID and ROS_LOG_DIR point at it."""
    with lease_domain() as lease, pytest.MonkeyPatch.context() as mp:
        mp.setenv("ROS_DOMAIN_ID", str(lease.domain_id))
        mp.setenv("ROS_LOG_DIR", str(lease.log_dir))
        yield lease


@pytest.fixture(scope="module")
def ros_ctx(ros_domain: DomainLease) -> Iterator[Any]:
    """An initialised rclpy context in the module's domain."""
    with ros_context(ros_domain) as ctx:
        yield ctx


@pytest.fixture
def ros_node(ros_ctx: Any, request: pytest.FixtureRequest) -> Iterator[Any]:
    """A fresh rclpy node in the module's domain, destroyed after the test."""
    import rclpy

    name = "test_" + "".join(c if c.isalnum() else "_" for c in request.node.name)[:60]
    node = rclpy.create_node(name, context=ros_ctx)
    try:
        yield node
    finally:
        node.destroy_node()
