"""What goes wrong, without ROS (beyond the paper): agents that stop, freeze or are lost, with
leader failover and reunion (`agents`).  An imperfect radio is `swarm_core.radio`."""
from swarm_core.faults.agents import Failover, Fault, FaultTimeline, Rendezvous

__all__ = ['Failover', 'Fault', 'FaultTimeline', 'Rendezvous']
