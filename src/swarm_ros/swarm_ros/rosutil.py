"""Small rclpy helpers shared by the swarm's nodes: parameter declaration with descriptions
and ranges, one-line rejection logs, the spin loop, message-info publisher ids."""
from __future__ import annotations

import cProfile
import gc
import math
import os
import signal
import sys
import threading
import time


class ParameterError(ValueError):
    """A bad start-up parameter; the message is one line naming it."""


def declare(node, name, default, description, lo=None, hi=None, choices=None, finite=True, read_only=False):
    """Declare a parameter with a description (and a range); return its validated value.
    ``read_only``: a value read once at the start, which ``ros2 param set`` may not change."""
    from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
    from rclpy.exceptions import ParameterException
    desc = ParameterDescriptor(description=description, read_only=read_only)
    if isinstance(default, bool):
        pass
    elif isinstance(default, int) and (lo is not None or hi is not None):
        desc.integer_range = [IntegerRange(from_value=int(-2**31 if lo is None else lo),
                                           to_value=int(2**31 - 1 if hi is None else hi), step=1)]
    elif isinstance(default, float) and (lo is not None or hi is not None):
        desc.floating_point_range = [FloatingPointRange(
            from_value=float(-1e300 if lo is None else lo), to_value=float(1e300 if hi is None else hi), step=0.0)]
    if choices:
        desc.additional_constraints = 'one of: ' + ', '.join(choices)
    try:
        value = node.declare_parameter(name, default, desc).value
    except ParameterException as err:
        raise ParameterError(f'parameter {name}: {str(err).splitlines()[0]}') from None
    except Exception as err:  # type mismatch and the like
        raise ParameterError(f'parameter {name}: {type(err).__name__}: {str(err).splitlines()[0]}') from None
    if isinstance(value, float):
        if finite and not math.isfinite(value):
            raise ParameterError(f'parameter {name}: must be finite, got {value!r}')
        if (lo is not None and value < lo) or (hi is not None and value > hi):
            raise ParameterError(f'parameter {name}: {value!r} outside [{lo}, {hi}]')
    if choices and value not in choices:
        raise ParameterError(f'parameter {name}: {value!r} is not one of {", ".join(choices)}')
    return value


def require_sim_clock(node, what):
    """A node whose program runs on the world's sim clock from 0 (a realtime commander, the
    realtime robots) refuses the system clock: ParameterError (one line) unless use_sim_time."""
    if not node.get_parameter('use_sim_time').value:
        now = node.get_clock().now().nanoseconds * 1e-9
        raise ParameterError(f'parameter use_sim_time: false, but {what} (the system clock reads {now:.0f} s): '
                             'set use_sim_time:=true')


def gid_key(gid) -> bytes:
    """Comparable bytes of a publisher gid (from message info or endpoint info)."""
    if isinstance(gid, dict):
        gid = gid.get('data', gid)
    return bytes(bytearray(gid))[:16]


def make_executor(context, events=None):
    """The EventsExecutor when available (fast), else the SingleThreadedExecutor.

    ``SWARM_EXECUTOR=single`` in the environment forces the SingleThreadedExecutor."""
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    if events is None:
        events = os.environ.get('SWARM_EXECUTOR', 'events') != 'single'
    try:
        if not events:
            raise ImportError
        return EventsExecutor(context=context)
    except Exception:  # pragma: no cover - older rclpy
        return SingleThreadedExecutor(context=context)


def spin_until(executor, context, done, timeout=0.1, wake=None):
    """Spin until done() (checked at least every ``timeout`` s), SIGINT or shutdown.

    Not ``EventsExecutor.spin()`` (it burns CPU while idle and ignores signals).  With the
    EventsExecutor, ``spin_until_future_complete`` on a future nobody completes, with a
    timeout, handles every event of that interval in C++ (one Python round trip per interval,
    not per message); other executors get a ``spin_once`` loop.  ``wake``: a Future that ends
    the current spin call when it completes (a signal handler completes it: a busy executor
    may not return at its timeout)."""
    from rclpy.executors import ExternalShutdownException
    from rclpy.task import Future
    events = type(executor).__name__ == 'EventsExecutor'
    never = Future() if wake is None else wake
    try:
        while context.ok() and not done():
            if events:
                executor.spin_until_future_complete(never, timeout_sec=timeout)
            else:
                executor.spin_once(timeout_sec=timeout)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass


def steady_clock():
    from rclpy.clock import Clock, ClockType
    return Clock(clock_type=ClockType.STEADY_TIME)


def when_matched(node, matched, then, limit, what):
    """Call ``then()`` once ``matched()`` holds (checked every 0.05 s on a steady-clock timer:
    sim time does not run yet), or after ``limit`` wall s with a warning that ``what`` did not
    happen.  For a node that must not start before a recorder reads its writers."""
    deadline = time.monotonic() + limit

    def check():
        ok = matched()
        if not ok and time.monotonic() < deadline:
            return
        if not ok:
            node.get_logger().warning(f'{what} after {limit:g} s; going on anyway')
        timer.cancel()
        then()
    timer = node.create_timer(0.05, check, clock=steady_clock())
    return timer


#: wall seconds a node's ROS teardown may take before the process exits without it
TEARDOWN_LIMIT = 10.0
#: after SIGINT / SIGTERM: wall seconds a running callback may take to return, and then the
#: teardown, before the process exits without them (`ExitWatch`): a node stops within a second
STOP_LIMIT = 0.5
STOPPED_TEARDOWN_LIMIT = 0.4


def _stderr_line(logger_name, text):
    """One log-like line straight to fd 2 (no logging lock: the main thread may hold it)."""
    os.write(2, f'[WARN] [{time.time():.9f}] [{logger_name}]: {text}\n'.encode(errors='replace'))


class ExitWatch:
    """The last resort of a node process after SIGINT / SIGTERM (`run_node`): a thread woken
    by the signal itself (`signal.set_wakeup_fd`: the C handler writes the signal number to a
    pipe, whatever the main thread is doing) gives the spin `STOP_LIMIT` s to return (a
    callback that runs on is not waited for) and ends the process with one line saying so
    (``os._exit(128 + signal)``).  ``returned()``: the spin has returned, the node stops
    normally (its teardown has its own limit).  Main thread only (else a no-op)."""

    def __init__(self, logger_name, limit=STOP_LIMIT):
        self.logger_name = logger_name
        self.limit = limit
        self.done = threading.Event()
        self.old_fd = None
        if threading.current_thread() is not threading.main_thread():
            return
        r, w = os.pipe()
        os.set_blocking(w, False)
        self.old_fd = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
        threading.Thread(target=self._watch, args=(r,), name='exit-watch', daemon=True).start()

    def _watch(self, r):
        stop = (signal.SIGINT, signal.SIGTERM)
        while True:
            got = [b for b in os.read(r, 64) if b in stop]
            if got:
                break
        if self.done.wait(self.limit):
            return
        _stderr_line(self.logger_name, f'{signal.Signals(got[0]).name}: a callback still runs {self.limit:g} s '
                     'later: exiting without it (no cleanup)')
        os._exit(128 + got[0])

    def returned(self):
        self.done.set()


def wants_help(argv) -> bool:
    """``-h`` / ``--help`` among a node executable's own arguments (not inside ``--ros-args``)."""
    from rclpy.utilities import remove_ros_args
    return any(a in ('-h', '--help') for a in remove_ros_args(list(argv))[1:])


def node_help(node_class, exe) -> str:
    """Usage of a node executable: what it is (its module's docstring, first paragraph) and
    its parameters with type, default and description, read from a node built with the
    defaults in a context of its own with DDS discovery off."""
    import rclpy
    from rclpy.context import Context

    doc = (sys.modules[node_class.__module__].__doc__ or '').strip().split('\n\n')[0]
    args = getattr(node_class, 'USAGE_ARGS', '')
    lines = [f'usage: {exe} [-h] {args + " " if args else ""}[--ros-args -p NAME:=VALUE ... | --params-file FILE]',
             '', doc, '',
             'Usually started by `swarm run` (which writes one parameter file for every node).', '']
    os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'OFF'     # this node is only looked at
    ctx = Context()
    rclpy.init(args=[exe], context=ctx)
    try:
        node = node_class(context=ctx)
    except ParameterError as err:
        rclpy.try_shutdown(context=ctx)
        return '\n'.join(lines + [f'(parameters not listed: {err})'])
    try:
        names = sorted(node._parameters)
        lines.append('parameters (name (type) = default: description):')
        for name, desc in zip(names, node.describe_parameters(names)):
            value = node.get_parameter(name).value
            text = ' '.join(desc.description.split()) or '(standard rclpy parameter)'
            lines.append(f'  {name} ({type(value).__name__}) = {value!r}: {text}')
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)
    return '\n'.join(lines)


def stop_on_signals():
    """SIGINT / SIGTERM set a flag instead of rclpy's handler (which shuts the context down
    under a running callback): returns (stop, wake, restore) — ``stop`` (a list) gets the
    signal number, ``wake`` (a Future, `spin_until`'s ``wake``) completes at once, ``restore()``
    puts the previous handlers back, unless a stop signal came: then later ones are still only
    noted, since the process is ending and a repeat must not raise KeyboardInterrupt while it
    writes its outputs (a parent-death signal comes once for each thread of a dying parent
    that exits: a launcher started by a script that is killed gets SIGINT two or three times).
    Installed only in the main thread (signals go there)."""
    from rclpy.task import Future

    stop, wake = [], Future()

    def on_signal(signum, _frame):
        stop.append(signum)
        if not wake.done():
            wake.set_result(signum)
    old = {}
    if threading.current_thread() is threading.main_thread():
        old = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}

    def restore():
        if stop:
            return
        for sig, handler in old.items():
            signal.signal(sig, handler)
    return stop, wake, restore


def profiler():
    """``SWARM_PROFILE=DIR`` in the environment: profile this node process's spin (cProfile);
    returns a function that writes ``DIR/<name>-<pid>.prof`` (None without the variable).
    Wall time by default; ``SWARM_PROFILE_TIMER=cpu``: the spinning thread's CPU time (what a
    loaded machine does not inflate; the time waiting for work and DDS's own threads left out)."""
    where = os.environ.get('SWARM_PROFILE')
    if not where:
        return None
    cpu = os.environ.get('SWARM_PROFILE_TIMER', 'wall') == 'cpu'
    prof = cProfile.Profile(time.thread_time) if cpu else cProfile.Profile()
    prof.enable()

    def dump(name):
        prof.disable()
        os.makedirs(where, exist_ok=True)
        prof.dump_stats(os.path.join(where, f'{name}-{os.getpid()}.prof'))
    return dump


def step_time(nodes, s):
    """Lockstep without /clock (the agents, the commander): the nodes' sim time is that of step
    message ``s`` (a decoded /lockstep/step)."""
    from rclpy.time import Time
    now = Time(nanoseconds=int(round(s.t * 1e9)))
    for nd in nodes:
        nd.get_clock().set_ros_time_override(now)


def settle_garbage():
    """Once the nodes are built: move every object alive now out of the garbage collector's
    reach (`gc.freeze`).  The nodes' objects live as long as the process; without this the
    collector walks all of them again and again while each step's short-lived objects come and
    go (measured: a container of 100 agents spent a third of its step time in the collector)."""
    gc.collect()
    gc.freeze()


#: exit code of a node process stopped by an error of the run itself (`run_node` ``fatal``: a law
#: that failed); its one line goes to the file `EXIT_NOTES` names, where a launcher reads it
FATAL_EXIT = 3
#: environment variable: a directory for the line of a node that stops with `FATAL_EXIT` (the
#: launcher says it once for all its agents); unset: the node logs it
EXIT_NOTES = 'SWARM_EXIT_NOTES'


#: the error that stops this process (`fail`), at most one
_FAILED = []


def fail(err) -> None:
    """Stop this node process on ``err``, an error of the run itself (a law that failed), from
    a callback: `run_node`'s spin ends, the one line is said (`fatal_note`) and the process
    exits with `FATAL_EXIT`.  (Raised on, it would reach the executor, which logs a traceback.)"""
    if not _FAILED:
        _FAILED.append(err)


def failure():
    """The error `fail` was given in this process, or None."""
    return _FAILED[0] if _FAILED else None


def fatal_note(logger, err) -> None:
    """The one line of a node that stops on ``err`` (`run_node` ``fatal``): into a file of the
    directory `EXIT_NOTES` names, else (or if that fails) logged as an error."""
    where = os.environ.get(EXIT_NOTES)
    if where:
        try:
            tmp = os.path.join(where, f'.{os.getpid()}.tmp')
            with open(tmp, 'w') as fh:
                fh.write(str(err))
            os.replace(tmp, os.path.join(where, f'{os.getpid()}.txt'))
            return
        except OSError:
            pass
    logger.error(str(err))


#: the suffix of the note a node stopped by a signal leaves in `EXIT_NOTES` (`stopped_note`):
#: its exit is no news to a launcher; a node that exits without any note vanished
STOPPED_SUFFIX = '.stopped'


def stopped_note(signum) -> None:
    """A node stopped by signal ``signum`` says so in `EXIT_NOTES` (if set): a launcher then
    knows its process did not vanish (a law that called ``os._exit``, which nothing can catch)."""
    where = os.environ.get(EXIT_NOTES)
    if where:
        try:
            with open(os.path.join(where, f'{os.getpid()}{STOPPED_SUFFIX}'), 'w') as fh:
                fh.write(signal.Signals(signum).name)
        except (OSError, ValueError):
            pass


def read_fatal_note(where) -> str | None:
    """The first line a node left in ``where`` (`fatal_note`), or None."""
    try:
        names = sorted(n for n in os.listdir(where) if n.endswith('.txt'))
        for name in names:
            with open(os.path.join(where, name)) as fh:
                return fh.read().strip()
    except OSError:
        return None
    return None


def run_node(node_class, logger_name, argv=None, *, done=None, exit_code=None, on_stop=None,
             more_nodes=None, fatal=()) -> int:
    """The ``main()`` of a node executable: init rclpy from ``argv``, build ``node_class()``
    (a bad parameter -> one error line, exit 2), spin until ``done(node)`` or SIGINT / SIGTERM,
    clean up; returns ``exit_code(node)`` (default 0).  ``-h`` / ``--help``: the usage and the
    node's parameters, exit 0 (no node is started).

    SIGINT / SIGTERM only set a flag that the spin loop checks (at least every 0.1 s): a
    callback that is running finishes (rclpy's own handler shut the context down under it, and
    every node logged a traceback on Ctrl-C), then ``on_stop(node)`` runs (e.g. the world
    saves the steps done so far) and the node is cleaned up (in `STOPPED_TEARDOWN_LIMIT` s); a
    callback still running `STOP_LIMIT` s after the signal is not waited for (`ExitWatch`), so a
    node stops within a second whatever its callbacks do.  ``more_nodes(node)``: further
    nodes the node holds (an agent container's agents), spun by the same executor.
    ``fatal``: exception classes that end the node with one line and `FATAL_EXIT`, not a
    traceback (an agent's law that failed: the launcher stops the run, `fatal_note`), as
    `fail` called in a callback does."""
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    args = sys.argv if argv is None else argv
    if wants_help(args):
        print(node_help(node_class, logger_name))
        return 0
    stop, wake, _ = stop_on_signals()
    watch = ExitWatch(logger_name)
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    ctx = rclpy.get_default_context()
    try:
        node = node_class()
    except ParameterError as err:
        rclpy.logging.get_logger(logger_name).error(str(err))
        if os.environ.get(EXIT_NOTES):      # and for the launcher, which stops the run with it
            fatal_note(rclpy.logging.get_logger(logger_name), err)
        rclpy.try_shutdown()
        return 2
    ex = make_executor(ctx)
    ex.add_node(node)
    for other in (more_nodes(node) if more_nodes is not None else ()):
        ex.add_node(other)
    settle_garbage()
    profile = profiler()
    failed = None
    try:
        spin_until(ex, ctx, lambda: bool(stop) or bool(_FAILED) or (done is not None and done(node)), wake=wake)
    except fatal as err:
        failed = err
    failed = failed or failure()
    if failed is not None:
        fatal_note(node.get_logger(), failed)
    watch.returned()
    if stop:
        stopped_note(stop[0])
    if profile is not None:
        profile(f'{logger_name}-{node.get_name()}')
    if stop and on_stop is not None:
        on_stop(node)
    reject = getattr(node, 'reject', None)
    if reject is not None and reject.summary():
        node.get_logger().info(reject.summary())
    code = FATAL_EXIT if failed is not None else exit_code(node) if exit_code is not None else 0
    # a DDS teardown that never returns (seen with Fast DDS after a peer process was SIGKILLed)
    # must not keep a finished node alive: its work is done and saved, so exit anyway
    limit = STOPPED_TEARDOWN_LIMIT if stop else TEARDOWN_LIMIT   # after a signal: stop within a second

    def give_up():
        _stderr_line(logger_name, f'shutdown took more than {limit:g} s: exiting without it')
        sys.stdout.flush()
        os._exit(code)
    watchdog = threading.Timer(limit, give_up)
    watchdog.daemon = True
    watchdog.start()
    node.destroy_node()
    rclpy.try_shutdown()
    watchdog.cancel()
    guards = sys.modules.get('swarm_core.laws.guards')     # an agent's law that left a thread running
    return code if guards is None else guards.exit_now_if_threads_left(code, logger_name)
