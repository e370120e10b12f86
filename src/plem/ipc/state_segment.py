"""The state segment `/{robot_id}_joint_actual_values`: a versioned header and the loop's state block.

The header says what the block holds (magic, layout version, DOF, a hash of the joint names, cycle time),
who writes it (owner pid), the joint limits and the named poses (SRDF group states), so a client can
validate commands and name targets without the description package. The state block behind it is the
seqlock of `plem.control.state`; its per-cycle time stamp is the driver's heartbeat. A segment whose
owner is gone, or whose heartbeat stopped, is stale and may be replaced by a driver of the same user; a
live one is never taken over, another user's never touched.
"""

from __future__ import annotations

import hashlib
import json
import logging
import os
import struct
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plem.control.limits import ArmLimits
from plem.control.state import JointState, StateBlock
from plem.errors import ConfigError
from plem.ipc.segment import SegmentError, SharedSegment

MAGIC = b"PLEMSTAT"
LAYOUT_VERSION = 2
NAMES_BYTES = 1024
_HEADER = struct.Struct("<8sIIQq16s")  # magic, layout version, dof, cycle time ns, owner pid, joint-name hash
POSES_BYTES = 4096
NAMES_OFFSET = 64                        # fixed header area, joint names, named poses (JSON), limits, the block
POSES_OFFSET = NAMES_OFFSET + NAMES_BYTES
LIMITS_OFFSET = POSES_OFFSET + POSES_BYTES
LIMIT_ROWS = ("min_position", "max_position", "max_velocity", "max_acceleration", "max_jerk", "max_effort")
STALE_AFTER_NS = 2_000_000_000
_log = logging.getLogger("plem.ipc")


def state_segment_name(robot_id: str) -> str:
    """The spec's name of a robot's state segment."""
    return f"/{robot_id}_joint_actual_values"


def joint_names_hash(joint_names: Sequence[str]) -> bytes:
    """A 16-byte digest of the joint names in order, so a reader can tell it maps the arm it expects."""
    return hashlib.blake2b("\0".join(joint_names).encode(), digest_size=16).digest()


@dataclass(frozen=True)
class SegmentHeader:
    """What a state segment says about itself."""

    dof: int
    cycle_time_ns: int
    owner_pid: int
    joint_names: tuple[str, ...]


def _block_offset(dof: int) -> int:
    return LIMITS_OFFSET + len(LIMIT_ROWS) * dof * 8


def _limits_view(buffer: memoryview, dof: int) -> np.ndarray:
    return np.ndarray((len(LIMIT_ROWS), dof), dtype=np.float64, buffer=buffer, offset=LIMITS_OFFSET)


def process_alive(pid: int) -> bool:
    """True while `pid` runs; a zombie (dead, not yet reaped) counts as gone."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        pass
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rpartition(")")[2].split()[0] != "Z"


class StateSegment:
    """A state segment mapped by its writer (`create`) or by a reader (`attach`)."""

    def __init__(self, segment: SharedSegment, header: SegmentHeader) -> None:
        self.segment = segment
        self.header = header
        self._limits = _limits_view(segment.buffer, header.dof)
        self.block = StateBlock(header.dof, segment.buffer, _block_offset(header.dof))

    @property
    def name(self) -> str:
        """The shared-memory name, e.g. /indy_joint_actual_values."""
        return self.segment.name

    @property
    def poses(self) -> dict[str, list[float]]:
        """Named joint poses, e.g. {'home': [...]} from the SRDF."""
        text = bytes(self.segment.buffer[POSES_OFFSET:LIMITS_OFFSET]).rstrip(b"\0")
        poses: dict[str, list[float]] = json.loads(text or b"{}")
        return poses

    @property
    def limits(self) -> ArmLimits:
        """The joint limits the driver enforces (a copy)."""
        return ArmLimits(self.header.joint_names, *self._limits.copy())

    def driver_gone(self, state: JointState | None) -> str | None:
        """Why the driver writing this segment is gone, or None while it runs.

        `state` is the newest state read from the block; the driver is gone once its process has ended
        (a zombie counts as ended) or once that state's time, its heartbeat, is older than STALE_AFTER_NS.
        """
        owner = self.header.owner_pid
        if not process_alive(owner):
            return f"its process {owner} has ended"
        age = None if state is None else time.monotonic_ns() - state.monotonic_ns
        if age is not None and age > STALE_AFTER_NS:
            return f"its last cycle was {age / 1e9:.1f} s ago"
        return None

    @staticmethod
    def size(dof: int) -> int:
        """Bytes of a state segment for `dof` joints: header, names, poses, limits and the state block."""
        return _block_offset(dof) + StateBlock.nbytes(dof)

    @classmethod
    def create(cls, robot_id: str, limits: ArmLimits, cycle_time_ns: int, *,
               poses: Mapping[str, Sequence[float]] | None = None, mode: int = 0o600, group: int | None = None,
               warn: Callable[[str], None] = _log.warning) -> StateSegment:
        """Create the segment for the RT driver; replaces a stale one (with a warning), refuses a live one.

        Only a leftover of the creating user is ever replaced: a name held by another user, or by a FIFO,
        link or directory, is a SegmentError that names its owner and is left alone.
        """
        name = state_segment_name(robot_id)
        joint_names = limits.joint_names
        names = "\n".join(joint_names).encode()
        poses_json = json.dumps({name: list(map(float, values)) for name, values in (poses or {}).items()}).encode()
        if len(names) > NAMES_BYTES or len(poses_json) > POSES_BYTES:
            raise ConfigError("joint names or named poses too long for the state segment",
                              what=f"at most {NAMES_BYTES} bytes of names and {POSES_BYTES} of poses",
                              why=f"{len(names)} and {len(poses_json)} bytes", how="use shorter names or fewer poses")
        if SharedSegment.own_leftover(name):
            cls._replace_stale(robot_id, name, warn)
        segment = SharedSegment.create(name, cls.size(len(joint_names)), mode, group)
        try:
            buffer = segment.buffer
            buffer[NAMES_OFFSET:NAMES_OFFSET + len(names)] = names
            buffer[POSES_OFFSET:POSES_OFFSET + len(poses_json)] = poses_json
            header = SegmentHeader(len(joint_names), cycle_time_ns, os.getpid(), tuple(joint_names))
            _limits_view(buffer, header.dof)[:] = [getattr(limits, row) for row in LIMIT_ROWS]
            buffer[:_HEADER.size] = _HEADER.pack(MAGIC, LAYOUT_VERSION, header.dof, cycle_time_ns, header.owner_pid,
                                                 joint_names_hash(joint_names))
        except BaseException:   # never leave a half-written segment behind
            segment.close()
            SharedSegment.unlink(name)
            raise
        return cls(segment, header)

    @classmethod
    def _replace_stale(cls, robot_id: str, name: str, warn: Callable[[str], None]) -> None:
        """Remove this user's segment left by a driver that is gone; a live driver's is refused."""
        try:
            existing = cls.attach(robot_id)
        except SegmentError as error:
            warn(f"replacing unreadable shared memory {name} ({error.summary})")
            SharedSegment.unlink(name)
            return
        try:
            owner = existing.header.owner_pid
            live = owner != os.getpid() and existing.driver_gone(existing.block.read(retries=100)) is None
        finally:
            existing.close()
        if live:
            raise SegmentError(f"robot '{robot_id}' already has a running RT driver",
                               what=f"one RT driver per robot_id; {name} must be free",
                               why=f"{name} belongs to the running process {owner}",
                               how=f"stop that robot first, or give this one another robot_id:=... "
                                   f"(kill {owner} if it is a leftover)")
        warn(f"replacing stale shared memory {name} left by process {owner}, which is gone "
             "or stopped updating it")
        SharedSegment.unlink(name)

    @classmethod
    def attach(cls, robot_id: str, expected_dof: int | None = None) -> StateSegment:
        """Map a robot's state segment for reading; checks magic, layout version and, if given, the DOF."""
        name = state_segment_name(robot_id)
        segment = SharedSegment.open(name)
        try:
            header = cls._read_header(segment)
        except SegmentError:
            segment.close()
            raise
        if expected_dof is not None and expected_dof != header.dof:
            segment.close()
            raise SegmentError("IPC DOF mismatch", what=f"a state segment for {expected_dof} joints",
                               why=f"{name} was created for {header.dof} joints "
                                   f"({', '.join(header.joint_names)})",
                               how="use the description package the robot was launched with, "
                                   "or connect without an expected DOF")
        return cls(segment, header)

    @staticmethod
    def _read_header(segment: SharedSegment) -> SegmentHeader:
        buffer = segment.buffer
        if segment.size < LIMITS_OFFSET:
            raise SegmentError(f"{segment.name} is not a plem state segment", what="a plem state segment",
                               why=f"it is only {segment.size} bytes", how="remove it and restart the robot")
        magic, version, dof, cycle_ns, pid, digest = _HEADER.unpack(bytes(buffer[:_HEADER.size]))
        if magic != MAGIC or version != LAYOUT_VERSION:
            raise SegmentError(f"{segment.name} has an unknown layout",
                               what=f"magic {MAGIC!r} with layout version {LAYOUT_VERSION}",
                               why=f"found magic {magic!r}, version {version}",
                               how="run the same plem version for the driver and the client, or remove the "
                                   f"segment {segment.name} if no driver runs")
        names = tuple(bytes(buffer[NAMES_OFFSET:POSES_OFFSET]).rstrip(b"\0").decode().split("\n"))
        if len(names) != dof or joint_names_hash(names) != digest or segment.size < StateSegment.size(dof):
            raise SegmentError(f"{segment.name} is inconsistent", what="header, joint names and size that agree",
                               why=f"DOF {dof}, {len(names)} joint names, {segment.size} bytes",
                               how="restart the robot (the segment will be recreated)")
        return SegmentHeader(dof, cycle_ns, pid, names)

    def close(self) -> None:
        """Drop the block's views, then unmap; closing twice does nothing more."""
        for view in ("block", "_limits"):
            if hasattr(self, view):
                delattr(self, view)
        self.segment.close()

    def remove(self) -> None:
        """Unmap and unlink (the writer's clean exit)."""
        name = self.segment.name
        self.close()
        SharedSegment.unlink(name)
