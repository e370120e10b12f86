"""A segment writer killed at random moments leaves a file that `repair` turns into a readable bag, losing ≤ 1 s."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from rosbags.rosbag2 import Reader

from plem.middleware.types import library
from plem.recording.repair import repair

WRITER = """
    import sys, time, numpy as np
    from pathlib import Path
    from plem.middleware.types import library
    from plem.ipc.records import raw_record_length
    from plem.middleware.raw_cdr import RawEncoder
    from plem.recording.segment import SegmentWriter
    encoder, record = RawEncoder(6), np.zeros(raw_record_length(6))
    segment = SegmentWriter(Path(sys.argv[1]), [("/r/rt_raw", "plem_msgs/msg/RtRaw")], library().store,
                            sys.argv[2])
    cycle = 0
    while True:
        record[0] = cycle
        segment.append("/r/rt_raw", 1_700_000_000_000_000_000 + cycle * 1_000_000, encoder.encode(record, 0))
        segment.flush_due()
        if cycle % 100 == 0:
            print(cycle, flush=True)
        cycle += 1
        time.sleep(0.001)
"""


@pytest.mark.parametrize(("storage", "seed"),
                         [("mcap", 0), ("sqlite3", 0)]  # one moment per storage in the fast suite, more in the slow
                         + [pytest.param(storage, seed, marks=pytest.mark.slow)
                            for storage, seed in (("mcap", 1), ("mcap", 2), ("mcap", 3), ("sqlite3", 1))])
def test_sigkill_at_a_random_moment_loses_at_most_the_last_second(tmp_path: Path, storage: str, seed: int):
    directory = tmp_path / "segment"
    writer = subprocess.Popen([sys.executable, "-c", textwrap.dedent(WRITER), str(directory), storage],
                              stdout=subprocess.PIPE, text=True)
    assert writer.stdout.readline().strip() == "0", "the writer wrote its first message"
    time.sleep(random.Random(seed).uniform(0.0, 2.7))  # counted from the first write, however slow the start
    writer.send_signal(signal.SIGKILL)
    printed = [int(line) for line in writer.communicate()[0].split()]
    report = repair(directory)
    with Reader(directory) as reader:
        messages = [(stamp, data) for _, stamp, data in reader.messages()]
    stamps = [stamp for stamp, _ in messages]
    cycles = [library().store.deserialize_cdr(data, "plem_msgs/msg/RtRaw").cycle for _, data in messages]
    assert report.repaired and report.messages == len(stamps)
    assert cycles == list(range(len(cycles))), "every recovered cycle, in order, none twice"
    assert all(later > earlier for earlier, later in zip(stamps, stamps[1:], strict=False))
    written = printed[-1] if printed else 0          # at least this many were written before the kill
    assert len(cycles) >= written - 1100, f"lost more than about a second: {len(cycles)} of >= {written}"
