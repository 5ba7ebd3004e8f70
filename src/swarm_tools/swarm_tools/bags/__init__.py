"""MCAP bags as rosbag2 writes them: `mcap_io` (reading and writing), `msgdefs` (the schemas),
and the verbs ``swarm record``, ``swarm play``, ``swarm report`` and ``swarm bag recover``."""
