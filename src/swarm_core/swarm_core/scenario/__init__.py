"""Scenario files (no ROS): everything a run needs, checked before anything runs.

`loader` reads and checks a file (`load`, `parse`; a bad file raises `ScenarioError` naming the
field); `sections` holds the schema of its world, faults, comms and expect sections;
`placement` says who is in the swarm and where each agent starts."""
from swarm_core.scenario.loader import Scenario, ScenarioError, load, parse, resolve, shipped_scenarios

__all__ = ['Scenario', 'ScenarioError', 'load', 'parse', 'resolve', 'shipped_scenarios']
