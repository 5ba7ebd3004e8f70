"""A 3D run's bag: `swarm report BAG.mcap` rebuilds the 3D trajectory (r, the frames, u and v)
and it equals `swarm simulate`; the report's ground is the one the world announces on /swarm/run;
the rebuild of an interrupted run (`salvage`) is 3D too; a bag without the run's announcement is
told 3D by its states."""
import json
import subprocess

import numpy as np

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from tests.agent.test_natural_core import short_3d
from tests.helpers import Lines


def _same_as_simulate(got, ref):
    """The bag's trajectory is the run's: r, u, v exactly (float64 on the wire), the frames to
    rounding (from the quaternions) and t (integer ns stamps) to 1e-9; λ is one the run had and
    the leaders are the run's but within two steps of a change (the commander publishes them
    now and then, and the bag's messages are placed by receive time: held between); one more
    sample after the last step (its (u, v) not known yet)."""
    T = len(ref.t)
    assert got.dim == 3 and got.r.shape == (T + 1, 6, 3) and got.theta is None
    np.testing.assert_allclose(got.t[:T], ref.t, rtol=0, atol=1e-9)
    assert np.isclose(got.lam[:T, None], ref.lam[None, :], rtol=0, atol=1e-9).any(axis=1).all()
    for key in ('r', 'u', 'v'):
        np.testing.assert_array_equal(getattr(got, key)[:T], getattr(ref, key), err_msg=key)
    changed = np.flatnonzero((ref.leader[1:] != ref.leader[:-1]).any(axis=1)) + 1
    near = (np.abs(np.arange(T)[:, None] - changed[None, :]) <= 2).any(axis=1)
    np.testing.assert_array_equal(got.leader[:T][~near], ref.leader[~near], err_msg='leader')
    assert got.leader[:T].any(axis=0).tolist() == ref.leader.any(axis=0).tolist()
    for key in ('x', 'y', 'z'):
        np.testing.assert_allclose(getattr(got, key)[:T], getattr(ref, key), rtol=0, atol=1e-12, err_msg=key)
    assert np.isnan(got.u[T]).all() and np.isnan(got.v[T]).all()
    assert np.abs(ref.v).max() > 0 and ref.leader.any() and np.ptp(ref.r[..., 2]) > 0


def test_report_of_a_3d_bag_equals_simulate(tmp_path, ros_domain, processes, swarm_cmd):
    path = short_3d(tmp_path / 'h3.yaml', duration=15.0, barrier={'ground': -40.0})     # a floor far below
    bag = tmp_path / 'run.mcap'
    p = processes.start([swarm_cmd, 'run', path, '--out', tmp_path / 'run', '--no-figure', '--agents-per-process',
                         '3', '--record', bag], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines = Lines(p)
    assert lines.wait(p, 300) == 0, ''.join(lines.lines[-40:])
    scn = load(str(path))
    ref = simulate(scn)

    out = tmp_path / 'report'
    r = subprocess.run([swarm_cmd, 'report', str(bag), '--out', str(out), '--animate'],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert '6 agents in 3D, 151 steps (lockstep)' in r.stdout, r.stdout
    assert 'no animation of a 3D run' in r.stderr, r.stderr
    assert (out / 'report.png').stat().st_size > 10_000 and not (out / 'swarm.gif').exists()
    _same_as_simulate(Trajectory.load(out / 'trajectory.npz'), ref)
    summary = json.loads((out / 'metrics.json').read_text())['summary']
    assert summary['dim'] == 3 and summary['agents'] == 6 and summary['cutoff_radius'] == scn.law.cutoff_radius
    assert summary['ground'] == -40.0 and summary['floor_intrusions_total'] == 0 and 'ground' not in r.stderr
    from swarm_ros.runinfo import parse_run, run_ground
    from swarm_tools.bags.mcap_io import iter_messages, parse_string
    (said,) = [parse_run(parse_string(m.data)) for m in iter_messages(bag, ['/swarm/run'])]
    assert run_ground(said) == (True, -40.0)

    # the rebuild `swarm run` makes when the world did not save the trajectory
    from swarm_tools.run.outputs import salvage
    again = tmp_path / 'salvaged'
    again.mkdir()
    assert salvage(scn, again, bag, 'lockstep', 1.0, figure=False)
    _same_as_simulate(Trajectory.load(again / 'trajectory.npz'), ref)

    # without the run's announcement on /swarm/run, the states tell
    from swarm_tools.bags.report import read_run, rebuild_trajectory
    from swarm_tools.bags.report3d import run_dim
    run = read_run(bag)
    assert run['dim'] == 3 and run_dim(None, run['per_agent']) == 3
    _same_as_simulate(rebuild_trajectory(run), ref)
