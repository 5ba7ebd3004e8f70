"""The commander's logic (no ROS): λ schedules and leader steering programs (`schedules`), their
scenario section (`spec`), and the decisions of each step with live commands (`plan`)."""
from swarm_core.command.plan import CommandPlan, read_commands
from swarm_core.command.schedules import LambdaSchedule, SteeringProgram

__all__ = ['CommandPlan', 'LambdaSchedule', 'SteeringProgram', 'read_commands']
