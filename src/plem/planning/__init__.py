"""Motion planning: inverse kinematics, collision checking, OMPL paths and time parameterisation within the limits.

The names here are plain data and the re-timing every trajectory gets; the planner itself
(`plem.planning.planner.Planner`, with pinocchio, coal and OMPL) is imported where it runs.
"""

from plem.planning.goals import JointGoal, NamedGoal, Plan, PlanOptions, PoseGoal
from plem.planning.poses import Pose
from plem.planning.retiming import Timed, along_straight_lines, fit_to_limits
from plem.planning.scene import Box, Cylinder, Mesh, PlanningScene, SceneObject, Sphere
from plem.planning.sequence import Circular, Joint, Linear, ToolLimits

__all__ = ["Box", "Circular", "Cylinder", "Joint", "JointGoal", "Linear", "Mesh", "NamedGoal", "Plan", "PlanOptions",
           "PlanningScene", "Pose", "PoseGoal", "SceneObject", "Sphere", "Timed", "ToolLimits", "along_straight_lines",
           "fit_to_limits"]
