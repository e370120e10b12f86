"""Running untrusted work (rendering a description package) in a forked child with less privilege and limits.

When plem runs as root, the child gives up root (to the owner of the package folder, or to nobody when that is
root). Whoever runs it, the child cannot regain privileges, start processes or write files, and has memory,
CPU-time and output limits; the parent waits with a wall-clock timeout. The result comes back as JSON over a
pipe (never pickled: the child may have run hostile code), and every way the child can fail becomes a
SandboxError with the limit or cause named.
"""

from __future__ import annotations

import ctypes
import gc
import json
import os
import resource
import select
import signal
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

from plem.description.problems import DescriptionError
from plem.errors import ConfigError, PlemError

NOBODY = 65534
PR_SET_NO_NEW_PRIVS = 38
MIB = 1 << 20
ERROR_FIELDS = ("summary", "what", "why", "how")
LIMIT_VARIABLES = {"memory_mb": "PLEM_RENDER_MEMORY_MB", "cpu_seconds": "PLEM_RENDER_CPU_SECONDS",
                   "output_mb": "PLEM_RENDER_OUTPUT_MB", "timeout_seconds": "PLEM_RENDER_TIMEOUT_SECONDS"}
_LIBC = ctypes.CDLL(None, use_errno=True)  # loaded before forking, so the child does not pay for it


class SandboxError(DescriptionError):
    """The limited child process doing the work hit a limit, timed out, or crashed."""


@dataclass(frozen=True)
class Limits:
    """What one render may use; each value can be raised through its environment variable."""

    memory_mb: int = 1024  # address space beyond what the process already had when it forked
    cpu_seconds: int = 30
    output_mb: int = 32
    timeout_seconds: int = 120  # wall clock, generous for busy machines

    @classmethod
    def from_environment(cls, environ: Mapping[str, str] | None = None) -> Limits:
        """The defaults, with any PLEM_RENDER_* variable that is set taking their place."""
        env = os.environ if environ is None else environ
        values = {}
        for field, variable in LIMIT_VARIABLES.items():
            text = env.get(variable, "").strip()
            if not text:
                continue
            if not text.isdigit() or int(text) == 0:
                raise ConfigError(f"{variable} is not a positive whole number",
                                  what=f"{variable} unset, or a whole number above 0",
                                  why=f"{variable}={text}",
                                  how=f"unset {variable} to use {getattr(cls, field)}, or set e.g. "
                                      f"{variable}={2 * getattr(cls, field)}")
            values[field] = int(text)
        return cls(**values)


def run_sandboxed(work: Callable[[], str], *, task: str, owner: Path, keep_fds: Sequence[int] = (),
                  error_types: Sequence[type[PlemError]] = (DescriptionError,)) -> str:
    """`work()` run in a forked child without root and within Limits; its text, or its PlemError re-raised here.

    `owner` is the folder whose owner the child runs as (when plem is root); `keep_fds` stay open in the child;
    a PlemError of one of `error_types` comes back as that type (any other as the first one)."""
    limits = Limits.from_environment()
    memory = _address_space() + limits.memory_mb * MIB
    outcome = _Outcome(task, limits)
    read_end, write_end = os.pipe()
    gc.freeze()  # the child's collections then skip the inherited objects instead of copying their pages
    try:
        pid = os.fork()
        if pid == 0:
            os.close(read_end)
            _child(work, write_end, owner, [*keep_fds, write_end], limits, memory)
    except OSError as error:
        os.close(read_end)
        raise outcome.crashed(f"could not be started: {error}") from None
    finally:
        gc.unfreeze()
        os.close(write_end)
    try:
        data = _collect(pid, read_end, limits, outcome)
    finally:
        os.close(read_end)
        if not outcome.reaped:
            outcome.stop(pid)
    return outcome.result(data, {cls.__name__: cls for cls in error_types}, error_types[0])


@dataclass
class _Outcome:
    """How the child ended, and the SandboxError for each way it can fail."""

    task: str
    limits: Limits
    reaped: bool = False
    status: int = 0
    cpu_seconds: float = 0.0

    def stop(self, pid: int) -> None:
        os.kill(pid, signal.SIGKILL)
        self.wait(pid)

    def wait(self, pid: int) -> None:
        _, self.status, usage = os.wait4(pid, 0)
        self.cpu_seconds = usage.ru_utime + usage.ru_stime
        self.reaped = True

    def result(self, data: bytes, types: Mapping[str, type[PlemError]], default: type[PlemError]) -> str:
        if os.WIFSIGNALED(self.status):
            number = os.WTERMSIG(self.status)
            if number == signal.SIGXCPU or (number == signal.SIGKILL and self.cpu_seconds >= self.limits.cpu_seconds):
                raise self.cpu_limit()  # the soft limit sends SIGXCPU, the hard one a second later SIGKILL
            raise self.crashed(f"was killed by signal {number} ({signal.strsignal(number)})")
        try:
            message = json.loads(data)
            if "ok" in message and isinstance(message["ok"], str):
                return message["ok"]
            if message.get("limit") == "memory":
                raise self.memory_limit()
            if message.get("limit") == "output":
                raise self.output_limit()
            if "error" in message:
                fields = {name: str(message[name]) for name in ERROR_FIELDS}
                raise types.get(str(message["error"]), default)(fields.pop("summary"), **fields)
            detail = str(message["crash"])
        except (ValueError, TypeError, KeyError, AttributeError):
            detail = f"exited with status {os.WEXITSTATUS(self.status)} without a readable result"
        raise self.crashed(detail)

    def _error(self, summary: str, limit: str, why: str, advice: str, variable: str, value: int) -> SandboxError:
        return SandboxError(f"{self.task} {summary}", what=f"{self.task} within {limit}", why=why,
                            how=f"{advice}; if the package really needs more, raise {variable} (now {value})")

    def memory_limit(self) -> SandboxError:
        memory = self.limits.memory_mb
        return self._error("hit the memory limit", f"{memory} MiB of memory",
                           f"it ran out of memory (address-space limit RLIMIT_AS, {memory} MiB) and was stopped",
                           "look for an expression or macro that builds a huge value", "PLEM_RENDER_MEMORY_MB", memory)

    def cpu_limit(self) -> SandboxError:
        cpu = self.limits.cpu_seconds
        return self._error("hit the CPU-time limit", f"{cpu} s of CPU time",
                           f"it used {self.cpu_seconds:.1f} s of CPU time (limit RLIMIT_CPU, {cpu} s) and was stopped",
                           "look for a macro that recurses or an expression that loops without end",
                           "PLEM_RENDER_CPU_SECONDS", cpu)

    def output_limit(self) -> SandboxError:
        output = self.limits.output_mb
        return self._error("hit the output limit", f"{output} MiB of output",
                           f"its result is larger than the output limit ({output} MiB) and was discarded",
                           "look for a macro or expression that repeats text without end", "PLEM_RENDER_OUTPUT_MB",
                           output)

    def timeout(self) -> SandboxError:
        seconds = self.limits.timeout_seconds
        return self._error("took too long", f"{seconds} s of wall-clock time",
                           f"it was still running after {seconds} s (wall-clock timeout) and was stopped",
                           "look for a macro that recurses without end", "PLEM_RENDER_TIMEOUT_SECONDS", seconds)

    def crashed(self, detail: str) -> SandboxError:
        return SandboxError(f"{self.task} crashed", what=f"{self.task} to finish and report its result",
                            why=f"the limited process doing it {detail}",
                            how="render the file alone with `xacro FILE` to see where it fails, and fix that part")


def _collect(pid: int, read_end: int, limits: Limits, outcome: _Outcome) -> bytes:
    """Everything the child writes until it exits, within the output cap and the wall-clock timeout."""
    deadline = time.monotonic() + limits.timeout_seconds
    cap = limits.output_mb * MIB + 4096  # room for the JSON around the text
    process = os.pidfd_open(pid)
    poller = select.poll()
    poller.register(read_end, select.POLLIN)
    poller.register(process, select.POLLIN)
    chunks: list[bytes] = []
    size, pipe_open, running = 0, True, True
    try:
        while pipe_open or running:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                outcome.stop(pid)
                raise outcome.timeout()
            for fd, _ in poller.poll(int(remaining * 1000) + 1):
                if fd == process:
                    running = False
                    poller.unregister(process)
                    continue
                chunk = os.read(read_end, MIB)
                if not chunk:
                    pipe_open = False
                    poller.unregister(read_end)
                size += len(chunk)
                chunks.append(chunk)
                if size > cap:
                    outcome.stop(pid)
                    raise outcome.output_limit()
    finally:
        os.close(process)
    outcome.wait(pid)
    return b"".join(chunks)


def _child(work: Callable[[], str], write_end: int, owner: Path, keep_fds: Sequence[int], limits: Limits,
           memory: int) -> NoReturn:
    """Runs in the forked child: isolate, limit, drop privileges, work, report; never returns."""
    try:
        _isolate(keep_fds)
        _limit(limits.cpu_seconds, memory)
        _drop_privileges(owner)
        message = _run(work)
        data = json.dumps(message).encode()
        if len(data) > limits.output_mb * MIB:
            data = json.dumps({"limit": "output"}).encode()
    except MemoryError:
        data = b'{"limit": "memory"}'
    except BaseException as error:  # noqa: BLE001 - anything at all must reach the parent as a report
        data = json.dumps({"crash": f"could not run: {type(error).__name__}: {error}"}).encode()
    try:
        view = memoryview(data)
        while view:
            view = view[os.write(write_end, view):]
    finally:
        os._exit(0)


def _run(work: Callable[[], str]) -> dict[str, Any]:
    try:
        return {"ok": work()}
    except PlemError as error:
        return {"error": type(error).__name__, **{name: getattr(error, name) for name in ERROR_FIELDS}}
    except MemoryError:
        return {"limit": "memory"}
    except Exception as error:  # noqa: BLE001 - a bug or an unexpected failure: reported, never a traceback
        return {"crash": f"failed: {type(error).__name__}: {error}"}


def _isolate(keep_fds: Sequence[int]) -> None:
    """Ordinary scheduling, default signal handling, standard streams to /dev/null, other descriptors closed.

    A real-time parent (the RT driver's threads run at SCHED_FIFO) must not hand its priority to the work.
    """
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    for number in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):
        signal.signal(number, signal.SIG_DFL)
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write beyond RLIMIT_FSIZE fails instead of killing
    null = os.open(os.devnull, os.O_RDWR)
    for stream in (0, 1, 2):
        os.dup2(null, stream)
    kept = sorted({0, 1, 2, *keep_fds})
    for low, high in zip(kept, [*kept[1:], os.sysconf("SC_OPEN_MAX")], strict=True):
        os.closerange(low + 1, high)


def _address_space() -> int:
    """This process's address-space size in bytes (read before forking: the child's starts the same)."""
    with open("/proc/self/statm", encoding="ascii") as statm:
        return int(statm.read().split()[0]) * resource.getpagesize()


def _limit(cpu_seconds: int, memory: int) -> None:
    """No core files, no files written, no new processes; address space and CPU time capped."""
    for kind, value in ((resource.RLIMIT_CORE, 0), (resource.RLIMIT_FSIZE, 0), (resource.RLIMIT_NPROC, 0),
                        (resource.RLIMIT_AS, memory)):
        _set_limit(kind, value, value)
    _set_limit(resource.RLIMIT_CPU, cpu_seconds, cpu_seconds + 1)  # SIGXCPU, then SIGKILL


def _set_limit(kind: int, soft: int, hard: int) -> None:
    _, current_hard = resource.getrlimit(kind)
    if current_hard != resource.RLIM_INFINITY:
        soft, hard = min(soft, current_hard), min(hard, current_hard)
    resource.setrlimit(kind, (soft, hard))


def _drop_privileges(owner: Path) -> None:
    """As root, become the owner of `owner` (nobody when that is root), with no groups; never gain privileges."""
    if os.geteuid() == 0:
        info = os.stat(owner)
        uid = info.st_uid or NOBODY
        gid = info.st_gid if info.st_uid and info.st_gid else NOBODY
        os.setgroups([])
        os.setresgid(gid, gid, gid)
        os.setresuid(uid, uid, uid)
        if 0 in os.getresuid() or 0 in os.getresgid():
            raise PermissionError("root privileges are still held after setresuid")
    if _LIBC.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_NO_NEW_PRIVS) failed")
