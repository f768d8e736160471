"""SIGINT/SIGTERM at any point of a node's life end it cleanly (``ird_ros.runtime.node_main.run_node``).

Properties:

- a signal raised *inside* a service callback does not interrupt it: the request is answered,
  then the node exits 0 (a signal only records the stop; nothing is raised inside rclpy);
- a signal during start-up (inside the node's factory) stops the node before it serves: exit 0,
  no ``ready`` line;
- a further signal during the clean-up does not cut it short: the node is destroyed, exit 0;
- a world node signalled 30 times at different points (idle, right after requests were sent,
  between the answers of a burst, twice in a row) exits 0 every time, never with a crash
  (-11, SIGSEGV; faulthandler's ``Fatal Python error``) nor a traceback.

The first three inject the signal at an exact point with ``signal.raise_signal`` (the handler
runs before ``raise_signal`` returns) in a small node run by ``run_node``; the last sends it from
outside, as a launcher or a terminal does.
"""

from __future__ import annotations

import signal
from pathlib import Path
from typing import Any

import pytest

from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DomainLease
from ird_ros.testing import NodeProcess, spawn_node_process
from ird_ros.waits import call_service

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
SERVICE = "/shutdown_test/trigger"

# A node run by run_node that raises a signal at one exact point of its life: argv[1] names the
# signal, argv[2] the point (``startup``, ``callback`` or ``cleanup``).
SELF_SIGNALLING = f"""
import signal, sys
from std_srvs.srv import Trigger
from ird_ros.runtime.guard import GuardedNode
from ird_ros.runtime.node_main import exit_process, run_node

SIG, WHEN = signal.Signals[sys.argv[1]], sys.argv[2]


class SelfSignalling(GuardedNode):
    def __init__(self):
        super().__init__("self_signalling")
        if WHEN == "startup":
            signal.raise_signal(SIG)
            print("factory went on after the signal", flush=True)
        self.create_service(Trigger, "{SERVICE}", self.on_trigger)

    calls = 0

    def on_trigger(self, request, response):
        self.calls += 1
        signalled = WHEN == "callback" and self.calls == 2
        if signalled:
            signal.raise_signal(SIG)
            signal.raise_signal(SIG)  # a second one changes nothing
        response.success = True
        response.message = "answered after the signal" if signalled else "answered"
        print(response.message, flush=True)
        return response

    def destroy_node(self):
        if WHEN == "cleanup":
            signal.raise_signal(signal.SIGINT)
        super().destroy_node()
        print("node destroyed", flush=True)


exit_process(run_node(SelfSignalling))
"""


def _finish(proc: NodeProcess, timeout: float = 60.0) -> tuple[int, str]:
    """Wait for the process to end by itself; its exit code and whole output."""
    code = proc.proc.wait(timeout=timeout)
    proc.stop()  # already exited: only collects the rest of its output
    return code, proc.output(last=2000)


def _assert_clean(code: int, output: str, what: str) -> None:
    assert code == 0, f"{what}: exit code {code}\n{output}"
    assert "Fatal Python error" not in output, f"{what}\n{output}"
    assert "Traceback" not in output, f"{what}\n{output}"


def _self_signalling(domain: DomainLease, sig: signal.Signals, when: str, **kw: Any) -> NodeProcess:
    return spawn_node_process(["-c", SELF_SIGNALLING, sig.name, when], domain=domain, name="self_signalling", **kw)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_inside_a_callback_lets_it_answer_then_exits_0(ros_domain: DomainLease, ros_node: Any,
                                                                sig: signal.Signals) -> None:
    from std_srvs.srv import Trigger

    proc = _self_signalling(ros_domain, sig, "callback", ready_text="self_signalling ready", ready_timeout=60.0)
    with proc:
        client = ros_node.create_client(Trigger, SERVICE)
        # A first answer proves the node has matched this client's response reader (before that
        # match a server waits for it, at most 5 s: tests/ros/test_service_answer_wait.py).
        first = call_service(ros_node, client, Trigger.Request(), timeout=60.0, processes=[proc])
        assert first.success and first.message == "answered", proc.describe()
        # Not processes=[proc]: the node exits right after answering, maybe before the answer is
        # taken here; the answer must arrive all the same (run_node lingers after an answer).
        try:
            response = call_service(ros_node, client, Trigger.Request(), timeout=60.0)
        except TimeoutError as exc:
            raise AssertionError(f"{exc}\n{proc.describe()}") from exc
        assert response.success and response.message == "answered after the signal", proc.describe()
        code, output = _finish(proc)
    _assert_clean(code, output, f"{sig.name} inside a callback")
    assert "node destroyed" in output, output


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_startup_stops_the_node_before_it_serves(ros_domain: DomainLease,
                                                                 sig: signal.Signals) -> None:
    with _self_signalling(ros_domain, sig, "startup") as proc:
        code, output = _finish(proc)
    _assert_clean(code, output, f"{sig.name} during start-up")
    assert "factory went on" not in output and "self_signalling ready" not in output, output


def test_a_signal_during_cleanup_does_not_cut_it_short(ros_domain: DomainLease) -> None:
    with _self_signalling(ros_domain, signal.SIGTERM, "cleanup", ready_text="self_signalling ready",
                          ready_timeout=60.0) as proc:
        proc.proc.send_signal(signal.SIGTERM)
        code, output = _finish(proc)
    _assert_clean(code, output, "SIGINT during the clean-up")
    assert "node destroyed" in output, output


# ----------------------------------------------------------------------------- world node, from outside

REPETITIONS = 30
PHASES = ("idle", "right after sending", "between answers", "twice between answers", "before discovery")


def _world(domain: DomainLease) -> NodeProcess:
    return spawn_node_process(
        ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS,
         "-p", "height:=12", "-p", "width:=12", "-p", "horizon:=20"],
        domain=domain, name="world", ready_text="world ready", ready_timeout=120.0)


@pytest.mark.slow
@pytest.mark.timeout(900)  # 30 node start-ups: about 2 min on a loaded 2-core machine
def test_world_node_exits_0_on_a_signal_at_any_point(ros_domain: DomainLease, ros_ctx: Any) -> None:
    """30 world nodes, one after the other; each is signalled at one of :data:`PHASES` with SIGINT
    or SIGTERM (every pair of phase and signal three times) and must exit 0."""
    for rep in range(REPETITIONS):
        phase = PHASES[rep % len(PHASES)]
        sig = (signal.SIGINT, signal.SIGTERM)[rep % 2]
        what = f"repetition {rep}: {sig.name} {phase}"
        proc = _world(ros_domain)
        with proc, IrdClient(context=ros_ctx, node_name=f"signal_client_{rep}") as ird:
            if phase != "before discovery":
                ird.wait_ready(60.0, services=(names.SRV_GENERATE,))
            if phase == "idle":
                proc.proc.send_signal(sig)
            elif phase == "right after sending":
                for seed in range(3):
                    ird.call_async(names.SRV_GENERATE, _generate_request(seed))
                proc.proc.send_signal(sig)
            elif phase in ("between answers", "twice between answers"):
                burst = [ird.call_async(names.SRV_GENERATE, _generate_request(seed)) for seed in range(4)]
                ird.spin_until(burst[0].done, timeout=60.0, what=f"the first answer ({what})")
                proc.proc.send_signal(sig)
                if phase == "twice between answers":
                    proc.proc.send_signal(signal.SIGTERM if sig == signal.SIGINT else signal.SIGINT)
            else:
                proc.proc.send_signal(sig)
            code, output = _finish(proc)
        _assert_clean(code, output, what)


def _generate_request(seed: int) -> Any:
    from ird_msgs.srv import GenerateWorld

    return GenerateWorld.Request(condition="side_effects", seed=seed)


def test_phases_cover_every_signal() -> None:
    """Every (phase, signal) pair occurs in the repetitions (the test above varies both)."""
    pairs = {(PHASES[rep % len(PHASES)], rep % 2) for rep in range(REPETITIONS)}
    assert len(pairs) == 2 * len(PHASES)
