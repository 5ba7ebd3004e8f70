"""`swarm report RUN_DIR` (run_report): a run directory without a bag; a 3D run's figure has a
3D view, a top view and a side view; a planar run's figure is the planar one."""
from __future__ import annotations

import json

import matplotlib.pyplot as plt
import numpy as np
import pytest

from swarm_core.analysis import plots3d
from swarm_core.analysis.outputs import analyse, write_outputs
from swarm_core.engine import reference as engine
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario import loader as scenario
from swarm_tools.bags import report
from swarm_tools.bags.run_report import run_trajectory


def _run_dir(tmp_path, name, duration):
    """``swarm simulate NAME --duration D --no-figure`` into tmp_path/NAME."""
    scn = scenario.load(name, duration=duration)
    traj = engine.simulate(scn)
    series, checks = analyse(traj, scenario=scn)
    out = tmp_path / name
    write_outputs(out, scn, traj, series, checks, figure=False)
    return out, traj


@pytest.fixture
def figures(monkeypatch):
    """The figures the report closes, kept open to be looked at."""
    kept = []
    close = plt.close
    monkeypatch.setattr(plt, 'close', lambda fig=None: kept.append(fig))
    yield kept
    for fig in kept:
        close(fig)


def test_a_3d_run_gets_a_3d_view_a_top_view_and_a_side_view(tmp_path, figures, capsys):
    run, traj = _run_dir(tmp_path, 'ground_3d', 160)
    rep = tmp_path / 'rep'
    assert report.main([str(run), '--out', str(rep)]) == 0
    assert 'wrote' in capsys.readouterr().out
    assert (rep / 'report.png').stat().st_size > 10_000
    np.testing.assert_array_equal(Trajectory.load(rep / 'trajectory.npz').r, traj.r)
    summary = json.loads((rep / 'metrics.json').read_text())['summary']
    assert summary['dim'] == 3 and summary['scenario'] == 'ground_3d' and summary['cutoff_radius'] == 4.0
    assert summary['floor_intrusions_total'] == 0 and summary['floor_clearance'] > 3.0   # the ground, from metrics.json
    assert summary['closest_centroid_target_distance'] < 8.0                            # the target too
    (fig,) = figures
    views = {ax.get_title(): ax for ax in fig.axes}
    three = [ax for ax in fig.axes if ax.name == '3d']
    assert len(three) == 1 and three[0].get_zlabel() == 'z'
    assert (views['top view'].get_xlabel(), views['top view'].get_ylabel()) == ('x', 'y')
    assert (views['side view'].get_xlabel(), views['side view'].get_ylabel()) == ('x', 'z')
    labels = views['side view'].get_legend_handles_labels()[1]
    assert 'ground' in labels and 'target' in labels
    # the side view draws the run's heights: every agent's z, start to end
    lines = views['side view'].get_lines()[0:2 * len(traj.names):2]          # each agent: its path, its end
    for k, line in enumerate(lines):
        assert line.get_ydata()[0] == traj.r[0, k, 2] and line.get_ydata()[-1] == traj.r[-1, k, 2]


def test_a_3d_trajectory_file_alone_and_animate(tmp_path, figures, capsys):
    """A trajectory.npz without its metrics.json: the default w, no target; --animate says no."""
    run, _ = _run_dir(tmp_path, 'target_3d', 30)
    lone = tmp_path / 'lone.npz'
    lone.write_bytes((run / 'trajectory.npz').read_bytes())
    assert report.main([str(lone), '--out', str(tmp_path / 'r'), '--animate']) == 0
    err = capsys.readouterr().err
    assert 'no cutoff_radius' in err and 'no animation of a 3D run' in err
    assert (tmp_path / 'r' / 'report.png').exists() and not (tmp_path / 'r' / 'swarm.gif').exists()
    assert [ax.name for ax in figures[0].axes].count('3d') == 1


def test_a_planar_run_dir_gets_the_planar_figure(tmp_path, figures, monkeypatch):
    def no_3d(*args, **kw):
        raise AssertionError('a planar run drew the 3D figure')
    monkeypatch.setattr('swarm_core.analysis.plots.plot_run_3d', no_3d)
    run, _ = _run_dir(tmp_path, 'target_barrier', 20)
    assert report.main([str(run), '--out', str(tmp_path / 'r')]) == 0
    (fig,) = figures
    assert all(ax.name == 'rectilinear' for ax in fig.axes) and len(fig.axes) == 4
    assert (fig.axes[0].get_xlabel(), fig.axes[0].get_ylabel()) == ('x', 'y')
    summary = json.loads((tmp_path / 'r' / 'metrics.json').read_text())['summary']
    assert summary['dim'] == 2 and 'barrier_clearance' in summary


def test_which_paths_are_runs(tmp_path):
    """A directory with a bag stays a bag's report; one with only a trajectory.npz is a run."""
    (tmp_path / 'trajectory.npz').write_bytes(b'')
    assert run_trajectory(tmp_path) == tmp_path / 'trajectory.npz'
    assert run_trajectory(tmp_path / 'trajectory.npz') == tmp_path / 'trajectory.npz'
    (tmp_path / 'run.mcap').write_bytes(b'')
    assert run_trajectory(tmp_path) is None
    assert run_trajectory(tmp_path / 'run.mcap') is None
    assert plots3d.VIEWS == (('top view', (0, 1)), ('side view', (0, 2)))


def test_a_bad_trajectory_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / 'bad.npz'
    bad.write_bytes(b'not a zip')
    assert report.main([str(bad), '--out', str(tmp_path / 'r')]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'not a trajectory.npz' in err[0]
