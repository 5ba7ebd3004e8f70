"""Which command topics the commander looks at in the ROS graph on each tick (no ROS import).

The commander makes a command topic's reader only once it has seen a writer of another node
on that topic (``CommanderNode._watch_commands``).  One look is one graph query per topic, and
there is one steering topic per agent, so looking at every topic every tick costs about 35 ms
per tick at 1,000 agents.  `CommandWatch` bounds that:

- the fixed topics (λ and the set-point) are looked at every tick;
- the steering topics in a round-robin slice of at most ``per_tick`` a tick: a swarm of up to
  ``per_tick`` agents still has every topic looked at every tick, 1,000 agents every 16 ticks;
- topics whose reader exists (``reading``) every tick too (up to ``per_tick`` of them, in turn
  if there are more), so a reader is dropped soon after its writers left;
- every topic every tick for ``window`` seconds after a node appeared in the graph.
  ``ros2 topic pub`` is a new node, so its writer is matched at once.  The node and its writer
  are discovered in either order, hence a window and not one look.  Nodes of the swarm itself
  (``ours``: agents, agent containers) open no window: they write no command topic, and
  1,000 of them appearing at start-up would otherwise keep the window open.

Missing a window (a node that left and another of the same name that came between two ticks)
costs only time: the round robin still finds the writer within ``len(rotating) / per_tick``
ticks, and a tool that waits for a match, as ``ros2 topic pub`` does, publishes after that.
"""
from __future__ import annotations

import math
from collections import Counter

#: at most this many steering topics looked at per tick outside a window (besides the fixed ones)
STEERING_PER_TICK = 64
#: seconds of looking at every topic every tick after a node appeared in the graph
FULL_LOOK = 2.0


def of_swarm(node, agents) -> bool:
    """True for a node of the swarm itself: an agent (``/<agent>/agent``, ``agents``: the
    roster) or an agent container (``agent_container_<k>``).  ``node``: (name, namespace)."""
    name, namespace = node
    return (name == 'agent' and namespace[1:] in agents) or name.startswith('agent_container_')


class CommandWatch:
    """Picks the command topics to look at on each tick.

    ``fixed``: keys looked at every tick; ``rotating``: keys looked at in turn; ``ours(node)``:
    True for a node (an item of the node list) that opens no window."""

    def __init__(self, fixed, rotating, per_tick: int = STEERING_PER_TICK, window: float = FULL_LOOK,
                 ours=None):
        if per_tick < 1:
            raise ValueError(f'per_tick={per_tick!r}: must be at least 1')
        if not window >= 0:
            raise ValueError(f'window={window!r}: must be ≥ 0')
        self.fixed = list(fixed)
        self.rotating = list(rotating)
        self.every = list(dict.fromkeys(self.fixed + self.rotating))
        self.place = {k: i for i, k in enumerate(self.rotating)}
        self.per_tick, self.window = int(per_tick), float(window)
        self.ours = ours or (lambda node: False)
        self.nodes = Counter()
        self.node_list = None
        self.full_until = -math.inf
        self.cursor = 0              # next rotating key of the round robin
        self.read_cursor = 0         # next key among those read, when more than per_tick are

    def nodes_seen(self, now: float, nodes) -> bool:
        """Take the graph's node list; True (and a window opens) if a node not ours appeared."""
        nodes = list(nodes)
        if nodes == self.node_list:
            return False
        self.node_list = nodes
        now_nodes = Counter(nodes)
        new = now_nodes - self.nodes
        self.nodes = now_nodes
        if any(not self.ours(nd) for nd in new):
            self.full_until = now + self.window
            return True
        return False

    def full(self, now: float) -> bool:
        """True while a window is open."""
        return now < self.full_until

    def pick(self, now: float, reading=()) -> list:
        """The keys to look at now (each once, the fixed ones first).  ``reading``: keys whose
        reader exists."""
        if self.full(now) or len(self.rotating) <= self.per_tick:
            return list(self.every)
        out = dict.fromkeys(self.fixed)
        read = sorted((k for k in reading if k in self.place and k not in out), key=self.place.__getitem__)
        if len(read) > self.per_tick:
            start = self.read_cursor % len(read)
            read = (read + read)[start:start + self.per_tick]
            self.read_cursor = start + self.per_tick
        out.update(dict.fromkeys(read))
        n = len(self.rotating)
        start = self.cursor % n
        out.update(dict.fromkeys(self.rotating[(start + i) % n] for i in range(self.per_tick)))
        self.cursor = (start + self.per_tick) % n
        return list(out)

    def tick(self, now: float, nodes, reading=()) -> list:
        """`nodes_seen` then `pick`: the keys to look at on this tick."""
        self.nodes_seen(now, nodes)
        return self.pick(now, reading)

    def period(self) -> int:
        """Ticks between two looks at a rotating key outside a window (at most)."""
        return max(1, math.ceil(len(self.rotating) / self.per_tick))
