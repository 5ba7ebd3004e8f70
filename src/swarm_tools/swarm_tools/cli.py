"""The ``swarm`` command: one verb table, each verb a function of the remaining argv that
returns an exit code.

Each verb imports its module only when it runs (``swarm simulate`` never loads rclpy), but
the imports are plain ``from ... import`` statements, so tools that follow imports see every
verb, and ``swarm --help`` lists them all.
"""
from __future__ import annotations

import sys


# ---------------------------------------------------------------- the batch engine (no ROS)
def simulate(argv):
    from swarm_tools.simulate import simulate_main
    return simulate_main(argv)


def sweep(argv):
    from swarm_tools.simulate import sweep_main
    return sweep_main(argv)


def scenarios(argv):
    from swarm_tools.simulate import scenarios_main
    return scenarios_main(argv)


def laws(argv):
    from swarm_tools.laws import laws_main
    return laws_main(argv)


# ---------------------------------------------------------------- ROS 2
def run(argv):
    from swarm_tools.run.launch import main
    return main(argv)


def record(argv):
    from swarm_tools.bags.record import main
    return main(argv)


def view(argv):
    from swarm_tools.live.view import main
    return main(argv)


def report(argv):
    from swarm_tools.bags.report import main
    return main(argv)


def play(argv):
    from swarm_tools.bags.play import main
    return main(argv)


def join(argv):
    from swarm_tools.run.join import main
    return main(argv)


def bag(argv):
    from swarm_tools.bags.recover import main
    return main(argv)


# ---------------------------------------------------------------- live verbs (swarm_tools.live.verbs)
def lambda_(argv):
    from swarm_tools.live.verbs import lambda_main
    return lambda_main(argv)


def steer(argv):
    from swarm_tools.live.verbs import steer_main
    return steer_main(argv)


def kill(argv):
    from swarm_tools.live.verbs import kill_main
    return kill_main(argv)


def pause(argv):
    from swarm_tools.live.verbs import pause_main
    return pause_main(argv)


def drop(argv):
    from swarm_tools.live.verbs import drop_main
    return drop_main(argv)


def partition(argv):
    from swarm_tools.live.verbs import partition_main
    return partition_main(argv)


VERBS = {
    'simulate': (simulate, 'run a scenario in the batch engine (no ROS)'),
    'sweep': (sweep, "how often a scenario shows the paper's behaviour over seeds; parameter studies"),
    'scenarios': (scenarios, 'list the shipped scenarios'),
    'laws': (laws, 'list the laws a scenario can name, with their parameters'),
    'run': (run, 'run a scenario as ROS 2 nodes (agents as processes)'),
    'lambda': (lambda_, 'set the homotopy parameter λ of a running swarm'),
    'steer': (steer, "set a leader's steering program in a running swarm"),
    'kill': (kill, 'kill an agent of a running swarm (fault injection)'),
    'pause': (pause, 'freeze an agent of a running swarm for some seconds'),
    'drop': (drop, 'burst packet loss in a running swarm'),
    'partition': (partition, 'partition a running swarm into groups that cannot hear each other'),
    'join': (join, 'start agents on this host that join a run on another host'),
    'record': (record, 'record a running swarm to an MCAP bag'),
    'view': (view, 'serve a running swarm live to the Foxglove app (WebSocket)'),
    'report': (report, 'metrics and figures from an MCAP bag'),
    'play': (play, 'republish an MCAP bag with its /clock'),
    'bag': (bag, 'bag tools: `swarm bag recover IN OUT` repairs a truncated MCAP bag'),
}


def _usage() -> str:
    lines = ['usage: swarm VERB [options]   (swarm VERB --help for each)', '', 'verbs:']
    lines += [f'  {v:<10} {h}' for v, (_, h) in VERBS.items()]
    return '\n'.join(lines)


def main(argv=None) -> int:
    code = _main(argv)
    # a law that left a thread running would hold the process at its exit for ever (loaded
    # only where a law ran: the light verbs import no law)
    guards = sys.modules.get('swarm_core.laws.guards')
    return code if guards is None else guards.exit_now_if_threads_left(code)


def _main(argv) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ('-h', '--help', 'help'):
        print(_usage())
        return 0
    verb, rest = argv[0], argv[1:]
    if verb not in VERBS:
        print(f'swarm: unknown verb {verb!r}\n\n{_usage()}', file=sys.stderr)
        return 2
    func, _ = VERBS[verb]
    try:
        return int(func(rest) or 0)
    except ImportError as err:
        print(f'swarm {verb}: not available ({err}); run scripts/setup.sh', file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f'swarm {verb}: interrupted', file=sys.stderr)
        return 130


if __name__ == '__main__':
    sys.exit(main())
