"""`EtherCATBus`: the IBus of a real arm, one CiA402 drive per joint in cyclic synchronous position, on pysoem.

One exchange per cycle: `write()` packs the outputs, sends the frame and waits for it to come back, at
most `RECEIVE_SHARE` of the cycle (a later answer counts as lost, so the loop never blocks past its
deadline); the next cycle's `read()` decodes what came back. The working counter is checked every cycle:
lost frames and wrong counters are counted in `status`, the round trip of every exchange in
`round_trip`; the last good inputs stand in for a bad cycle, and `bad_cycles_to_fault` consecutive bad
cycles make `read()` fail, which faults the arm naming the slaves that stopped answering. While frames
come back with a short working counter (a slave fell to SAFEOP, e.g. on its watchdog), the bus asks the
slaves for OP again every `RECOVERY_PERIOD_S`, acknowledging their errors: one broadcast register write,
with the drives kept disabled, so a reset can enable them once the counter is whole. No mailbox traffic
runs while the segment is in OP.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from plem.control.timing import TimingSeries
from plem.errors import PlemError
from plem.fieldbus.bus import BusIO, BusSetup, BusStatus, DriveState
from plem.fieldbus.cia402 import PowerSequencer, decode_statusword
from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.bringup import REG_AL_STATUS, Segment, bring_up, close_master, interface_lock

#: Consecutive cycles without a good working counter that fault the arm (10 ms at 1 kHz).
DEFAULT_BAD_CYCLES_TO_FAULT = 10
#: Longest wait for a frame to come back, as a share of the cycle time.
RECEIVE_SHARE = 0.5
#: While frames come back but some slave is out of OP, ask every slave for OP (acknowledging errors) this often.
RECOVERY_PERIOD_S = 0.2
OP_WITH_ACKNOWLEDGE = 0x18
#: Cycles `close()` exchanges at most while the drives switch off, before the slaves leave OP.
CLOSING_CYCLES = 50

_RX_DTYPE = np.dtype([(e.name, e.dtype) for e in objects.RX_ENTRIES])
_TX_DTYPE = np.dtype([(e.name, e.dtype) for e in objects.TX_ENTRIES])


class EtherCATBus:
    """The arm's drives on an EtherCAT segment (IBus); `setup.drives` gives ids, gearing and direction."""

    def __init__(self, *, bad_cycles_to_fault: int = DEFAULT_BAD_CYCLES_TO_FAULT) -> None:
        if not isinstance(bad_cycles_to_fault, int) or bad_cycles_to_fault < 1:
            raise PlemError("invalid number of bad EtherCAT cycles before a fault",
                            what="a whole number ≥ 1", why=f"got {bad_cycles_to_fault!r}",
                            how=f"use the default, {DEFAULT_BAD_CYCLES_TO_FAULT}")
        self.bad_cycles_to_fault = bad_cycles_to_fault
        self.io = BusIO(0)
        self.status = BusStatus()
        self.segment: Segment | None = None
        self.round_trip = TimingSeries(10_000)
        self._held = contextlib.ExitStack()
        self._wkc = 0

    # ---- IBus -------------------------------------------------------------------------------------

    def open(self, setup: BusSetup) -> None:
        """Bring the drives of `setup` to OP on `setup.network_interface`, disabled and holding where they are."""
        n = setup.dof
        self.io = BusIO(n)
        self._rx = np.zeros(n, dtype=_RX_DTYPE)
        self._tx = np.zeros(n, dtype=_TX_DTYPE)
        self._power = PowerSequencer(n)
        self._bad = 0
        self._decoded = np.zeros(n, dtype=np.uint16)  # the statuswords `_seen` was decoded from
        self._seen = [decode_statusword(0)] * n
        cycle_ns = round(setup.cycle_time_s * 1e9)
        self._receive_timeout_us = max(50, round(setup.cycle_time_s * 1e6 * RECEIVE_SHARE))
        self._recovery_cycles = max(1, round(RECOVERY_PERIOD_S / setup.cycle_time_s))
        with contextlib.ExitStack() as held:
            held.enter_context(interface_lock(setup.network_interface, f"an RT driver (master {setup.master_index})"))
            self.segment = bring_up(setup.network_interface, setup.joint_names, setup.drives, cycle_ns,
                                    self._hold_exchange)
            self._held = held.pop_all()
        self._slaves = self.segment.slaves
        self._master = self.segment.master
        self._expected = self._master.expected_wkc
        gear = np.array([d.gear_ratio for d in setup.drives])
        direction = np.array([d.direction for d in setup.drives])
        self._newton_metres_per_unit = np.array(self.segment.rated_torque_mnm) / 1e6 * gear * direction
        self._units_per_newton_metre = np.divide(1.0, self._newton_metres_per_unit,
                                                 out=np.zeros(n), where=self._newton_metres_per_unit != 0)
        self.status = BusStatus(expected_working_counter=self._expected)
        self.round_trip = TimingSeries(10_000)
        self._decode()
        self.io.target_position[:] = self.io.position
        self._send()
        self._period_s = setup.cycle_time_s
        self._keepalive = _Keepalive(self._send, setup.cycle_time_s)

    def close(self) -> None:
        """Disable the drives (switch on disabled), then bring the slaves to SAFEOP and INIT; safe to repeat."""
        segment, self.segment = self.segment, None
        if segment is None:
            return
        self._keepalive.stop()
        try:
            self._power.request(DriveState.SWITCH_ON_DISABLED)
            for _ in range(CLOSING_CYCLES):
                time.sleep(self._period_s)
                self._send()
                if self._wkc == self._expected:
                    self._decode()
                if all(state is DriveState.SWITCH_ON_DISABLED or state is DriveState.FAULT for state in self._seen):
                    break
        except Exception:  # noqa: BLE001 - the segment may be gone: the drives stop on their watchdog
            pass
        finally:
            close_master(segment.master)
            self._held.close()

    def read(self) -> bool:
        """The answer to the last exchange into `io`; False after `bad_cycles_to_fault` bad cycles in a row."""
        if self._keepalive.running:
            self._keepalive.stop()
        status, wkc = self.status, self._wkc
        status.working_counter = wkc
        if wkc == self._expected:
            self._decode()
            if self._bad:
                self._bad = 0
                status.communication_ok = True
                status.detail = ""
            return True
        if wkc <= 0:
            status.lost_frames += 1
        else:
            status.working_counter_errors += 1
        self._bad += 1
        if wkc > 0 and self._bad % self._recovery_cycles == 0:
            self._request_operational()
        if self._bad < self.bad_cycles_to_fault:
            return True
        if status.communication_ok:
            status.communication_ok = False
            status.detail = self._silent_slaves(wkc)
            self._power.master_lost()
        return False

    def write(self) -> None:
        """Exchange this cycle's targets and the controlwords that move each drive toward the wanted state."""
        self._send()

    def drive_state(self, drive: int) -> DriveState:
        """The power state of one drive, from its last statusword."""
        return self._seen[drive]

    def enable(self) -> None:
        """Request operation enabled on every drive (shutdown → switch on → enable operation)."""
        self._power.request(DriveState.OPERATION_ENABLED)

    def disable(self) -> None:
        """Request switch on disabled on every drive."""
        self._power.request(DriveState.SWITCH_ON_DISABLED)

    def fault_reset(self) -> None:
        """One fault-reset edge (controlword bit 7) to every drive in fault."""
        self._power.request_reset()

    # ---- internals --------------------------------------------------------------------------------

    def _hold_exchange(self, master: Any) -> None:
        """While the segment comes up: frames with zero outputs (drives disabled) keep the watchdogs fed."""
        master.send_processdata()
        master.receive_processdata(2000)

    def _decode(self) -> None:
        tx, io = self._tx, self.io
        for i, slave in enumerate(self._slaves):
            tx[i] = np.frombuffer(slave.input, dtype=_TX_DTYPE, count=1)[0]
        io.statusword[:] = tx["statusword"]
        io.position[:] = tx["position_actual"]
        io.velocity[:] = tx["velocity_actual"]
        np.multiply(tx["torque_actual"], self._newton_metres_per_unit, out=io.torque)
        io.error_code[:] = tx["error_code"]
        if not np.array_equal(io.statusword, self._decoded):
            self._seen = [decode_statusword(int(sw)) for sw in io.statusword]
            self._decoded[:] = io.statusword

    def _send(self) -> None:
        rx, io = self._rx, self.io
        rx["controlword"] = self._power.commands(self._seen)
        rx["target_position"] = io.target_position
        rx["velocity_offset"] = io.velocity_offset
        rx["torque_offset"] = np.clip(np.rint(io.torque_offset * self._units_per_newton_metre), -32768, 32767)
        rx["mode"] = io.mode
        for slave, record in zip(self._slaves, rx, strict=True):
            slave.output = record.tobytes()
        master = self._master
        sent = time.perf_counter_ns()
        master.send_processdata()
        self._wkc = master.receive_processdata(self._receive_timeout_us)
        self.round_trip.add(time.perf_counter_ns() - sent)

    def _request_operational(self) -> None:
        """Ask every slave for OP, acknowledging an error (slaves already in OP stay there)."""
        master = self._master
        master.state = OP_WITH_ACKNOWLEDGE
        master.write_state()

    def _silent_slaves(self, wkc: int) -> str:
        """Which slaves stopped answering, read from their AL status registers once, at the fault."""
        if wkc <= 0:
            head = f"no frame came back for {self._bad} cycles"
        else:
            head = f"working counter {wkc} instead of {self._expected} for {self._bad} cycles"
        from pysoem import WkcError

        silent, states = [], []
        for position, slave in enumerate(self._slaves):
            try:
                state = int.from_bytes(slave._fprd(REG_AL_STATUS, 2, 1000), "little")  # noqa: SLF001 — register read
            except WkcError:  # no answer: this slave is the one that stopped
                silent.append(str(position))
                continue
            if state & 0x0F != 0x08:
                states.append(f"slave {position} in state 0x{state:02X}")
        parts = [head]
        if silent:
            parts.append(f"slave{'s' if len(silent) > 1 else ''} {', '.join(silent)} did not answer")
        parts.extend(states)
        return "; ".join(parts)


class _Keepalive:
    """Exchanges process data every cycle from OP until the loop's first cycle, so no watchdog expires between."""

    def __init__(self, exchange: Callable[[], None], period_s: float) -> None:
        self._exchange, self._period = exchange, period_s
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="plem-ethercat-keepalive", daemon=True)
        self.running = True
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._period):
            self._exchange()

    def stop(self) -> None:
        """Stop exchanging; returns once the thread's last exchange has ended."""
        self.running = False
        self._stop.set()
        if self._thread is not threading.current_thread():
            self._thread.join()

