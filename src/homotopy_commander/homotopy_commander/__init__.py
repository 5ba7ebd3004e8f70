"""CommanderNode: homotopy parameter schedules and ramps, leader steering programs, and a CLI."""
