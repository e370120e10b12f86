"""The virtual EtherCAT network of one arm: its emulated drives serving frames, and the control of its faults.

`VirtualNetwork.run()` creates the veth pair and namespace, serves the emulated segment on the drive end
until stopped, and removes the network again. A master (plem's, or another SOEM program) opens the
master end like a wired port. A control socket takes fault injections while it runs; `Control` is its
client (tests, `plem ethercat inject`).
"""

from __future__ import annotations

import json
import logging
import os
import socket
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from plem.description.drives import DriveParameters
from plem.errors import PlemError
from plem.fieldbus.ethercat.virtual.drives import EmulatedDrives
from plem.fieldbus.ethercat.virtual.network import VethNamespace
from plem.fieldbus.ethercat.virtual.segment import Segment
from plem.fieldbus.ethercat.virtual.sii import SlaveIdentity
from plem.fieldbus.ethercat.virtual.wire import serve
from plem.ipc.command_socket import FrameReader, connect, frame, listen, remove_own_socket

#: Identity of an emulated drive whose joint declares none (a vendor id reserved for no real vendor).
DEFAULT_VENDOR_ID = 0x00000000
DEFAULT_PRODUCT_CODE = 0x00000402
DEFAULT_REVISION = 0x00010000
#: With no frame for this many cycles, the drives' own clock advances the arm (a stop ramps down).
IDLE_CYCLES = 3
#: SCHED_FIFO priority of the emulated drives when permitted: below the RT driver's loop (98), above
#: everything else, so the virtual network answers like a wire whatever load the machine carries.
PRIORITY = 90
_log = logging.getLogger("plem.ethercat_sim")


def control_name(index: int) -> str:
    """The name of the control socket of virtual network `index` (beside the robots' sockets)."""
    return f"ethercat_sim{index}"


@dataclass(frozen=True)
class Arm:
    """What the emulated drives need of the arm: joints, URDF, drive parameters, cycle and encoder zeros."""

    joint_names: tuple[str, ...]
    urdf_xml: str | None
    drives: tuple[DriveParameters, ...]
    cycle_time_s: float
    encoder_zero: tuple[int, ...] | None = None
    home_position: tuple[float, ...] | None = None
    #: Where the arm starts (initial_positions:=), and the position limits the driver enforces, which the start
    #: found otherwise stays within.
    initial_positions: tuple[float, ...] | None = None
    position_limits: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    #: Objects the drives' dictionaries leave out, as drives that implement fewer do (e.g. rated torque 0x6076).
    missing_objects: frozenset[int] = frozenset()


class ClockedDrives(EmulatedDrives):
    """The emulated drives, stepped by frames and, when frames stop, by their own clock; thread-safe."""

    def __init__(self, arm: Arm) -> None:
        super().__init__(arm.joint_names, arm.urdf_xml, arm.drives, arm.cycle_time_s, raw_zero=arm.encoder_zero,
                         initial_positions=arm.initial_positions, home_position=arm.home_position,
                         position_limits=arm.position_limits)
        self.lock = threading.Lock()
        self.cycle_time_s = arm.cycle_time_s
        self.last_step = time.monotonic()
        self.frames = 0

    def step(self, operational: np.ndarray) -> None:
        """One frame's cycle, under the lock so the idle clock never steps the drives at the same time."""
        with self.lock:
            super().step(operational)
            self.last_step = time.monotonic()
            self.frames += 1

    def communication_lost(self, drive: int) -> None:
        """A drive's quick stop on lost process data, under the lock like every step."""
        with self.lock:
            super().communication_lost(drive)

    def tick_when_idle(self, stop: threading.Event) -> None:
        """Run the drives' clock while no frame arrives (in its own thread, until `stop`)."""
        period = self.cycle_time_s
        while not stop.wait(period):
            with self.lock:
                if time.monotonic() - self.last_step > IDLE_CYCLES * period:
                    self.idle_tick()


def identities(arm: Arm) -> list[SlaveIdentity]:
    """The SII identity of each emulated drive: the description's ids, else the emulator's own."""
    return [SlaveIdentity(vendor_id=d.vendor_id if d.vendor_id is not None else DEFAULT_VENDOR_ID,
                          product_code=d.product_code if d.product_code is not None else DEFAULT_PRODUCT_CODE,
                          revision=d.revision if d.revision is not None else DEFAULT_REVISION,
                          serial=position + 1, name="plem virtual CiA402 drive")
            for position, (joint, d) in enumerate(zip(arm.joint_names, arm.drives, strict=True))]


class VirtualNetwork:
    """One arm's virtual EtherCAT network, numbered `index` (its interfaces and namespace carry the number)."""

    def __init__(self, arm: Arm, index: int = 0, *, seed: int = 0) -> None:
        self.arm = arm
        self.index = index
        self.link = VethNamespace(index)
        self.drives = ClockedDrives(arm)
        self.identities = identities(arm)
        self.seed = seed
        self.stop = threading.Event()

    @property
    def master_interface(self) -> str:
        """The interface a master opens: the near end of the veth pair."""
        return self.link.master_end

    def run(self, ready: Callable[[VirtualNetwork], None] | None = None) -> None:
        """Create the network, serve until `stop` is set, remove the network (on every exit path)."""
        self.segment = Segment(self.identities, self.drives, seed=self.seed, missing_objects=self.arm.missing_objects)
        self._replace_stale_network()
        self.link.create()
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(PRIORITY))
        except PermissionError:
            _log.warning("the emulated drives run at normal priority: frames may come back late on a busy machine")
        control = listen(control_name(self.index))
        threads = [threading.Thread(target=self.drives.tick_when_idle, args=(self.stop,), daemon=True),
                   threading.Thread(target=self._serve_control, args=(control,), daemon=True)]
        try:
            with self.link.open_drive_socket() as sock:
                for thread in threads:
                    thread.start()
                if ready is not None:
                    ready(self)
                serve(sock, self.segment, stop=self.stop)
        finally:
            self.stop.set()
            control.close()
            remove_own_socket(control_name(self.index))
            self.link.remove()

    def _replace_stale_network(self) -> None:
        """Remove a network of this index that no emulator serves any more (left by a killed run)."""
        if not self.link.exists():
            return
        try:
            Control(self.index).state()
        except PlemError:
            remove_own_socket(control_name(self.index))
            self.link.remove()
            return
        raise PlemError(f"virtual EtherCAT network {self.index} is already running",
                        what=f"interface {self.link.master_end} free for a new virtual network",
                        why="another `plem ethercat simulate` or launch with bus:=ethercat_sim serves it",
                        how=f"use it (eth_interface:={self.link.master_end}), stop it, or choose another "
                            "master_index:=")

    # ---- fault injection ----------------------------------------------------------------------------

    def inject(self, request: dict[str, Any]) -> dict[str, Any]:
        """Apply one control request (see `Control`); the answer as a dict."""
        op = request.get("op")
        drives, segment = self.drives, self.segment
        with drives.lock:
            if op == "drive_fault":
                drives.inject_fault(int(request["drive"]), int(request["code"]),
                                           bool(request.get("persistent", False)))
            elif op == "clear_fault":
                drives.clear_fault(int(request["drive"]))
            elif op == "refuse_enable":
                drives.refuse_enable(int(request["drive"]), bool(request.get("refuse", True)))
            elif op == "drop_rate":
                segment.drop_rate = float(request["rate"])
            elif op == "delay":
                segment.delay_s = float(request["seconds"])
            elif op == "push":
                drives.arm.apply_external_torque(int(request["drive"]), float(request["torque"]))
            elif op == "inputs":
                drives.arm.set_digital_inputs(int(request["drive"]), int(request["value"]))
            elif op == "disappear":
                segment.disappear(int(request["slave"]))
            elif op == "reappear":
                segment.reappear(int(request["slave"]))
            elif op != "state":
                raise ValueError(f"unknown control operation {op!r}")
            arm = drives.arm
            return {"ok": True, "frames": drives.frames, "positions": arm.true_positions.tolist(),
                    "velocities": arm.true_velocities.tolist(),
                    "statuswords": drives.statusword.tolist(), "digital_inputs": drives.digital_inputs.tolist(),
                    "position_actual": drives.position_actual.tolist(),
                    "torque_offsets": drives.torque_offset.tolist()}

    def _serve_control(self, server: socket.socket) -> None:
        server.setblocking(True)
        server.settimeout(0.2)
        while not self.stop.is_set():
            try:
                connection, _ = server.accept()
            except (TimeoutError, OSError):
                continue
            with connection:
                connection.settimeout(2.0)
                reader = FrameReader()
                try:
                    requests: list[bytes] = []
                    while not requests:
                        data = connection.recv(65536)
                        if not data:
                            break
                        requests = reader.feed(data)
                    for request in requests:
                        try:
                            answer = self.inject(json.loads(request))
                        except (ValueError, KeyError, TypeError, IndexError, PlemError) as error:
                            answer = {"ok": False, "error": str(error)}
                        connection.sendall(frame(json.dumps(answer).encode()))
                except OSError as error:
                    _log.warning("control connection failed: %s", error)


class Control:
    """A client of a running virtual network's control socket: fault injection and the true arm state."""

    def __init__(self, index: int = 0) -> None:
        self.index = index

    def request(self, op: str, **values: Any) -> dict[str, Any]:
        """Send one operation with its arguments and return the network's JSON answer."""
        connection = connect(control_name(self.index))
        try:
            connection.setblocking(True)
            connection.settimeout(5.0)
            connection.sendall(frame(json.dumps({"op": op, **values}).encode()))
            reader = FrameReader()
            while True:
                try:
                    data = connection.recv(65536)
                except OSError as error:
                    raise PlemError("the virtual EtherCAT network does not answer its control socket",
                                    what=f"an answer to {op}", why=str(error),
                                    how="stop that `plem ethercat simulate` (Ctrl-C) and start it again") from None
                if not data:
                    raise PlemError("the virtual EtherCAT network closed the control connection",
                                    what="an answer to the control request", why="the connection closed",
                                    how="check that `plem ethercat simulate` (or the launch) still runs")
                answers = reader.feed(data)
                if answers:
                    answer: dict[str, Any] = json.loads(answers[0])
                    break
        finally:
            connection.close()
        if not answer.get("ok"):
            raise PlemError(f"the virtual network refused {op}", what="a valid control request",
                            why=str(answer.get("error")), how="check the drive or slave number and the values")
        return answer

    def state(self) -> dict[str, Any]:
        """True joint positions and velocities of the emulated arm, and the drives' statuswords."""
        return self.request("state")
