"""``swarm run --robots`` checks the robots before any process starts: a number of the
``robots:`` section or of its robot description out of range, a description file that cannot be
read, or a step longer than the robots can follow is one line and exit 2; a step in which the
robots brake is one warning line on stderr (pure: nothing starts)."""
from pathlib import Path

import pytest
import yaml

from swarm_tools.run import launch

BASE = dict(name='r', dt=0.1, duration=2.0, agents=dict(count=3), robots=dict(length_scale=0.3, cruise_speed=0.15))


@pytest.fixture
def nothing_starts(monkeypatch):
    def started(run):
        raise AssertionError('the run started')
    monkeypatch.setattr(launch, 'execute', started)


def _main(tmp_path, robots=None, *options):
    path = tmp_path / 'scn.yaml'
    path.write_text(yaml.safe_dump(dict(BASE, robots=dict(BASE['robots'], **(robots or {})))))
    return launch.main([str(path), '--out', str(tmp_path / 'out'), '--robots', 'mujoco', *options])


@pytest.mark.parametrize('robots, said', [
    (dict(cruise_speed=1000.0), 'robots.cruise_speed: cruise_speed=1000.0: must be a finite number in [0.001, 100]'),
    (dict(length_scale=1e-300), 'robots.length_scale: length_scale=1e-300: must be a finite number in [0.001, 1000]'),
    (dict(max_angular=1e6), 'robots.max_angular: max_angular=1000000.0: must be a finite number in [0.001, 100]'),
    (dict(description='robot.yaml'), 'max_angular_accel=1e-300: must be a finite number in [0.01, 10000]'),
    (dict(description='missing.yaml'), 'robots.description: '),
    (dict(cruise_speed=0.001), 'robots: a step of dt = 0.1 model s lasts 30 robot s (L/v0 = 0.3 m / 0.001 m/s'),
])
def test_robots_swarm_run_cannot_drive_are_one_line_and_exit_2(tmp_path, capsys, nothing_starts, robots, said):
    (tmp_path / 'robot.yaml').write_text('max_angular_accel: 1.0e-300\n')
    assert _main(tmp_path, robots) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('swarm run: ') and said in err[0], err


def test_a_step_in_which_the_robots_brake_is_one_warning_line(tmp_path, capsys):
    path = tmp_path / 'scn.yaml'
    path.write_text(yaml.safe_dump(BASE))
    run = launch.validate(launch._parser().parse_args([str(path), '--out', str(tmp_path / 'out'), '--dt', '1.0',
                                                       '--robots', 'mujoco:agent_0']))
    assert run is not None and run.scn.dt == 1.0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith('swarm run: WARNING: robots: a step of dt = 1 model s lasts 2 robot s')
    assert 'the robots brake in every step' in err[0]
    launch.validate(launch._parser().parse_args([str(path), '--out', str(tmp_path / 'out')]))     # no robots
    launch.validate(launch._parser().parse_args([str(path), '--out', str(tmp_path / 'out'), '--robots', 'external']))
    assert capsys.readouterr().err == ''


def test_the_launch_file_stops_at_once_on_an_agent_that_refused_its_parameters(tmp_path, monkeypatch):
    """As `swarm run` does (tests/tools/run/ros/test_refused_parameters.py): the agent's line
    from the run's notes, the run stops with code 2, not after the world's start timeout."""
    from swarm_ros.rosutil import EXIT_NOTES
    from swarm_tools.run import launch_description as ld
    monkeypatch.setattr(launch, 'finish', lambda run, code, wall: code)
    plan = ld.prepare(dict(scenario='homotopy_global', out=str(tmp_path / 'out')))
    try:
        for i, label in enumerate(f'agent_{k}' for k in range(6)):
            plan.started(label, 4240 + i)
        note = 'parameter cruise_speed: out of range'
        (Path(plan.procs.env[EXIT_NOTES]) / '4242.txt').write_text(note)
        lines, stop = plan.exited('agent_2', 2)
        assert stop and lines == [f'swarm run: agent_2 refused its parameters: {note}; stopping the run']
        assert plan.code == 2 and plan.run.stopped == f'agent_2 refused its parameters: {note}'
        assert plan.exited('agent_3', 2) == ([], False)                    # said once
        assert plan.exited('world', 130) == ([], True) and plan.result == 2
    finally:
        plan.close()
