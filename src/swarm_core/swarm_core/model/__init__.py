"""The agent model (no ROS): unit-speed agents in Frenet-Serret frames (eq. 3).

`frenet`: headings, the planar quaternions agents exchange and the frames computed from them;
`integrate`: one step of dr/dt = x, dθ/dt = u (`zoh_step`, what every agent runs; `rk4_step`);
`natural`: the model in three dimensions, natural frames [x y z] steered by (u, v)."""
from swarm_core.model.frenet import frame_from_quaternion, heading_frame, quaternion_from_heading, yaw_from_quaternion
from swarm_core.model.integrate import rk4_step, zoh_step

__all__ = ['frame_from_quaternion', 'heading_frame', 'quaternion_from_heading', 'rk4_step', 'yaw_from_quaternion',
           'zoh_step']
