"""``swarm join``: start some agents of a run whose world, commander (and recorder) run on
another host.

The run's host starts ``swarm run SCENARIO --remote-agents LIST --interface ITS_ADDR``; it runs
a discovery server and prints its ``ADDR:PORT``.  Here ``swarm join SCENARIO --agents LIST
--server ADDR:PORT --interface THIS_ADDR`` starts those agents with the same parameters (the
same scenario, seed, dt, duration and mode) as clients of that server.  They take part in
lockstep like local ones.  ``swarm join`` ends when the world has gone from the graph (the run
is over), on Ctrl-C, or if the run does not appear within ``--wait`` seconds.  It starts the
agents once it has heard the run's announcement (``/swarm/run``): they get its run id, so they
take part in that run only.

Robot agents: the run's announcement names the robot of each remote agent (``swarm run
--remote-agents LIST --robots KIND:AGENTS``); ``swarm join`` starts those agents as robot agents
with the scenario's ``robots:`` section (`robots.apply_robots`), driving ``/AGENT/cmd_vel``
from ``/AGENT/odom`` over the network (a MuJoCo robot world runs on the run's host; an external
robot is whatever serves those topics).

Faults: the world signals agents by pid on its own host only; ``swarm kill`` of an agent that
runs here leaves it out of the table (it stops moving and speaking) but does not end its process.
"""
from __future__ import annotations

import argparse
import os
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from swarm_core.laws.paper import compiled_sums
from swarm_ros.runinfo import RunWatch, describe, join_error, one_run, run_robots
from swarm_tools.run import dds
from swarm_tools.run.launch import add_network_options, check_interface, parse_agents, set_state_readers
from swarm_tools.run.params import load_scenario, node_parameters, write_params_file
from swarm_tools.run.processes import REFUSED_EXIT, agent_commands, refused_label, supervised
from swarm_tools.run.robots import apply_robots

#: wall seconds the world may stay out of the graph before ``swarm join`` takes the run as over
GONE_AFTER = 3.0


def _parser():
    p = argparse.ArgumentParser(prog='swarm join', description=(
        'Start agents of a run whose world and commander run on another host (started there with '
        '`swarm run SCENARIO --remote-agents LIST`). Give the same scenario options as that run.'))
    p.add_argument('scenario', help='shipped scenario name or YAML file (the same as the run)')
    p.add_argument('--agents', required=True, metavar='LIST', help='agent indices to start here, e.g. 48-95 or 0,2,5-7')
    p.add_argument('--server', required=True, metavar='ADDR:PORT',
                   help="the run's discovery server (swarm run prints it)")
    add_network_options(p)
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default='lockstep', help='as the run (default lockstep)')
    p.add_argument('--duration', type=float, help="as the run (default: the scenario's)")
    p.add_argument('--seed', type=int, help="as the run (default: the scenario's)")
    p.add_argument('--dt', type=float, help="as the run (default: the scenario's)")
    p.add_argument('--compiled', choices=compiled_sums.CHOICES, default='auto',
                   help='as the run: ' + compiled_sums.HELP)
    p.add_argument('--recorded', action='store_true',
                   help='the run records (swarm run --record): wait for the recorder too')
    p.add_argument('--wait', type=float, default=180.0,
                   help='give up if the world has not appeared after this many s (default 180)')
    return p


def world_present(node) -> bool:
    return any(nm == 'world' and ns == '/' for nm, ns in node.get_node_names_and_namespaces())


@dataclass
class JoinPlan:
    """The agents ``swarm join`` starts here (`plan`): their names and parameters."""
    scenario: str               # as given (for messages)
    roster: list                # every agent of the run
    agents: str                 # --agents as given
    names: list                 # the agents started here
    params: dict                # their parameters; the run id is set once the run is heard
    server: str                 # the run's discovery server, ADDR:PORT
    wait: float                 # s to wait for the run
    scn: object = None          # the scenario (its robots: section)
    mode: str = 'lockstep'
    scenario_hash: str = ''     # Scenario.content_hash: the run's must be the same

    def for_run(self, run: dict) -> str | None:
        """Take the run's id and its robots (the announcement ``run``) into the parameters; the
        line that says the robots (None: none here)."""
        for p in self.params.values():
            p['run_id'] = run['run_id']
        return apply_robots(self.params, self.scn, run_robots(run, self.names), self.mode)


def plan(a, scn, ref: str) -> JoinPlan:
    """What ``a`` (the parsed options) asks to start for the scenario ``scn`` (loaded from
    ``ref``); ValueError naming the first bad option.  Nothing is started or written."""
    idx = parse_agents(a.agents, len(scn.names))
    addr, port = dds.parse_server(a.server)
    if not a.wait > 0:
        raise ValueError(f'--wait {a.wait}: must be > 0')
    names = [scn.names[i] for i in idx]
    params = node_parameters(scn, ref, a.mode, duration=scn.duration, compiled=a.compiled)
    params = {f'/{nm}/agent': params[f'/{nm}/agent'] for nm in names}
    set_state_readers(params, 1 if a.recorded else 0, a.mode)
    return JoinPlan(scenario=a.scenario, roster=list(scn.names), agents=a.agents, names=names, params=params,
                    server=f'{addr}:{port}', wait=a.wait, scn=scn, mode=a.mode, scenario_hash=scn.content_hash)


def main(argv=None) -> int:
    """validate and plan (nothing started), then start the agents once the run is heard and
    watch it until it is over."""
    a = _parser().parse_args(argv)
    scn, ref = load_scenario('swarm join', a)
    if scn is None:
        return 2
    try:
        join = plan(a, scn, ref)
        interface = check_interface(a.interface)
    except ValueError as err:
        print(f'swarm join: {err}', file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix='swarm_join_') as tmp, \
            supervised('swarm join', signals=(signal.SIGINT, signal.SIGTERM)) as (sup, stopped):
        env = dds.environment(len(join.names) + 1, Path(tmp), interface=interface, server=join.server)
        for k in [k for k in os.environ if k not in env]:
            del os.environ[k]               # this process's own graph watcher: a client like the agents
        os.environ.update(env)

        def start(run):
            line = join.for_run(run)
            if line:
                print(f'swarm join: {line}', flush=True)
            ros = ['--ros-args', '--params-file', str(write_params_file(join.params, Path(tmp) / 'params.yaml'))]
            for label, _, cmd in agent_commands([[nm] for nm in join.names], ros):
                sup.start(label, cmd, env)
        return execute(join, start, sup.alive, stopped, lambda: refused_label(sup.procs))


def execute(join: JoinPlan, start, alive, stopped, refused=lambda: None) -> int:
    """Watch the graph: ``start(run)`` the agents once the run is heard; 0 once the world has
    left (the run is over), 130 on a signal (``stopped()``), `REFUSED_EXIT` once an agent here
    refused its parameters (``refused()``: its label, else None; the run cannot go on without
    it), 1 if the run is not heard within the wait, is another, or every agent here
    (``alive()``) has exited."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    ctx = Context()
    try:
        rclpy.init(context=ctx)
        node = rclpy.create_node('swarm_join', context=ctx, start_parameter_services=False)
        watch = RunWatch(node)          # the run's id: its agents take part only in that run
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        return _watch(join, node, lambda: ex.spin_once(timeout_sec=0.2), watch, start, alive, stopped, refused)
    finally:
        rclpy.try_shutdown(context=ctx)


def _heard(join: JoinPlan, watch):
    """(the run's announcement or None, an error line or None)."""
    run, err = one_run(watch.runs, 'swarm join')
    if err is None and run is not None and list(run.get('agents', [])) != join.roster:
        err = (f'swarm join: {describe(run)} has other agents than {join.scenario}: '
               'give the same scenario options as the run')
    if err is None and run is not None:
        err = join_error(run, join.names, join.scenario_hash)
    return run, err


def _watch(join: JoinPlan, node, spin, watch, start, alive, stopped, refused=lambda: None) -> int:
    t0, run, seen, gone_since = time.monotonic(), None, False, None
    print(f'swarm join: waiting for the run at {join.server}', flush=True)
    while not stopped():
        spin()
        now = time.monotonic()
        if run is None:
            run, err = _heard(join, watch)
            if err:
                print(err, file=sys.stderr, flush=True)
                return 1
            if run is not None:
                start(run)
                print(f'swarm join: {len(join.names)} agents ({join.agents}) joining {describe(run)}', flush=True)
        elif (label := refused()) is not None:
            print(f'swarm join: {label} refused its parameters (its line is above); stopping the agents here',
                  file=sys.stderr, flush=True)
            return REFUSED_EXIT
        elif not alive():
            print('swarm join: every agent here has exited', file=sys.stderr, flush=True)
            return 1
        if world_present(node):
            if not seen:
                print(f'swarm join: the world found after {now - t0:.1f} s', flush=True)
            seen, gone_since = True, None
        elif seen:
            gone_since = gone_since or now
            if now - gone_since > GONE_AFTER:
                print('swarm join: the world has left the graph; the run is over', flush=True)
                return 0
        if run is None and now - t0 > join.wait:
            print(f'swarm join: no run at {join.server} after {join.wait:g} s', file=sys.stderr, flush=True)
            return 1
    return 130
