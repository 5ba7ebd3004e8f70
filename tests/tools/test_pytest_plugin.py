"""The pytest plugin's ROS_DOMAIN_ID range (swarm_tools.pytest_plugin): set by the option
``--swarm-domains LO-HI`` or the environment's ``SWARM_DOMAINS`` (the option wins), so that a CI
that reserves a range keeps to it; a bad range is one usage error before any test.  Each case
runs a user's test under the installed plugin (no conftest of ours); the fixture only sets the
environment, so no ROS process is started."""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from swarm_tools import pytest_plugin as plugin

USER_TEST = '''
import os

def test_domain(ros_domain):
    assert os.environ['ROS_DOMAIN_ID'] == str(ros_domain)
    print(f'DOMAIN={ros_domain}')
'''


def _pytest(tmp_path, *args, env=None):
    (tmp_path / 'test_user.py').write_text(USER_TEST)
    full = {k: v for k, v in os.environ.items() if k != plugin.DOMAINS_ENV}
    full.update(env or {}, SWARM_DOMAIN_LOCK_DIR=str(tmp_path / 'locks'))
    r = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-s', '-p', 'no:cacheprovider', '--rootdir',
                        str(tmp_path), *args, str(tmp_path / 'test_user.py')],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path, env=full)
    return r.returncode, r.stdout + r.stderr


@pytest.mark.parametrize('args, env, want', [
    (['--swarm-domains', '150-152'], {}, range(150, 153)),
    ([], {plugin.DOMAINS_ENV: '201-201'}, [201]),
    (['--swarm-domains', '160'], {plugin.DOMAINS_ENV: '201-201'}, [160]),     # the option wins
])
def test_the_domain_range_is_set_by_the_option_or_the_environment(tmp_path, args, env, want):
    rc, out = _pytest(tmp_path, *args, env=env)
    assert rc == 0, out
    dom = int(out.split('DOMAIN=')[1].split()[0])
    assert dom in want, out


@pytest.mark.parametrize('args, env, said', [
    (['--swarm-domains', '90-80'], {}, "--swarm-domains='90-80': want 0 <= LO <= HI <= 232"),
    (['--swarm-domains', 'ten'], {}, "--swarm-domains='ten': want LO-HI"),
    ([], {plugin.DOMAINS_ENV: '1-300'}, "SWARM_DOMAINS='1-300': want 0 <= LO <= HI <= 232"),
])
def test_a_bad_range_is_one_usage_error(tmp_path, args, env, said):
    rc, out = _pytest(tmp_path, *args, env=env)
    assert rc == 4 and said in out and 'Traceback' not in out, out


def test_claim_domain_keeps_to_its_range(tmp_path, monkeypatch):
    monkeypatch.setattr(plugin, '_LOCK_DIR', tmp_path)
    held = [plugin.claim_domain((7, 9)) for _ in range(3)]
    try:
        assert sorted(dom for dom, _ in held) == [7, 8, 9]
        monkeypatch.setattr(plugin, 'CLAIM_WAIT', 0.0)
        with pytest.raises(RuntimeError, match=r'no free ROS_DOMAIN_ID in 7\.\.9'):
            plugin.claim_domain((7, 9))
    finally:
        for _, f in held:
            f.close()
