"""Hostile and careless scenario inputs are refused at load, with one line naming the field,
before anything runs or is written (no ROS)."""
from __future__ import annotations

import errno
import os
import time
from pathlib import Path

import numpy as np
import pytest

from swarm_core.scenario import loader as scenario
from swarm_core.scenario.loader import ScenarioError, load, parse
from swarm_tools import simulate as simulate_cli

BASE = dict(name='t', dt=0.1, duration=1.0, agents=dict(count=3))


def _bad(match, **changes):
    data = {**BASE, **changes}
    with pytest.raises(ScenarioError, match=match):
        parse(data, 'x.yaml')


def test_bad_fields_are_refused_at_load():
    """Item 5: every one of these used to pass validation and fail late (or silently)."""
    _bad('positions', agents=dict(positions=[]))                               # engine.py IndexError
    _bad('one line', barrier=dict(points=[[0, 0], [1, 1], [2, 2]]))          # QhullError in the world
    _bad('one line', barrier=dict(points=[[5, 5], [5, 5], [5, 5]]))
    _bad('at least 3', barrier=dict(points=[[0, 0], [1, 0]]))                # intrusion check off
    _bad('not a convex polygon', barrier=dict(points=[[0, 0], [4, 0], [4, 4], [0, 4], [2, 1]]))
    _bad('expect', expect=dict(one_cluster_at='soon'))                         # crashed after the run
    _bad('expect.no_such_check', expect=dict(no_such_check=1))
    _bad('empty', expect=dict(split_between=[600, 440]))
    _bad('expect.polarisation_above', expect=dict(polarisation_above=dict(at=1)))
    _bad('shorter than one step', duration=0.04)                              # 0 steps, exit 0
    _bad('target.position', target=dict(position=[1e308, 0]))                 # NaN trajectory
    _bad('law.alpha', law=dict(alpha=1e300))
    _bad('agents.positions', agents=dict(count=3, positions=dict(rule='grid', spacing=1e300)))
    # a valid convex barrier still loads, and the shipped scenarios' checks are unchanged
    parse({**BASE, 'barrier': dict(points=[[0, 0], [1, 0], [1, 1], [0, 1]])}, 'x.yaml')
    scn = load('leader_failover')
    assert scn.spec.expect['follows_program'] == {'slot': 0, 'from': 490, 'to': 565, 'tolerance': 0.3}


def test_agent_names_must_be_ros_name_tokens():
    """Item 7: "" or "b/../c d" passed and then every node died with a traceback."""
    for bad in ['', 'b/../c d', '1abc', 'a__b', '/abs', 'x' * 65, 'ok name']:
        _bad('agent name|names', agents=dict(names=['a', 'b', bad]))
    parse({**BASE, 'agents': dict(names=['agent_0', 'Leader1', 'b_'])}, 'x.yaml')


def test_scenario_name_is_a_label_not_a_path(tmp_path, monkeypatch):
    """Item 7: a name with ../ or an absolute path wrote outside --out."""
    for name in ['../../escape', '/tmp/abs/escape', '..', '.hidden/../x']:
        label = scenario.safe_label(name)
        assert '/' not in label and not label.startswith('.') and label
    out = tmp_path / 'out'
    f = tmp_path / 'evil.yaml'
    f.write_text('name: ../../evil_escape\ndt: 0.1\nduration: 0.5\nagents: {count: 2}\n')
    monkeypatch.chdir(tmp_path)
    assert simulate_cli.simulate_main([str(f), '--out', str(out), '--quiet']) == 0
    written = sorted(p.name for p in out.iterdir())
    assert 'evil_escape.png' in written, written
    assert not list(tmp_path.parent.glob('evil_escape*')) and not list(tmp_path.glob('evil_escape*'))
    # the default --out is under runs/ too
    assert simulate_cli.simulate_main([str(f), '--quiet', '--no-figure']) == 0
    assert [p.parent for p in tmp_path.glob('runs/*/trajectory.npz')] == [tmp_path / 'runs' / 'evil_escape-seed0']


def test_resource_limits_before_parsing(tmp_path):
    """Item 6: an alias bomb hung at 3 GB; a 50 MB positions list took minutes and GBs."""
    bomb = tmp_path / 'bomb.yaml'
    lines = ['name: bomb', 'agents: {count: 2}', 'expect:', '  a0: &a0 [x, x, x, x, x, x, x, x, x]']
    for i in range(1, 12):
        lines.append(f'  a{i}: &a{i} [' + ', '.join([f'*a{i - 1}'] * 9) + ']')
    bomb.write_text('\n'.join(lines) + '\n')
    t0 = time.monotonic()
    with pytest.raises(ScenarioError, match='aliases'):
        load(str(bomb))
    assert time.monotonic() - t0 < 30
    big = tmp_path / 'big.yaml'
    with open(big, 'w') as fh:
        fh.write('name: big\nagents:\n  positions: [')
        fh.write('[1.0, 2.0], ' * (scenario.MAX_FILE_BYTES // 10))
        fh.write('[0, 0]]\n')
    with pytest.raises(ScenarioError, match='at most'):
        load(str(big))


def test_read_only_out_is_refused_before_the_run(tmp_path, capsys):
    """Item 5: an existing read-only --out crashed after the computation."""
    out = tmp_path / 'ro'
    out.mkdir()
    out.chmod(0o555)
    if os.access(out, os.W_OK):     # root writes anywhere: take a directory of a read-only mount
        out = next((Path(p) for p in ('/sys/kernel', '/sys', '/proc/self') if Path(p).is_dir()
                    and not _writable(Path(p))), None)
        if out is None:
            pytest.skip('no read-only directory to test with')
    try:
        with pytest.raises(SystemExit) as e:
            simulate_cli.simulate_main(['global_alignment', '--out', str(out), '--quiet', '--duration', '1'])
        assert e.value.code == 2
        assert 'not writable' in capsys.readouterr().err
    finally:
        (tmp_path / 'ro').chmod(0o755)


def _writable(d):
    try:
        (d / '.swarm_write_probe').touch()
    except OSError:
        return False
    (d / '.swarm_write_probe').unlink()
    return True


def test_full_disk_gives_one_line_and_no_empty_trajectory(tmp_path, monkeypatch, capsys):
    """Item 5: results are written atomically; a full disk leaves no 0-byte trajectory.npz."""
    real_savez = np.savez_compressed

    def full_disk(fh, **arrays):
        real_savez(fh, **{k: v[:1] for k, v in arrays.items()})   # some bytes, then the disk is full
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(getattr(fh, 'name', fh)))
    monkeypatch.setattr(np, 'savez_compressed', full_disk)
    out = tmp_path / 'out'
    code = simulate_cli.simulate_main(['global_alignment', '--out', str(out), '--quiet', '--duration', '1',
                                       '--no-figure'])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1
    assert len(err) == 1 and 'No space left on device' in err[0], err
    assert list(out.iterdir()) == []           # no partial trajectory.npz, no temp file left


def test_swarm_run_parameters_grow_linearly_and_agents_are_limited(tmp_path):
    """Item 6: the roster was written into every agent's section (O(N²): 10,000 agents took
    over 300 s before anything started); now it is shared, and `swarm run` has a limit."""
    import subprocess
    import sys

    import yaml

    from swarm_tools.run import launch
    from swarm_tools.run import params as node_params

    def params_size(n):
        scn = parse(dict(name='big', agents=dict(count=n)), 'x.yaml')
        params = node_params.node_parameters(scn, 'x.yaml', 'lockstep')
        path = node_params.write_params_file(params, tmp_path / f'p{n}.yaml')
        return params, path

    (_, f1), (p4, f4) = params_size(250), params_size(1000)
    assert f4.stat().st_size < 4.6 * f1.stat().st_size          # O(N²) gives ~16×
    doc = yaml.safe_load(f4.read_text())
    shared = doc[node_params.AGENTS_SECTION]['ros__parameters']
    for fqn in ('/agent_0/agent', '/agent_999/agent'):       # each agent still gets everything
        assert {**shared, **doc[fqn]['ros__parameters']} == p4[fqn]
    assert doc['/world']['ros__parameters'] == p4['/world']
    big = tmp_path / 'many.yaml'
    big.write_text(f'name: many\nagents: {{count: {launch.MAX_RUN_AGENTS + 1}}}\n')
    r = subprocess.run([sys.executable, '-m', 'swarm_tools.cli', 'run', str(big), '--out', str(tmp_path / 'o')],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and f'at most {launch.MAX_RUN_AGENTS}' in r.stderr, r.stderr
