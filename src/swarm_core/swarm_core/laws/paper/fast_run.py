"""The paper's laws' compiled whole run: a whole run of a small swarm as one compiled loop
(numba), no ROS; the fast engine (`engine.fast`) takes it from the law (`PaperLaw.compiled_run`).

`run` runs what the kernels (`fast_run_kernels`) cover; `fallback_reason` says why a run is
not covered, and the fast engine then hands it to the reference engine (today's numpy engine,
which the ROS nodes are checked against bit for bit).  Covered: the
zoh integrator; the laws global, local, leader_following, homotopy and target (eq. 4, 9,
10-15) with the target and barrier terms (eq. 15, 16) over all pairs of at most
`pair_sums.DENSE_LIMIT` agents; fixed leaders or the lateral_extremes rule; constant and
sinusoid steering programs; any λ schedule (evaluated ahead by the schedule itself, as the
commander does); per-agent noise (the same streams, drawn ahead); the radio model
(`comms`): loss, latency, jitter, radio range, partitions, per-link values, timeout and dead
reckoning, with the same fates (`comms.link_uniforms`) and beliefs.  Not covered (the
reference runs): faults, failover, reunion, scheduled radio events (``comms.events``),
waypoint steering, rk4, live commands, more than DENSE_LIMIT agents.

The kernels form each receiver's pair sums as the reference does (`pair_sums._pair_sums_dense`
and `_combine`: the same moments, products and numpy's pairwise summation order; with a radio
`_pair_sums_sparse`: the believed senders one after the other), so they agree with the
reference to rounding (tests/core/engine/test_compiled_engine.py, test_compiled_radio.py: 1e-9
to t = 50).
Compiled once per machine (``cache=True`` keeps the machine code in __pycache__); no ROS
process imports this module.
"""
from __future__ import annotations

import math
import time

import numpy as np

from swarm_core.command.plan import CHOOSE_RISE
from swarm_core.command.schedules import ConstantLambda, ConstantSteering, SinusoidSteering, TanhWindow
from swarm_core.engine.trajectory import Trajectory
from swarm_core.faults.agents import event_names
from swarm_core.laws.paper.fast_run_kernels import _run, _tanh_window
from swarm_core.laws.paper.pair_sums import DENSE_LIMIT
from swarm_core.radio import delay_stats


def fallback_reason(scn, integrator=None, commands=None) -> str | None:
    """None if the fast kernel covers this run, else why the reference engine runs it."""
    spec = scn.spec
    checks = (
        ((integrator or spec.integrator) != 'zoh', 'integrator rk4'),
        (bool(commands), 'live commands'),
        (scn.law.kernel_code < 0, f'law {scn.law.kind}'),
        (len(scn.names) > DENSE_LIMIT, f'more than {DENSE_LIMIT} agents'),
        (bool(spec.faults) or spec.failover is not None, 'faults or failover'),
        (bool(spec.reunion), 'reunion'),
        (spec.comms is not None and _has_radio_events(scn), 'radio events'),
    )
    for bad, why in checks:
        if bad:
            return why
    plan = scn.command_plan()
    progs = list(plan.fixed_leaders.values()) + list(plan.rule_programs)
    if any(not isinstance(p, (ConstantSteering, SinusoidSteering)) for p in progs):
        return 'steering program other than constant or sinusoid'
    return None


def _has_radio_events(scn) -> bool:
    """Whether the scenario's radio changes in time (scheduled ``comms.events``: not covered)."""
    model = scn.comm_model()
    return model is not None and bool(model.events)


# ------------------------------------------------------------------ the run

def _lambdas(schedule, steps, dt):
    """λ(t_i) of every step i, as the commander evaluates it (t_i = i·dt)."""
    t = np.arange(steps + 1) * dt
    if isinstance(schedule, TanhWindow):
        s = schedule
        return _tanh_window(t, s.rise_at, s.fall_at, s.tau, s.low, s.high)
    if isinstance(schedule, ConstantLambda):
        return np.full(steps + 1, float(schedule.value(0.0)))
    return np.array([float(schedule.value(i * dt)) for i in range(steps + 1)])


def _program_rows(progs):
    """(P, 5) rows (kind, a, b, c, d) of steering programs (see `_steering`)."""
    rows = np.zeros((max(1, len(progs)), 5))
    for i, p in enumerate(progs):
        if isinstance(p, ConstantSteering):
            rows[i, :2] = (0.0, p.curvature)
        else:
            rows[i] = (1.0, p.amplitude, p.period, p.phase, p.offset)
    return rows


def _world(scn):
    """(world, barrier points) of `_world_terms`: the target and barrier terms where the
    scenario has them and their gains are not 0 (as `paper.terms.add_world_terms`)."""
    law = scn.law
    world, barrier = np.zeros(8), np.zeros((0, 2))
    if scn.target is not None and law.target_gain != 0.0:
        world[:5] = (1.0, *scn.target, law.target_gain, float(law.target_normalised))
    if scn.barrier is not None and law.barrier_gain != 0.0 and len(scn.barrier):
        world[5:] = (1.0, law.barrier_gain, float(law.barrier_mode == 'literal'))
        barrier = scn.barrier
    return world, barrier


#: rf (the kernel's radio numbers): on, has range, R², dt, max age (steps), dead reckoning
RF_FIELDS = 6


def radio_arguments(model, n: int):
    """The radio arguments of `fast_run_kernels._run` for a `comms.CommModel` (None: the perfect radio):
    (rf, seed (1,) uint64, link (4, n, n): loss, latency, jitter and the delay in steps
    without jitter, partition labels (n,), stats (2 + ring,) int64 filled by the kernel:
    sent, delivered, the histogram of delays)."""
    if model is None:
        return (np.zeros(RF_FIELDS), np.zeros(1, np.uint64), np.zeros((4, 0, 0)),
                np.zeros(0, np.int64), np.zeros(2, np.int64))
    rows = np.arange(n)
    link = np.stack([np.broadcast_to(np.asarray(model._param(key, rows, rows), float), (n, n))
                     for key in ('loss', 'latency', 'jitter', 'latency')])
    link[3] = np.maximum(np.ceil(link[1] / model.dt - 1e-9), 0.0)          # as `CommModel.decide`
    # U₁ < 1, so no delay exceeds ceil((L + J)/dt − 1e-9) steps: a ring of that many + 1 sends
    ring = int(max(0.0, math.ceil(float(((link[1] + link[2]) / model.dt - 1e-9).max())))) + 1
    r = model.radio_range
    rf = np.array([1.0, float(r is not None), 0.0 if r is None else r * r, model.dt,
                   float(model.max_age_steps()), float(model.dead_reckoning)])
    return (rf, np.array([model.seed], np.uint64), link, model.labels.astype(np.int64),
            np.zeros(2 + ring, np.int64))


def radio_stats(stats, dt: float) -> dict:
    """``meta['comms']`` of a run (as `engine.SwarmStepper.comms_stats`)."""
    sent, got = int(stats[0]), int(stats[1])
    return dict(sent=sent, delivered=got, delivered_fraction=got / sent if sent else None,
                **delay_stats(stats[2:], dt))


def _noise(scn, steps):
    """(steps, n, 3) noise of every step, from each agent's own stream (as the reference draws
    it, three numbers per step), or an empty array without noise."""
    noise = scn.spec.noise
    scale = np.array([noise.position, noise.position, noise.heading])
    n = len(scn.names)
    if not np.any(scale > 0):
        return np.zeros((0, n, 3))
    draws = np.stack([scn.noise_rng(i).uniform(-1.0, 1.0, size=(steps, 3)) for i in range(n)], axis=1)
    return draws * scale


def run(scn, *, record_every: int = 1, neighbour_search: str = 'auto', progress=None) -> Trajectory:
    """A run the kernels cover (`fallback_reason` None) as one compiled loop, recorded every
    ``record_every`` steps; ``meta['engine']`` is 'fast'."""
    wall = time.perf_counter()
    law, plan, steps, n = scn.law, scn.command_plan(), scn.steps, len(scn.names)
    gains = np.array([law.alpha, law.eta, law.mu, law.r0, law.cutoff_radius, law.leader_gain])
    rule = plan.rule is not None
    leader_prog = np.full(n, -1, dtype=np.int64)
    if rule:
        progs = list(plan.rule_programs)
    else:
        progs = list(plan.fixed_leaders.values())
        leader_prog[list(plan.fixed_leaders)] = np.arange(len(progs))
    rows = steps // record_every + 1
    r, th, u = np.empty((rows, n, 2)), np.empty((rows, n)), np.empty((rows, n))
    lead = np.empty((rows, n), dtype=bool)
    lams = _lambdas(plan.schedule, steps, scn.dt)
    model = scn.comm_model()
    radio = radio_arguments(model, n)
    chosen = _run(scn.pos0[:, 0].copy(), scn.pos0[:, 1].copy(), scn.theta0.astype(float),
                  float(scn.dt), lams, law.kernel_code, float(law.q0), gains, leader_prog,
                  _program_rows(progs), rule, float(plan.choose_at), CHOOSE_RISE, *_world(scn), _noise(scn, steps),
                  radio, int(record_every), r, th, u, lead)
    events = []
    if chosen >= 0:
        slots = [int(k) for k in sorted(np.flatnonzero(leader_prog >= 0), key=lambda k: leader_prog[k])]
        events.append(event_names(dict(t=chosen * scn.dt, kind='leaders_chosen',
                                       leaders=sorted(slots), slots=slots), scn.names))
    if progress is not None:
        progress(steps, steps)
    every = slice(None, None, record_every)
    meta = dict(scenario=scn.name, seed=scn.seed, dt=scn.dt, duration=scn.duration,
                integrator='zoh', steps=steps, record_every=record_every,
                wall_seconds=time.perf_counter() - wall, neighbour_search=neighbour_search,
                interrupted=False, events=events, engine='fast')
    if model is not None:
        meta['comms'] = radio_stats(radio[4], scn.dt)
    return Trajectory(scn.names, (np.arange(steps + 1) * scn.dt)[every], r, th, u, lams[every], lead, meta)


def warm_up() -> float:
    """Compile the kernels (or load them from numba's cache) on a two-agent, two-step run;
    returns the seconds it took.  A study calls it once before forking its workers."""
    t0 = time.perf_counter()
    n, steps = 2, 2
    r, th, u = np.empty((steps + 1, n, 2)), np.empty((steps + 1, n)), np.empty((steps + 1, n))
    _run(np.array([0.0, 1.0]), np.zeros(n), np.zeros(n), 0.1, _tanh_window(np.arange(steps + 1) * 0.1,
         400.0, 600.0, 30.0, 0.0, 1.0), 3, 1.0, np.array([0.02, 0.02, 0.02, 1.5, 4.0, 30.0]),
         np.full(n, -1, dtype=np.int64), _program_rows([ConstantSteering(0.01)]), True, 0.0, CHOOSE_RISE,
         np.zeros(8), np.zeros((0, 2)), np.zeros((0, n, 3)), radio_arguments(None, n), 1, r, th, u,
         np.empty((steps + 1, n), dtype=bool))
    return time.perf_counter() - t0
