"""Launcher, MCAP recorder, replay and reports for homotopy-swarm."""
