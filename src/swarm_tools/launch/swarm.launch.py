"""``ros2 launch swarm_tools swarm.launch.py scenario:=homotopy_global [duration:=60 mode:=realtime ...]``

The run ``swarm run SCENARIO ...`` starts, from the same plan: the world, the commander and the
agent processes as ``launch_ros`` nodes with the same executables, parameters file, names and
DDS environment; at the end the same outputs in ``out`` (trajectory.npz, metrics.json, the
figure, run.json).  The launch arguments are `swarm run`'s options (``no_figure:=true`` for
``--no-figure``; ``ros2 launch swarm_tools swarm.launch.py -s`` lists them).  All the logic is in
`swarm_tools.run.launch_description`; this file only turns its specs into launch actions.
"""
import atexit

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, ExecuteProcess, OpaqueFunction, RegisterEventHandler, Shutdown
from launch.event_handlers import OnProcessExit, OnProcessStart, OnShutdown
from launch_ros.actions import Node

from swarm_tools.run import launch_description as spec


def generate_launch_description():
    return LaunchDescription([DeclareLaunchArgument(a.name, **a.declare_kwargs()) for a in spec.launch_arguments()]
                             + [OpaqueFunction(function=_start)])


def _start(context):
    try:
        run = spec.prepare(context.launch_configurations)
    except spec.NotStarted as err:
        raise RuntimeError(f'{spec.PROG}: {err}') from None
    atexit.register(run.close)
    for line in run.start_lines():
        print(line, flush=True)
    actions = []
    for a in run.actions:
        proc = Node(**a.kwargs) if a.kind == 'node' else ExecuteProcess(**a.kwargs)
        actions += [
            RegisterEventHandler(OnProcessStart(
                target_action=proc, on_start=lambda event, _ctx, label=a.label: run.started(label, event.pid))),
            RegisterEventHandler(OnProcessExit(
                target_action=proc, on_exit=lambda event, _ctx, label=a.label: _exited(run, label, event.returncode))),
            proc]
    actions.append(RegisterEventHandler(OnShutdown(on_shutdown=lambda _event, _ctx: run.shutting_down())))
    return actions


def _exited(run, label, returncode):
    lines, stop = run.exited(label, returncode)
    for line in lines:
        print(line, flush=True)
    if label == 'world':
        run.close()
        if run.failed:      # ros2 launch exits 1
            raise RuntimeError(f'swarm run: the run failed (exit code {run.result}); outputs in {run.run.out}')
    return [Shutdown(reason=f'{label} exited with code {returncode}')] if stop else None
