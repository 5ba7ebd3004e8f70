"""What goes wrong, without ROS (beyond the paper): agents that stop, freeze or are lost, with
leader failover and reunion (`agents`), and an imperfect radio: loss, delay and what each agent
believes of the others (`radio`)."""
from swarm_core.faults.agents import Failover, Fault, FaultTimeline, Rendezvous
from swarm_core.faults.radio import Beliefs, CommModel, StreamRadio

__all__ = ['Beliefs', 'CommModel', 'Failover', 'Fault', 'FaultTimeline', 'Rendezvous', 'StreamRadio']
