"""A cancel reaches a running IK search: the planner's service ends it at once with PREEMPTED, however long the
request asked to search, and serves the next request."""

from __future__ import annotations

import threading
from typing import Any

from plem.description.validate import validate_package
from plem.errors import MoveItCode
from plem.planning.goals import MAX_IK_TIMEOUT_S
from plem.planning.service import PlannerService
from tests.e2e.launched import wait_for
from tests.integration.test_planner import Arm
from tests.integration.test_planner_packages import Still

#: A pose no Indy7 reaches: the search would run its whole timeout.
FAR = {"position": [3.0, 0.0, 0.5], "orientation": [0.0, 0.0, 0.0, 1.0]}


def test_a_cancel_ends_a_running_ik_search() -> None:
    arm = Arm(validate_package("indy7_v2_description"))
    service = PlannerService(arm.planner, Still())  # type: ignore[arg-type]
    home = arm.home.tolist()
    answers: list[dict[str, Any]] = []
    request = {"op": "ik", "pose": FAR, "seed": home, "timeout_s": MAX_IK_TIMEOUT_S}
    searching = threading.Thread(target=lambda: answers.append(service.handle(request)), daemon=True)
    searching.start()
    cancelled = wait_for(service.cancel, MAX_IK_TIMEOUT_S)          # the first cancel that finds it running
    searching.join(MAX_IK_TIMEOUT_S * 3)
    assert cancelled is not None and cancelled.startswith("an ik request from this process")
    assert answers[0]["error"]["code"] == MoveItCode.PREEMPTED, answers
    assert service.handle({"op": "fk", "positions": home})["result"]["tcp"]["position"]
