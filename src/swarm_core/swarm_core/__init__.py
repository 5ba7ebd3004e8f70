"""Pure numpy model of Morgan and Schwartz swarm control laws: integrator, scenarios, metrics, batch engine (no ROS)."""
