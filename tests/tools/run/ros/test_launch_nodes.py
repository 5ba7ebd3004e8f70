"""The launcher's nodes in one process (`swarm_tools.run.launch.run_in_process`) equal
`swarm simulate`, and the parameter files it writes (`swarm_tools.run.params`) keep strings
that look like numbers strings; each test on its own ROS_DOMAIN_ID."""

import numpy as np
import rclpy

from swarm_core.engine.reference import simulate
from swarm_core.engine.trajectory import Trajectory
from swarm_core.scenario.loader import load
from swarm_tools.run.launch import run_in_process
from swarm_tools.run.params import node_parameters
from tests.helpers import short_homotopy


def short_scenario(tmp_path, seed=0, duration=40.0, rise=10.0, fall=30.0, tau=3.0, at=5.0):
    """homotopy_global's law and agents with the λ window and leader choice brought forward."""
    lam = f'{{kind: tanh_window, rise_at: {rise}, fall_at: {fall}, tau: {tau}}}'
    return str(short_homotopy(tmp_path / 'homotopy_short.yaml', seed=seed, duration=duration, lam=lam, at=at))


def test_lockstep_in_process_equals_simulate(tmp_path, ros_domain):
    """World, commander and six agents in ONE executor equal `swarm simulate` (positions and u exactly) over a
    run with the leader choice and a full λ window (800 steps)."""
    path = short_scenario(tmp_path)
    scn = load(path)
    out = tmp_path / 'run'
    params = node_parameters(scn, path, 'lockstep', output_dir=str(out))
    assert run_in_process(params, domain_id=ros_domain) == 0
    got = Trajectory.load(out / 'trajectory.npz')
    ref = simulate(scn)
    assert ref.leader.any() and ref.lam.max() > 0.99
    np.testing.assert_array_equal(got.r, ref.r)                # exact: the same law, the same order
    np.testing.assert_array_equal(got.u, ref.u)
    assert np.abs(got.theta - ref.theta).max() <= 1e-9         # θ comes back through the quaternion
    assert np.array_equal(got.lam, ref.lam) and np.array_equal(got.leader, ref.leader)


def test_string_parameters_that_look_like_numbers_stay_strings(tmp_path, rclpy_context):
    """A run id such as ``7710e017`` written by `write_params_file` reaches the node as a string
    (ROS's parameter-file parser reads it as a double unless it is quoted)."""
    from swarm_tools.run.params import write_params_file
    path = write_params_file({'/probe_node': {'run_id': '7710e017', 'other': '1e5', 'n': 3}}, tmp_path / 'p.yaml')
    node = rclpy.create_node('probe_node', context=rclpy_context,
                             cli_args=['--ros-args', '--params-file', str(path)])
    try:
        assert node.declare_parameter('run_id', '').value == '7710e017'
        assert node.declare_parameter('other', '').value == '1e5'
        assert node.declare_parameter('n', 0).value == 3
    finally:
        node.destroy_node()
