"""``swarm run``: a scenario as ROS 2 nodes — every agent, the world and the commander as
separate OS processes (default) or all in one process and one executor (``--in-process``).
With ``--agents-per-process K`` the agents run K to a process (agent containers,
``swarm_agents``; each agent still its own node), see docs/scale.md.

The launcher writes one parameter file for all nodes (agents get their name, roster, initial
state, law and gains, w, dt; world and commander get the scenario reference), starts the
processes in one process group of their own, prints the world's progress, stops everything on
Ctrl-C / SIGTERM (SIGINT to the group, then SIGKILL after a grace period) and, at the end,
writes what ``swarm simulate`` writes (trajectory.npz from what was published, metrics.json,
a figure) to ``--out``.

Faults (``swarm kill`` / ``swarm pause``, a scenario's ``faults``): the launcher writes the
agents' pids to ``pids.json`` (in the run's temporary directory, and a copy in ``--out``) and
gives its path to the world,
which signals the agent processes at the right sim step (SIGKILL; SIGSTOP ... SIGCONT) and logs
every event to ``events.jsonl`` in ``--out``.  An agent that exits is not a run failure: if
the events name it as killed the launcher says so; otherwise it warns, and the world drops the
agent after its ``missing_timeout``.  Stopping a run first sends SIGCONT to every child (a
stopped process cannot handle SIGINT).
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

from swarm_core.scenario import ScenarioError, load

from . import dds

STOP_GRACE = 4.0


def agent_parameters(scn, i: int, mode: str) -> dict:
    noise = scn.spec.noise
    return dict(agent_name=scn.names[i], agent_index=i, agent_names=list(scn.names), leader=False,
                x=float(scn.pos0[i, 0]), y=float(scn.pos0[i, 1]), theta=float(scn.theta0[i]),
                **scn.law.parameters(), dt=scn.dt, mode=mode,
                noise_position=float(noise.position), noise_heading=float(noise.heading),
                seed=int(scn.seed), use_sim_time=True,
                comms=json.dumps(scn.comms_config()) if scn.comms_config() is not None else '')


def node_parameters(scn, scenario_ref: str, mode: str, rtf: float = 1.0, output_dir: str = '',
                    duration: float = 0.0, extra_world=None) -> dict:
    """{fully qualified node name: parameters} for every node of a run."""
    common = dict(scenario=str(scenario_ref), seed=int(scn.seed), dt=float(scn.dt), mode=mode)
    world = dict(common, duration=float(duration or scn.duration), rtf=float(rtf), output_dir=str(output_dir),
                 use_sim_time=False, **(extra_world or {}))
    out = {'/world': world, '/commander': dict(common, use_sim_time=True)}
    for i, nm in enumerate(scn.names):
        out[f'/{nm}/agent'] = agent_parameters(scn, i, mode)
    return out


def write_params_file(params: dict, path: Path) -> Path:
    doc = {fqn: {'ros__parameters': p} for fqn, p in params.items()}
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


# ---------------------------------------------------------------- in-process

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


def run_in_process(params: dict, domain_id=None) -> int:
    """Every node in one executor until the world is done.  SIGINT / SIGTERM (main thread
    only) set a flag the spin loop checks, so no callback is cut off; the world then saves
    the steps done (exit 130)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.signals import SignalHandlerOptions

    from swarm_ros.rosutil import ParameterError, make_executor, spin_until, stop_on_signals
    stop, wake, restore_signals = stop_on_signals()
    ctx = Context()
    rclpy.init(context=ctx, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
    try:
        try:
            world, commander, agents = build_nodes(params, ctx)
        except ParameterError as err:
            print(f'swarm run: {err}', file=sys.stderr)
            return 2
        ex = make_executor(ctx)
        for nd in [world, commander, *agents]:
            ex.add_node(nd)
        spin_until(ex, ctx, lambda: world.done or bool(stop), wake=wake)
        code = 0 if world.done and world.failed is None else (1 if world.failed else 130)
        if code == 130:
            world.save_partial()            # Ctrl-C: keep the steps done
        for nd in [world, commander, *agents]:
            nd.destroy_node()
        return code
    finally:
        if ctx.ok():
            rclpy.shutdown(context=ctx)
        restore_signals()


# ---------------------------------------------------------------- processes

class Supervisor:
    """Child processes in one process group of their own; ended together."""

    def __init__(self):
        self.procs = {}
        self.pgid = None

    def start(self, label, args, env, **kw):
        kw['process_group'] = 0 if self.pgid is None else self.pgid
        p = subprocess.Popen(args, env=env, **kw)
        if self.pgid is None:
            self.pgid = p.pid
        self.procs[label] = p
        return p

    def alive(self):
        return {k: p for k, p in self.procs.items() if p.poll() is None}

    def signal_all(self, sig):
        for p in self.alive().values():
            try:
                p.send_signal(sig)
            except ProcessLookupError:
                pass

    def stop(self, grace=STOP_GRACE, first=()):
        """SIGINT to ``first`` (e.g. the recorder, so it can finish its file) and everyone else,
        wait, then SIGKILL the process group."""
        self.signal_all(signal.SIGCONT)          # a frozen (SIGSTOPped) agent cannot stop
        for label in first:
            p = self.procs.get(label)
            if p is not None and p.poll() is None:
                p.send_signal(signal.SIGINT)
        self.signal_all(signal.SIGINT)
        deadline = time.monotonic() + grace
        while self.alive() and time.monotonic() < deadline:
            time.sleep(0.05)
        if self.alive():
            self.signal_all(signal.SIGKILL)
            if self.pgid is not None:
                try:
                    os.killpg(self.pgid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
        for p in self.procs.values():
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                pass


#: wall seconds to wait for the recorder's subscriptions before the nodes start
RECORDER_READY_TIMEOUT = 30.0


def wait_until_ready(proc, marker: str, timeout: float) -> bool:
    """Forward ``proc``'s stderr lines to ours (on a thread, for its whole life) and wait until
    one contains ``marker`` (the recorder has subscribed to the swarm's topics, so nothing
    published from step 0 on is missed); False on timeout or if ``proc`` ends first."""
    seen = threading.Event()

    def pump():
        for line in proc.stderr:
            sys.stderr.write(line)
            sys.stderr.flush()
            if marker in line:
                seen.set()
        seen.set()

    threading.Thread(target=pump, daemon=True).start()
    return seen.wait(timeout) and proc.poll() is None


def _exe(name):
    here = Path(sys.executable).parent
    cand = here / name
    return str(cand) if cand.exists() else (shutil.which(name) or name)


def killed_agents(events_file) -> set:
    """Agents the events file records as killed (deliberately) or lost."""
    out = set()
    try:
        lines = Path(events_file).read_text().splitlines()
    except OSError:
        return out
    for line in lines:
        try:
            ev = json.loads(line)
        except ValueError:
            continue
        if ev.get('kind') in ('kill', 'lost'):
            out.add(ev.get('agent'))
    return out


def agent_commands(groups, ros) -> list:
    """(label, agent names, command) of each agent process: ``swarm_agent`` for a group of one
    (label: the agent's name), the container ``swarm_agents`` for more (label: ``agents[a..b]``)."""
    out = []
    for g in groups:
        if len(g) == 1:
            out.append((g[0], g, [_exe('swarm_agent')] + ros + ['-r', '__node:=agent', '-r', f'__ns:=/{g[0]}']))
        else:
            out.append((f'agents[{g[0]}..{g[-1]}]', g, [_exe('swarm_agents'), *g] + ros))
    return out


def run_processes(params: dict, params_file: Path, names, env, record=None, out_dir=None,
                  pid_file=None, events_file=None, groups=None) -> int:
    """``groups``: the agents of each agent process (default: one process per agent)."""
    sup = Supervisor()
    stopping = {'sig': None}

    def on_signal(signum, frame):
        stopping['sig'] = signum

    old = {s: signal.signal(s, on_signal) for s in (signal.SIGINT, signal.SIGTERM)}
    ros = ['--ros-args', '--params-file', str(params_file)]
    code = 1
    try:
        if record:
            rec = sup.start('record', [_exe('swarm'), 'record', '--out', str(record)], env,
                            stderr=subprocess.PIPE, text=True, bufsize=1)
            if not wait_until_ready(rec, 'swarm record: ready', RECORDER_READY_TIMEOUT):
                print(f'swarm run: the recorder did not say it was ready within '
                      f'{RECORDER_READY_TIMEOUT:g} s; starting the run anyway', file=sys.stderr, flush=True)
        world = sup.start('world', [_exe('swarm_world')] + ros + ['-r', '__node:=world'], env)
        sup.start('commander', [_exe('homotopy_commander')] + ros + ['-r', '__node:=commander'], env)
        members = {}                    # agent process label -> its agents
        for label, group, cmd in agent_commands(groups or [[nm] for nm in names], ros):
            sup.start(label, cmd, env)
            members[label] = group
        if pid_file is not None:
            # agents sharing a process share its pid: the world signals only a pid of one agent
            tmp = Path(str(pid_file) + '.tmp')
            tmp.write_text(json.dumps({nm: sup.procs[label].pid for label, g in members.items() for nm in g}))
            tmp.replace(pid_file)
            if out_dir is not None:
                shutil.copyfile(pid_file, Path(out_dir) / 'pids.json')
        agents = set(members)
        gone = set()
        while True:
            if stopping['sig'] is not None:
                print(f'swarm run: {signal.Signals(stopping["sig"]).name}: stopping {len(sup.alive())} processes',
                      file=sys.stderr, flush=True)
                code = 130
                break
            rc = world.poll()
            if rc is not None:
                code = rc
                break
            dead = [k for k, p in sup.procs.items() if p.poll() is not None and k != 'world' and k not in gone]
            for k in [k for k in dead if k in agents]:
                gone.add(k)
                rc = sup.procs[k].returncode
                if len(members[k]) > 1:
                    print(f'swarm run: {k} exited with code {rc}: its {len(members[k])} agents are gone; the '
                          'world drops them from the roster after its missing_timeout', file=sys.stderr, flush=True)
                elif k in killed_agents(events_file) if events_file else ():
                    print(f'swarm run: {k} killed (fault injection)', file=sys.stderr, flush=True)
                else:
                    print(f'swarm run: {k} exited with code {rc}; the world drops it from the roster '
                          'after its missing_timeout', file=sys.stderr, flush=True)
            dead = [k for k in dead if k not in agents]
            if dead:
                k = dead[0]
                print(f'swarm run: {k} exited with code {sup.procs[k].returncode}; stopping the run',
                      file=sys.stderr, flush=True)
                code = 1
                break
            time.sleep(0.05)
    finally:
        sup.stop(first=('record',))
        for s, h in old.items():
            signal.signal(s, h)
    return code


def read_events(path) -> list:
    """The events of a run (``events.jsonl`` as the world writes it); [] if none."""
    try:
        return [json.loads(line) for line in Path(path).read_text().splitlines() if line.strip()]
    except (OSError, ValueError):
        return []


# ---------------------------------------------------------------- CLI

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
    p.add_argument('--duration', type=float, help="sim seconds (default: the scenario's)")
    p.add_argument('--seed', type=int, help="seed (default: the scenario's)")
    p.add_argument('--dt', type=float, help="step (default: the scenario's)")
    p.add_argument('--out', help='output directory (default: runs/SCENARIO-seedN-ros)')
    p.add_argument('--no-figure', action='store_true', help='no figure at the end')
    p.add_argument('--progress-every', type=float, default=50.0, help='progress line every this many sim s (default 50)')
    p.add_argument('--missing-timeout', type=float, default=10.0,
                   help='lockstep: the world drops an agent whose state has not come after this many wall s (default 10)')
    p.add_argument('--clock-every', type=int, default=1, metavar='K', help=(
        'lockstep: the world publishes /clock every K steps (default 1). Every node receives each '
        '/clock; K = 10 saves about a fifth of the CPU per step with 6-24 agent processes, and sim '
        'time in the nodes then advances in steps of K dt (lockstep results do not change)'))
    p.add_argument('--agents-per-process', default='1', metavar='K', help=(
        'processes: K agents per process (agent containers; each agent still its own node), or auto '
        '(1 for a small swarm, larger containers when the agents outnumber the cores; default 1)'))
    p.add_argument('--dds', choices=dds.CHOICES, default='auto', help=(
        'DDS set-up of the processes: auto (default: a generated Fast DDS profile, UDP on '
        '127.0.0.1 without shared memory, unless FASTRTPS_DEFAULT_PROFILES_FILE names one), udp '
        '(that profile in any case) or localhost (rmw_fastrtps localhost discovery with shared '
        'memory: up to 32 processes, and an agent killed or frozen by fault injection can block '
        'shared memory for the others)'))
    return p


def main(argv=None) -> int:
    a = _parser().parse_args(argv)
    if not (a.missing_timeout >= 0.1 and a.missing_timeout < 1e6):
        print(f'swarm run: --missing-timeout {a.missing_timeout}: must be in [0.1, 1e6)', file=sys.stderr)
        return 2
    if a.clock_every < 1:
        print(f'swarm run: --clock-every {a.clock_every}: must be ≥ 1', file=sys.stderr)
        return 2
    if a.rtf is not None and not (a.rtf > 0 and a.rtf < 1e4):
        print(f'swarm run: --rtf {a.rtf}: must be in (0, 1e4)', file=sys.stderr)
        return 2
    try:
        scn = load(a.scenario, seed=a.seed, duration=a.duration, dt=a.dt)
    except ScenarioError as err:
        print(f'swarm run: {err}', file=sys.stderr)
        return 2
    from swarm_agent.container_core import agents_per_process, split_agents
    if a.agents_per_process == 'auto':
        per = agents_per_process(len(scn.names), os.cpu_count())
    else:
        try:
            per = int(a.agents_per_process)
            if per < 1:
                raise ValueError
        except ValueError:
            print(f'swarm run: --agents-per-process {a.agents_per_process}: must be a whole number ≥ 1 or auto',
                  file=sys.stderr)
            return 2
    groups = split_agents(scn.names, per)
    ref = a.scenario
    if Path(a.scenario).suffix in ('.yaml', '.yml') or Path(a.scenario).exists():
        ref = str(Path(a.scenario).resolve())
    out = Path(a.out or os.path.join('runs', f'{scn.name}-seed{scn.seed}-ros')).resolve()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        print(f'swarm run: cannot create output directory {out}: {err.strerror or err} ({err.filename})', file=sys.stderr)
        return 2
    if a.record and not a.in_process:
        bag = Path(a.record)
        if bag.suffix != '.mcap':
            print(f'swarm run: --record {a.record}: must name a .mcap file', file=sys.stderr)
            return 2
        try:
            bag.resolve().parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            print(f'swarm run: --record {a.record}: cannot create its directory: {err.strerror or err} ({err.filename})',
                  file=sys.stderr)
            return 2
        if not os.access(bag.resolve().parent, os.W_OK) or (bag.exists() and not os.access(bag, os.W_OK)):
            print(f'swarm run: --record {a.record}: not writable', file=sys.stderr)
            return 2
    traj_file = out / 'trajectory.npz'
    if traj_file.exists():
        traj_file.unlink()
    if (out / 'events.jsonl').exists():
        (out / 'events.jsonl').unlink()
    params = node_parameters(scn, ref, a.mode, a.rtf, str(out), scn.duration,
                             extra_world=dict(progress_every=float(a.progress_every), clock_every=int(a.clock_every),
                                              missing_timeout=float(a.missing_timeout)))
    if a.record and not a.in_process and a.mode == 'lockstep':
        for nm in scn.names:            # the recorder must hear every state from step 0
            params[f'/{nm}/agent']['state_subscribers'] = 2
        params['/world']['wait_for_recorder'] = True          # ... every /clock
        params['/commander']['wait_for_recorder'] = True      # ... and every λ and steering message
    n_proc = len(groups) + 2 + (1 if a.record else 0)
    if not a.in_process and per > 1:
        # the world waits for the step relay's readers (one per agent process) and, with a
        # recorder, for the /clock readers (lone agents, and containers that follow /clock)
        lone = sum(len(g) == 1 for g in groups)
        params['/world'].update(step_readers=len(groups),
                                clock_readers=lone + 2 + (len(groups) - lone if a.mode == 'realtime' else 0))
    per_text = '' if a.in_process or per == 1 else f' ({per} agents per process)'
    print(f'swarm run: {scn.name} seed {scn.seed}: {len(scn.names)} agents, {a.mode}, '
          f'{"one process" if a.in_process else f"{n_proc} processes"}{per_text}, t = {scn.duration:g}, '
          f'dt = {scn.dt:g}', flush=True)
    t0 = time.monotonic()
    if a.in_process:
        if a.record:
            print('swarm run: --record needs --processes (the recorder is a process); ignored', file=sys.stderr)
        code = run_in_process(params)
    else:
        with tempfile.TemporaryDirectory(prefix='swarm_run_') as tmp:
            pid_file = Path(tmp) / 'pids.json'
            params['/world'].update(pid_file=str(pid_file), events_file=str(out / 'events.jsonl'))
            pfile = write_params_file(params, Path(tmp) / 'params.yaml')
            env = dds.environment(n_proc, Path(tmp), choice=a.dds)
            code = run_processes(params, pfile, scn.names, env, record=a.record, out_dir=out,
                                 pid_file=pid_file, events_file=out / 'events.jsonl', groups=groups)
    wall = time.monotonic() - t0
    if code in (0, 130) and traj_file.exists():      # 130: Ctrl-C; the world saved the steps done
        try:
            from swarm_core.trajectory import Trajectory
            from swarm_core.simulate_cli import analyse, write_outputs
            traj = Trajectory.load(traj_file)
            traj.meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration, source='ros',
                             mode=a.mode, wall_seconds=wall, events=read_events(out / 'events.jsonl'),
                             interrupted=code == 130)
            series, checks = analyse(scn, traj)
            summary = write_outputs(out, scn, traj, series, checks, figure=not a.no_figure)
            what = (f'stopped (code {code}) at t = {summary["t_end"]:g} after {wall:.1f} s; partial run'
                    if code else f'done in {wall:.1f} s')
            print(f'swarm run: {what}; final clusters {summary.get("final_clusters", "?")}; '
                  f'wrote {out}/trajectory.npz, metrics.json' + ('' if a.no_figure else f', {scn.name}.png'),
                  flush=True)
        except Exception as err:  # the trajectory is there; the extras are a bonus
            print(f'swarm run: wrote {traj_file} (metrics/figure failed: {err})', flush=True)
    elif code != 0:
        print(f'swarm run: stopped (code {code}) after {wall:.1f} s', file=sys.stderr, flush=True)
    (out / 'run.json').write_text(json.dumps(dict(exit_code=code, wall_seconds=wall, mode=a.mode,
                                                  processes=not a.in_process, agents=len(scn.names),
                                                  agents_per_process=per)))
    return code
