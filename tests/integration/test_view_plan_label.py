"""The planned path's label in the view says whether the arm ran the plan: a dry run's path says it was not."""

from __future__ import annotations

import numpy as np

from plem.description.validate import validate_package
from plem.view.model import ViewModel
from plem.view.scene import ArmScene
from plem.view.server import start_server


def test_a_plan_is_labelled_not_executed_until_the_arm_moves_along_it():
    report = validate_package("indy7_v2_description")
    assert report.urdf is not None and report.urdf_xml is not None
    names = tuple(joint.name for joint in report.urdf.actuated_joints)
    server = start_server("127.0.0.1", 0, "plan label")
    try:
        scene = ArmScene(server, ViewModel(report.urdf_xml, names))
        start, end = np.zeros(6), np.array([0.5, -0.3, 0.2, 0.0, 0.1, 0.0])
        scene.show_path([start, (start + end) / 2, end], 1.5)
        label = scene._path[-1]
        assert label.text == "plan 1.50 s — dry run — not executed"
        scene.follow_plan(start + 1e-4)                       # a dry run: the arm stays where the plan starts
        assert label.text == "plan 1.50 s — dry run — not executed"
        scene.follow_plan((start + end) / 2)
        assert label.text == "plan 1.50 s — executing"
        scene.follow_plan(end)
        assert label.text == "plan 1.50 s — executed"
        scene.follow_plan(start)                              # moved on afterwards: that plan still ran
        assert label.text == "plan 1.50 s — executed"
    finally:
        server.stop()
