"""Helpers shared by the live-control commands (`swarm lambda/steer`, `swarm kill/pause`,
`swarm drop/partition`); rclpy is imported only inside `cli_node`, so ``--help`` stays fast."""
from __future__ import annotations

import argparse
import contextlib
import math


def seconds(text: str) -> float:
    """argparse type: a finite, non-negative number of seconds."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
    if not (math.isfinite(value) and value >= 0.0):
        raise argparse.ArgumentTypeError(f'must be a finite number ≥ 0, got {text}')
    return value


def add_wait(parser: argparse.ArgumentParser, what: str, default: float = 10.0):
    """``--wait S``: wall seconds to wait for ``what`` to be found on the ROS graph."""
    parser.add_argument('--wait', type=seconds, default=default, metavar='S',
                        help=f'wall seconds to wait for {what} to be found (default {default:g})')


@contextlib.contextmanager
def cli_node(name: str):
    """(node, executor) of a short-lived command-line node in a context of its own; everything
    is shut down on every path (an early return once left the executor to a GC after
    shutdown: "Exception ignored in Executor.__del__ ... InvalidHandle")."""
    import rclpy
    from rclpy.context import Context
    from rclpy.executors import SingleThreadedExecutor

    ctx = Context()
    rclpy.init(context=ctx)
    node = ex = None
    try:
        node = rclpy.create_node(name, context=ctx, start_parameter_services=False)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        yield node, ex
    finally:
        if ex is not None:
            ex.shutdown()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)
