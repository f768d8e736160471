"""Loopback-only DDS: the stack's node processes bind no socket outside 127.0.0.0/8 and still talk.

The sockets of a process are read from /proc: the inodes behind /proc/<pid>/fd/* matched
against /proc/<pid>/net/{udp,udp6,tcp,tcp6}. 0.0.0.0 and :: count as outside loopback. The
same check on the same node started without the profile (the set-up before it existed:
LOCALHOST discovery range, no profile) and with the multi-machine switch finds sockets
outside, so the check can fail. The rule that sets the variables exists in Python
(``ird_ros.graph.domains.dds_env``) and in shell (``scripts/lib/ros_env.sh``); they must agree.
"""

from __future__ import annotations

import ipaddress
import os
import subprocess
import sys
from pathlib import Path
from typing import Any, Iterator

import pytest

from ird_msgs.msg import ProxyReward, TerrainGrid
from ird_ros.client import IrdClient
from ird_ros.graph import names
from ird_ros.graph.domains import DDS_PROFILE, DDS_PROFILE_VAR, DomainLease, dds_env, lease_domain
from ird_ros.launch import GraphLauncher
from ird_ros.testing import NodeProcess, running_nodes, spawn_node_process

ROOT = Path(__file__).resolve().parents[2]
PARAMS = str(ROOT / "msgs_config" / "params" / "graph.yaml")
WORLD = ["-m", "ird_ros.nodes.world", "--ros-args", "--params-file", PARAMS, "-p", "condition:=side_effects",
         "-p", "seed:=3", "-p", "height:=6", "-p", "width:=7", "-p", "horizon:=8", "-p", "obs_dim:=12"]
PERCEPTION = ["-m", "ird_ros.nodes.perception", "--ros-args", "--params-file", PARAMS]
DDS_KEYS = ("ROS_AUTOMATIC_DISCOVERY_RANGE", DDS_PROFILE_VAR, "ROS_LOCALHOST_ONLY")


# ---------------------------------------------------------------- sockets from /proc


def _address(hex_addr: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address:
    """A /proc/net address (host byte order, 32-bit words) as an ``ipaddress`` object."""
    raw = bytes.fromhex(hex_addr)
    words = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
    return ipaddress.IPv4Address(words) if len(words) == 4 else ipaddress.IPv6Address(words)


def bound_sockets(pid: int) -> list[tuple[str, str, int]]:
    """(protocol, local address, local port) of every UDP/TCP socket process ``pid`` holds."""
    inodes = set()
    fd_dir = Path(f"/proc/{pid}/fd")
    for fd in fd_dir.iterdir():
        try:
            target = os.readlink(fd)
        except FileNotFoundError:  # closed while listing
            continue
        if target.startswith("socket:["):
            inodes.add(target[len("socket:["):-1])
    found = []
    for proto in ("udp", "udp6", "tcp", "tcp6"):
        for line in Path(f"/proc/{pid}/net/{proto}").read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] in inodes:
                host, port = fields[1].split(":")
                found.append((proto, str(_address(host)), int(port, 16)))
    return found


def is_loopback(address: str) -> bool:
    ip = ipaddress.ip_address(address)
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        ip = ip.ipv4_mapped
    return ip.is_loopback


def outside_loopback(pid: int) -> list[tuple[str, str, int]]:
    return [s for s in bound_sockets(pid) if not is_loopback(s[1])]


def test_address_parsing_and_loopback_rule() -> None:
    assert str(_address("0100007F")) == "127.0.0.1" and str(_address("020200C0")) == "192.0.2.2"
    assert str(_address("00000000000000000000000001000000")) == "::1"
    assert _address("0000000000000000FFFF00000100007F") == ipaddress.ip_address("::ffff:127.0.0.1")
    assert [is_loopback(a) for a in ("127.0.0.1", "127.8.9.10", "::1", "::ffff:127.0.0.1")] == [True] * 4
    assert [is_loopback(a) for a in ("0.0.0.0", "::", "192.0.2.2", "239.255.0.1")] == [False] * 4


def test_bound_sockets_sees_a_socket_of_this_process() -> None:
    import socket

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as wide, \
            socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as narrow:
        wide.bind(("0.0.0.0", 0))
        narrow.bind(("127.0.0.1", 0))
        mine = bound_sockets(os.getpid())
        assert ("udp", "0.0.0.0", wide.getsockname()[1]) in mine
        assert ("udp", "127.0.0.1", narrow.getsockname()[1]) in mine
        assert ("udp", "0.0.0.0", wide.getsockname()[1]) in outside_loopback(os.getpid())


# ---------------------------------------------------------------- the environment rule


CASES = {
    "default": {},
    "inherited_profile": {DDS_PROFILE_VAR: str(DDS_PROFILE), "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"},
    "network": {"IRD_DDS_NETWORK": "1", "ROS_LOCALHOST_ONLY": "1"},
    "network_word": {"IRD_DDS_NETWORK": "Yes", DDS_PROFILE_VAR: str(DDS_PROFILE)},
    "network_off": {"IRD_DDS_NETWORK": "off"},
    "user_profile": {DDS_PROFILE_VAR: "/etc/my_fastdds.xml"},
    "user_profile_network": {DDS_PROFILE_VAR: "/etc/my_fastdds.xml", "IRD_DDS_NETWORK": "true"},
    "user_fastdds3_profile": {"FASTDDS_DEFAULT_PROFILES_FILE": "/etc/my_fastdds.xml"},
    "skip_xml": {"SKIP_DEFAULT_XML_FILE": "1"},
}


def _shell_dds_env(env: dict[str, str]) -> subprocess.CompletedProcess:
    script = 'source scripts/lib/ros_env.sh && ird_dds_env && env -0'
    base = {k: v for k, v in os.environ.items()
            if k not in DDS_KEYS + ("IRD_DDS_NETWORK", "FASTDDS_DEFAULT_PROFILES_FILE", "SKIP_DEFAULT_XML_FILE")}
    return subprocess.run(["bash", "-c", script], check=False, cwd=ROOT, env={**base, **env}, capture_output=True, text=True,
                          timeout=30)


@pytest.mark.parametrize("case", sorted(CASES))
def test_shell_and_python_apply_the_same_rule(case: str) -> None:
    given = CASES[case]
    done = _shell_dds_env(given)
    assert done.returncode == 0, done.stderr
    shell = dict(item.split("=", 1) for item in done.stdout.split("\0") if "=" in item)
    python = dds_env(dict(given))
    assert {k: shell.get(k) for k in DDS_KEYS} == {k: python.get(k) for k in DDS_KEYS}
    network = given.get("IRD_DDS_NETWORK", "").lower() in ("1", "true", "yes", "on")
    own = bool(given.get(DDS_PROFILE_VAR, str(DDS_PROFILE)) != str(DDS_PROFILE)
               or given.get("FASTDDS_DEFAULT_PROFILES_FILE") or given.get("SKIP_DEFAULT_XML_FILE"))
    expected_range = "SUBNET" if network else "LOCALHOST" if own else "SYSTEM_DEFAULT"
    assert python["ROS_AUTOMATIC_DISCOVERY_RANGE"] == expected_range
    assert "ROS_LOCALHOST_ONLY" not in python
    if own:  # the user's profile is kept as it is
        assert python.get(DDS_PROFILE_VAR) == given.get(DDS_PROFILE_VAR)
    else:
        assert python.get(DDS_PROFILE_VAR) == (None if network else str(DDS_PROFILE))


def test_a_bad_switch_value_is_refused_by_both() -> None:
    with pytest.raises(ValueError, match="IRD_DDS_NETWORK"):
        dds_env({"IRD_DDS_NETWORK": "maybe"})
    done = _shell_dds_env({"IRD_DDS_NETWORK": "maybe"})
    assert done.returncode != 0 and "IRD_DDS_NETWORK" in done.stderr


def test_the_profile_file_exists_and_names_loopback_only() -> None:
    text = DDS_PROFILE.read_text()
    assert '<interface name="127.0.0.1"/>' in text
    assert "<useBuiltinTransports>false</useBuiltinTransports>" in text
    # discovery by unicast to 127.0.0.1; no multicast locator, so no socket on 239.255.0.1
    assert "<metatrafficUnicastLocatorList>" in text and "<initialPeersList>" in text
    assert "MulticastLocatorList" not in text


# A participant in domain 240 is refused by Fast DDS with a logged error ("Calculated port
# number is too high"): a sure way to make its log speak.
_DDS_ERROR = """
import os, rclpy
ctx = rclpy.context.Context()
rclpy.init(context=ctx, domain_id=240)
rclpy.create_node("dds_log_probe", context=ctx)
"""


@pytest.mark.parametrize("profile", [True, False], ids=["profile", "without_profile"])
def test_fast_dds_logs_to_stderr_never_into_stdout(profile: bool) -> None:
    """Commands whose stdout is parsed (``ird graph``, ``ird echo``) must not carry Fast DDS's log
    lines: the profile sends every level to stderr. Without it they land in stdout."""
    env = dds_env({k: v for k, v in os.environ.items() if k not in DDS_KEYS})
    if not profile:
        env["SKIP_DEFAULT_XML_FILE"] = "1"
        env.pop(DDS_PROFILE_VAR)
    done = subprocess.run([sys.executable, "-c", _DDS_ERROR], env=env, capture_output=True, text=True, timeout=60)
    tag = "Calculated port number is too high. Probably the domainId is over 232"
    log_line = [line for line in (done.stdout + done.stderr).splitlines() if "RTPS" in line and tag in line]
    assert len(log_line) == 1, (done.stdout, done.stderr)
    assert (log_line[0] in done.stderr.splitlines()) is profile, (done.stdout, done.stderr)
    assert (log_line[0] in done.stdout.splitlines()) is not profile, (done.stdout, done.stderr)


# ---------------------------------------------------------------- real node processes


@pytest.fixture(scope="module")
def graph(ros_domain: DomainLease) -> Iterator[list[NodeProcess]]:
    """world + perception with the stack's default environment (loopback profile)."""
    with running_nodes(ros_domain, ("world", WORLD), ("perception", PERCEPTION)) as procs:
        yield procs


def shared_memory_files(pid: int) -> set[str]:
    """Fast DDS's files under /dev/shm that process ``pid`` maps or holds open (its shared-memory
    transport maps segments and ports there and holds their lock files open; LTTng's files, which
    rcl maps, are not Fast DDS's)."""
    maps = {line.split(None, 5)[5] for line in Path(f"/proc/{pid}/maps").read_text().splitlines()
            if len(line.split(None, 5)) == 6}
    opened = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            opened.add(os.readlink(fd))
        except FileNotFoundError:  # closed while listing
            continue
    return {name for name in maps | opened if name.startswith(("/dev/shm/fastrtps_", "/dev/shm/sem.fastrtps_"))}


def test_node_processes_bind_nothing_outside_loopback(graph: list[NodeProcess]) -> None:
    for proc in graph:
        sockets = bound_sockets(proc.pid)
        # DDS's receive sockets exist (unicast discovery and user traffic): the check sees them
        assert sum(1 for s in sockets if s[0] == "udp") >= 3, (proc.name, sockets)
        assert outside_loopback(proc.pid) == [], (proc.name, sockets)


def test_node_processes_use_no_shared_memory_transport(graph: list[NodeProcess]) -> None:
    """The profile leaves Fast DDS's shared memory out (its ports outlive killed processes and cut
    later ones off, see the profile); without the profile a node maps its segments (next test)."""
    assert "<type>SHM</type>" not in DDS_PROFILE.read_text()
    for proc in graph:
        assert shared_memory_files(proc.pid) == set(), proc.name


def test_nodes_still_talk_over_loopback(graph: list[NodeProcess], ros_ctx: Any) -> None:
    """A service call to world; world's latched proxy, and perception's latched classes
    computed from world's new map (node to node), both reach this process."""
    with IrdClient(context=ros_ctx, node_name="loopback_probe", processes=graph) as ird:
        ird.subscribe(names.TOPIC_PROXY, names.TOPIC_TERRAIN_CLASSES)
        proxies: list[ProxyReward] = ird.received(names.TOPIC_PROXY)
        classes: list[TerrainGrid] = ird.received(names.TOPIC_TERRAIN_CLASSES)
        response = ird.generate_world("reward_hacking", 11, timeout=30.0)
        assert response.ok, response.message

        def classes_of_new_map() -> bool:
            new = [p.header.stamp for p in proxies if (p.condition, p.seed) == ("reward_hacking", 11)]
            return bool(new) and any(c.header.stamp == new[-1] for c in classes)

        ird.spin_until(classes_of_new_map, timeout=30.0, what="perception's classes of the new map")


def test_the_launcher_gives_loopback_dds_to_a_graph_started_from_a_plain_shell() -> None:
    """No DDS variables inherited and a given (not leased by the launcher) domain: the launcher
    still applies the rule. A domain of its own: the module's world would make this one ready."""
    plain = {k: v for k, v in os.environ.items() if k not in DDS_KEYS}
    with lease_domain() as lease, \
            GraphLauncher(nodes=["world"], domain_id=lease.domain_id, output="quiet", env=plain) as graph:
        graph.wait_ready(timeout=60)
        assert graph.env[DDS_PROFILE_VAR] == str(DDS_PROFILE)
        assert graph.env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
        pid = graph.pids()["world"]
        assert bound_sockets(pid) and outside_loopback(pid) == [], bound_sockets(pid)


@pytest.mark.parametrize("setting", [{"SKIP_DEFAULT_XML_FILE": "1"}, {"IRD_DDS_NETWORK": "1"}],
                         ids=["without_profile", "network_switch"])
def test_without_the_profile_the_check_finds_sockets_outside(setting: dict[str, str]) -> None:
    """The same node without the profile (LOCALHOST range, as before the profile existed) and
    with the multi-machine switch binds 0.0.0.0. Own domain: no talk with the module's graph."""
    env = {**os.environ, **setting}
    expected_range = "SUBNET" if "IRD_DDS_NETWORK" in setting else "LOCALHOST"
    assert dds_env(dict(env))["ROS_AUTOMATIC_DISCOVERY_RANGE"] == expected_range
    with lease_domain() as lease, spawn_node_process(WORLD, domain=lease, env=env, name="world",
                                                     ready_text="world ready", ready_timeout=60.0) as proc:
        outside = outside_loopback(proc.pid)
        assert any(address in ("0.0.0.0", "::") for _, address, _ in outside), bound_sockets(proc.pid)
        # Fast DDS's builtin transports include shared memory: the check above can fail
        assert shared_memory_files(proc.pid), "no Fast DDS segment mapped without the profile"
