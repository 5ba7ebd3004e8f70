"""The ``swarm`` command.

``simulate`` and ``sweep`` run the batch engine (no ROS).  The other verbs live in the ROS
packages and are imported only when used, so swarm_core itself never imports rclpy:
each is ``module:function`` taking the remaining argv and returning an exit code.
"""
from __future__ import annotations

import argparse
import importlib
import sys

ROS_VERBS = {
    'run': ('swarm_tools.launch:main', 'run a scenario as ROS 2 nodes (agents as processes)'),
    'lambda': ('homotopy_commander.cli:lambda_main', 'set the homotopy parameter λ of a running swarm'),
    'steer': ('homotopy_commander.cli:steer_main', "set a leader's steering program in a running swarm"),
    'join': ('swarm_tools.join:main', 'start agents on this host that join a run on another host'),
    'record': ('swarm_tools.record:main', 'record a running swarm to an MCAP bag'),
    'report': ('swarm_tools.report:main', 'metrics and figures from an MCAP bag'),
    'play': ('swarm_tools.play:main', 'republish an MCAP bag with its /clock'),
    'kill': ('swarm_world.fault_cli:kill_main', 'kill an agent of a running swarm (fault injection)'),
    'pause': ('swarm_world.fault_cli:pause_main', 'freeze an agent of a running swarm for some seconds'),
    'drop': ('swarm_world.comms_cli:drop_main', 'burst packet loss in a running swarm'),
    'partition': ('swarm_world.comms_cli:partition_main', 'partition a running swarm into groups that cannot hear each other'),
}
CORE_VERBS = {
    'simulate': ('swarm_core.simulate_cli:simulate_main', 'run a scenario in the batch engine (no ROS)'),
    'sweep': ('swarm_core.simulate_cli:sweep_main', "how often a scenario shows the paper's behaviour over seeds"),
    'scenarios': ('swarm_core.simulate_cli:scenarios_main', 'list the shipped scenarios'),
}
VERBS = {**CORE_VERBS, **ROS_VERBS}


def _usage() -> str:
    lines = ['usage: swarm VERB [options]   (swarm VERB --help for each)', '', 'verbs:']
    lines += [f'  {v:<10} {h}' for v, (_, h) in VERBS.items()]
    return '\n'.join(lines)


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help', 'help'):
        print(_usage())
        return 0
    verb, rest = argv[0], argv[1:]
    if verb not in VERBS:
        print(f'swarm: unknown verb {verb!r}\n\n{_usage()}', file=sys.stderr)
        return 2
    target, _ = VERBS[verb]
    mod_name, func_name = target.split(':')
    try:
        func = getattr(importlib.import_module(mod_name), func_name)
    except ImportError as err:
        print(f'swarm {verb}: not available ({err}); run scripts/setup.sh', file=sys.stderr)
        return 2
    try:
        return int(func(rest) or 0)
    except KeyboardInterrupt:
        print(f'swarm {verb}: interrupted', file=sys.stderr)
        return 130


def _argparser(verb: str, description: str) -> argparse.ArgumentParser:
    return argparse.ArgumentParser(prog=f'swarm {verb}', description=description)


if __name__ == '__main__':
    sys.exit(main())
