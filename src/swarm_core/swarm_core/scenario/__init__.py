"""Scenario files (no ROS): everything a run needs, checked before anything runs.

`loader` reads and checks a file (`load`, `parse`; a bad file raises `ScenarioError` naming the
field); `placement` says who is in the swarm and where each agent starts."""
from swarm_core.scenario.loader import Scenario, ScenarioError, load, parse, resolve, shipped_scenarios

__all__ = ['Scenario', 'ScenarioError', 'load', 'parse', 'resolve', 'shipped_scenarios']
