"""The seqlock state block: readers never see a half-written cycle and never block the writer (written here by the
Python stand-in for the core's writer)."""

from __future__ import annotations

import sys
import threading

import numpy as np

from plem.control.modes import Mode
from plem.control.state import ROWS, StateBlock


def test_nothing_published_reads_none_then_a_copy():
    block = StateBlock(6)
    assert block.read() is None
    values = np.arange(len(ROWS) * 6, dtype=float).reshape(len(ROWS), 6)
    block.publish(values, cycle=7, monotonic_ns=123, mode=int(Mode.HOLD), faulted=False, drives_enabled=True)
    state = block.read()
    assert state.cycle == 7 and state.mode is Mode.HOLD and state.drives_enabled and not state.faulted
    assert np.array_equal(state.position, values[0]) and np.array_equal(state.command_acceleration, values[5])
    values[0, 0] = -1.0
    assert state.position[0] == 0.0  # the state is a copy


def test_block_over_an_external_buffer_is_shared():
    buffer = bytearray(StateBlock.nbytes(7))
    writer, reader = StateBlock(7, buffer), StateBlock(7, buffer)
    writer.publish(np.ones((len(ROWS), 7)), 1, 0, int(Mode.IDLE), False, False)
    assert reader.read().cycle == 1


def test_concurrent_reader_never_sees_a_torn_sample():
    previous = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as possible so a tear would show up
    block = StateBlock(7)
    stop = threading.Event()
    torn: list[int] = []

    def write() -> None:
        values = np.zeros((len(ROWS), 7))
        cycle = 0
        while not stop.is_set():
            cycle += 1
            values.fill(cycle)  # every value of one sample equals its cycle number
            block.publish(values, cycle, cycle, int(Mode.TRAJECTORY), False, True)

    writer = threading.Thread(target=write)
    writer.start()
    seen = 0
    try:
        while seen < 3000:
            state = block.read()
            if state is None:
                continue
            seen += 1
            for row in (state.position, state.velocity, state.effort, state.command_position):
                if not np.all(row == state.cycle):
                    torn.append(state.cycle)
    finally:
        stop.set()
        writer.join()
        sys.setswitchinterval(previous)
    assert not torn
