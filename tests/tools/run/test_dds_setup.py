"""The DDS set-up of a run: profiles, the discovery server, agent lists (pure), and a small
run through a discovery server that `swarm lambda` and a stock-tool graph listing reach."""
import os
import signal
import subprocess
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from swarm_core.trajectory import Trajectory
from swarm_tools import dds
from swarm_tools.launch import parse_agents

from conftest import Lines, short_homotopy

NS = '{http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles}'


def _xml(text):
    return ET.fromstring(text)


def test_profile_simple_and_server():
    simple = _xml(dds.profile_xml(10))
    assert [e.text for e in simple.iter(NS + 'address')] == ['127.0.0.1', '127.0.0.1']   # whitelist, peer
    assert simple.find(f'.//{NS}maxInitialPeersRange').text == str(int(10 * 1.25) + 8)
    server = _xml(dds.profile_xml(150, interface='10.1.2.3', server=True))
    assert [e.text for e in server.iter(NS + 'address')] == ['10.1.2.3']                  # whitelist only
    assert server.find(f'.//{NS}initialPeersList') is None
    assert int(server.find(f'.//{NS}mutation_tries').text) >= 4 * 150
    own = _xml(dds.DiscoveryServer('127.0.0.1', 11811).profile_xml())       # the server's own profile
    assert own.find(f'.//{NS}discoveryProtocol').text == 'SERVER'
    assert [e.text for e in own.iter(NS + 'address')] == ['127.0.0.1', '127.0.0.1']
    assert own.find(f'.//{NS}port').text == '11811'
    assert own.find(f'.//{NS}useBuiltinTransports').text == 'false'          # no shared memory


def test_environment_server_and_super_client(tmp_path):
    base = {'ROS_SUPER_CLIENT': 'TRUE', 'ROS_STATIC_PEERS': '1.2.3.4'}
    env = dds.environment(5, tmp_path, base=base, server='127.0.0.1:12345')
    assert env['ROS_DISCOVERY_SERVER'] == '127.0.0.1:12345'
    assert 'ROS_SUPER_CLIENT' not in env and 'ROS_STATIC_PEERS' not in env    # agents are plain clients
    assert 'initialPeersList' not in (tmp_path / 'fastdds_loopback.xml').read_text()
    assert dds.super_client(env)['ROS_SUPER_CLIENT'] == 'TRUE'
    assert 'ROS_SUPER_CLIENT' not in dds.super_client(dds.environment(5, tmp_path, base={}))
    # a profile named by the user is replaced when the run needs the server or another interface
    named = {'FASTRTPS_DEFAULT_PROFILES_FILE': '/x.xml', 'ROS_DISCOVERY_SERVER': 'old:1'}
    assert dds.environment(5, tmp_path, base=named)['FASTRTPS_DEFAULT_PROFILES_FILE'] == '/x.xml'
    assert 'ROS_DISCOVERY_SERVER' not in dds.environment(5, tmp_path, base=named)
    env = dds.environment(5, tmp_path, base=named, interface='10.0.0.7')
    assert env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(tmp_path / 'fastdds_loopback.xml')
    with pytest.raises(ValueError, match='localhost'):
        dds.environment(5, tmp_path, base={}, choice='localhost', server='127.0.0.1:1')
    assert dds.user_line('10.0.0.1', 11811) == 'export ROS_DISCOVERY_SERVER=10.0.0.1:11811 ROS_SUPER_CLIENT=TRUE'


def test_agent_lists_and_addresses():
    assert parse_agents('48-95', 96) == list(range(48, 96))
    assert parse_agents('0,2,5-7', 8) == [0, 2, 5, 6, 7]
    for bad, word in (('3-1', "'3-1'"), ('0-8', 'outside 0..7'), ('x', "'x'"), ('1,', "''")):
        with pytest.raises(ValueError, match=word):
            parse_agents(bad, 8)
    assert dds.parse_server('10.0.0.1:11811') == ('10.0.0.1', 11811)
    assert dds.parse_server('localhost:7') == ('127.0.0.1', 7)
    for bad, word in (('10.0.0.1', 'ADDRESS:PORT'), ('10.0.0.1:0', 'port'), ('10.0.0.1:x', 'port'),
                      ('no.such.host.invalid:5', 'not an IPv4')):
        with pytest.raises(ValueError, match=word):
            dds.parse_server(bad)
    with pytest.raises(ValueError, match='--interface'):
        dds.check_address('eth0', '--interface')
    assert dds.check_local('127.0.0.1') == '127.0.0.1'
    with pytest.raises(ValueError, match='not an address of this host'):
        dds.check_local('192.0.2.1', '--interface')          # TEST-NET-1: no host has it


def test_join_and_run_reject_bad_options(swarm_cmd):
    for args, word in ((['join', 'homotopy_global', '--agents', '0-99', '--server', '127.0.0.1:5'], 'outside'),
                       (['join', 'homotopy_global', '--agents', '1', '--server', 'nowhere'], 'ADDRESS:PORT'),
                       (['run', 'homotopy_global', '--remote-agents', '2', '--discovery', 'simple'], 'discovery server'),
                       (['run', 'homotopy_global', '--interface', 'eth0'], '--interface'),
                       (['run', 'homotopy_global', '--interface', '192.0.2.1'], 'not an address of this host'),
                       (['join', 'homotopy_global', '--agents', '1', '--server', '127.0.0.1:5',
                         '--interface', '192.0.2.1'], 'not an address of this host')):
        r = subprocess.run([swarm_cmd, *args], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and word in r.stderr, (args, r.stderr)


# `ros2 topic list --no-daemon` (ros2cli jazzy: ros2topic/verb/list.py with
# ros2cli/node/direct.py): a DirectNode named with the hidden prefix '_ros2cli' spins for
# DEFAULT_TIMEOUT = 0.5 s, then prints get_topic_names_and_types(); no waiting for a match.
# The test runs it as a user would: again, as a new process, until the topic shows or it gives up.
TOPIC_LIST = """
import time, rclpy
rclpy.init()
node = rclpy.create_node('_ros2cli_direct_node', start_parameter_services=False)
end = time.monotonic() + 0.5
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
print('\\n'.join(sorted(t for t, _ in node.get_topic_names_and_types())))
"""


def topic_list(env, tries):
    """Topics a fresh `ros2 topic list --no-daemon` shows, at the first try that lists
    /swarm/states (at most ``tries``); the last listing otherwise."""
    out = ''
    for _ in range(tries):
        out = subprocess.run([sys.executable, '-c', TOPIC_LIST], env=env, capture_output=True,
                             text=True, timeout=60).stdout
        if '/swarm/states' in out:
            break
    return out


@pytest.mark.ros
def test_run_through_a_discovery_server(tmp_path, ros_domain, processes, swarm_cmd):
    """A lockstep run with --discovery server: the launcher prints the line a shell needs; with
    it `swarm lambda` reaches the commander (λ changes in the published trajectory) and a stock
    topic listing as a super client sees the run; a listing through another discovery server, or
    with simple discovery on the same domain, does not (a run with its own server is apart)."""
    path = short_homotopy(tmp_path / 'short.yaml', duration=4000, lam='{kind: constant, value: 0.0}', at=5)
    out = tmp_path / 'run'
    p = processes.start([swarm_cmd, 'run', path, '--discovery', 'server', '--out', out, '--no-figure',
                         '--progress-every', '1'], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait_for('[world] t=', 180), ''.join(lines.lines)
    line = next(ln for ln in lines.lines if 'export ROS_DISCOVERY_SERVER=' in ln)
    shell = dict(os.environ)                  # the test's shell: its domain, LOCALHOST range
    for kv in line.split('export ', 1)[1].split():
        k, v = kv.split('=', 1)
        shell[k] = v
    assert shell['ROS_SUPER_CLIENT'] == 'TRUE' and shell['ROS_DISCOVERY_SERVER'].startswith('127.0.0.1:')
    listed = topic_list(shell, 10)
    assert '/swarm/states' in listed and '/lockstep/step' in listed, listed
    # apart: another discovery server's super client, and simple discovery, see none of it
    other = dds.DiscoveryServer('127.0.0.1')
    other.start(lambda label, args, env, **kw: processes.start(args, env=env, **kw), dict(os.environ), tmp_path)
    assert '/swarm/states' not in topic_list(dict(shell, ROS_DISCOVERY_SERVER=other.locator), 2)
    plain = {k: v for k, v in shell.items() if k not in ('ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT')}
    assert '/swarm/states' not in topic_list(plain, 2)
    # swarm lambda, from that shell
    cli = subprocess.run([swarm_cmd, 'lambda', '1.0'], env=shell, capture_output=True, text=True, timeout=90)
    assert cli.returncode == 0, cli.stdout + cli.stderr
    assert lines.wait_for('λ=1.000', 180), ''.join(lines.lines[-20:])
    p.send_signal(signal.SIGINT)
    assert lines.wait(p, 60) == 130
    got = Trajectory.load(out / 'trajectory.npz')
    assert got.lam[0] == 0.0 and got.lam[-1] == 1.0
    assert np.all(np.diff(got.lam) >= 0)
