"""Motion planning: time parameterisation within the joint limits, shared by trajectories and plans."""

from plem.planning.retiming import Timed, fit_to_limits

__all__ = ["Timed", "fit_to_limits"]
