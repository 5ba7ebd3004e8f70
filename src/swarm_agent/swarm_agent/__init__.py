"""AgentNode: one swarm agent as an rclpy node integrating its own Frenet frame."""
