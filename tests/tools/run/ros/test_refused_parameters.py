"""A run whose agents refuse their parameters stops at once with an agent's line, not after the
world's start timeout, and leaves no process behind.  The refusal is forced through the run's
parameters (an absurd cruise speed the agent nodes refuse), so the test does not depend on the
scenario check, which refuses that speed before anything starts."""
import os
import time

import yaml

from swarm_tools.run import launch


def test_agents_that_refuse_their_parameters_stop_the_run_at_once(tmp_path, ros_domain, capfd):
    path = tmp_path / 'three.yaml'
    path.write_text(yaml.safe_dump({'name': 'three', 'dt': 0.1, 'duration': 5.0, 'agents': {'count': 3},
                                    'robots': {'length_scale': 0.3, 'cruise_speed': 0.15}}))
    out = tmp_path / 'out'
    run = launch.validate(launch._parser().parse_args(
        [str(path), '--out', str(out), '--no-figure', '--robots', 'external', '--start-timeout', '60']))
    for fqn, p in run.params.items():
        if fqn.endswith('/agent'):
            p['cruise_speed'] = 1e9             # what every agent node refuses
    t0 = time.monotonic()
    code, wall = launch.execute(run)
    code = launch.finish(run, code, wall)
    took = time.monotonic() - t0
    err = capfd.readouterr().err
    assert code == 2, err[-3000:]
    assert took < 40, f'{took:.1f} s: the launcher waited for the start timeout\n{err[-3000:]}'
    said = [ln for ln in err.splitlines() if ln.startswith('swarm run: agent_') and 'refused its parameters' in ln]
    assert len(said) == 1 and 'cruise_speed' in said[0], err[-3000:]
    assert 'trajectory is lost' not in err                      # nothing ran: nothing to rebuild
    pids = yaml.safe_load((out / 'pids.json').read_text())
    for pid in set(pids.values()):                              # no agent process left behind
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            continue
        assert open(f'/proc/{pid}/stat').read().split()[2] == 'Z', f'agent process {pid} still runs'
