"""Laws by name (no ROS): the registry's built-in laws, a law an installed package registers under
the entry-point group ``swarm_core.laws`` (a package on sys.path with its dist-info, as pip leaves
it) runs by name in `swarm simulate`, a name two sources claim is one line naming both, and
`swarm laws` lists every law with its parameters."""
from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import yaml

from swarm_core.engine.reference import simulate
from swarm_core.laws import Law, LawError, law_class, make_law, names, param
from swarm_core.laws.registry import BUILT_IN, GROUP, catalogue, describe
from swarm_core.scenario.loader import load
from swarm_tools.cli import main as swarm_main
from tests.helpers import ROOT

PACKAGE_LAW = '''\
import numpy as np

from swarm_core.laws import Law, param


class Spin(Law):
    """Every agent turns at one rate: a law an installed package registers by name."""
    rate = param(0.05, lo=-1.0, hi=1.0, doc='curvature of every agent')

    def control(self, view):
        return np.full(view.receivers.size, self.rate)
'''


def installed_package(root, entry_points: dict, name='spinlaws'):
    """A package ``name`` in ``root`` with its dist-info, as pip installs one: its module holds
    `Spin`; ``entry_points``: entry-point name → object reference, under the group swarm_core.laws."""
    (root / f'{name}.py').write_text(PACKAGE_LAW)
    info = root / f'{name}-1.0.dist-info'
    info.mkdir()
    (info / 'METADATA').write_text(f'Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n')
    (info / 'entry_points.txt').write_text(f'[{GROUP}]\n' + ''.join(f'{k} = {v}\n' for k, v in entry_points.items()))
    return root


@pytest.fixture
def spin_package(tmp_path, monkeypatch):
    """`installed_package` with ``spin = spinlaws:Spin``, on sys.path; its directory."""
    root = tmp_path / 'site'
    root.mkdir()
    installed_package(root, {'spin': 'spinlaws:Spin'})
    monkeypatch.syspath_prepend(str(root))
    yield root
    sys.modules.pop('spinlaws', None)


def test_the_built_in_laws_are_registered_by_kind():
    assert names()[:len(BUILT_IN)] == list(BUILT_IN)
    for kind in BUILT_IN:
        cls = law_class(kind)
        assert cls.kind == kind and issubclass(cls, Law)
        assert cls.dims == ((2,) if kind.startswith('spl_') else (2, 3))     # the paper's lifted to 3D; SPL planar
    assert law_class('global')().couples_globally(0.3) and not law_class('local')().couples_globally(0.3)


def test_an_installed_package_adds_a_law_by_name(spin_package):
    assert 'spin' in names()
    law = make_law({'kind': 'spin', 'rate': 0.2})
    assert law.kind == 'spin' and law.rate == 0.2
    assert law.mapping() == {'kind': 'spin', 'cutoff_radius': 4.0, 'rate': 0.2}
    u = law.evaluate(np.zeros((3, 2)), np.ones(3), np.zeros(3), np.arange(3))
    assert u.tolist() == [0.2, 0.2, 0.2]


def test_swarm_simulate_runs_a_registered_law_by_name(spin_package, tmp_path):
    path = tmp_path / 'spin.yaml'
    path.write_text(yaml.safe_dump({'name': 'spin', 'seed': 0, 'dt': 0.1, 'duration': 3.0, 'agents': {'count': 3},
                                    'law': {'kind': 'spin', 'rate': -0.3}}))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(spin_package), os.environ.get('PYTHONPATH', '')]))
    out = tmp_path / 'out'
    r = subprocess.run([sys.executable, '-m', 'swarm_tools.cli', 'simulate', str(path), '--out', str(out),
                        '--no-figure'], capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    got = np.load(out / 'trajectory.npz')
    assert np.all(got['u'] == -0.3)
    np.testing.assert_array_equal(got['r'], simulate(load(str(path))).r)


def test_a_name_two_sources_claim_is_one_line_naming_both(tmp_path, monkeypatch, capsys):
    root = tmp_path / 'site'
    root.mkdir()
    installed_package(root, {'global': 'spinlaws:Spin', 'twice': 'spinlaws:Spin'})
    other = tmp_path / 'other'
    other.mkdir()
    installed_package(other, {'twice': 'otherlaws:Spin'}, name='otherlaws')
    monkeypatch.syspath_prepend(str(root))
    monkeypatch.syspath_prepend(str(other))
    with pytest.raises(LawError) as err:
        make_law({'kind': 'global'})
    assert str(err.value) == ("law.kind 'global': claimed by two sources: built-in swarm_core.laws.paper.laws:Global"
                              " and entry point spinlaws:Spin (spinlaws)")
    with pytest.raises(LawError, match=r"'twice': claimed by two sources: entry point .*laws:Spin \(.*laws\) and "
                                       r"entry point .*laws:Spin \(.*laws\)$"):
        make_law({'kind': 'twice'})
    assert swarm_main(['laws']) == 2
    said = capsys.readouterr().err.splitlines()
    assert len(said) == 2 and all('claimed by two sources' in s for s in said), said
    assert swarm_main(['laws', 'global']) == 2


def test_swarm_laws_lists_every_law_with_its_parameters(capsys):
    assert swarm_main(['laws']) == 0
    out = capsys.readouterr().out.splitlines()
    heads = [ln for ln in out if not ln.startswith(' ')]
    assert [h.split()[0] for h in heads] == names()
    assert all(h.split('  ')[1] == ('[2D]' if h.startswith('spl_') else '[2D, 3D]') for h in heads)
    assert heads[0] == 'global  [2D, 3D]  Global coupling of every pair (eq. 4).'
    assert heads[names().index('blend')].startswith('blend  [2D, 3D]  u = (1 − λ) u_from + λ u_to')
    # each parameter's line: its name, default, range or choices, description
    table = {ln.split()[0]: ln for ln in out[1:out.index(heads[1])]}
    assert table['alpha'].split() == ['alpha', '0.02', '[0,', '1e+06]', 'spacing', 'gain', 'α', 'of', 'the', 'pair',
                                      'term', '(eq.', '5)']
    assert table['q0'].split()[:4] == ['q0', '1', '[0,', '1]']
    assert table['barrier_mode'].split()[:5] == ['barrier_mode', "'ahead'", 'ahead', '|', 'literal']
    assert table['target_normalised'].split()[:3] == ['target_normalised', 'False', 'yes/no']
    assert sum(1 for ln in out if ln.startswith(' ')) == sum(
        len(law_class(k).param_specs()) + len(law_class(k).parts) for k in names())
    assert '\n'.join(out) == '\n'.join(catalogue()[0])


def test_swarm_laws_name_shows_one_and_an_unknown_name_is_one_line(capsys):
    assert swarm_main(['laws', 'spl_circular']) == 0
    out = capsys.readouterr().out.splitlines()
    assert out == describe(law_class('spl_circular'))
    assert out[0].startswith('spl_circular  [2D]  Agents on one circle of radius 1/ω0')
    assert [ln.split()[0] for ln in out[1:]] == list(law_class('spl_circular').param_specs())
    assert 'harmonics          1         [1, 1000] integer' in out[4]
    assert swarm_main(['laws', str(ROOT / 'examples' / 'laws' / 'alignment.py') + ':Alignment']) == 0
    assert 'coupling K' in capsys.readouterr().out
    assert swarm_main(['laws', 'no_such_law']) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and err[0].startswith("swarm laws.kind 'no_such_law': not a law kind (global, local")


def test_a_law_class_declares_its_dimensions():
    class Flat(Law):
        gain = param(1.0, lo=0.0, hi=2.0)

        def control(self, view):
            return np.zeros(view.receivers.size)

    assert Flat.dims == (2,) and describe(Flat)[0].split()[1] == '[2D]'
