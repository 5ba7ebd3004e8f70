"""Engines that run a whole scenario without ROS, and what they write.

`reference`: the batch engine in numpy, the reference the ROS nodes equal bit for bit;
`fast`: the study fast path, a law's compiled whole run where it has one (numba, imported on
first use); `trajectory`: a run's states;
`registry`: engines by name, including those other packages register."""
from swarm_core.engine.reference import SwarmStepper, simulate
from swarm_core.engine.trajectory import Trajectory

__all__ = ['SwarmStepper', 'Trajectory', 'simulate']
