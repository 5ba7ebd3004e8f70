"""Option helpers shared by the live-control commands (`swarm lambda/steer`, `swarm kill/pause`,
`swarm drop/partition`); no rclpy import, so ``--help`` stays fast (their node is
`swarm_tools.live.client.Client`)."""
from __future__ import annotations

import argparse
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
