"""A running swarm from outside: `client` (the one client path, an rclpy node of its own), the
verbs ``swarm lambda``, ``swarm steer`` and friends (`verbs`) and the Foxglove live view (`view`)."""
