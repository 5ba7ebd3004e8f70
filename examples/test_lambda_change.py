"""A user's integration test of a λ change, written against the project's pytest plugin.

``ros_domain`` and ``swarm`` come from swarm_tools.pytest_plugin (installed with the project):
the test gets a ROS_DOMAIN_ID of its own, and every process of the runs it starts is gone
after it, passed or failed.  Run it with ``pytest examples/test_lambda_change.py``.

The check: at λ = 0 the six agents stay one swarm; raised to λ = 1, the two leaders steering
apart split it into two clusters, one leader each (the homotopy law, Morgan & Schwartz).
"""
from pathlib import Path

import pytest

SCENARIO = Path(__file__).with_name('six_agents_live.yaml')
#: the split a user's change is expected to keep (override in a variant of this test)
EXPECTED_CLUSTERS = 2

pytestmark = pytest.mark.ros


def test_raising_lambda_splits_the_swarm(swarm):
    # realtime at 4× wall speed: a lockstep run of 60 s can end before the test has looked at it
    run = swarm(SCENARIO, mode='realtime', rtf=4, duration=60, no_figure=True)
    before = run.wait_until(lambda m: m['t'] >= 3, timeout=10)
    assert before['clusters'] == 1 and before['lambda'] == 0.0

    run.set_lambda(1.0, ramp=2)                 # returns once the commander has taken it
    split = run.wait_until(lambda m: m['clusters'] >= 2, timeout=30)
    assert split['clusters'] == EXPECTED_CLUSTERS, split

    run.stop()                                  # as Ctrl-C: the outputs are written
    summary = run.metrics_json()['summary']
    assert summary['final_clusters'] == EXPECTED_CLUSTERS
