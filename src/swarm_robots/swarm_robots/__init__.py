"""Robots for the swarm: a robot description, a pure emulation of diff_drive_controller and a MuJoCo robot world.

The modules here are pure (no ROS import): `description` (the robot), `diff_drive` (the
controller's command path and wheel odometry) and `physics` (the MuJoCo world), `timing` and
`world_setup` (the robot world's place in a run); `mujoco_world_node` is the ROS node over them."""
