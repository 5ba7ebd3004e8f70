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

    choice: 'auto' (the UDP loopback profile, unless the environment already names a profile
    file), 'udp' (the profile in any case), or 'localhost' (rmw_fastrtps' localhost discovery
    range with Fast DDS's default transports, shared memory + UDP; at most `LOCALHOST_LIMIT`
    processes find each other).

    Shared memory is off unless asked for: a SIGKILLed peer (fault injection, a crashed agent)
    can leave Fast DDS's shared-memory ports blocked for the processes that remain
    (eProsima/Fast-DDS#5469) and leaves its segments in /dev/shm.  With the localhost range
    rmw_fastrtps sets the transports itself (``FASTDDS_BUILTIN_TRANSPORTS`` is ignored), so
    the profile is the way to keep discovery on 127.0.0.1 without shared memory."""
    if choice not in CHOICES:
        raise ValueError(f'DDS choice {choice!r}: one of {", ".join(CHOICES)}')
    env = dict(os.environ if base is None else base)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env.setdefault('PYTHONUNBUFFERED', '1')
    named = 'FASTRTPS_DEFAULT_PROFILES_FILE' in env or 'FASTDDS_DEFAULT_PROFILES_FILE' in env
    if choice == 'udp' or (choice == 'auto' and not named):
        path = Path(workdir) / 'fastdds_loopback.xml'
        path.write_text(profile_xml(n_processes))
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(path)
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(path)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        env.pop('ROS_STATIC_PEERS', None)
    elif choice == 'localhost':
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
    else:                                   # auto, with the caller's own profile file
        env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env
