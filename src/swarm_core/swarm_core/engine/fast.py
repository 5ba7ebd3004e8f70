"""The fast engine (no ROS): a whole run as one compiled loop, where the run's law has one
(`Law.compiled_run`: the paper's laws', `laws.paper.fast_run`) and that loop covers the run,
else the reference engine.  ``meta['engine']`` says which ran, ``meta['fallback']`` why not
the fast one.  numba is imported with a law's compiled run only: no ROS process loads it."""
from __future__ import annotations

from swarm_core.engine import reference
from swarm_core.engine.trajectory import Trajectory
from swarm_core.laws.registry import BUILT_IN, law_class


def fallback_reason(scn, integrator=None, commands=None) -> str | None:
    """None if the law's compiled run covers this run, else why the reference engine runs it."""
    if scn.dim == 3:
        return 'a 3D scenario'
    compiled = scn.law.compiled_run()
    if compiled is None:
        return f'law {scn.law.kind}'
    return compiled.fallback_reason(scn, integrator, commands)


def simulate(scn, *, integrator=None, record_every: int = 1, neighbour_search: str = 'auto',
             progress=None, commands=None, compiled: str = 'auto') -> Trajectory:
    """`engine.simulate` on the law's compiled run where it covers the run (`fallback_reason`),
    else on the reference engine (with the run's ``compiled`` pair sums, `reference.run_search`)."""
    reason = fallback_reason(scn, integrator, commands)
    if reason is not None:
        traj = reference.simulate(scn, integrator=integrator, record_every=record_every,
                                  neighbour_search=neighbour_search, progress=progress, commands=commands,
                                  compiled=compiled)
        traj.meta.update(engine='reference', fallback=reason)
        return traj
    return scn.law.compiled_run().run(scn, record_every=record_every, neighbour_search=neighbour_search,
                                      progress=progress)


def warm_up() -> float:
    """Compile the built-in laws' compiled runs (or load them from numba's cache); returns the
    seconds it took.  A study calls it once before forking its workers."""
    runs = {id(m): m for m in (law_class(kind).compiled_run() for kind in BUILT_IN) if m is not None}
    return sum(m.warm_up() for m in runs.values())
