#!/usr/bin/env python3
"""Benchmark: the loopback DDS profile (UDP only) against the same profile with Fast DDS's
shared-memory transport added (the profile before it was dropped), on one reliable round trip.

    python scripts/bench_dds_transport.py [--sizes 20000 300000 1600000] [--trips 20]

Each case starts an echo process and a pinger process in a private domain, both with the case's
profile; the pinger publishes a ``std_msgs/UInt8MultiArray`` of the size on ``/ping`` (reliable,
keep last 10), the echo publishes it back on ``/pong``, and the pinger times each round trip
after one warm-up trip. 1.6 MB is a 64x64 map of 50-d float64 features, the largest message the
stack sends. The table gives the median and maximum round trip per size and profile, and the
ratio UDP / shared memory of the medians (below 1: UDP is faster). Cases run one after another
in this process's run, so they share the machine's load.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from ird_ros.graph.domains import DDS_PROFILE, DDS_PROFILE_VAR, lease_domain  # noqa: E402

SHM_DESCRIPTOR = """      <transport_descriptor>
        <transport_id>ird_shm</transport_id>
        <type>SHM</type>
      </transport_descriptor>
    </transport_descriptors>"""


def with_shared_memory(profile: str) -> str:
    """The loopback profile with the shared-memory transport declared and used first."""
    text = profile.replace("    </transport_descriptors>", SHM_DESCRIPTOR, 1)
    text = text.replace("<userTransports>", "<userTransports>\n          <transport_id>ird_shm</transport_id>", 1)
    if text.count("ird_shm") != 2:
        raise SystemExit("bench_dds_transport: the profile's layout changed; update with_shared_memory")
    return text


def _echo() -> None:
    import rclpy
    from std_msgs.msg import UInt8MultiArray

    rclpy.init()
    node = rclpy.create_node("bench_echo")
    pub = node.create_publisher(UInt8MultiArray, "/pong", _qos())
    node.create_subscription(UInt8MultiArray, "/ping", pub.publish, _qos())
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass


def _qos():  # noqa: ANN202 - rclpy imported late
    from rclpy.qos import QoSProfile, ReliabilityPolicy

    return QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def _ping(size: int, trips: int) -> list[float]:
    import rclpy
    from std_msgs.msg import UInt8MultiArray

    rclpy.init()
    node = rclpy.create_node("bench_ping")
    got: list[float] = []
    pub = node.create_publisher(UInt8MultiArray, "/ping", _qos())
    node.create_subscription(UInt8MultiArray, "/pong", lambda _m: got.append(time.monotonic()), _qos())
    echo = subprocess.Popen([sys.executable, __file__, "--role", "echo"])
    try:
        deadline = time.monotonic() + 60
        while pub.get_subscription_count() == 0 or node.count_publishers("/pong") == 0:
            rclpy.spin_once(node, timeout_sec=0.1)
            if time.monotonic() > deadline:
                raise SystemExit("bench_dds_transport: the echo process was not discovered in 60 s")
        msg = UInt8MultiArray()
        msg.data = bytes(size)
        times = []
        for _ in range(trips + 1):  # the first trip warms up
            start, before = time.monotonic(), len(got)
            pub.publish(msg)
            while len(got) == before:
                rclpy.spin_once(node, timeout_sec=0.5)
                if time.monotonic() - start > 60:
                    raise SystemExit(f"bench_dds_transport: no answer in 60 s for {size} bytes")
            times.append(got[-1] - start)
        return times[1:]
    finally:
        echo.terminate()
        echo.wait(timeout=30)


def run_case(profile_text: str, size: int, trips: int) -> list[float]:
    """Round-trip seconds of ``trips`` messages of ``size`` bytes with the given profile."""
    with tempfile.TemporaryDirectory() as tmp, lease_domain() as lease:
        profile = Path(tmp) / "profile.xml"
        profile.write_text(profile_text)
        env = lease.env()
        env[DDS_PROFILE_VAR] = str(profile)
        out = subprocess.run([sys.executable, __file__, "--role", "ping", "--size", str(size),
                              "--trips", str(trips)], env=env, capture_output=True, text=True, timeout=600)
        if out.returncode != 0:
            raise SystemExit(f"bench_dds_transport: the ping process failed:\n{out.stderr}")
        return [float(v) for v in out.stdout.split()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[20_000, 300_000, 1_600_000])
    parser.add_argument("--trips", type=int, default=20)
    parser.add_argument("--role", choices=["bench", "ping", "echo"], default="bench", help=argparse.SUPPRESS)
    parser.add_argument("--size", type=int, default=0, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.role == "echo":
        _echo()
        return 0
    if args.role == "ping":
        print(" ".join(f"{t:.6f}" for t in _ping(args.size, args.trips)))
        return 0
    udp = DDS_PROFILE.read_text()
    profiles = {"udp (the profile)": udp, "udp + shm (reference)": with_shared_memory(udp)}
    print(f"round trip of one reliable message, {args.trips} trips per case (after one warm-up trip)")
    for size in args.sizes:
        medians = {}
        for name, text in profiles.items():
            times = run_case(text, size, args.trips)
            medians[name] = statistics.median(times)
            print(f"{size:>9} B  {name:<22} median {medians[name] * 1e3:7.2f} ms  max {max(times) * 1e3:7.2f} ms",
                  flush=True)
        ratio = medians["udp (the profile)"] / medians["udp + shm (reference)"]
        print(f"{size:>9} B  ratio udp / udp+shm (medians): {ratio:.2f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
