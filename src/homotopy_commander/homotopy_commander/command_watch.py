"""Which command topics the commander looks at in the ROS graph on each tick (no ROS import).

The commander makes a command topic's reader only once it has seen a writer of another node
on that topic (``CommanderNode._watch_commands``).  One look is one graph query per topic, and
there is one steering topic per agent: looking at every topic every tick costs about 35 ms per
tick at 1,000 agents in an empty graph, and a query costs more the more endpoints the graph
holds.  `CommandWatch` bounds that:

- the fixed topics (λ; the set-point has a reader from the start) are looked at every tick;
- a swarm of up to ``per_tick`` agents has every steering topic looked at every tick;
- in a bigger one, ``turn`` steering topics a tick, in turn (1,000 agents: every 250 ticks);
- topics whose reader exists (``reading``) every tick too (up to ``per_tick`` of them, in turn
  if there are more), so a reader is dropped soon after its writers left;
- for ``window`` seconds after a node appeared in the graph, the caller asks that node which
  topics it writes (one cheap query per node) and passes the command topics among them
  (``found``): ``ros2 topic pub`` is a new node, so its writer is matched at once.  The node
  and its writer are discovered in either order, hence a window and not one look.  Nodes of
  the swarm itself (``ours``: agents, agent containers) are not asked: they write no command
  topic, and there may be 1,000 of them.

A writer that a node already in the graph adds later, or one missed between two ticks (a node
that left and another of the same name that came), is found by the turns, within
``len(rotating) / turn`` ticks; a tool that waits for a match, as ``ros2 topic pub`` does,
publishes after that.
"""
from __future__ import annotations

import math
from collections import Counter

#: a swarm of up to this many agents has every steering topic looked at every tick
STEERING_PER_TICK = 64
#: steering topics looked at per tick, in turn, in a bigger swarm
STEERING_TURN = 4
#: seconds during which a node that appeared in the graph is asked which topics it writes
NEW_NODE_LOOK = 2.0


def of_swarm(node, agents) -> bool:
    """True for a node of the swarm itself: an agent (``/<agent>/agent``, ``agents``: the
    roster) or an agent container (``agent_container_<k>``).  ``node``: (name, namespace)."""
    name, namespace = node
    return (name == 'agent' and namespace[1:] in agents) or name.startswith('agent_container_')


class CommandWatch:
    """Picks the command topics to look at on each tick.

    ``fixed``: keys looked at every tick; ``rotating``: keys looked at in turn; ``ours(node)``:
    True for a node (an item of the node list) that opens no window."""

    def __init__(self, fixed, rotating, per_tick: int = STEERING_PER_TICK, window: float = NEW_NODE_LOOK,
                 ours=None, turn: int = STEERING_TURN):
        if per_tick < 1 or turn < 1:
            raise ValueError(f'per_tick={per_tick!r}, turn={turn!r}: must be at least 1')
        if not window >= 0:
            raise ValueError(f'window={window!r}: must be ≥ 0')
        self.fixed = list(fixed)
        self.rotating = list(rotating)
        self.every = list(dict.fromkeys(self.fixed + self.rotating))
        self.place = {k: i for i, k in enumerate(self.rotating)}
        self.per_tick, self.turn, self.window = int(per_tick), int(turn), float(window)
        self.ours = ours or (lambda node: False)
        self.nodes = Counter()
        self.node_list = None
        self.new = {}                # node -> until when it is asked for its topics
        self.cursor = 0              # next rotating key of the turns
        self.read_cursor = 0         # next key among those read, when more than per_tick are

    def nodes_seen(self, now: float, nodes) -> bool:
        """Take the graph's node list; True if a node not ours appeared (it is asked for its
        topics for ``window`` s: `recent`)."""
        nodes = list(nodes)
        if nodes == self.node_list:
            return False
        self.node_list = nodes
        now_nodes = Counter(nodes)
        new = [nd for nd in now_nodes - self.nodes if not self.ours(nd)]
        self.nodes = now_nodes
        for nd in new:
            self.new[nd] = now + self.window
        return bool(new)

    def recent(self, now: float) -> list:
        """The nodes to ask which topics they write: those that appeared less than ``window`` s ago."""
        for nd in [nd for nd, until in self.new.items() if now >= until]:
            del self.new[nd]
        return list(self.new)

    def pick(self, now: float, reading=(), found=()) -> list:
        """The keys to look at now (each once, the fixed ones first).  ``reading``: keys whose
        reader exists; ``found``: keys that a recent node writes."""
        if len(self.rotating) <= self.per_tick:
            return list(self.every)
        out = dict.fromkeys(self.fixed)
        read = sorted((k for k in reading if k in self.place and k not in out), key=self.place.__getitem__)
        if len(read) > self.per_tick:
            start = self.read_cursor % len(read)
            read = (read + read)[start:start + self.per_tick]
            self.read_cursor = start + self.per_tick
        out.update(dict.fromkeys(read))
        out.update(dict.fromkeys(k for k in found if k in self.place or k in out))
        n = len(self.rotating)
        start = self.cursor % n
        out.update(dict.fromkeys(self.rotating[(start + i) % n] for i in range(min(self.turn, n))))
        self.cursor = (start + self.turn) % n
        return list(out)

    def period(self) -> int:
        """Ticks between two looks at a rotating key in its turn (at most)."""
        if len(self.rotating) <= self.per_tick:
            return 1
        return max(1, math.ceil(len(self.rotating) / self.turn))
