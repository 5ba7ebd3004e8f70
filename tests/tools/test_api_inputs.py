"""The Python API's timeouts without a run: every `Swarm` method that takes one refuses NaN, ∞,
a negative number, a bool or a string at once, with a ValueError naming the argument, before it
sends, starts or waits for anything (``wait_until(timeout=nan)`` used to wait for ever).  So do
`Swarm.attach` and `Swarm.start` a ``domain`` that is no ROS_DOMAIN_ID (0-232), naming the range.
The pytest plugin's domain range: tests/tools/test_pytest_plugin.py."""
from __future__ import annotations

import math
import os
import re
import subprocess
import sys

import pytest

from swarm_tools.api import Swarm

BAD = [math.nan, math.inf, -math.inf, -1.0, True, '5']


class _NoRun:
    """A stand-in for a Swarm whose every use fails loudly: a method that checks its timeout
    first never gets to it."""

    proc = None
    running = True
    t = 0.0

    def __getattr__(self, name):
        raise AssertionError(f'{name} used before the timeout was checked')


CALLS = {
    'wait_until timeout': lambda v: Swarm.wait_until(_NoRun(), bool, timeout=v),
    'wait_until wall_timeout': lambda v: Swarm.wait_until(_NoRun(), bool, timeout=1.0, wall_timeout=v),
    'wait_until on=states timeout': lambda v: Swarm.wait_until(_NoRun(), bool, timeout=v, on='states'),
    'set_lambda wait': lambda v: Swarm.set_lambda(_NoRun(), 0.5, wait=v),
    'set_lambda timeout': lambda v: Swarm.set_lambda(_NoRun(), 0.5, timeout=v),
    'steer wait': lambda v: Swarm.steer(_NoRun(), 'agent_0', 0.1, wait=v),
    'steer timeout': lambda v: Swarm.steer(_NoRun(), 'agent_0', 0.1, timeout=v),
    'kill wait': lambda v: Swarm.kill(_NoRun(), 'agent_0', wait=v),
    'kill timeout': lambda v: Swarm.kill(_NoRun(), 'agent_0', timeout=v),
    'pause wait': lambda v: Swarm.pause(_NoRun(), 'agent_0', 1.0, wait=v),
    'pause timeout': lambda v: Swarm.pause(_NoRun(), 'agent_0', 1.0, timeout=v),
    'partition wait': lambda v: Swarm.partition(_NoRun(), ['agent_0'], wait=v),
    'drop wait': lambda v: Swarm.drop(_NoRun(), 0.5, wait=v),
    'wait timeout': lambda v: Swarm.wait(_NoRun(), timeout=v),
    'stop grace': lambda v: Swarm.stop(_NoRun(), grace=v),
    'attach wait': lambda v: Swarm.attach(domain=0, wait=v),
    'start start_timeout': lambda v: Swarm.start('no_such_scenario', start_timeout=v),
}


@pytest.mark.parametrize('call', CALLS)
@pytest.mark.parametrize('value', BAD, ids=repr)
def test_a_timeout_that_is_not_a_finite_number_of_seconds_is_refused_at_once(call, value):
    arg = call.split()[-1]
    with pytest.raises(ValueError, match=rf'^{arg}={value!r}: must be a finite number in \[0, '):
        CALLS[call](value)


def test_good_timeouts_pass_the_check():
    from swarm_tools.api import check_timeout
    assert check_timeout('timeout', 0) == 0.0 and check_timeout('timeout', 2.5) == 2.5
    assert check_timeout('wall_timeout', None, none=True) is None
    with pytest.raises(ValueError, match='^timeout=None'):
        check_timeout('timeout', None)


# ------------------------------------------------------------ the domain
#: ROS_DOMAIN_IDs no DDS participant can have: past 232 Fast DDS's ports do not fit (it then
#: ended the caller's process, a notebook kernel too), a negative one, or not an integer
BAD_DOMAINS = [999, 233, -3, '7', True, 7.0]
DOMAIN_CALLS = {
    'attach': 'Swarm.attach(domain={!r}, wait=0)',
    'start': "Swarm.start('no_such_scenario', domain={!r})",
}
DOMAIN_ERROR = r'must be a ROS_DOMAIN_ID, an integer in \[0, 232\] \(0-101 are safe on Linux\)'


def _in_a_child(code: str, **env) -> subprocess.CompletedProcess:
    """``code`` run by a Python process of its own (a domain past 232 used to end the process
    that tried it: here that fails the test, not the test run)."""
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, timeout=60,
                          env=dict(os.environ, **env))


@pytest.mark.parametrize('call', DOMAIN_CALLS)
@pytest.mark.parametrize('domain', BAD_DOMAINS, ids=repr)
def test_a_domain_outside_0_to_232_is_a_value_error_naming_the_range(call, domain):
    code = ('from swarm_tools.api import Swarm\n'
            f'try:\n    {DOMAIN_CALLS[call].format(domain)}\n'
            'except ValueError as err:\n    print("ValueError:", err)\n')
    r = _in_a_child(code, SWARM_DISCOVERY_SETTLE='0')
    assert r.returncode == 0 and r.stdout.strip().startswith('ValueError:'), (r.returncode, r.stdout, r.stderr[-2000:])
    assert re.fullmatch(rf'ValueError: domain={re.escape(repr(domain))}: {DOMAIN_ERROR}', r.stdout.strip()), r.stdout


@pytest.mark.parametrize('call', DOMAIN_CALLS)
def test_a_ros_domain_id_past_232_in_the_environment_is_a_value_error_naming_the_variable(call):
    code = ('from swarm_tools.api import Swarm\n'
            f'try:\n    {DOMAIN_CALLS[call].format(None)}\n'
            'except ValueError as err:\n    print("ValueError:", err)\n')
    r = _in_a_child(code, ROS_DOMAIN_ID='999', SWARM_DISCOVERY_SETTLE='0')
    assert r.returncode == 0, (r.returncode, r.stdout, r.stderr[-2000:])
    assert re.fullmatch(rf'ValueError: ROS_DOMAIN_ID=999: {DOMAIN_ERROR}', r.stdout.strip()), r.stdout


def test_the_domains_there_are_pass_the_check():
    import numpy as np

    from swarm_ros.runinfo import check_domain
    assert [check_domain(d) for d in (0, 7, 101, 232, np.int64(9))] == [0, 7, 101, 232, 9]
    assert type(check_domain(np.int64(9))) is int
