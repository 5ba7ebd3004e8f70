"""The names a law's parameters may not take (no ROS).

An agent node declares each parameter of its law as a ROS parameter of its own, beside the
agent's own parameters (`AGENT_PARAMETERS`).  A law parameter named ``x`` or ``dt`` would be
declared twice, and the agent would fail to start, in `swarm run` only.  A parameter named like
a method of `Law` (``parameters``, ``control``) would hide it, in every engine.  So the scenario
refuses such a law when it is loaded (`check_law_names`), for every engine alike, and so does an
agent node started by hand.
"""
from __future__ import annotations

from swarm_core.laws import Law, LawError

#: the ROS parameters an agent node has besides its law's (swarm_agent: agent_node, drivers,
#: robot_driver), rclpy's own among them; ``law`` is the law's kind
AGENT_PARAMETERS = (
    'agent_index', 'agent_name', 'agent_names', 'catch_up_limit', 'comms', 'dt', 'future_tolerance', 'law',
    'leader', 'lockstep_clock', 'mode', 'noise_heading', 'noise_position', 'pair_sums', 'robot', 'run_id', 'seed',
    'stale_after', 'start_type_description_service', 'state_subscribers', 'theta', 'use_sim_time', 'x', 'y',
    'dim', 'z', 'frame', 'ground',     # a 3D run's
    # a robot agent's
    'cmd_type', 'cruise_speed', 'length_scale', 'max_angular', 'max_jump', 'neighbour_timeout',
    'odom_reliability', 'odom_timeout', 'robot_clock', 'robot_frame',
)


def law_attributes() -> tuple:
    """The names of `Law`'s methods and attributes (``kind``, ``dims``, ``parts``,
    ``uses_leaders``), its parameters aside: a parameter of that name would hide them."""
    return tuple(sorted({'kind'} | {n for n in dir(Law) if not n.startswith('_')} - set(Law.param_specs())))


def reserved_names() -> tuple:
    """Every name a law parameter may not take, sorted."""
    return tuple(sorted(set(AGENT_PARAMETERS) | set(law_attributes())))


def _own_parameters(law):
    """(law, name) of each parameter of ``law`` and of the laws it holds (a blend's from and to)."""
    for part in (getattr(law, 'from_law', None), getattr(law, 'to_law', None)):
        if part is not None:
            yield from _own_parameters(part)
    specs = getattr(type(law), 'param_specs', None)
    if callable(specs):
        yield from ((law, name) for name in specs())


def check_law_names(law) -> None:
    """LawError naming the law, the parameter and every reserved name (one line) if a parameter
    of ``law`` (or of a law it holds) takes a reserved name (`reserved_names`)."""
    reserved = reserved_names()
    clash = next(((part, name) for part, name in _own_parameters(law) if name in reserved), None)
    if clash is not None:
        part, name = clash
        raise LawError(f'law {part.kind}: parameter {name!r} takes a reserved name; a law parameter may not be '
                       f'named as an agent node\'s own parameter ({", ".join(sorted(AGENT_PARAMETERS))}) '
                       f'nor as a method of Law ({", ".join(law_attributes())})')
