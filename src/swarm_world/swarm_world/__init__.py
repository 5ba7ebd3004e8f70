"""WorldNode: sim clock and lockstep, target, barrier, swarm view and live metrics."""
