"""The DDS set-up of a run (`swarm_tools.run.dds`), without a run: the profiles (the large-n
UDP one too), the discovery server, agent lists and bad options.  Runs through them:
tests/e2e/test_dds_runs.py."""
import subprocess
import xml.etree.ElementTree as ET

import pytest

from swarm_tools.run import dds
from swarm_tools.run.launch import parse_agents

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
                       (['run', 'homotopy_global', '--remote-agents', '2', '--discovery', 'simple'],
                        'discovery server'),
                       (['run', 'homotopy_global', '--interface', 'eth0'], '--interface'),
                       (['run', 'homotopy_global', '--interface', '192.0.2.1'], 'not an address of this host'),
                       (['join', 'homotopy_global', '--agents', '1', '--server', '127.0.0.1:5',
                         '--interface', '192.0.2.1'], 'not an address of this host')):
        r = subprocess.run([swarm_cmd, *args], capture_output=True, text=True, timeout=60)
        assert r.returncode == 2 and word in r.stderr, (args, r.stderr)


def test_udp_profile_is_written_for_large_runs(tmp_path):
    env = dds.environment(98, tmp_path, base={'ROS_DOMAIN_ID': '5'})
    xml = (tmp_path / 'fastdds_loopback.xml').read_text()
    assert env['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(tmp_path / 'fastdds_loopback.xml')
    assert env['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
    assert '<maxInitialPeersRange>130</maxInitialPeersRange>' in xml
    # small runs get the profile too (no shared memory); 'localhost' is rmw_fastrtps' own range
    (tmp_path / 'x').mkdir()
    small = dds.environment(8, tmp_path / 'x', base={})
    assert small['FASTRTPS_DEFAULT_PROFILES_FILE'] == str(tmp_path / 'x' / 'fastdds_loopback.xml')
    assert '<useBuiltinTransports>false</useBuiltinTransports>' in (tmp_path / 'x' / 'fastdds_loopback.xml').read_text()
    shm = dds.environment(8, tmp_path / 'y', base={}, choice='localhost')
    assert shm['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST' and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in shm
    own = dds.environment(8, tmp_path / 'z', base={'FASTRTPS_DEFAULT_PROFILES_FILE': '/my.xml'})
    assert own['FASTRTPS_DEFAULT_PROFILES_FILE'] == '/my.xml'        # the user's profile is kept
