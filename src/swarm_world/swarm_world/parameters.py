"""The world node's ROS parameters: name → (default, description, limits), one place for each
default, and which of them are one mode's own (`MODE_PARAMETERS`).  The scenario's
(``scenario``, ``seed``, ``duration``, ``dt``) are shared with the commander
(swarm_ros.scenario_params); its movable target and barrier are declared by the node from the
scenario it loads."""
from __future__ import annotations

from swarm_ros import protocol as P
from swarm_ros.msg_checks import FUTURE_TOLERANCE

#: the modes of a world node (parameter ``mode``; `swarm_world.drivers.DRIVERS` drives each)
MODES = ('lockstep', 'realtime')

#: every parameter of a world node, declared whatever its mode (as the agent declares those of
#: every mode); the node keeps those every mode shares as its attributes
WORLD = {
    'mode': ('lockstep', 'lockstep or realtime', dict(choices=MODES)),
    'rtf': (1.0, 'realtime: sim seconds per wall second', dict(lo=1e-3, hi=1e4)),
    'output_dir': ('', 'where to write trajectory.npz at the end ("": nowhere)', {}),
    'progress_every': (50.0, 'progress line every this many sim s (0: none)', dict(lo=0.0, hi=1e9)),
    'view_every': (20, 'markers and metrics every this many steps (0: never)', dict(lo=0, hi=10**9)),
    'clock_every': (1, 'lockstep: publish /clock every this many steps (every node receives each one; '
                    'lockstep inputs carry their own time)', dict(lo=1, hi=10**9)),
    'stall_timeout': (2.0, 'lockstep: repeat the last message after this many wall s', dict(lo=0.1, hi=1e6)),
    'wait_for_recorder': (False, 'lockstep: start step 0 only once /clock has one reader more than the agents '
                          f'and the commander (a recorder; at most {P.RECORDER_MATCH_WAIT:g} s)', {}),
    'step_timeout': (120.0, 'lockstep: give up (exit 1) if one step has not completed after this many wall s',
                     dict(lo=1.0, hi=1e9)),
    'start_timeout': (180.0, 'give up if not everyone is discovered in this many wall s', dict(lo=1.0, hi=1e6)),
    'collision_distance': (0.01, 'pairs closer than this count as a collision', dict(lo=0.0, hi=1e6)),
    'missing_timeout': (10.0, 'lockstep: drop an agent whose state has not come after this many wall s; '
                        'realtime: an agent (not frozen by a fault) that has sent no state for this many wall s '
                        'is lost', dict(lo=0.1, hi=1e6)),
    'step_readers': (0, 'lockstep: readers of the step relay to wait for (one per agent process; 0: one per '
                     'agent)', dict(lo=0, hi=100000)),
    'clock_readers': (0, 'with wait_for_recorder: /clock readers to wait for (0: the recorder; the lockstep '
                      'agents and commander take their time from the step messages)', dict(lo=0, hi=100000)),
    'remote_agents': ('', 'the agents other hosts start (swarm join), comma-separated; announced on /swarm/run',
                      {}),
    'remote_robots': ('', 'the robots of remote agents, NAME=KIND comma-separated (KIND external or mujoco); '
                      'announced on /swarm/run, where swarm join reads them', {}),
    'robot_poses': ('', 'lockstep: the agents on robots of the MuJoCo world, comma-separated: their states come '
                    f'from the robot world ({P.LOCK_ROBOT_STATES}) and only u from their own answers', {}),
    'pid_file': ('', 'JSON {agent: pid} of the agent processes, for kill/pause ("": none)', {}),
    'events_file': ('', 'append every event here as JSON lines ("": output_dir/events.jsonl)', {}),
    'trail_length': (200, 'trail points per agent in the markers', dict(lo=0, hi=100000)),
    'future_tolerance': (FUTURE_TOLERANCE, 'realtime: reject states stamped more than this many sim s ahead '
                         'of the world clock', dict(lo=0.0, hi=1e9)),
}

#: each mode's own parameters (of `WORLD`), given to the mode's driver (`swarm_world.drivers`)
MODE_PARAMETERS = {
    'lockstep': ('clock_every', 'stall_timeout', 'wait_for_recorder', 'step_timeout', 'start_timeout',
                 'missing_timeout', 'step_readers', 'clock_readers', 'robot_poses'),
    'realtime': ('rtf', 'future_tolerance', 'missing_timeout'),
}
