"""The event log keeps faults apart from the other events, so the newest fault is never pushed out."""

from __future__ import annotations

from dataclasses import replace

from plem.control.events import FAULT_HISTORY, EventKind, EventLog, newest_fault
from plem.control.modes import Mode
from plem.ipc.records import event_from_record, event_record


def overruns(log: EventLog, count: int) -> None:
    for i in range(count):
        log.emit(EventKind.OVERRUN, "overrun", f"report {i}", Mode.FAULT, 2000 + i)


def test_a_flood_of_other_events_never_pushes_the_newest_fault_out():
    log = EventLog(capacity=100)
    log.emit(EventKind.MODE_CHANGED, "drives_enabled", "all drives enabled", Mode.HOLD, 10, Mode.IDLE)
    fault = log.emit(EventKind.FAULT, "drive_fault", "joint3 drive fault: 0x7121 motor blocked", Mode.FAULT, 1000,
                     Mode.HOLD)
    overruns(log, 150)
    assert not log.recent({EventKind.FAULT}), "the general log is bounded: the fault left it"
    assert log.last_fault() is fault
    assert log.faults() == [fault]


def test_the_last_fault_stays_known_after_it_was_cleared_and_later_faults_replace_it():
    log = EventLog()
    assert log.last_fault() is None and log.faults() == []
    first = log.emit(EventKind.FAULT, "tracking_error", "joint2 is 0.06 rad from its command", Mode.FAULT, 5, Mode.HOLD)
    cleared = log.emit(EventKind.FAULT_CLEARED, "reset_fault", first.reason, Mode.HOLD, 900)
    assert log.last_fault() is first and log.faults() == [first, cleared]
    second = log.emit(EventKind.FAULT, "drive_fault", "joint1 drive fault", Mode.FAULT, 1200, Mode.HOLD)
    assert log.last_fault() is second and newest_fault(log.faults()) is second


def test_the_fault_history_is_bounded():
    log = EventLog()
    for cycle in range(FAULT_HISTORY + 10):
        log.emit(EventKind.FAULT, "drive_fault", f"fault {cycle}", Mode.FAULT, cycle, Mode.HOLD)
        log.emit(EventKind.FAULT_CLEARED, "reset_fault", f"fault {cycle}", Mode.HOLD, cycle)
    history = log.faults()
    assert len(history) == FAULT_HISTORY and history[-1].kind is EventKind.FAULT_CLEARED
    assert log.last_fault().reason == f"fault {FAULT_HISTORY + 9}"


def test_an_event_too_long_for_its_ring_slot_is_cut_short_and_still_reads_back():
    log = EventLog()
    reason = "joint_with_a_long_name² " * 200
    event = log.emit(EventKind.MOTION_STARTED, "trajectory", reason, Mode.TRAJECTORY, 7)
    record = event_record(event, 1024)
    assert len(record) <= 1024
    back = event_from_record(record)
    assert back.reason.endswith("…") and reason.startswith(back.reason[:-1]) and len(back.reason) > 100
    assert event_from_record(event_record(replace(event, reason="short"))).reason == "short"
