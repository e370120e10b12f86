"""Two hosts on one machine: `plem launch` in one network namespace, a ROS 2 peer in another, joined by a veth pair.

The launch runs with the default discovery (SUBNET: multicast on the veth), the peer in the other
namespace reaches the robot only over DDS (it reads no shared memory, although /dev/shm is shared
between network namespaces). Needs root for `ip netns`; skipped otherwise.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import shutil
import subprocess
import sys
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from plem.middleware.action import SUCCEEDED
from tests.conftest import fresh_domain
from tests.e2e.launched import READY_LINE, Launch, clean_environment, new_robot_id
from tests.e2e.ros_peer import JOINT_NAMES

ROOT = Path(__file__).resolve().parents[2]
ARRIVED = 1e-3


def ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)
    if check and result.returncode != 0:
        raise AssertionError(f"ip {' '.join(args)} failed: {result.stderr.strip()}")
    return result


@dataclass(frozen=True)
class Host:
    namespace: str
    interface: str
    address: str


@contextlib.contextmanager
def two_hosts() -> Iterator[tuple[Host, Host]]:
    """Network namespaces plem_a_<tag> and plem_b_<tag> joined by a veth pair on 10.231.<x>.0/24."""
    if os.geteuid() != 0:
        pytest.skip("network namespaces need root (ip netns add)")
    if shutil.which("ip") is None:
        pytest.skip("the ip command (iproute2) is not installed")
    tag, subnet = uuid.uuid4().hex[:6], random.randint(1, 254)
    hosts = (Host(f"plem_a_{tag}", f"pa_{tag}", f"10.231.{subnet}.1"),
             Host(f"plem_b_{tag}", f"pb_{tag}", f"10.231.{subnet}.2"))
    created: list[str] = []
    try:
        for host in hosts:
            result = ip("netns", "add", host.namespace, check=False)
            if result.returncode != 0:
                pytest.skip(f"ip netns add {host.namespace} failed: {result.stderr.strip()}")
            created.append(host.namespace)
        a, b = hosts
        ip("link", "add", a.interface, "netns", a.namespace, "type", "veth", "peer", "name", b.interface,
           "netns", b.namespace)
        for host in hosts:
            ip("-n", host.namespace, "addr", "add", f"{host.address}/24", "dev", host.interface)
            ip("-n", host.namespace, "link", "set", "dev", "lo", "up")
            ip("-n", host.namespace, "link", "set", "dev", host.interface, "multicast", "on")
            ip("-n", host.namespace, "link", "set", "dev", host.interface, "up")
            ip("-n", host.namespace, "route", "add", "224.0.0.0/4", "dev", host.interface)
        if shutil.which("ping"):
            ping = subprocess.run(["ip", "netns", "exec", a.namespace, "ping", "-c", "1", "-W", "5", b.address],
                                  capture_output=True, text=True, timeout=30)
            assert ping.returncode == 0, f"{a.namespace} cannot reach {b.address}:\n{ping.stdout}{ping.stderr}"
        yield a, b
    finally:
        for namespace in created:  # deleting a namespace removes its end of the veth pair, and so the pair
            ip("netns", "delete", namespace, check=False)


def test_a_peer_on_another_host_reads_joint_states_and_moves_the_arm(tmp_path: Path):
    domain = str(fresh_domain())
    robot_id = new_robot_id()
    with two_hosts() as (a, b):
        env = clean_environment(tmp_path / "plem_home", ROS_DOMAIN_ID=domain)
        env.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)  # the default: SUBNET
        # `ip netns exec` execs plem in namespace A, so the launch's pid is plem's.
        launch = Launch(["bus:=mock", f"robot_id:={robot_id}"], [robot_id], tmp_path, env,
                        command_prefix=["ip", "netns", "exec", a.namespace])
        try:
            launch.wait_for(READY_LINE)
            assert f"ROS_DOMAIN_ID={domain}, discovery subnet" in launch.output, launch.describe()
            plan = {"joint": 0, "distance": 0.2, "duration": 2.0, "discovery_timeout": 30}
            peer_env = {**clean_environment(tmp_path / "peer_home", ROS_DOMAIN_ID=domain), "PYTHONPATH": str(ROOT)}
            peer_env.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
            peer = subprocess.run(["ip", "netns", "exec", b.namespace, sys.executable, "-m", "tests.e2e.ros_peer",
                                   robot_id, json.dumps(plan)], cwd=ROOT, env=peer_env, capture_output=True,
                                  text=True, timeout=120)
            assert peer.returncode == 0, f"peer: {peer.stdout}{peer.stderr}\n" + launch.describe()
            report = json.loads(peer.stdout.strip().splitlines()[-1])
            assert report["domain"] == f"ROS_DOMAIN_ID={domain}, discovery subnet"
            assert report["joint_states"] >= 50 and 70 < report["joint_state_rate"] < 110, report  # 100 Hz for 1 s
            assert report["names"] == list(JOINT_NAMES)
            assert report["servers"] and report["set_mode"] == {"status": SUCCEEDED, "success": True, "mode": "hold"}
            follow = report["follow"]
            assert (follow["status"], follow["error_code"]) == (SUCCEEDED, 0), follow["error_string"]
            assert follow["feedback"] > 0
            assert np.allclose(report["final"], report["target"], atol=ARRIVED), report
            assert launch.process.poll() is None, launch.describe()
            assert launch.stop() == 0, launch.describe()
        finally:
            launch.cleanup()
