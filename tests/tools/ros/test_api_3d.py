"""The Python API reads a 3D run's states: `Swarm.states` gives `States3D` (positions (N, 3),
the frames x, y, z, and u, v), equal to the run's own record, and no state is rejected;
`Swarm.steer` takes (s_u, s_v) in a 3D run and refuses one number."""
import numpy as np
import pytest

from tests.agent.test_natural_core import short_3d


def test_states_of_a_3d_run_are_the_runs(swarm, tmp_path):
    from swarm_tools.api import States3D
    path = short_3d(tmp_path / 'h3.yaml', duration=200.0)     # lockstep: long enough to be heard running
    run = swarm(path, rtf=4, agents_per_process=3, no_figure=True)
    assert run.run['dim'] == 3
    st = run.wait_until(lambda s: s is not None and s.names == run.agents and s.t.min() >= 6.0, timeout=200,
                        on='states')
    assert isinstance(st, States3D) and st.r.shape == st.x.shape == st.y.shape == st.z.shape == (6, 3)
    run.steer('agent_1', (0.0, 0.02))           # (s_u, s_v): returns once the commander took it
    with pytest.raises(ValueError, match='is 3D: give two numbers, s_u s_v'):
        run.steer('agent_1', 0.02)
    assert run.wait(timeout=300) == 0           # to its end: the record has every step heard
    assert run.client.reject.count == 0, run.client.reject.lines
    traj = run.trajectory()
    assert traj.dim == 3
    for i, name in enumerate(st.names):
        j, k = traj.names.index(name), int(round(st.t[i] / 0.1))
        np.testing.assert_array_equal(st.r[i], traj.r[k, j])                       # float64 on the wire
        for got, want in ((st.x, traj.x), (st.y, traj.y), (st.z, traj.z)):        # from the quaternion
            np.testing.assert_allclose(got[i], want[k, j], rtol=0, atol=1e-12)
        assert (st.u[i], st.v[i]) == (traj.u[k - 1, j], traj.v[k - 1, j])       # held over the step that ended
    assert np.abs(st.v).max() > 0 and np.ptp(st.r[:, 2]) > 0
