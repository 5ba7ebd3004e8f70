"""DDS environment for a run's child processes.

Up to 32 processes: localhost discovery (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) unless
the caller's environment already chooses.  rmw_fastrtps' LOCALHOST range probes a fixed number
of participant ports, so more than 32 processes on one host do not all find each other; beyond
that a generated Fast DDS profile is used instead (`profile_xml`):

- UDPv4 on 127.0.0.1 only, no shared memory (it failed with many processes on 2 cores),
  builtin multicast avoided, initial peers on 127.0.0.1 with a peer range as large as the run;
- socket buffers as large as the kernel allows (up to 4 MiB; ``net.core.rmem_max`` /
  ``wmem_max``): with the default ~200 KiB a loopback burst of ~100 states per lockstep step
  overflowed receive buffers (``RcvbufErrors`` in /proc/net/snmp) and every step stalled;
- writers' heartbeat period 0.25 s (default 3 s), so that a datagram lost anyway is repaired
  by the reliable protocol well before the world's stall timer.
"""
from __future__ import annotations

import os
from pathlib import Path

LOCALHOST_LIMIT = 32

PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds>
 <profiles xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <transport_descriptors>
   <transport_descriptor>
    <transport_id>swarm_udp_loopback</transport_id>
    <type>UDPv4</type>
    <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
    <maxInitialPeersRange>{peers}</maxInitialPeersRange>
    <sendBufferSize>{send}</sendBufferSize>
    <receiveBufferSize>{receive}</receiveBufferSize>
   </transport_descriptor>
  </transport_descriptors>
  <participant profile_name="swarm_loopback" is_default_profile="true">
   <rtps>
    <userTransports><transport_id>swarm_udp_loopback</transport_id></userTransports>
    <useBuiltinTransports>false</useBuiltinTransports>
    <builtin>
     <avoid_builtin_multicast>true</avoid_builtin_multicast>
     <initialPeersList>
      <locator><udpv4><address>127.0.0.1</address></udpv4></locator>
     </initialPeersList>
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


#: socket buffer size asked for (bytes), capped by the kernel's maximum
SOCKET_BUFFER = 4 * 1024 * 1024


def _kernel_max(name: str) -> int:
    try:
        return int(Path(f'/proc/sys/net/core/{name}').read_text())
    except (OSError, ValueError):
        return 212992                   # the usual Linux default


def profile_xml(n_processes: int) -> str:
    return PROFILE.format(peers=max(8, int(n_processes * 1.25) + 8),
                          send=min(SOCKET_BUFFER, _kernel_max('wmem_max')),
                          receive=min(SOCKET_BUFFER, _kernel_max('rmem_max')))


CHOICES = ('auto', 'localhost', 'udp')


def environment(n_processes: int, workdir: Path, base=None, choice: str = 'auto') -> dict:
    """Environment for the children of a run of ``n_processes`` ROS processes.

    choice: 'auto' (localhost discovery up to `LOCALHOST_LIMIT` processes, the UDP loopback
    profile beyond, unless the environment already names a profile file), 'localhost', or
    'udp' (the profile whatever the size)."""
    if choice not in CHOICES:
        raise ValueError(f'DDS choice {choice!r}: one of {", ".join(CHOICES)}')
    env = dict(os.environ if base is None else base)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env.setdefault('PYTHONUNBUFFERED', '1')
    use_profile = choice == 'udp' or (choice == 'auto' and n_processes > LOCALHOST_LIMIT
                                      and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in env)
    if use_profile:
        path = Path(workdir) / 'fastdds_loopback.xml'
        path.write_text(profile_xml(n_processes))
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(path)
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(path)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        env.pop('ROS_STATIC_PEERS', None)
    elif choice == 'localhost':
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    else:
        env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env
