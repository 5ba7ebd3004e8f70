"""A whole run as the stock ROS 2 tools see it (their faithful stand-ins in tests/fakes/, each a
DDS participant of its own, with the tool's waits and default QoS):

- ``ros2 node list`` lists exactly the node names docs/ros-graph.md gives (agents alone, with the
  recorder, and in containers);
- ``ros2 topic pub`` with its default QoS (reliable, volatile, depth 10) on /swarm/lambda and on
  a steering topic, once and at its rate, reaches the commander and makes no node of the run
  log an incompatible-QoS warning (their stderr, which ``swarm run`` passes on, and their log
  files); a writer that a node really cannot match still shows in the same capture, so the
  check can see a warning.
"""
import os
import re
import signal
import subprocess
import sys
import time

from tests.helpers import FAKES, ROOT, Lines, short_homotopy

#: the sentence of docs/ros-graph.md that says what `ros2 node list` shows
DOC_NAMES = ('`ros2 node list` shows `/world`, `/commander`, `/agent_k/agent` for every agent, one\n'
             '`/agent_container_<k>` per container, `/robots` with MuJoCo robots, and `/swarm_recorder`\n'
             '(`--record`) and `/swarm_view` (`--foxglove`) when they run.')


def documented_names(names, per, record):
    """The node names docs/ros-graph.md gives for a run of ``names`` in processes of ``per``."""
    assert DOC_NAMES in (ROOT / 'docs' / 'ros-graph.md').read_text()
    out = {'/world', '/commander'} | {f'/{nm}/agent' for nm in names}
    if per > 1:
        out |= {f'/agent_container_{i}' for i in range(0, len(names), per)}
    if record:
        out.add('/swarm_recorder')
    return out


def start_run(processes, swarm_cmd, tmp_path, *options):
    """A realtime run of the six agents that goes on until stopped; (process, its lines)."""
    # dt 0.1: a live run is all the tools need, and a realtime run's CPU grows with its rate
    path = short_homotopy(tmp_path / 'rt.yaml', duration=100000, lam='{kind: constant, value: 0.0}', at=1e6, dt=0.1)
    env = dict(os.environ, ROS_LOG_DIR=str(tmp_path / 'ros_log'))       # the nodes' log files
    run = processes.start([swarm_cmd, 'run', path, '--mode', 'realtime', '--out', tmp_path / 'out', '--no-figure',
                           *options], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)
    lines = Lines(run)
    assert lines.wait_for('agents discovered', 180), ''.join(lines.lines[-40:])
    return run, lines


def stop(run, lines):
    run.send_signal(signal.SIGINT)
    lines.wait(run, 60)


def listed_as_documented(names, per, record):
    """``ros2 node list`` (run again as a user would, each time a fresh participant with the
    tool's 0.5 s of discovery) comes to list exactly the documented names and never another:
    an error line, else None."""
    from tests.fakes.ros2cli_verbs import node_list
    want = documented_names(names, per, record)
    seen, listed, end = set(), [], time.monotonic() + 90
    while time.monotonic() < end and seen != want:
        listed.append(node_list())
        seen = set(listed[-1])
        if not seen <= want:
            return f'not documented: {sorted(seen - want)}'
    return None if seen == want else f'missing {sorted(want - seen)} after {len(listed)} tries'


def test_ros2_node_list_shows_the_documented_names_of_containers(tmp_path, ros_domain, processes, swarm_cmd):
    """Agents three to a container: ``ros2 node list`` shows the documented names (lone agents and
    the recorder: `test_stock_topic_pub_makes_no_node_warn_about_qos`, on the same kind of run)."""
    run, lines = start_run(processes, swarm_cmd, tmp_path, '--agents-per-process', '3')
    why = listed_as_documented([f'agent_{i}' for i in range(6)], 3, False)
    stop(run, lines)
    assert why is None, why


def _tool(processes, *argv):
    """The ``ros2 topic pub`` stand-in as its own process (stdout and stderr together)."""
    return processes.start([sys.executable, FAKES / 'emulate_topic_pub.py', *map(str, argv)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def _logs(tmp_path, lines):
    """Everything the run's nodes said: their stderr (through ``swarm run``) and their log files."""
    files = sorted((tmp_path / 'ros_log').rglob('*.log'))
    return ''.join(lines.lines) + ''.join(f.read_text(errors='replace') for f in files)


def test_stock_topic_pub_makes_no_node_warn_about_qos(tmp_path, ros_domain, processes, swarm_cmd):
    """Against a recorded realtime run (six agent processes, world, commander, recorder):
    ``ros2 topic pub --once`` on /swarm/lambda and on /agent_1/steering, then the tool at its
    default rate (1 Hz) on both for a few seconds.  The commander takes each command, and no
    node logs an incompatible-QoS line (agents logged five or six per command before).  The
    control: a stock writer on /swarm/fault_request, which the world reads transient-local,
    makes the world say so in the same capture.  First, on the same run, ``ros2 node list``
    shows the documented names (lone agents and the recorder)."""
    run, lines = start_run(processes, swarm_cmd, tmp_path, '--record', tmp_path / 'bag.mcap')
    why = listed_as_documented([f'agent_{i}' for i in range(6)], 1, True)
    assert why is None, why
    Float64 = 'std_msgs/msg/Float64'
    for argv in [('--once', '/swarm/lambda', Float64, '{data: 0.25}'),
                 ('--once', '/agent_1/steering', Float64, '{data: 0.015}')]:
        p = _tool(processes, *argv)
        assert p.wait(timeout=120) == 0, p.stdout.read()
    assert lines.wait_for('λ set-point 0.25', 30), ''.join(lines.lines[-30:])
    assert lines.wait_for('steering of agent_1 set to 0.015', 30), ''.join(lines.lines[-30:])
    rate = [_tool(processes, '/swarm/lambda', Float64, '{data: 0.35}'),
            _tool(processes, '/agent_1/steering', Float64, '{data: 0.025}')]
    assert lines.wait_for('λ set-point 0.35', 60) and lines.wait_for('steering of agent_1 set to 0.025', 60)
    time.sleep(3.0)                      # a few messages at 1 Hz, and time for every node to see the writers
    for p in rate:
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    time.sleep(1.0)
    said = [ln for ln in _logs(tmp_path, lines).splitlines() if re.search('incompatible', ln, re.I)]
    assert not said, '\n'.join(said[:20])
    # the control: the world reads /swarm/fault_request transient-local; a stock writer there warns
    control = _tool(processes, '/swarm/fault_request', 'std_msgs/msg/String', '{data: x}')
    seen = lines.wait_for(lambda ln: 'incompatible' in ln and '/swarm/fault_request' in ln, 30)
    control.send_signal(signal.SIGINT)
    control.wait(timeout=30)
    stop(run, lines)
    assert seen, 'the capture did not show the control warning: it cannot see one'
    said = [ln for ln in _logs(tmp_path, lines).splitlines() if re.search('incompatible', ln, re.I)]
    assert said and all('/swarm/fault_request' in ln for ln in said), '\n'.join(said[:20])
