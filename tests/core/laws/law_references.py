"""Reference outputs of the paper's laws from the code before laws became plug-ins (revision
1f236c6), which test_law_plugins.py compares the engine with bit for bit.

The cases: every shipped scenario of the paper, and every paper law kind for 100 s at a
constant λ = 0 and λ = 1 (leaders chosen at t = 20).  For each case the sha256 of t, r, θ, u,
λ and the leader flags (−0.0 counted as 0.0), and every 200th step in a small .npz to see
where a difference starts.  Made once, from a worktree of that revision::

    git worktree add /tmp/oldtree 1f236c6
    PYTHONPATH=/tmp/oldtree/src/swarm_core .venv/bin/python tests/core/laws/law_references.py

It runs with the old or the new swarm_core (only the scenario loader's `parse` and
`read_yaml` and the reference engine's `simulate`, which both have).
"""
from __future__ import annotations

import copy
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

DATA = Path(__file__).with_name('data')
REVISION = '1f236c6'
#: the shipped scenarios of the paper's laws
PAPER_SCENARIOS = ('global_alignment', 'homotopy_global', 'homotopy_local', 'homotopy_reunion',
                   'leader_failover', 'leader_no_failover', 'target_barrier')
PAPER_KINDS = ('global', 'local', 'leader_following', 'homotopy', 'target')
#: every kth step goes into the .npz
SAMPLE_EVERY = 200


def _modules():
    try:
        from swarm_core.engine import reference as engine
        from swarm_core.scenario import loader as scenario
    except ImportError:            # the old tree: swarm_core/engine.py, swarm_core/scenario.py
        from swarm_core import engine, scenario
    return scenario, engine


def kind_case(kind: str, lam: float) -> dict:
    """The scenario mapping of paper law ``kind`` for 100 s at constant λ (target: with the
    target and barrier of target_barrier; the others: homotopy_global's agents and leaders)."""
    scenario, _ = _modules()
    base = 'target_barrier' if kind == 'target' else 'homotopy_global'
    data = copy.deepcopy(scenario.read_yaml(base)[0])
    data.pop('expect', None)
    data['name'] = f'{kind}_lambda{lam:g}'
    data['duration'] = 100.0
    data['lambda'] = {'kind': 'constant', 'value': lam}
    data['law'] = dict(data['law'], kind=kind)
    if kind != 'target':
        data['leaders'] = dict(data['leaders'], at=20)
    return data


def cases() -> dict:
    """name → scenario mapping of every reference case."""
    scenario, _ = _modules()
    out = {name: scenario.read_yaml(name)[0] for name in PAPER_SCENARIOS}
    for kind in PAPER_KINDS:
        for lam in (0.0, 1.0):
            data = kind_case(kind, lam)
            out[data['name']] = data
    return out


def arrays(traj) -> dict:
    """The arrays a case is compared by (−0.0 as 0.0: a blend's 0·u may flip the sign of a zero)."""
    return {'t': np.asarray(traj.t, float) + 0.0, 'r': np.asarray(traj.r, float) + 0.0,
            'theta': np.asarray(traj.theta, float) + 0.0, 'u': np.asarray(traj.u, float) + 0.0,
            'lam': np.asarray(traj.lam, float) + 0.0, 'leader': np.asarray(traj.leader, bool)}


def digests(arr: dict) -> dict:
    return {k: hashlib.sha256(np.ascontiguousarray(v).tobytes()).hexdigest() for k, v in arr.items()}


def run(data: dict, source: str = '<reference>'):
    """The case through the numpy sums (the old tree had no other; the new one's ``--compiled
    auto`` takes the compiled path for runs of `compiled_sums.LONG_RUN` steps and more)."""
    scenario, engine = _modules()
    scn = scenario.parse(data, source)
    if 'compiled' in engine.simulate.__code__.co_varnames:
        return engine.simulate(scn, compiled='off')
    return engine.simulate(scn)


def main() -> int:
    DATA.mkdir(exist_ok=True)
    table, samples = {}, {}
    for name, data in cases().items():
        arr = arrays(run(data, name))
        table[name] = {'steps': int(len(arr['t'])), **digests(arr)}
        for k, v in arr.items():
            samples[f'{name}/{k}'] = v[::SAMPLE_EVERY]
        print(f'{name}: {len(arr["t"])} steps', file=sys.stderr)
    import numpy
    meta = {'revision': REVISION, 'numpy': numpy.__version__, 'sample_every': SAMPLE_EVERY, 'cases': table}
    (DATA / f'paper_laws_{REVISION}.json').write_text(json.dumps(meta, indent=1) + '\n')
    np.savez_compressed(DATA / f'paper_laws_{REVISION}.npz', **samples)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
