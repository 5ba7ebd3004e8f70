"""CommandWatch: which command topics the commander looks at on each tick (plain pytest)."""
import pytest

from homotopy_commander.command_watch import CommandWatch, of_swarm

FIXED = ['/swarm/lambda', '/commander/lambda_setpoint']
ME = ('commander', '/')


def agents(n):
    return [f'agent_{i}' for i in range(n)]


def ours(node):
    return of_swarm(node, set(agents(1000)))


def settled(n, per_tick=64, window=2.0, nodes=(ME,)):
    """A watch that took its first node list at t = 0 (everything new) and let it age."""
    w = CommandWatch(FIXED, agents(n), per_tick=per_tick, window=window, ours=ours)
    assert w.nodes_seen(0.0, nodes)          # the first list: everything is new
    assert w.recent(window) == []
    return w


def tick(w, now, nodes, reading=(), found=()):
    """The keys the commander looks at on one tick: `nodes_seen`, then `pick`."""
    w.nodes_seen(now, nodes)
    return w.pick(now, reading, found)


@pytest.mark.parametrize('n', [1, 6, 64])
def test_small_swarm_every_topic_every_tick(n):
    w = settled(n)
    for k in range(5):
        assert tick(w, 10.0 + k, [ME]) == FIXED + agents(n)
    assert w.period() == 1


def test_big_swarm_turns_bounded_and_covering():
    n, turn = 1000, 4
    w = settled(n)
    seen_at = {}
    for k in range(w.period()):
        keys = tick(w, 10.0 + 0.05 * k, [ME])
        assert keys[:2] == FIXED and len(keys) == 2 + turn and len(set(keys)) == len(keys)
        for key in keys[2:]:
            seen_at.setdefault(key, k)
    assert w.period() == 250 and set(seen_at) == set(agents(n))     # 250 ticks = 12.5 s at 0.05 s
    # and it goes on: the next turn starts where the last one stopped
    assert tick(w, 20.0, [ME])[2] == agents(n)[(250 * turn) % n]


def test_a_new_node_is_asked_for_its_topics_for_a_while():
    w = settled(1000)
    assert len(tick(w, 10.0, [ME])) == 6
    tool = ('_ros2cli_4242', '/')
    assert w.nodes_seen(10.05, [ME, tool]) and w.recent(10.05) == [tool]      # ros2 topic pub appeared
    keys = w.pick(10.05, found=['agent_777', '/swarm/lambda', 'not_a_key'])   # what it writes
    assert keys[:3] == FIXED + ['agent_777'] and 'not_a_key' not in keys and len(keys) == 7
    assert w.recent(11.9) == [tool]                        # still inside 2 s
    assert w.recent(12.1) == []                            # window over
    assert not w.nodes_seen(12.2, [ME])                    # a node leaving is nothing new
    assert w.nodes_seen(12.3, [ME, tool]) and w.recent(12.3) == [tool]    # the same name coming back is
    # a second node of the same name (counted, not a set)
    w = settled(1000, nodes=[ME, tool])
    assert w.nodes_seen(10.0, [ME, tool, tool]) and w.recent(10.0) == [tool]
    # the same nodes in another order is no change
    w = settled(1000, nodes=[ME, tool])
    assert not w.nodes_seen(10.0, [tool, ME]) and w.recent(10.0) == []


def test_swarm_nodes_are_not_asked():
    w = settled(1000)
    swarm = [('agent', f'/agent_{i}') for i in range(1000)] + [('agent_container_0', '/')]
    assert not w.nodes_seen(10.0, [ME] + swarm) and w.recent(10.0) == []
    assert w.nodes_seen(10.05, [ME] + swarm + [('swarm_lambda', '/')])
    assert w.recent(10.05) == [('swarm_lambda', '/')]


def test_read_topics_every_tick_bounded():
    w = settled(1000, per_tick=64)
    keys = tick(w, 10.0, [ME], reading={'agent_900', '/swarm/lambda'})
    assert keys[:2] == FIXED and keys[2] == 'agent_900' and len(keys) == 7
    for k in range(20):                                    # not only when its turn comes
        assert 'agent_900' in tick(w, 10.1 + k, [ME], reading={'agent_900'})
    # more topics read than per_tick: those are looked at in turn too, at most per_tick a tick
    many = set(agents(1000)[::5])                          # 200 topics read
    got = set()
    for k in range(4):
        keys = tick(w, 40.0 + k, [ME], reading=many)
        assert len(keys) <= 2 + 64 + 4
        got |= many & set(keys)
    assert got == many


def test_bad_arguments():
    with pytest.raises(ValueError, match='per_tick'):
        CommandWatch(FIXED, agents(3), per_tick=0)
    with pytest.raises(ValueError, match='turn'):
        CommandWatch(FIXED, agents(3), turn=0)
    with pytest.raises(ValueError, match='window'):
        CommandWatch(FIXED, agents(3), window=float('nan'))


def test_of_swarm():
    roster = {'agent_0', 'agent_7'}
    assert of_swarm(('agent', '/agent_7'), roster) and of_swarm(('agent_container_3', '/'), roster)
    assert not of_swarm(('agent', '/agent_8'), roster)             # not in the roster
    assert not of_swarm(('_ros2cli_4242', '/'), roster) and not of_swarm(('commander', '/'), roster)
    assert not of_swarm(('swarm_lambda', '/'), roster)
