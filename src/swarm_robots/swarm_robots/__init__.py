"""swarm_robots: differential-drive robots on a MuJoCo physics world, driven by the agents."""
