"""``swarm run``: a scenario as ROS 2 nodes — every agent, the world and the commander as
separate OS processes (default) or all in one process and one executor (``--in-process``).
With ``--agents-per-process K`` the agents run K to a process (agent containers,
``swarm_agent_container``; each agent still its own node), see docs/scale.md.

The launcher writes one parameter file for all nodes (agents get their name, roster, initial
state, law and gains, w, dt; world and commander get the scenario reference), starts the
processes in one process group of their own, prints the world's progress, stops everything on
Ctrl-C / SIGTERM / SIGHUP (SIGTERM to the group, then SIGKILL after a grace period) and, at the end,
writes what ``swarm simulate`` writes (trajectory.npz from what was published, metrics.json,
a figure) to ``--out``.

Faults (``swarm kill`` / ``swarm pause``, a scenario's ``faults``): the launcher writes the
agents' pids to ``pids.json`` (in the run's temporary directory, and a copy in ``--out``) and
gives its path to the world,
which signals the agent processes at the right sim step (SIGKILL; SIGSTOP ... SIGCONT) and logs
every event to ``events.jsonl`` in ``--out``.  An agent that exits is not a run failure: if
the events name it as killed the launcher says so; otherwise it warns, and the world drops the
agent after its ``missing_timeout``.  Stopping a run first sends SIGCONT to every child (a
stopped process cannot handle the stop signal).

``--foxglove [PORT]`` also starts ``swarm view`` (`swarm_tools.live.view`), the live Foxglove
WebSocket bridge, as one more process of the run; it stops with the run.

No orphans: every child gets a parent-death signal (Linux ``PR_SET_PDEATHSIG``: SIGKILL when
the launcher dies, whatever killed it), so a SIGKILLed launcher leaves nothing running.  The
recorder of ``--record`` is not vital: if it dies the run goes on with a warning.  If the
world dies, the launcher says what is lost and, with ``--record``, rebuilds what it can from
the bag.

`main` validates the options and plans the run (`plan`: a `RunPlan` of the processes, their
parameters and the outputs, made without side effects), executes it and finishes (outputs, exit
code).  `plan_processes` turns a plan into the processes to start (`processes.ProcessSpec`) and
writes the files they read; ``ros2 launch swarm_tools swarm.launch.py`` starts the same ones from
the same plan (`swarm_tools.run.launch_description`) and finishes the same way (`finish`, in
`swarm_tools.run.outputs`).
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

from swarm_agent.container_core import agent_services, agents_per_process, split_agents
from swarm_core.analysis.outputs import check_output_dir
from swarm_core.laws import LawError
from swarm_core.laws.paper import compiled_sums
from swarm_robots.world_setup import SUMMARY_FILE
from swarm_ros.rosutil import (
    EXIT_NOTES,
    ParameterError,
    failure,
    make_executor,
    settle_garbage,
    spin_until,
    stop_on_signals,
)
from swarm_ros.runinfo import new_run_id, robots_text
from swarm_tools.run import dds
from swarm_tools.run.outputs import finish
from swarm_tools.run.params import load_scenario, node_parameters, write_params_file
from swarm_tools.run.processes import process_specs, run_processes
from swarm_tools.run.robots import ROBOTS_NODE, add_robot_world, apply_robots, parse_robots, robot_steps

#: most agents of one ``swarm run`` (each its own node; beyond a few per core, in agent
#: containers); larger swarms are for ``swarm simulate``
MAX_RUN_AGENTS = 5000


def build_nodes(params: dict, context, log=print):
    """World, commander and agent nodes (in that order) from `node_parameters`' output."""
    from rclpy.parameter import Parameter

    from homotopy_commander.commander_node import CommanderNode
    from swarm_agent.agent_node import AgentNode
    from swarm_world.world_node import WorldNode


    def ov(p):
        return [Parameter(k, value=v) for k, v in p.items()]
    world = WorldNode(context=context, parameter_overrides=ov(params['/world']), log=log)
    commander = CommanderNode(context=context, parameter_overrides=ov(params['/commander']))
    agents = [AgentNode('agent', namespace=fqn.split('/')[1], context=context, parameter_overrides=ov(p))
              for fqn, p in params.items() if fqn.endswith('/agent')]
    return world, commander, agents


def robots_nodes(params: dict, context) -> list:
    """The run's MuJoCo robot world (`swarm_robots.mujoco_world_node`), if it has one."""
    from rclpy.parameter import Parameter

    from swarm_robots.mujoco_world_node import RobotsNode
    if ROBOTS_NODE not in params:
        return []

    return [RobotsNode(context=context, parameter_overrides=[
        Parameter(k, value=v) for k, v in params[ROBOTS_NODE].items()])]


def run_in_process(params: dict, domain_id=None, stopped_by=None) -> int:
    """Every node in one executor until the world is done.  SIGINT / SIGTERM (main thread
    only) set a flag the spin loop checks, so no callback is cut off; the world then saves
    the steps done (exit 130).  A law that fails (`LawError`) stops the run with one line
    (appended to ``stopped_by``), the steps done saved (exit 1)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    stop, wake, restore_signals = stop_on_signals()
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    try:
        try:
            world, commander, agents = build_nodes(params, ctx)
            robots = robots_nodes(params, ctx)
        except ParameterError as err:
            print(f'swarm run: {err}', file=sys.stderr)
            return 2
        ex = make_executor(ctx)
        for nd in [world, commander, *agents, *robots]:
            ex.add_node(nd)
        settle_garbage()
        failed = None
        try:
            spin_until(ex, ctx, lambda: world.done or bool(stop) or failure() is not None, wake=wake)
        except LawError as err:     # (the agents' callbacks `fail` with it; any other path)
            failed = err
        failed = failed or failure()
        if failed is not None:
            print(f'swarm run: {failed}; stopping the run', file=sys.stderr, flush=True)
            if stopped_by is not None:
                stopped_by.append(str(failed))
        code = 0 if world.done and world.failed is None else (1 if world.failed or failed else 130)
        if code == 130 or failed:
            world.save_partial()            # Ctrl-C or a law that failed: keep the steps done
        for nd in robots:
            nd.finish()
        for nd in [world, commander, *agents, *robots]:
            nd.destroy_node()
        return code
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)
        restore_signals()


# ---------------------------------------------------------------- processes

def _parser():
    p = argparse.ArgumentParser(prog='swarm run', description=(
        'Run a scenario as ROS 2 nodes: every agent, the world and the commander as separate '
        'processes (default) or in one process. Lockstep equals `swarm simulate` to rounding.'))
    p.add_argument('scenario', help='shipped scenario name or YAML file')
    g = p.add_mutually_exclusive_group()
    g.add_argument('--processes', dest='in_process', action='store_false', default=False,
                   help='one OS process per node (default)')
    g.add_argument('--in-process', dest='in_process', action='store_true', help='all nodes in one executor')
    p.add_argument('--mode', choices=('lockstep', 'realtime'), default='lockstep', help=(
        'lockstep (default: deterministic, equals swarm simulate) or realtime (timers against a '
        'clock at --rtf)'))
    p.add_argument('--rtf', type=float, default=1.0, help='realtime: sim seconds per wall second (default 1)')
    p.add_argument('--record', metavar='BAG.mcap', help='also record the run (swarm record)')
    p.add_argument('--state-readers', type=int, default=0, metavar='N', help=(
        'lockstep: each agent publishes its first state only once N readers of /swarm/states besides '
        "the run's own recorder have matched it (at most 30 s), e.g. 1 for a `ros2 bag record` started "
        'before the run, so that it gets every state from step 0 (default 0)'))
    p.add_argument('--foxglove', metavar='PORT', nargs='?', type=int, const=8765, default=None, help=(
        'also serve the run live to the Foxglove app (swarm view) on ws://127.0.0.1:PORT '
        '(default 8765; 0: a free port, printed)'))
    p.add_argument('--duration', type=float, help="sim seconds (default: the scenario's)")
    p.add_argument('--seed', type=int, help="seed (default: the scenario's)")
    p.add_argument('--dt', type=float, help="step (default: the scenario's)")
    p.add_argument('--out', help='output directory (default: runs/SCENARIO-seedN-ros)')
    p.add_argument('--no-figure', action='store_true', help='no figure at the end')
    p.add_argument('--progress-every', type=float, default=50.0,
                   help='progress line every this many sim s (default 50)')
    p.add_argument('--missing-timeout', type=float, default=10.0, help=(
        'the world drops an agent whose state has not come after this many wall s (default 10; realtime: '
        'an agent silent this long is lost)'))
    p.add_argument('--clock-every', type=int, default=1, metavar='K', help=(
        'lockstep: the world publishes /clock every K steps (default 1). Every node receives each '
        '/clock; K = 10 saves about a fifth of the CPU per step with 6-24 agent processes, and sim '
        'time in the nodes then advances in steps of K dt (lockstep results do not change)'))
    p.add_argument('--agents-per-process', default='1', metavar='K', help=(
        'processes: K agents per process (agent containers; each agent still its own node), or auto '
        '(1 for a small swarm, larger containers when the agents outnumber the cores; default 1)'))
    p.add_argument('--compiled', choices=compiled_sums.CHOICES, default='auto', help=compiled_sums.HELP)
    p.add_argument('--agent-services', choices=('auto', 'on', 'off'), default='auto', help=(
        'processes: do the agent nodes in containers keep their parameter services, type-description '
        'service and /rosout writer (15 of their 17 DDS endpoints)? auto: yes up to 100 agents in the '
        'run (default auto; a lone agent always keeps them)'))
    p.add_argument('--dds', choices=dds.CHOICES, default='auto', help=(
        'DDS set-up of the processes: auto (default: a generated Fast DDS profile, UDP on '
        '127.0.0.1 without shared memory, unless FASTRTPS_DEFAULT_PROFILES_FILE names one), udp '
        '(that profile in any case) or localhost (rmw_fastrtps localhost discovery with shared '
        'memory: up to 32 processes, and an agent killed or frozen by fault injection can block '
        'shared memory for the others)'))
    p.add_argument('--start-timeout', type=float, default=180.0, metavar='S', help=(
        'the world gives up if not every agent is there after this many wall s (default 180; '
        'raise it for hundreds of processes or agents joining from other hosts)'))
    add_network_options(p)
    p.add_argument('--discovery', choices=dds.DISCOVERY, default='auto', help=(
        f'simple (every process finds the others), server (a Fast DDS discovery server the run '
        f'starts; every process is its client) or auto (default: server above {dds.SIMPLE_LIMIT} '
        f'processes, or with --remote-agents)'))
    p.add_argument('--server-port', type=int, default=0, metavar='PORT',
                   help='UDP port of the discovery server (default: a free one)')
    p.add_argument('--remote-agents', metavar='LIST', default='', help=(
        'agents (indices, e.g. 48-95 or 0,2,5-7) this host does not start: other hosts start '
        'them with `swarm join`; the world waits for them'))
    p.add_argument('--robots', action='append', metavar='KIND[:AGENTS]', help=(
        'agents that drive robots through /AGENT/cmd_vel and /AGENT/odom (docs/robots.md): '
        'external (a robot, Gazebo or a simulator of your own; nothing else starts) for every agent, '
        'or external:agent_0-agent_2 (a range or a comma list) for some; mujoco: robots of a MuJoCo '
        'world the run starts (node robots; mujoco:agent_0-agent_2 likewise); the scenario needs a '
        'robots: section. Robot agents share agent containers as kinematic ones do. Realtime: the sim clock runs '
        'at v0/L model s per wall s (robots live in wall time; --rtf does not apply)'))
    return p


def add_network_options(p):
    p.add_argument('--interface', default='127.0.0.1', metavar='ADDR', help=(
        "this host's IPv4 address the ROS processes use (default 127.0.0.1: this host only)"))


def parse_agents(text: str, n: int) -> list:
    """'48-95' or '0,2,5-7' -> sorted agent indices in 0..n-1; ValueError naming the bad part."""
    out = set()
    for part in [q.strip() for q in text.split(',')]:
        lo, sep, hi = part.partition('-')
        if not lo.strip().isdigit() or (sep and not hi.strip().isdigit()):
            raise ValueError(f'agents {text!r}: {part!r} is not an index or a range like 48-95')
        a, b = int(lo), int(hi) if sep else int(lo)
        if a > b or b >= n:
            raise ValueError(f'agents {text!r}: {part!r} is outside 0..{n - 1} (the scenario has {n} agents)')
        out.update(range(a, b + 1))
    return sorted(out)


class NotStarted(Exception):
    """Why the run cannot start (a bad option, output or network set-up): `main` says it in one
    line ``swarm run: ...`` and exits 2, with nothing left running."""


def check_options(a) -> None:
    """ValueError naming the first option of ``a`` out of its range (checked before the
    scenario is read)."""
    for ok, why in ((0.1 <= a.missing_timeout < 1e6, f'--missing-timeout {a.missing_timeout}: must be in [0.1, 1e6)'),
                    (1 <= a.start_timeout <= 1e6, f'--start-timeout {a.start_timeout}: must be in [1, 1e6]'),
                    (a.clock_every >= 1, f'--clock-every {a.clock_every}: must be ≥ 1'),
                    (a.foxglove is None or 0 <= a.foxglove <= 65535,
                     f'--foxglove {a.foxglove}: must be a port in 0..65535'),
                    (0 <= a.state_readers <= 1000, f'--state-readers {a.state_readers}: must be in 0..1000'),
                    (0 < a.rtf < 1e4, f'--rtf {a.rtf}: must be in (0, 1e4)')):
        if not ok:
            raise ValueError(why)


def check_interface(text: str) -> str:
    """``--interface``: an IPv4 address of this host (ValueError otherwise)."""
    return dds.check_local(dds.check_address(text, '--interface'), '--interface')


def set_state_readers(params: dict, readers: int, mode: str) -> None:
    """lockstep: every agent in ``params`` publishes its first state only once ``readers``
    readers of /swarm/states (recorders) have matched, so they hear every state from step 0."""
    if readers and mode == 'lockstep':
        for fqn, p in params.items():
            if fqn.endswith('/agent'):
                p['state_subscribers'] = readers


@dataclass
class RunPlan:
    """What a ``swarm run`` starts and writes (`plan`); making it has no side effects."""
    scn: object                 # the scenario (`swarm_core.scenario.loader.Scenario`)
    mode: str                   # lockstep or realtime
    in_process: bool            # every node in one executor (else a process each, or containers)
    out: Path                   # the output directory
    params: dict                # {node: its parameters}: the run's parameters file
    run_id: str
    local: list                 # names of the agents this host starts
    remote: list                # indices of the agents other hosts start (`swarm join`)
    groups: list                # the agents of each agent process
    per: int                    # agents per process
    services: bool              # contained agent nodes keep their services
    record: str | None = None   # the bag of --record (processes only)
    foxglove: int | None = None  # the port of the live view (processes only)
    use_server: bool = False    # a discovery server
    interface: str = '127.0.0.1'
    server_port: int = 0
    dds: str = 'auto'
    figure: bool = True
    join: tuple = ('', '')      # the swarm join command for the remote agents: before and after --server
    ignored: list = field(default_factory=list)     # options the run ignores, one line each
    robots: dict = field(default_factory=dict)      # {agent: robot kind} (`run.robots`)
    robots_line: str | None = None                  # the scale to the robots, said at start
    stopped: str | None = None                      # why the run stopped early (a law that failed)

    @property
    def processes(self) -> int:
        """OS processes of a --processes run: agent processes, world, commander, recorder, view."""
        return (len(self.groups) + 2 + (self.record is not None) + (self.foxglove is not None)
                + (ROBOTS_NODE in self.params))

    @property
    def traj_file(self) -> Path:
        return self.out / 'trajectory.npz'

    @property
    def events_file(self) -> Path:
        return self.out / 'events.jsonl'

    def summary(self) -> str:
        """The line that starts the run."""
        scn = self.scn
        per = '' if self.in_process or self.per == 1 else f' ({self.per} agents per process' + (
            '' if self.services else ', agent nodes without services') + ')'
        return (f'swarm run: run {self.run_id}: {scn.name} seed {scn.seed}: {len(scn.names)} agents, {self.mode}, '
                f'{"one process" if self.in_process else f"{self.processes} processes"}{per}, '
                f't = {scn.duration:g}, dt = {scn.dt:g}')


def agents_per_process_option(a, n: int, cores) -> int:
    """``--agents-per-process`` for ``n`` agents started here (auto: by ``cores``)."""
    if a.agents_per_process == 'auto':
        return agents_per_process(n, cores)
    try:
        per = int(a.agents_per_process)
        if per >= 1:
            return per
    except ValueError:
        pass
    raise ValueError(f'--agents-per-process {a.agents_per_process}: must be a whole number ≥ 1 or auto')


def run_parameters(a, scn, ref, out: Path, run_id: str) -> dict:
    """Every node's parameters for the run ``a`` asks for (`node_parameters` and the options)."""
    processes = not a.in_process
    params = node_parameters(scn, ref, a.mode, a.rtf, str(out), scn.duration, compiled=a.compiled,
                             extra_world=dict(progress_every=float(a.progress_every), clock_every=int(a.clock_every),
                                              missing_timeout=float(a.missing_timeout),
                                              start_timeout=float(a.start_timeout)))
    set_state_readers(params, a.state_readers + (1 if a.record and processes else 0), a.mode)
    if a.record and processes and a.mode == 'lockstep':
        params['/world']['wait_for_recorder'] = True          # ... every /clock
        params['/commander']['wait_for_recorder'] = True      # ... and every λ and steering message
    for p in params.values():
        p['run_id'] = run_id            # on the lockstep messages and /swarm/run (swarm_ros.runinfo)
    if processes:
        params['/world']['events_file'] = str(out / 'events.jsonl')
    return params


def plan(a, scn, ref: str, *, interface: str = '127.0.0.1', cores=1, run_id: str = '') -> RunPlan:
    """The run that ``a`` (the parsed options) asks for with scenario ``scn`` (loaded from
    ``ref``), on a host of ``cores`` cores: ValueError naming the first bad option.  Pure: it
    starts, writes and checks on disk nothing."""
    n = len(scn.names)
    robots = parse_robots(a.robots, scn.names)
    remote = parse_agents(a.remote_agents, n) if a.remote_agents else []
    if not 0 <= a.server_port < 65536:
        raise ValueError(f'--server-port {a.server_port}: must be 0 (a free port) or in 1..65535')
    if remote and a.in_process:
        raise ValueError('--remote-agents needs --processes')
    if remote and a.discovery == 'simple':
        raise ValueError('--remote-agents needs a discovery server (--discovery server or auto)')
    per = agents_per_process_option(a, n - len(remote), cores)
    if n > MAX_RUN_AGENTS:
        raise ValueError(f'{n} agents: at most {MAX_RUN_AGENTS} per run (one node each); '
                         'use swarm simulate for larger swarms')
    out = Path(a.out or os.path.join('runs', f'{scn.label}-seed{scn.seed}-ros')).resolve()
    local = [nm for i, nm in enumerate(scn.names) if i not in set(remote)]
    run = RunPlan(scn=scn, mode=a.mode, in_process=a.in_process, out=out, run_id=run_id,
                  params=run_parameters(a, scn, ref, out, run_id), local=local, remote=remote,
                  groups=split_agents(local, per), per=per,
                  services=agent_services(n, per, a.agent_services), interface=interface,
                  server_port=a.server_port, dds=a.dds, figure=not a.no_figure, robots=robots)
    run.robots_line = apply_robots(run.params, scn, robots, a.mode)
    add_robot_world(run.params, robots)
    if a.in_process:
        given = (('record', 'recorder', a.record), ('foxglove', 'view', a.foxglove is not None))
        run.ignored = [f'--{opt} needs --processes (the {what} is a process); ignored' for opt, what, on in given if on]
        return run
    run.record, run.foxglove = a.record or None, a.foxglove
    run.use_server = a.discovery == 'server' or (a.discovery == 'auto' and (
        run.processes > dds.SIMPLE_LIMIT or bool(remote)))
    if remote:          # announced on /swarm/run: `swarm join` refuses any other agent, starts robot agents so
        names = [scn.names[i] for i in remote]
        run.params['/world'].update(remote_agents=','.join(names),
                                    remote_robots=robots_text({nm: robots[nm] for nm in names if nm in robots}))
    if per > 1:
        # the world waits for the step relay's readers: one per agent process
        run.params['/world'].update(step_readers=len(run.groups) + len(remote))
    same = ''.join(f' --{k} {v}' for k, v in (('seed', a.seed), ('dt', a.dt), ('duration', a.duration),
                                              ('mode', a.mode if a.mode != 'lockstep' else None)) if v is not None)
    run.join = (f'{a.scenario} --agents {a.remote_agents}',
                ' --interface ADDR' + same + (' --recorded' if a.record else ''))
    return run


def prepare_outputs(run: RunPlan) -> None:
    """The output directory (and the bag's) made and writable, the old trajectory and events
    gone; ValueError saying what is not writable."""
    err = check_output_dir(run.out)
    if err:
        raise ValueError(err)
    if run.record:
        bag = Path(run.record)
        if bag.suffix != '.mcap':
            raise ValueError(f'--record {run.record}: must name a .mcap file')
        try:
            bag.resolve().parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise ValueError(f'--record {run.record}: cannot create its directory: '
                             f'{err.strerror or err} ({err.filename})') from None
        if not os.access(bag.resolve().parent, os.W_OK) or (bag.exists() and not os.access(bag, os.W_OK)):
            raise ValueError(f'--record {run.record}: not writable')
    for old in (run.traj_file, run.events_file, run.out / SUMMARY_FILE):      # a file or a link (never followed)
        if old.is_symlink() or old.is_file():
            old.unlink()


def execute(run: RunPlan) -> tuple[int, float]:
    """Run it: (exit code, wall seconds).  `NotStarted` if the DDS set-up fails."""
    print(run.summary(), flush=True)
    if run.robots_line:
        print(f'swarm run: {run.robots_line}', flush=True)
    t0 = time.monotonic()
    if run.in_process:
        for line in run.ignored:
            print(f'swarm run: {line}', file=sys.stderr)
        stopped_by = []
        code = run_in_process(run.params, stopped_by=stopped_by)
        run.stopped = stopped_by[0] if stopped_by else None
    else:
        code = _run_processes(run)
    return code, time.monotonic() - t0


@dataclass
class ProcessPlan:
    """The processes of a ``--processes`` run and the files they read (`plan_processes`)."""
    params: dict                # the parameters file's content (the world's with pid_file)
    params_file: Path
    pid_file: Path              # {agent: pid}, for the world's faults (written once they run)
    env: dict                   # the processes' environment (DDS set-up, `dds.environment`)
    server: object              # a `dds.DiscoveryServer` to start first, or None
    specs: list                 # `processes.ProcessSpec` of each process, in start order


def plan_processes(run: RunPlan, workdir: Path, notes: bool = False) -> ProcessPlan:
    """What a ``--processes`` run starts, with its parameters file and DDS profile written to
    ``workdir``: `swarm run` (`run_processes`) and ``ros2 launch swarm_tools swarm.launch.py``
    (`swarm_tools.run.launch_description`) both start these.  `NotStarted` if the DDS set-up fails.
    ``notes``: the processes leave the line of a law that failed in ``workdir``/notes
    (`rosutil.fatal_note`, which `run_processes` says), not in their log."""
    pid_file = Path(workdir) / 'pids.json'
    params = dict(run.params, **{'/world': dict(run.params['/world'], pid_file=str(pid_file))})
    pfile = write_params_file(params, Path(workdir) / 'params.yaml')
    try:
        server = dds.DiscoveryServer(run.interface, run.server_port) if run.use_server else None
        env = dds.environment(run.processes, Path(workdir), choice=run.dds, interface=run.interface,
                              server=server.locator if server else None)
    except (ValueError, OSError) as err:
        raise NotStarted(str(err)) from None
    if notes:
        (Path(workdir) / 'notes').mkdir(exist_ok=True)
        env = dict(env, **{EXIT_NOTES: str(Path(workdir) / 'notes')})
    specs = process_specs(pfile, env, run.groups, run.services, robots=ROBOTS_NODE in params, foxglove=run.foxglove)
    return ProcessPlan(params=params, params_file=pfile, pid_file=pid_file, env=env, server=server, specs=specs)


def _run_processes(run: RunPlan) -> int:
    with tempfile.TemporaryDirectory(prefix='swarm_run_') as tmp:
        procs = plan_processes(run, Path(tmp), notes=True)
        if run.remote:
            print(f'swarm run: waiting for {len(run.remote)} agents from other hosts: swarm join '
                  f'{run.join[0]} --server {procs.server.locator}{run.join[1]}', flush=True)
        stopped_by = []
        code = run_processes(procs.params, procs.params_file, procs.specs, procs.env, record=run.record,
                             out_dir=run.out, pid_file=procs.pid_file, events_file=run.events_file,
                             server=procs.server, notes=procs.env.get(EXIT_NOTES), stopped_by=stopped_by)
        run.stopped = stopped_by[0] if stopped_by else None
        return code


def validate(a) -> RunPlan | None:
    """The run ``a`` asks for, planned, its outputs ready; `NotStarted` naming a bad option or
    output, None for a bad scenario (said)."""
    try:
        check_options(a)
        scn, ref = load_scenario('swarm run', a)
        if scn is None:
            return None
        run = plan(a, scn, ref, interface=check_interface(a.interface), cores=os.cpu_count(), run_id=new_run_id())
        prepare_outputs(run)
    except ValueError as err:
        raise NotStarted(str(err)) from None
    brakes = robot_steps(run.scn, run.robots)        # (a step too long for the robots: refused in plan)
    if brakes:
        print(f'swarm run: WARNING: {brakes}', file=sys.stderr, flush=True)
    return run


def main(argv=None) -> int:
    """validate and plan (nothing started), execute, finish (outputs, exit code)."""
    a = _parser().parse_args(argv)
    try:
        run = validate(a)
        if run is None:
            return 2
        code, wall = execute(run)
    except NotStarted as err:
        print(f'swarm run: {err}', file=sys.stderr)
        return 2
    return finish(run, code, wall)
