"""`EtherCATBus`: a real arm's drives, one CiA402 drive per joint in cyclic synchronous position, on the core's master.

Python opens the segment (`bringup`) and closes it; in between, the compiled core's cycle exchanges the process
data through the same SOEM master: it receives the answer to last cycle's frame, decodes it, runs the arm and
sends the next frame, checking the working counter every cycle. Lost frames and short working counters are
counted (`status`), the last good inputs stand in for a bad cycle, and `bad_cycles_to_fault` bad cycles in a
row fault the arm; `status.detail` then names the slaves that stopped answering. While frames come back with a
short working counter (a slave fell to SAFEOP, e.g. on its watchdog), `service()` (the core's service thread)
asks every slave for OP again every `RECOVERY_PERIOD_S`, acknowledging their errors: one broadcast register
write, the drives kept disabled, so a reset can enable them once the counter is whole. From OP until the core's
first cycle the master's own keepalive thread (C, never waiting for the interpreter) exchanges frames, so no
watchdog expires in between however long Python takes to build the rest of the robot.
"""

from __future__ import annotations

import contextlib
import logging
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from plem.control.compiled import CONSTANTS, MASTER_STATUS
from plem.control.timing import CoreSeries
from plem.description.drives import DriveParameters
from plem.errors import CommandRejected, PlemError
from plem.fieldbus.bus import BusIO, BusSetup, BusStatus, DriveState
from plem.fieldbus.cia402 import PowerSequencer, decode_statusword
from plem.fieldbus.ethercat import objects
from plem.fieldbus.ethercat.bringup import (
    OP_STATE,
    REG_AL_STATUS,
    RatedTorque,
    Segment,
    bring_up,
    close_master,
    interface_lock,
    per_mille_warning,
)

#: Consecutive cycles without a good working counter that fault the arm (10 ms at 1 kHz).
DEFAULT_BAD_CYCLES_TO_FAULT = 10
#: Longest wait for last cycle's answer, as a share of the cycle time: it has had a whole period to come back, and
#: an answer up to half a period later still arrives in time for this cycle's work.
RECEIVE_SHARE = 0.5
#: Longest wait for an answer outside the cycle (bring-up, keepalive, shut-down), µs.
EXCHANGE_TIMEOUT_US = 2000
#: While frames come back but some slave is out of OP, ask every slave for OP (acknowledging errors) this often.
RECOVERY_PERIOD_S = 0.2
OP_WITH_ACKNOWLEDGE = OP_STATE | 0x10
#: Cycles `close()` exchanges at most while the drives switch off, before the slaves leave OP.
CLOSING_CYCLES = 50

_log = logging.getLogger("plem.ethercat")
_RX_DTYPE = np.dtype([(e.name, e.dtype) for e in objects.RX_ENTRIES])
_TX_DTYPE = np.dtype([(e.name, e.dtype) for e in objects.TX_ENTRIES])


def _check_pdo_layout() -> None:
    """The core packs the PDOs at the offsets `objects` assigns: compare both sides once, at import."""
    expected = {f"PLEM_RX_{name.upper()}": at for name, at in objects.offsets(objects.RX_ENTRIES).items()}
    expected |= {f"PLEM_TX_{name.removesuffix('_actual').upper()}": at
                 for name, at in objects.offsets(objects.TX_ENTRIES).items()}
    expected |= {"PLEM_RX_BYTES": _RX_DTYPE.itemsize, "PLEM_TX_BYTES": _TX_DTYPE.itemsize,
                 "PLEM_TX_DIGITAL_INPUTS": _TX_DTYPE.itemsize,
                 "PLEM_TX_BYTES_WITH_INPUTS": _TX_DTYPE.itemsize + objects.DIGITAL_INPUTS.bits // 8}
    differing = sorted(name for name, at in expected.items() if CONSTANTS.get(name) != at)
    if differing:
        raise PlemError("the compiled core packs EtherCAT process data differently from plem's PDO assignment",
                        what="the same byte offsets on both sides", why=f"differing: {', '.join(differing)}",
                        how="reinstall plem so its core is compiled from the same sources: `pip install -e .`")


_check_pdo_layout()


class EtherCATBus:
    """The arm's drives on an EtherCAT segment; `setup.drives` gives ids, gearing and direction."""

    def __init__(self, *, bad_cycles_to_fault: int = DEFAULT_BAD_CYCLES_TO_FAULT) -> None:
        if not isinstance(bad_cycles_to_fault, int) or bad_cycles_to_fault < 1:
            raise PlemError("invalid number of bad EtherCAT cycles before a fault",
                            what="a whole number ≥ 1", why=f"got {bad_cycles_to_fault!r}",
                            how=f"use the default, {DEFAULT_BAD_CYCLES_TO_FAULT}")
        self.bad_cycles_to_fault = bad_cycles_to_fault
        self.io = BusIO(0)
        self.joint_names: tuple[str, ...] = ()
        self.segment: Segment | None = None
        self._held = contextlib.ExitStack()
        self._status: np.ndarray | None = None
        self._detail = ""
        self._recovered_at = 0.0
        self._period_s = 0.001

    @property
    def core_master(self) -> Any:
        """The master the core's cycle exchanges through (None while closed)."""
        return None if self.segment is None else self.segment.master

    @property
    def torque_in_newton_metres(self) -> tuple[bool, ...]:
        """Per drive, whether its torque reads as N·m at the joint (its rated torque is known); empty while closed."""
        return () if self.segment is None else tuple(r.newton_metres is not None for r in self.segment.rated_torque)

    @property
    def free_drive_refusal(self) -> CommandRejected | None:
        """Why free drive cannot run on these drives (None when it can): it holds the arm up with a gravity torque
        in N·m, which a drive whose rated torque is unknown cannot be sent, so without it the arm would fall."""
        if self.segment is None:
            return None
        unknown = [(joint, r.source) for joint, r in zip(self.joint_names, self.segment.rated_torque, strict=True)
                   if r.newton_metres is None]
        if not unknown:
            return None
        return CommandRejected(
            "free drive needs each drive's rated torque",
            what="a rated torque for every drive, to send free drive's gravity torque in the drive's units",
            why=f"unknown for {', '.join(joint for joint, _ in unknown)} ({unknown[0][1]}); without the gravity "
                "torque the arm would fall",
            how='give each joint <param name="rated_torque"> (the motor\'s rated torque in N·m) in the description '
                "package's ros2_control block and launch again; until then move the arm with `plem move`")

    @property
    def exchange(self) -> CoreSeries | None:
        """Time each cycle spends in SOEM's receive and send (None while closed)."""
        return None if self._status is None else CoreSeries(self._status[0]["exchange"])

    # ---- opening and closing ----------------------------------------------------------------------

    def open(self, setup: BusSetup) -> None:
        """Bring the drives of `setup` to OP on `setup.network_interface`, disabled and holding where they are."""
        n = setup.dof
        self.io = BusIO(n)
        self.joint_names = setup.joint_names
        cycle_ns = round(setup.cycle_time_s * 1e9)
        self._period_s = setup.cycle_time_s
        with contextlib.ExitStack() as held:
            held.enter_context(interface_lock(setup.network_interface, f"an RT driver (master {setup.master_index})"))
            segment = bring_up(setup.network_interface, setup.joint_names, setup.drives, cycle_ns, _hold_exchange)
            held.callback(close_master, segment.master)
            segment.master.prepare(torque_units(segment.rated_torque, setup.drives), self.bad_cycles_to_fault,
                                   max(20, round(setup.cycle_time_s * 1e6 * RECEIVE_SHARE)),
                                   [r.newton_metres is not None for r in segment.rated_torque])
            self._held = held.pop_all()
        self.segment = segment
        warning = per_mille_warning(setup.joint_names, segment.rated_torque)
        if warning:
            _log.warning(warning)
        self._status = np.frombuffer(segment.master.status, dtype=MASTER_STATUS)
        self._decode()
        self.io.target_position[:] = self.io.position
        segment.master.start_keepalive(cycle_ns, EXCHANGE_TIMEOUT_US)

    def hand_over(self) -> None:
        """The core's cycle exchanges from now on: stop the keepalive (returns once its last exchange ended)."""
        if self.segment is not None:
            self.segment.master.stop_keepalive()

    def close(self) -> None:
        """Disable the drives (switch on disabled), then bring the slaves to SAFEOP and INIT; safe to repeat.

        Call it once the core's cycle has stopped exchanging."""
        segment = self.segment
        if segment is None:
            return
        self.hand_over()
        try:
            self._switch_off(segment.master)
        except Exception:  # noqa: BLE001 - the segment may be gone: the drives stop on their watchdog
            pass
        finally:
            self.segment = None
            self._held.close()

    def _switch_off(self, master: Any) -> None:
        """Exchange frames whose controlwords take every drive to switch on disabled, holding where it is."""
        self._decode()   # what the drives reported last, to the core's cycle or to the keepalive
        power = PowerSequencer(len(self.io.position))
        power.request(DriveState.SWITCH_ON_DISABLED)
        for _ in range(CLOSING_CYCLES):
            seen = [decode_statusword(int(word)) for word in self.io.statusword]
            if all(state in (DriveState.SWITCH_ON_DISABLED, DriveState.FAULT) for state in seen):
                return
            outputs = np.zeros(len(seen), dtype=_RX_DTYPE)
            outputs["controlword"] = power.commands(seen)
            outputs["target_position"] = self.io.position
            outputs["mode"] = 8
            for slave, record in enumerate(outputs, start=1):
                master.set_outputs(slave, record.tobytes())
            if master.exchange(EXCHANGE_TIMEOUT_US) == self.status.expected_working_counter:
                self._decode()
            time.sleep(self._period_s)

    # ---- what Python reads of the bus ---------------------------------------------------------------

    def _decode(self) -> None:
        """The inputs of the last exchange outside the cycle into `io`."""
        segment, io = self.segment, self.io
        if segment is None:
            return
        size = _TX_DTYPE.itemsize   # the digital inputs some drives map after these are not read here
        inputs = np.frombuffer(b"".join(segment.master.inputs(i + 1)[:size] for i in range(len(segment.slaves))),
                               dtype=_TX_DTYPE)
        io.statusword[:] = inputs["statusword"]
        io.position[:] = inputs["position_actual"]
        io.velocity[:] = inputs["velocity_actual"]
        io.error_code[:] = inputs["error_code"]

    @property
    def status(self) -> BusStatus:
        """The cycle's figures: working counter, lost frames, and while communication is lost, who fell silent."""
        if self._status is None:
            return BusStatus()
        figures = self._status[0]
        ok = bool(figures["communication_ok"])
        if ok:
            self._detail = ""
        elif not self._detail:
            self._detail = self._silent_slaves(int(figures["working_counter"]), int(figures["bad_cycles"]))
        return BusStatus(communication_ok=ok, working_counter=int(figures["working_counter"]),
                         expected_working_counter=int(figures["expected_working_counter"]),
                         lost_frames=int(figures["lost_frames"]),
                         working_counter_errors=int(figures["working_counter_errors"]), detail=self._detail)

    def service(self) -> None:
        """Outside the cycle, often: while frames come back short, ask the slaves for OP every RECOVERY_PERIOD_S."""
        if self._status is None or self.segment is None:
            return
        figures = self._status[0]
        if int(figures["bad_cycles"]) == 0 or int(figures["working_counter"]) <= 0:
            return
        now = time.monotonic()
        if now - self._recovered_at >= RECOVERY_PERIOD_S:
            self._recovered_at = now
            self.segment.master.write_state(OP_WITH_ACKNOWLEDGE)

    def _silent_slaves(self, wkc: int, bad: int) -> str:
        """Which slaves stopped answering, read from their AL status registers once, at the fault."""
        head = (f"no frame came back for {bad} cycles" if wkc <= 0 else
                f"working counter {wkc} instead of {int(self._status[0]['expected_working_counter'])} "
                f"for {bad} cycles") if self._status is not None else "no frame came back"
        if self.segment is None:
            return head
        silent, states = [], []
        for slave in self.segment.slaves:
            state = slave.register(REG_AL_STATUS)
            if state is None:  # no answer: this slave is the one that stopped
                silent.append(str(slave.position))
            elif state & 0x0F != OP_STATE:
                states.append(f"slave {slave.position} in state 0x{state:02X}")
        parts = [head]
        if silent:
            parts.append(f"slave{'s' if len(silent) > 1 else ''} {', '.join(silent)} did not answer")
        parts.extend(states)
        return "; ".join(parts)


def torque_units(rated: Sequence[RatedTorque], drives: Sequence[DriveParameters]) -> list[float]:
    """What one unit of each drive's torque objects is at the joint: N·m (a thousandth of the rated motor torque,
    geared), or, with the rated torque unknown, one per mille itself; signed by the drive's direction."""
    return [drive.direction * (1.0 if r.newton_metres is None else r.newton_metres / 1000.0 * drive.gear_ratio)
            for r, drive in zip(rated, drives, strict=True)]


def _hold_exchange(master: Any) -> None:
    """While the segment comes up: frames with the outputs as they are (drives disabled), so the watchdogs stay
    fed."""
    master.exchange(EXCHANGE_TIMEOUT_US)
