"""Checks of a host's readiness for real-time EtherCAT, each returning a `Finding` for `plem doctor`.

Every check reads its sources (sysfs, procfs, resource limits, ethtool) through parameters whose defaults
are this machine's, so tests can point them at a fake tree; a missing or unreadable source becomes a
finding, never an exception.
"""

from __future__ import annotations

import os
import re
import resource
import shutil
import subprocess
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, Literal

from plem.control.realtime import CPU_DMA_LATENCY
from plem.errors import ConfigError, PlemError
from plem.fieldbus.network_interface import SYS_CLASS_NET, available_interfaces, check_network_interface

Severity = Literal["error", "warning", "info"]

REALTIME_FLAG = Path("/sys/kernel/realtime")
OSRELEASE = Path("/proc/sys/kernel/osrelease")
PROC_STATUS = Path("/proc/self/status")
SYS_CPU = Path("/sys/devices/system/cpu")
DEFAULT_PRIORITY = 98
MIN_MEMLOCK = 256 * 2**20
MIN_SPEED_MBPS = 100
CAP_NET_ADMIN, CAP_NET_RAW, CAP_IPC_LOCK, CAP_SYS_NICE = 12, 13, 14, 23
#: ethtool lives in sbin, which an ordinary user's PATH often lacks.
ETHTOOL_PATH = os.pathsep.join([os.environ.get("PATH", os.defpath), "/usr/sbin", "/sbin"])
ETHTOOL_TIMEOUT_S = 5
NOTHING_TO_DO = "nothing to do"


@dataclass(frozen=True)
class Finding:
    """One check's outcome: what the host should offer, what was found and how to fix it when not `ok`."""

    name: str
    ok: bool
    severity: Severity
    summary: str
    what: str
    why: str
    how: str

    def render(self) -> str:
        """The project's WHAT/WHY/HOW block, headed ERROR, WARNING or INFO by severity."""
        text = PlemError(self.summary, what=self.what, why=self.why, how=self.how).render()
        return self.severity.upper() + text.removeprefix("ERROR")

    def to_dict(self) -> dict[str, Any]:
        """A JSON-ready form for `plem doctor --format json`."""
        return asdict(self)


def ready(findings: list[Finding]) -> bool:
    """Whether the host can run a robot: no finding failed with error severity (warnings only cost latency)."""
    return not any(not f.ok and f.severity == "error" for f in findings)


def _passed(name: str, summary: str, what: str, why: str) -> Finding:
    return Finding(name, True, "info", summary, what, why, NOTHING_TO_DO)


def _read(path: Path, default: str = "") -> str:
    """A sysfs or procfs value without its trailing newline, or `default` when it cannot be read."""
    try:
        return path.read_text().strip()
    except (OSError, UnicodeDecodeError):
        return default


def _effective_capabilities(status: Path) -> int | None:
    match = re.search(r"^CapEff:\s*([0-9a-fA-F]+)\s*$", _read(status), re.MULTILINE)
    return int(match.group(1), 16) if match else None


def _capable(bit: int, status: Path, euid: int | None) -> bool:
    """Whether the effective capability set holds `bit`; when CapEff cannot be read, whether euid is root."""
    capabilities = _effective_capabilities(status)
    if capabilities is None:
        return (os.geteuid() if euid is None else euid) == 0
    return bool(capabilities >> bit & 1)


def _soft_limit(which: int, limit: int | None) -> int:
    return resource.getrlimit(which)[0] if limit is None else limit


def _limit_text(limit: int, unit: str = "", scale: int = 1) -> str:
    return "unlimited" if limit == resource.RLIM_INFINITY else f"{limit / scale:g}{unit}"


def _reaches(limit: int, wanted: int) -> bool:
    return limit == resource.RLIM_INFINITY or limit >= wanted


def _limits_fix(priority: int = DEFAULT_PRIORITY) -> str:
    return ("write /etc/security/limits.d/plem.conf with the lines\n"
            f"  @realtime - rtprio {priority}\n"
            "  @realtime - memlock unlimited\n"
            "then `sudo groupadd -f realtime && sudo usermod -aG realtime $USER` and log in again "
            f"(for a systemd service: LimitRTPRIO={priority} and LimitMEMLOCK=infinity), or run plem as root")


def check_preempt_rt(realtime_flag: Path = REALTIME_FLAG, osrelease: Path = OSRELEASE,
                     kernel_version: str | None = None) -> Finding:
    """Whether the kernel is PREEMPT_RT: without it plem runs, but how late a cycle can wake is unbounded."""
    version = os.uname().version if kernel_version is None else kernel_version
    release = _read(osrelease, "unknown release")
    what = "a PREEMPT_RT kernel, which bounds how late the loop wakes each cycle"
    if _read(realtime_flag) == "1" or "PREEMPT_RT" in release or "PREEMPT_RT" in version:
        return _passed("kernel.preempt_rt", f"PREEMPT_RT kernel ({release})", what,
                       f"{realtime_flag} or the kernel version says PREEMPT_RT ({release}, {version})")
    return Finding("kernel.preempt_rt", False, "warning", f"Kernel is not PREEMPT_RT ({release})", what=what,
                   why=f"{realtime_flag} does not contain 1 and neither the release nor the version ({version}) "
                       "names PREEMPT_RT: plem runs, but other kernel work can delay a cycle by milliseconds",
                   how="install a PREEMPT_RT kernel and reboot into it: on Debian `sudo apt install "
                       "linux-image-rt-amd64`, on Ubuntu `sudo pro enable realtime-kernel`")


def check_rt_priority(priority: int = DEFAULT_PRIORITY, limit: int | None = None, status: Path = PROC_STATUS,
                      euid: int | None = None) -> Finding:
    """Whether the loop may take SCHED_FIFO `priority`: an rtprio limit that high, or CAP_SYS_NICE."""
    limit = _soft_limit(resource.RLIMIT_RTPRIO, limit)
    what = f"permission to run the loop at SCHED_FIFO priority {priority}"
    if _capable(CAP_SYS_NICE, status, euid):
        return _passed("limits.rtprio", f"Real-time priority {priority} allowed (CAP_SYS_NICE)", what,
                       "the process holds CAP_SYS_NICE")
    shown = _limit_text(limit)
    if _reaches(limit, priority):
        return _passed("limits.rtprio", f"Real-time priority {priority} allowed (rtprio limit {shown})", what,
                       f"the rtprio limit is {shown}")
    return Finding("limits.rtprio", False, "error", f"Real-time priority {priority} not allowed (rtprio limit {shown})",
                   what=what, why=f"the rtprio limit is {shown} and the process lacks CAP_SYS_NICE: the loop would "
                                  "run at normal priority, where any busy process can delay a cycle",
                   how=_limits_fix(priority))


def check_memlock(limit: int | None = None, status: Path = PROC_STATUS, euid: int | None = None,
                  minimum: int = MIN_MEMLOCK) -> Finding:
    """Whether the loop can lock its memory (mlockall): a memlock limit of `minimum` or more, or CAP_IPC_LOCK."""
    limit = _soft_limit(resource.RLIMIT_MEMLOCK, limit)
    what = f"a locked-memory limit of at least {minimum // 2**20} MiB, so no page fault stalls a cycle"
    shown = _limit_text(limit, " MiB", 2**20)
    if _capable(CAP_IPC_LOCK, status, euid):
        return _passed("limits.memlock", "Memory locking allowed (CAP_IPC_LOCK)", what,
                       "the process holds CAP_IPC_LOCK")
    if _reaches(limit, minimum):
        return _passed("limits.memlock", f"Memory locking allowed (memlock limit {shown})", what,
                       f"the memlock limit is {shown}")
    return Finding("limits.memlock", False, "warning", f"Locked memory limited to {shown}", what=what,
                   why=f"the memlock limit is {shown} and the process lacks CAP_IPC_LOCK: mlockall fails and a "
                       "page fault can delay a cycle",
                   how=_limits_fix())


def check_raw_sockets(status: Path = PROC_STATUS, euid: int | None = None) -> Finding:
    """Whether plem may open the raw socket EtherCAT frames travel on: CAP_NET_RAW and CAP_NET_ADMIN."""
    missing = [name for name, bit in (("CAP_NET_RAW", CAP_NET_RAW), ("CAP_NET_ADMIN", CAP_NET_ADMIN))
               if not _capable(bit, status, euid)]
    what = "CAP_NET_RAW and CAP_NET_ADMIN, to send and receive EtherCAT frames on a raw socket"
    if not missing:
        return _passed("caps.raw_socket", "Raw sockets allowed (CAP_NET_RAW, CAP_NET_ADMIN)", what,
                       f"both capabilities are in the effective set ({status})")
    return Finding("caps.raw_socket", False, "error", f"Raw sockets not allowed (missing {', '.join(missing)})",
                   what=what, why=f"the effective capability set ({status}) lacks {' and '.join(missing)}",
                   how="run plem as root (sudo), or grant the interpreter the capabilities with\n"
                       "  sudo setcap cap_net_raw,cap_net_admin+ep $(readlink -f $(which python3))\n"
                       "which grants them to every script that interpreter runs; for the virtual network only, "
                       "run inside a user and network namespace: `unshare -rn plem ...`")


def check_isolated_cpus(isolated: Path = SYS_CPU / "isolated") -> Finding:
    """Whether some CPUs are kept free of other work, so the loop can have one to itself."""
    cpus = _read(isolated)
    what = "isolated CPUs (isolcpus) the loop can be pinned to, away from other processes and kernel work"
    if cpus:
        return _passed("cpu.isolated", f"Isolated CPUs: {cpus}", what, f"{isolated} lists {cpus}")
    return Finding("cpu.isolated", False, "info", "No isolated CPUs", what=what,
                   why=f"{isolated} is empty or absent: other processes and interrupts share the loop's CPU",
                   how="add e.g. `isolcpus=3 nohz_full=3 rcu_nocbs=3` to GRUB_CMDLINE_LINUX in /etc/default/grub, "
                       "run `sudo update-grub` and reboot, then pin the loop there with "
                       "`Robot.builder(config).with_loop_settings(cpus=(3,))`")


def check_dma_latency(device: Path = Path(CPU_DMA_LATENCY)) -> Finding:
    """Whether plem can hold /dev/cpu_dma_latency at 0 while it runs, keeping CPUs out of deep idle states."""
    what = f"write access to {device}, which plem holds at 0 while it runs"
    if device.exists() and os.access(device, os.W_OK):
        return _passed("cpu.dma_latency", f"{device} writable", what, f"{device} exists and is writable")
    return Finding("cpu.dma_latency", False, "warning", f"{device} not writable", what=what,
                   why=f"{device} is {'not writable by this user' if device.exists() else 'absent'}: waking from "
                       "a deep CPU idle state can add hundreds of µs to a cycle",
                   how="run plem as root, or let the realtime group write it: put the line\n"
                       '  KERNEL=="cpu_dma_latency", GROUP="realtime", MODE="0660"\n'
                       "in /etc/udev/rules.d/99-plem.rules and run `sudo udevadm trigger`")


def check_governor(cpu_root: Path = SYS_CPU) -> Finding:
    """Whether every CPU runs the performance governor: others change clock speed and so cycle times."""
    governors = [_read(path, "unreadable") for path in cpu_root.glob("cpu[0-9]*/cpufreq/scaling_governor")]
    slow = sorted({governor for governor in governors if governor != "performance"})
    what = "the performance frequency governor on every CPU, so compute time does not vary with clock speed"
    if not governors:
        return Finding("cpu.governor", False, "info", "No CPU frequency scaling exposed", what=what,
                       why=f"no {cpu_root}/cpu*/cpufreq/scaling_governor: a virtual machine or a fixed clock",
                       how="nothing to do here; on a physical machine set the performance governor in the firmware "
                           "setup or with `sudo cpupower frequency-set -g performance`")
    if not slow:
        return _passed("cpu.governor", f"CPU governor performance on all {len(governors)} CPUs", what,
                       f"every scaling_governor under {cpu_root} is performance")
    count = sum(governor != "performance" for governor in governors)
    return Finding("cpu.governor", False, "warning",
                   f"CPU governor not performance on {count} of {len(governors)} CPUs ({', '.join(slow)})",
                   what=what, why=f"governors {', '.join(slow)} change the clock with load, so the same cycle "
                                  "takes longer when the CPU has slowed down",
                   how="`sudo cpupower frequency-set -g performance` (Debian: `sudo apt install linux-cpupower`)")


def check_interface_kind(name: str, sys_class_net: Path = SYS_CLASS_NET) -> Finding:
    """Whether `name` exists and is wired Ethernet, neither wireless nor loopback."""
    try:
        check_network_interface(name, sys_class_net)
    except ConfigError as error:
        return Finding("interface.kind", False, "error", error.summary, error.what, error.why, error.how)
    return _passed("interface.kind", f"{name} is a wired interface", "a wired Ethernet interface for EtherCAT",
                   f"{name} exists and is neither wireless nor loopback")


def check_link(name: str, sys_class_net: Path = SYS_CLASS_NET) -> Finding:
    """Whether `name` has a link (carrier), i.e. a cable to a powered drive."""
    device = sys_class_net / name
    carrier, operstate = _read(device / "carrier", "unreadable"), _read(device / "operstate", "unknown")
    what = f"a link on {name}: the cable plugged in and the robot's first drive powered"
    if carrier == "1":
        return _passed("interface.link", f"{name} link up (operstate {operstate})", what, "carrier is 1")
    return Finding("interface.link", False, "error", f"{name} has no link (operstate {operstate})", what=what,
                   why=f"{device / 'carrier'} is {carrier} (it cannot be read while the interface is down)",
                   how=f"bring it up with `sudo ip link set {name} up`, check the cable and that the robot is "
                       f"powered; `ip link show {name}` shows LOWER_UP once the link is up")


def check_speed(name: str, sys_class_net: Path = SYS_CLASS_NET) -> Finding:
    """Whether `name` links at 100 Mb/s full duplex or faster, as EtherCAT needs."""
    device = sys_class_net / name
    text, duplex = _read(device / "speed"), _read(device / "duplex", "unknown")
    speed = int(text) if text.lstrip("-").isdigit() else -1
    what = f"a link of at least {MIN_SPEED_MBPS} Mb/s, full duplex"
    if speed <= 0:
        return Finding("interface.speed", False, "info", f"{name} link speed unknown", what=what,
                       why=f"{device / 'speed'} gives no speed: the link is down or the driver does not report one "
                           "(virtual NICs often do not)",
                       how=f"connect the robot and rerun; `ethtool {name}` also shows speed and duplex")
    if speed >= MIN_SPEED_MBPS and duplex != "half":
        return _passed("interface.speed", f"{name} at {speed} Mb/s, {duplex} duplex", what,
                       f"speed {speed} Mb/s, duplex {duplex}")
    return Finding("interface.speed", False, "error", f"{name} at {speed} Mb/s, {duplex} duplex", what=what,
                   why=f"EtherCAT runs at 100 Mb/s full duplex; the link negotiated {speed} Mb/s {duplex} duplex",
                   how=f"use a Cat 5e cable straight to the robot and let the port negotiate: "
                       f"`sudo ethtool -s {name} autoneg on`")


def check_coalescing(name: str, ethtool: str = "ethtool") -> Finding:
    """Whether `name` hands each received frame over at once; interrupt coalescing holds frames back."""
    what = f"interrupt coalescing off on {name} (rx-usecs 0), so each frame is handed over when it arrives"
    executable = shutil.which(ethtool, path=ETHTOOL_PATH)
    if executable is None:
        return Finding("interface.coalescing", False, "info", "ethtool not installed: coalescing not checked",
                       what=what, why=f"{ethtool} is not on the PATH or in /usr/sbin",
                       how=f"`sudo apt install ethtool`, then rerun `plem doctor {name}`")
    try:
        result = subprocess.run([executable, "-c", name], capture_output=True, text=True, check=False,
                                timeout=ETHTOOL_TIMEOUT_S)
        output, problem = result.stdout, result.stderr.strip() or f"exit status {result.returncode}"
    except (OSError, subprocess.SubprocessError) as error:
        output, problem = "", str(error)
    settings = dict(re.findall(r"^([\w-]+):\s*(\S+)", output, re.MULTILINE))
    adaptive = re.search(r"^Adaptive RX:\s*(\S+)", output, re.MULTILINE)
    adaptive_rx = adaptive.group(1) if adaptive else "n/a"
    if "rx-usecs" not in settings:
        return Finding("interface.coalescing", False, "info", f"{name} reports no interrupt coalescing",
                       what=what, why=f"`ethtool -c {name}` gave no rx-usecs ({problem})",
                       how="nothing to do for a virtual interface; for a NIC, check its driver supports "
                           f"`ethtool -c {name}`")
    rx_usecs, rx_frames = settings["rx-usecs"], settings.get("rx-frames", "n/a")
    shown = f"rx-usecs {rx_usecs}, rx-frames {rx_frames}, adaptive RX {adaptive_rx}"
    delayed = (rx_usecs.isdigit() and int(rx_usecs) > 0) or adaptive_rx == "on"
    if not delayed:
        return _passed("interface.coalescing", f"{name} interrupt coalescing off ({shown})", what, shown)
    return Finding("interface.coalescing", False, "warning", f"{name} coalesces interrupts ({shown})", what=what,
                   why="the NIC waits up to rx-usecs before raising an interrupt, which adds latency to every frame",
                   how=f"`sudo ethtool -C {name} {'adaptive-rx off ' if adaptive_rx == 'on' else ''}rx-usecs 0` "
                       "(it lasts until reboot: run it from a systemd unit or the interface's configuration)")


def check_interface(name: str, sys_class_net: Path = SYS_CLASS_NET, ethtool: str = "ethtool") -> list[Finding]:
    """The interface checks: its kind, then, when it can carry EtherCAT, link, speed and interrupt coalescing."""
    kind = check_interface_kind(name, sys_class_net)
    if not kind.ok:
        return [kind]
    return [kind, check_link(name, sys_class_net), check_speed(name, sys_class_net), check_coalescing(name, ethtool)]


def _wired(name: str, sys_class_net: Path) -> bool:
    try:
        check_network_interface(name, sys_class_net)
    except ConfigError:
        return False
    return True


def check_candidates(sys_class_net: Path = SYS_CLASS_NET) -> Finding:
    """Without an interface to check: the wired interfaces the robot could be on, physical NICs first."""
    wired = [name for name in available_interfaces(sys_class_net) if _wired(name, sys_class_net)]
    physical = [name for name in wired if (sys_class_net / name / "device").exists()]
    virtual = [name for name in wired if name not in physical]
    example = (physical or wired or ["enp3s0"])[0]
    return Finding("interface.candidates", False, "info",
                   f"No interface given; physical wired interfaces: {', '.join(physical) or 'none'}",
                   what="the interface wired to the robot, to check its link, speed and interrupt coalescing",
                   why=f"physical wired interfaces: {', '.join(physical) or 'none'}; "
                       f"virtual ones: {', '.join(virtual) or 'none'}",
                   how=f"rerun with the robot's port, e.g. `plem doctor {example}`")


def check_core() -> Finding:
    """Whether plem's compiled core is built and loads, and how it was built."""
    what = "plem's compiled real-time core (plem.control._core), built when plem was installed"
    try:
        from plem.control import compiled
    except PlemError as error:
        return Finding("core.build", False, "error", error.summary, what, error.why, error.how)
    return _passed("core.build", f"Compiled core: {compiled.describe()}", what,
                   "the extension loads and its structures match plem's Python view of them")


def check_host(interface: str | None = None, priority: int = DEFAULT_PRIORITY) -> list[Finding]:
    """Every check on this machine, with the interface checks for `interface` or a list of candidates."""
    findings = [check_core(), check_preempt_rt(), check_rt_priority(priority), check_memlock(), check_raw_sockets(),
                check_isolated_cpus(), check_dma_latency(), check_governor()]
    return findings + (check_interface(interface) if interface else [check_candidates()])
