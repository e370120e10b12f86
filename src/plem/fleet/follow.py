"""The continuous export's process (`export_dir:=`): `python -m plem.fleet.follow ROBOT_DIR DEST THRESHOLD`.

The recorder starts it as a child of its own. It drops to the lowest priority the system has (SCHED_IDLE, nice
19) before it imports anything heavy, so all of its work, imports included, runs on CPU time nothing else wants:
never in the real-time driver, and never holding the recorder's interpreter (another process). It exports
closed segments (plem.fleet.continuous) until SIGTERM (the recorder is ending), then makes one last pass.
"""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path


def lower_priority() -> None:
    """Run only on CPU time nothing else wants: SCHED_IDLE where the system has it, and nice 19."""
    with contextlib.suppress(AttributeError, OSError):
        os.sched_setscheduler(0, os.SCHED_IDLE, os.sched_param(0))
    os.setpriority(os.PRIO_PROCESS, 0, 19)


def main(argv: list[str] | None = None) -> int:
    """The export process of one recorder: ROBOT_DIR DEST DISK_THRESHOLD."""
    robot_dir, text, threshold = (sys.argv[1:] if argv is None else argv)[:3]
    lower_priority()
    from plem.fleet.continuous import follow
    from plem.launch.component import begin

    stop = begin("export")
    follow(Path(robot_dir), text, float(threshold), stop)
    return 0


if __name__ == "__main__":
    sys.exit(main())
