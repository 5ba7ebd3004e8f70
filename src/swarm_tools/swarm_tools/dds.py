"""DDS environment for a run's child processes.

Up to 32 processes: localhost discovery (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``) unless
the caller's environment already chooses.  rmw_fastrtps' LOCALHOST range probes a fixed number
of participant ports, so more than 32 processes on one host do not all find each other; beyond
that a generated Fast DDS profile is used instead: UDPv4 on 127.0.0.1 only, no shared memory
(it failed with many processes on 2 cores), initial peers on 127.0.0.1 with a peer range as
large as the run, builtin multicast avoided.
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
 </profiles>
</dds>
"""


def profile_xml(n_processes: int) -> str:
    return PROFILE.format(peers=max(8, int(n_processes * 1.25) + 8))


def environment(n_processes: int, workdir: Path, base=None) -> dict:
    """Environment for the children of a run of ``n_processes`` ROS processes."""
    env = dict(os.environ if base is None else base)
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env.setdefault('PYTHONUNBUFFERED', '1')
    if n_processes > LOCALHOST_LIMIT and 'FASTRTPS_DEFAULT_PROFILES_FILE' not in os.environ:
        path = Path(workdir) / 'fastdds_loopback.xml'
        path.write_text(profile_xml(n_processes))
        env['FASTRTPS_DEFAULT_PROFILES_FILE'] = str(path)
        env['FASTDDS_DEFAULT_PROFILES_FILE'] = str(path)
        env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
        env.pop('ROS_STATIC_PEERS', None)
    else:
        env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    return env
