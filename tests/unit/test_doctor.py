"""`plem doctor`: each host check against a fake /sys and /proc tree, and the command's output and exit code."""

from __future__ import annotations

import json
import resource
from pathlib import Path

import pytest

from plem.cli import doctor as doctor_command
from plem.cli.app import run
from plem.fieldbus.ethercat import host
from plem.fieldbus.ethercat.host import Finding

MIB = 2**20
NO_CAPS = 0
ALL_NEEDED = 1 << host.CAP_NET_ADMIN | 1 << host.CAP_NET_RAW | 1 << host.CAP_IPC_LOCK | 1 << host.CAP_SYS_NICE
COALESCE = """Coalesce parameters for eth0:
Adaptive RX: {adaptive}  TX: off
stats-block-usecs: n/a
sample-interval: n/a

rx-usecs: {usecs}
rx-frames: 0
rx-usecs-irq: n/a
"""


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def status(tmp_path: Path, capabilities: int) -> Path:
    return write(tmp_path / "status", f"Name:\tpython3\nCapInh:\t0000000000000000\nCapEff:\t{capabilities:016x}\n")


def fake_ethtool(tmp_path: Path, output: str, exit_status: int = 0) -> str:
    script = write(tmp_path / "bin" / "ethtool", f"#!/bin/sh\ncat <<'EOF'\n{output}EOF\nexit {exit_status}\n")
    script.chmod(0o755)
    return str(script)


def fake_net(tmp_path: Path) -> Path:
    """Two physical NICs, a veth, a wireless NIC and loopback, as /sys/class/net shows them."""
    net = tmp_path / "net"
    for name in ("eth0", "enp3s0", "wlan0"):
        (net / name / "device").mkdir(parents=True)
    (net / "wlan0" / "wireless").mkdir()
    (net / "veth0").mkdir()
    write(net / "lo" / "type", "772\n")
    return net


def link(net: Path, name: str, **values: str) -> None:
    for key, value in values.items():
        write(net / name / key, value + "\n")


# -- kernel and limits -----------------------------------------------------------------------------------------
def test_preempt_rt_from_the_flag_or_the_kernel_version(tmp_path: Path):
    flag, release = write(tmp_path / "realtime", "1\n"), write(tmp_path / "osrelease", "6.1.0-rt-amd64\n")
    assert host.check_preempt_rt(flag, release, "#1 SMP PREEMPT_DYNAMIC").ok
    assert host.check_preempt_rt(tmp_path / "absent", release, "#1 SMP PREEMPT_RT Debian 6.1.76-1").ok
    assert host.check_preempt_rt(tmp_path / "absent", write(tmp_path / "rt", "6.1.0 PREEMPT_RT\n"), "#1 SMP").ok


def test_missing_preempt_rt_is_a_warning_naming_the_kernel_package(tmp_path: Path):
    finding = host.check_preempt_rt(tmp_path / "absent", tmp_path / "absent", "#1 SMP PREEMPT_DYNAMIC")
    assert (finding.ok, finding.severity) == (False, "warning")
    assert "apt install linux-image-rt-amd64" in finding.how


@pytest.mark.parametrize(("limit", "capabilities", "ok"), [
    (0, NO_CAPS, False), (97, NO_CAPS, False), (98, NO_CAPS, True), (resource.RLIM_INFINITY, NO_CAPS, True),
    (0, 1 << host.CAP_SYS_NICE, True)])
def test_rt_priority_needs_the_limit_or_cap_sys_nice(tmp_path: Path, limit: int, capabilities: int, ok: bool):
    finding = host.check_rt_priority(98, limit, status(tmp_path, capabilities), euid=0)
    assert finding.ok is ok
    if not ok:
        assert finding.severity == "error"
        assert "/etc/security/limits.d/plem.conf" in finding.how and "@realtime - rtprio 98" in finding.how
        assert "@realtime - memlock unlimited" in finding.how and "usermod -aG realtime" in finding.how


def test_without_cap_eff_root_is_trusted(tmp_path: Path):
    assert host.check_rt_priority(98, 0, tmp_path / "absent", euid=0).ok
    assert not host.check_rt_priority(98, 0, tmp_path / "absent", euid=1000).ok


@pytest.mark.parametrize(("limit", "capabilities", "ok"), [
    (8 * MIB, NO_CAPS, False), (256 * MIB, NO_CAPS, True), (resource.RLIM_INFINITY, NO_CAPS, True),
    (64 * 1024, 1 << host.CAP_IPC_LOCK, True)])
def test_memlock_needs_256_mib_or_cap_ipc_lock(tmp_path: Path, limit: int, capabilities: int, ok: bool):
    finding = host.check_memlock(limit, status(tmp_path, capabilities), euid=0)
    assert finding.ok is ok
    if not ok:
        assert finding.severity == "warning" and "8 MiB" in finding.summary
        assert "@realtime - memlock unlimited" in finding.how


def test_raw_sockets_need_both_capabilities(tmp_path: Path):
    assert host.check_raw_sockets(status(tmp_path, ALL_NEEDED), euid=1000).ok
    finding = host.check_raw_sockets(status(tmp_path, 1 << host.CAP_NET_RAW), euid=0)
    assert (finding.ok, finding.severity) == (False, "error")
    assert "CAP_NET_ADMIN" in finding.summary and "CAP_NET_RAW" not in finding.summary
    assert "setcap cap_net_raw,cap_net_admin+ep" in finding.how and "every script" in finding.how
    assert "unshare" in finding.how
    assert host.check_raw_sockets(tmp_path / "absent", euid=0).ok


# -- CPUs ------------------------------------------------------------------------------------------------------
def test_isolated_cpus(tmp_path: Path):
    finding = host.check_isolated_cpus(write(tmp_path / "isolated", "2-3\n"))
    assert finding.ok and "2-3" in finding.summary
    for source in (write(tmp_path / "empty", "\n"), tmp_path / "absent"):
        finding = host.check_isolated_cpus(source)
        assert (finding.ok, finding.severity) == (False, "info")
        assert "isolcpus=" in finding.how and "nohz_full=" in finding.how and "rcu_nocbs=" in finding.how


def test_dma_latency_device(tmp_path: Path):
    assert host.check_dma_latency(write(tmp_path / "cpu_dma_latency", "")).ok
    finding = host.check_dma_latency(tmp_path / "absent")
    assert (finding.ok, finding.severity) == (False, "warning")


def test_governor(tmp_path: Path):
    for cpu in ("cpu0", "cpu1"):
        write(tmp_path / cpu / "cpufreq" / "scaling_governor", "performance\n")
    assert host.check_governor(tmp_path).ok
    write(tmp_path / "cpu1" / "cpufreq" / "scaling_governor", "powersave\n")
    (tmp_path / "cpu2" / "cpufreq" / "scaling_governor").mkdir(parents=True)  # unreadable, not a crash
    finding = host.check_governor(tmp_path)
    assert (finding.ok, finding.severity) == (False, "warning")
    assert "2 of 3" in finding.summary and "powersave" in finding.summary
    assert "cpupower frequency-set -g performance" in finding.how
    absent = host.check_governor(tmp_path / "vm")
    assert (absent.ok, absent.severity) == (False, "info")


# -- the network interface -------------------------------------------------------------------------------------
@pytest.mark.parametrize(("name", "words"), [("wlan0", "wireless"), ("lo", "loopback"), ("nosuch0", "not exist")])
def test_unusable_interface_is_one_error_finding(tmp_path: Path, name: str, words: str):
    (finding,) = host.check_interface(name, fake_net(tmp_path), fake_ethtool(tmp_path, ""))
    assert (finding.name, finding.ok, finding.severity) == ("interface.kind", False, "error")
    assert words in finding.summary and finding.how


def test_wired_interface_with_link_and_speed(tmp_path: Path):
    net = fake_net(tmp_path)
    link(net, "eth0", carrier="1", operstate="up", speed="1000", duplex="full")
    findings = host.check_interface("eth0", net, fake_ethtool(tmp_path, COALESCE.format(adaptive="off", usecs=0)))
    assert [f.name for f in findings] == ["interface.kind", "interface.link", "interface.speed",
                                          "interface.coalescing"]
    assert all(f.ok for f in findings), [f.summary for f in findings]
    assert "1000 Mb/s" in findings[2].summary


@pytest.mark.parametrize("carrier", ["0", None])
def test_no_link_is_an_error(tmp_path: Path, carrier: str | None):
    net = fake_net(tmp_path)
    link(net, "eth0", operstate="down", **({"carrier": carrier} if carrier else {}))
    finding = host.check_link("eth0", net)
    assert (finding.ok, finding.severity) == (False, "error")
    assert "ip link set eth0 up" in finding.how


@pytest.mark.parametrize(("speed", "duplex", "ok", "severity"), [
    ("100", "full", True, "info"), ("10", "full", False, "error"), ("100", "half", False, "error"),
    ("-1", "unknown", False, "info"), (None, None, False, "info")])
def test_speed(tmp_path: Path, speed: str | None, duplex: str | None, ok: bool, severity: str):
    net = fake_net(tmp_path)
    if speed is not None:
        link(net, "eth0", speed=speed, duplex=duplex)
    finding = host.check_speed("eth0", net)
    assert (finding.ok, finding.severity) == (ok, severity)


def test_coalescing_delays_frames(tmp_path: Path):
    finding = host.check_coalescing("eth0", fake_ethtool(tmp_path, COALESCE.format(adaptive="off", usecs=3)))
    assert (finding.ok, finding.severity) == (False, "warning")
    assert "rx-usecs 3" in finding.summary and "rx-frames 0" in finding.summary
    assert "ethtool -C eth0 rx-usecs 0" in finding.how
    adaptive = host.check_coalescing("eth0", fake_ethtool(tmp_path, COALESCE.format(adaptive="on", usecs=0)))
    assert not adaptive.ok and "ethtool -C eth0 adaptive-rx off rx-usecs 0" in adaptive.how


def test_coalescing_without_ethtool_or_support(tmp_path: Path):
    missing = host.check_coalescing("eth0", str(tmp_path / "no-ethtool"))
    assert (missing.ok, missing.severity) == (False, "info") and "apt install ethtool" in missing.how
    unsupported = host.check_coalescing("eth0", fake_ethtool(tmp_path, "netlink error: Operation not supported\n", 1))
    assert (unsupported.ok, unsupported.severity) == (False, "info")


def test_candidates_prefer_physical_wired_interfaces(tmp_path: Path):
    finding = host.check_candidates(fake_net(tmp_path))
    assert (finding.ok, finding.severity) == (False, "info")
    assert finding.summary.endswith("enp3s0, eth0")
    assert "virtual ones: veth0" in finding.why
    assert "plem doctor enp3s0" in finding.how
    assert "none" in host.check_candidates(tmp_path / "nonet").summary


# -- findings and the command ----------------------------------------------------------------------------------
def finding(severity: str, ok: bool = False) -> Finding:
    return Finding(f"test.{severity}", ok, severity, f"{severity} summary", "expected", "found", "fix it")


def test_render_heads_the_block_by_severity():
    assert finding("warning").render() == "WARNING: warning summary\nWHAT: expected\nWHY: found\nHOW: fix it"
    assert finding("error").render().startswith("ERROR: ") and finding("info").render().startswith("INFO: ")


def test_ready_ignores_warnings_notes_and_passed_checks():
    assert host.ready([finding("warning"), finding("info"), finding("error", ok=True)])
    assert not host.ready([finding("info"), finding("error")])


@pytest.mark.parametrize(("failed", "code"), [([finding("warning")], 0), ([finding("warning"), finding("error")], 1)])
def test_exit_code_and_text_output(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
                                   failed: list[Finding], code: int):
    monkeypatch.setattr(doctor_command, "check_host", lambda interface: [finding("info", ok=True), *failed])
    assert run(["doctor"]) == code
    out, err = capsys.readouterr()
    assert "ok    info summary" in out and "WARN  warning summary" in out
    assert "WARNING: warning summary\nWHAT: expected\nWHY: found\nHOW: fix it" in err
    assert "info summary" not in err, "passed checks print no block"
    assert ("NOT READY" in out) is (code == 1)
    if code:
        assert "FAIL  error summary" in out and "ERROR: error summary" in err


def test_missing_interface_fails_with_json(capsys: pytest.CaptureFixture[str]):
    assert run(["doctor", "nosuch0", "--format", "json"]) == 1
    report = json.loads(capsys.readouterr().out)
    assert report["ready"] is False
    (kind,) = [f for f in report["findings"] if f["name"].startswith("interface.")]
    assert (kind["name"], kind["ok"], kind["severity"]) == ("interface.kind", False, "error")


@pytest.mark.parametrize("argv", [["doctor", "--format", "json"], ["doctor", "lo", "--format", "json"]])
def test_this_host_report_is_well_formed(capsys: pytest.CaptureFixture[str], argv: list[str]):
    code = run(argv)
    report = json.loads(capsys.readouterr().out)
    fields = {"name", "ok", "severity", "summary", "what", "why", "how"}
    assert report["findings"] and all(set(f) == fields for f in report["findings"])
    assert all(f["severity"] in ("error", "warning", "info") and all(f[k] for k in fields - {"ok"})
               for f in report["findings"])
    failed = any(not f["ok"] and f["severity"] == "error" for f in report["findings"])
    assert report["ready"] is not failed and code == (1 if failed else 0)
