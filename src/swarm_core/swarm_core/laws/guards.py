"""What a law may not do to the process that runs it (no ROS), and the engines' defences.

A law's `control` runs inside every engine's process: the batch engine, a sweep's workers, an
agent node.  `Law.evaluate` turns whatever it raises, any `BaseException` (``sys.exit``, a
``KeyboardInterrupt`` of its own, ``GeneratorExit``), into a `LawError` naming the law, so the
run stops with one line and keeps the steps done.  Two things are told apart here:

- **the user's Ctrl-C** from a law's own ``KeyboardInterrupt``: `watch_interrupts` counts the
  SIGINTs Python's default handler turns into ``KeyboardInterrupt``; one raised during a call
  with no SIGINT counted is the law's (`user_interrupted`);
- **a thread a law leaves running**: a non-daemon thread that outlives the call would hold the
  process at its exit for ever (Python joins them).  `Law.evaluate` refuses it (`left_threads`)
  and keeps it in a list; `exit_now_if_threads_left` ends a finished process at once (with a
  line) while any of them still runs, and `exit_workers_leaving_no_thread` does it for a pool's
  worker processes.

A law that calls ``os._exit`` ends its process with no word: nothing in Python can catch it
(docs/laws.md).  `swarm run` then reports that process as vanished.
"""
from __future__ import annotations

import os
import signal
import sys
import threading
import weakref
from multiprocessing import util

_sigints = 0
#: threads a law left running (`left_threads`), while they live
_left = weakref.WeakSet()


def _count_sigint(signum, frame):
    """Python's default SIGINT handler, counted."""
    global _sigints
    _sigints += 1
    raise KeyboardInterrupt


def watch_interrupts() -> int:
    """Count the user's Ctrl-C from now on where it raises ``KeyboardInterrupt`` (the default
    SIGINT handler of the main thread; a node's own handler, which raises nothing, stays);
    returns the count so far."""
    if (signal.getsignal(signal.SIGINT) is signal.default_int_handler
            and threading.current_thread() is threading.main_thread()):
        signal.signal(signal.SIGINT, _count_sigint)
    return _sigints


def user_interrupted(before: int) -> bool:
    """Was a ``KeyboardInterrupt`` raised since `watch_interrupts` returned ``before`` the
    user's Ctrl-C?  Counted: if a SIGINT came.  Not counted (another handler, another thread):
    only if the handler in force is Python's default one, which a Ctrl-C reaches."""
    handler = signal.getsignal(signal.SIGINT)
    if handler is _count_sigint:
        return _sigints != before
    return handler is signal.default_int_handler


def left_threads(before: set) -> list[threading.Thread]:
    """The non-daemon threads running now that were not in ``before`` (thread idents): those a
    call left behind; they are kept for `exit_now_if_threads_left`."""
    out = [t for t in threading.enumerate() if t.ident not in before and not t.daemon and t.is_alive()]
    _left.update(out)
    return out


def exit_now_if_threads_left(code: int, who: str = 'swarm') -> int:
    """``code``, or, while a thread a law left (`left_threads`) still runs, end the process at
    once with ``code`` after one line: Python would wait for that thread at its exit for ever."""
    alive = [t for t in list(_left) if t.is_alive()]
    if not alive:
        return code
    print(f'{who}: a law left {len(alive)} thread(s) running ({", ".join(t.name for t in alive[:3])}): '
          'exiting without waiting for them', file=sys.stderr, flush=True)
    sys.stdout.flush()
    os._exit(code)


def exit_workers_leaving_no_thread() -> None:
    """In a pool's worker process (its initializer): at its exit, before Python joins its
    threads, end it at once if a law left one running (`exit_now_if_threads_left`)."""
    util.Finalize(None, exit_now_if_threads_left, args=(0, 'swarm worker'), exitpriority=100)
