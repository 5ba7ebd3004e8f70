"""``swarm run`` and ``swarm join``: a scenario as ROS 2 processes on one host or several.

`launch` (the verb), `outputs` (what an ended run writes), `processes` (the supervisor and its
children), `params` (every node's parameters from the scenario), `dds` (the DDS set-up of the
children), `robots` (which agents drive robots, and the MuJoCo robot world), `join` (agents of a
run on another host)."""
