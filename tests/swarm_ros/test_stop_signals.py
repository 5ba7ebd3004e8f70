"""Stop signals of a launcher or node process (`swarm_ros.rosutil.stop_on_signals`): noted, not
raised; the old handlers come back only if none came.  A launcher started by a script that is
killed gets its parent-death SIGINT once for each thread of the script that exits, so the
repeats must not raise KeyboardInterrupt while the run's outputs are written."""
import os
import signal

import pytest

from swarm_ros.rosutil import stop_on_signals


@pytest.fixture
def handlers():
    """Whatever the test does to SIGINT / SIGTERM, pytest's own handlers are back after it."""
    old = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    yield
    for s, h in old.items():
        signal.signal(s, h)


def test_without_a_signal_the_old_handlers_come_back(handlers):
    before = signal.getsignal(signal.SIGINT)
    stop, wake, restore = stop_on_signals()
    assert signal.getsignal(signal.SIGINT) is not before
    restore()
    assert signal.getsignal(signal.SIGINT) is before and stop == [] and not wake.done()


def test_after_a_stop_signal_repeats_are_only_noted(handlers):
    signal.signal(signal.SIGINT, signal.default_int_handler)          # what a plain script has
    stop, wake, restore = stop_on_signals()
    os.kill(os.getpid(), signal.SIGINT)
    assert stop == [signal.SIGINT] and wake.done()
    restore()
    os.kill(os.getpid(), signal.SIGINT)                                # no KeyboardInterrupt
    os.kill(os.getpid(), signal.SIGTERM)
    assert stop == [signal.SIGINT, signal.SIGINT, signal.SIGTERM]
