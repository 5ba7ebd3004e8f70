"""Parameter studies: a grid over scenario fields × seeds, a tidy table, rates with CIs (no ROS).

A study is a scenario, a grid ``{field: [values]}`` (fields in dotted form, ``law.leader_gain``,
``lambda.tau``, ``faults.0.at``), fixed overrides and a list of seeds.  Every cell is validated
through the scenario model (`scenario.parse`) before anything runs.  Each run is one task that
carries its whole scenario mapping, so a worker needs only the project installed.  Runs are
cached one JSON file per run, keyed by (scenario content hash, parameter values, seed, code
version): a study re-run skips what finished.  The table is sorted by cell and seed and holds
nothing that depends on the executor (no wall times), so it is the same for any executor and
any number of workers.  The checks are the scenario's own (`outcomes.evaluate`).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import json
import signal
import sys
import warnings
from concurrent import futures
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import get_args

import numpy as np
from pydantic import BaseModel

from swarm_core.analysis.outputs import analyse, summary_of
from swarm_core.checks import InputError
from swarm_core.engine import registry
from swarm_core.laws import LawError
from swarm_core.laws.guards import exit_workers_leaving_no_thread
from swarm_core.laws.paper.parameters import LAW_KINDS
from swarm_core.laws.registry import law_code_hash
from swarm_core.robot_units import ROBOT_SETS
from swarm_core.scenario import loader as scenario
from swarm_core.scenario import placement
from swarm_core.study.cache import ROBOT_METRICS, ROW_METRICS, Cache, row_error
from swarm_core.study.grid import ROBOT_SET, Study, StudyError, check_size, parse_set, parse_values

# ------------------------------------------------------------------ the study

def _scenario_text(name_or_path):
    try:
        data, source = scenario.read_yaml(name_or_path)
    except scenario.ScenarioError as err:
        raise StudyError(str(err)) from None
    if not isinstance(data, dict):
        raise StudyError(f'{source}: a scenario is a YAML mapping')
    return data, source


def make_study(scenario_name, sets=(), seeds=10, first_seed=0, fixed=None, name=None) -> Study:
    """A study from a scenario name or file and ``--set`` expressions."""
    data, source = _scenario_text(scenario_name)
    grid = {}
    for expr in sets:
        fld, vals = parse_set(expr) if isinstance(expr, str) else expr
        if fld in grid:
            raise StudyError(f'--set {fld}: given twice')
        grid[fld] = vals
    check_size(grid, seeds)
    seed_list = list(range(first_seed, first_seed + seeds)) if isinstance(seeds, int) else list(seeds)
    return Study(data=data, source=source, grid=grid, fixed=dict(fixed or {}), seeds=seed_list,
                 name=name or data.get('name', 'study'))


def load_study(path, base_dir=None) -> Study:
    """A study file (YAML)::

        name: fig3_ramp
        scenario: homotopy_global      # a shipped name or a file (relative to the study file)
        seeds: 10                      # or first_seed + seeds, or a list
        set: {duration: 800}           # fixed overrides (optional)
        grid:
          law.leader_gain: [10, 30, 50]
          lambda.tau: "5:45:3"         # a list or a range string
        figure: {check: all}           # optional
    """
    p = Path(path)
    if not p.is_file():
        raise StudyError(f'{path}: cannot read: no such file')
    try:                          # the limits of scenario files: size, no aliases, depth
        doc, _ = scenario.read_yaml(str(p))
    except scenario.ScenarioError as err:
        raise StudyError(str(err)) from None
    if not isinstance(doc, dict):
        raise StudyError(f'{path}: a study is a YAML mapping')
    unknown = set(doc) - {'name', 'description', 'scenario', 'seeds', 'first_seed', 'set', 'grid', 'figure'}
    if unknown:
        raise StudyError(f'{path}: unknown key(s) {sorted(unknown)}')
    if 'scenario' not in doc or 'grid' not in doc:
        raise StudyError(f'{path}: a study needs `scenario:` and `grid:`')
    scn = str(doc['scenario'])
    here = Path(base_dir) if base_dir else p.parent
    rel = here / scn
    if scn.endswith(('.yaml', '.yml')) and rel.is_file():
        scn = str(rel)
    sets = []
    if not isinstance(doc['grid'], dict) or not doc['grid']:
        raise StudyError(f'{path}: grid: a mapping FIELD: [values] with at least one field')
    for k, v in doc['grid'].items():
        if isinstance(v, str):
            try:
                v = parse_values(v)
            except StudyError as err:
                raise StudyError(f'{path}: grid.{k}: {err}') from None
        if not isinstance(v, list) or not v:
            raise StudyError(f'{path}: grid.{k}: needs a non-empty list or a START:STOP:COUNT range')
        sets.append((str(k), [_named_here(str(k), x, here) for x in v]))
    seeds = doc.get('seeds', 10)
    fixed = doc.get('set') or {}
    if isinstance(fixed, dict):
        fixed = {k: _named_here(k, v, here) for k, v in fixed.items()}
    st = make_study(scn, sets, seeds=seeds, first_seed=int(doc.get('first_seed', 0)),
                    fixed=fixed, name=doc.get('name') or p.stem)
    st.figure = doc.get('figure') or {}
    return st


#: the field of a robot description: one a study file names is relative to the study file
DESCRIPTION_FIELD = 'robots.description'


def _named_here(fld: str, value, here: Path):
    """``value`` of the field ``fld`` a study file sets: a robot description's path (relative
    to the study file's directory ``here``) made absolute, anything else as it is."""
    if fld != DESCRIPTION_FIELD or not isinstance(value, str):
        return value
    return str(scenario.description_path(value, here))


def _say(line: str) -> None:
    print(f'swarm sweep: WARNING: {line}', file=sys.stderr, flush=True)


def validate(study: Study, warn=_say) -> None:
    """Parse every cell through the scenario model (which reads and checks the robot
    description a ``robots:`` section names); the first bad one raises `StudyError` naming
    the ``--set`` field and the scenario's complaint.  A cell on robots whose step is too long
    for them is refused too; one whose robots brake in every step is said once (``warn``: one
    line each, on stderr).  Nothing runs."""
    if not study.seeds:
        raise StudyError('no seeds (--seeds must be ≥ 1)')
    for k, vals in study.grid.items():
        if not vals:
            raise StudyError(f'--set {k}: empty list of values')
    said = set()
    for k, v in study.fixed.items():
        _check_cell(study, {}, f'set {k}={v}', cell_of_grid=False)
    for cell in study.cells():
        line = _check_cell(study, cell, ', '.join(f'{k}={v}' for k, v in cell.items()))
        if line and line not in said:
            said.add(line)
            warn(line)


def _known(data: dict, dotted: str) -> bool:
    """Is ``dotted`` a field the scenario model has (a section may be absent from the file)?
    Under a ``law:`` of another kind than the paper's, the law checks its own fields."""
    law = data.get('law')
    if dotted.startswith('law.') and isinstance(law, dict) and law.get('kind', LAW_KINDS[0]) not in LAW_KINDS:
        return True
    model = scenario.ScenarioSpec
    for part in dotted.split('.'):
        if part.isdigit():
            continue
        fields = getattr(model, 'model_fields', None)
        if fields is None:
            return True          # a union or a free mapping below: the model validates it
        match = [n for n, f in fields.items() if part in (n, f.alias)]
        if not match:
            return False
        ann = fields[match[0]].annotation
        model = _model_in(ann)
        if model is None:
            return True
    return True


def _model_in(ann):

    if isinstance(ann, type) and issubclass(ann, BaseModel):
        return ann
    models = []
    stack = [ann]
    while stack:
        a = stack.pop()
        if isinstance(a, type) and issubclass(a, BaseModel):
            models.append(a)
        else:
            stack.extend(get_args(a))
    return models[0] if len(models) == 1 else None


def _check_cell(study, cell, label, cell_of_grid=True):
    for k in list(study.fixed) + list(cell):
        if k != ROBOT_SET and not _known(study.data, k):
            raise StudyError(f'--set {k}: unknown scenario field')
    try:
        data = study.cell_data(cell)
        scn = scenario.parse(data, study.source, seed=study.seeds[0])
    except (StudyError, scenario.ScenarioError) as err:
        raise StudyError(f'{label}: {err}') from None
    robots = study.robot_set(cell)
    if robots is not None and robots not in ROBOT_SETS:
        raise StudyError(f'{label}: {ROBOT_SET} {robots!r}: one of {", ".join(ROBOT_SETS)}')
    if robots is not None and scn.spec.robots is None and cell_of_grid:
        raise StudyError(f'{label}: {ROBOT_SET} needs the scenario\'s robots: section (length_scale, cruise_speed)')
    if robots in (None, 'none') or not cell_of_grid:
        return None
    try:                # the robots of the cell follow its steps (the description: checked by parse)
        return scn.spec.robots.step_check(scn.dt)
    except InputError as err:
        raise StudyError(f'{label}: {err}') from None


# ------------------------------------------------------------------ runs and the cache

def _canon(x) -> str:
    return json.dumps(x, sort_keys=True, separators=(',', ':'), default=str)


@functools.lru_cache(maxsize=None)
def code_version(package: str = 'swarm_core') -> str:
    """A hash of a package's sources (swarm_core: a change to the law or the checks invalidates
    the cache; swarm_robots too for runs on the robot engine)."""
    h = hashlib.sha256()
    root = Path(importlib.util.find_spec(package).origin).parent       # found, not imported
    for p in sorted(root.rglob('*')):
        if p.suffix in ('.py', '.yaml') and '__pycache__' not in p.parts:
            h.update(p.relative_to(root).as_posix().encode())
            h.update(p.read_bytes())
    return h.hexdigest()[:16]


def run_key(base_hash: str, cell: dict, seed: int, version: str) -> str:
    """The cache key of one run: (scenario content hash, parameter values, seed, code version)."""
    return hashlib.sha256(_canon([base_hash, cell, seed, version]).encode()).hexdigest()[:24]


@dataclass
class Task:
    """One run: everything a worker needs (the scenario travels with the task)."""
    key: str
    index: int
    cell: dict
    seed: int
    data: dict
    source: str
    version: str = ''
    engine: str = 'fast'
    robot_set: str | None = None      # engine 'robots': which agents are robots


#: the engines a study runs on: 'fast' (`swarm_core.engine.fast.simulate`: the compiled kernel where it covers
#: the run, else the reference) and 'reference' (`engine.simulate`); a cell with a `ROBOT_SET`
#: runs on ROBOTS_ENGINE (registered by swarm_robots, `engine.registry`) whatever the engine asked for
ENGINES = ('fast', 'reference')
#: the engine of a cell with a robot set: ``simulate(scenario, robot_set)``
ROBOTS_ENGINE = 'robots'


def description_hash(data: dict, base_dir=None) -> str:
    """A hash of the robot description file that a cell's ``robots:`` section names ('' for
    none), read with the limits of every input (`scenario.read_text`): part of the cell's cache
    key, as a user's law file is (`law_code_hash`).  StudyError for a file that cannot be read."""
    robots = data.get('robots')
    name = robots.get('description') if isinstance(robots, dict) else None
    if not name:
        return ''
    try:
        text = scenario.read_text(scenario.description_path(name, base_dir), 'robot description')
    except ValueError as err:             # ScenarioError: not a regular file, too large, ...
        raise StudyError(f'robots.description: {err}') from None
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def tasks(study: Study, version: str | None = None, engine: str = 'fast') -> list[Task]:
    if engine not in ENGINES:
        raise StudyError(f'engine {engine!r}: one of {", ".join(ENGINES)}')
    version = version or code_version()
    base = hashlib.sha256(_canon([study.data, study.fixed]).encode()).hexdigest()
    out = []
    for ci, cell in enumerate(study.cells()):
        data = study.cell_data(cell)
        on = ROBOTS_ENGINE if study.robot_set(cell) is not None else engine
        tag = {'fast': version, 'reference': f'{version}-reference'}.get(on) or \
            f'{version}-robots-{code_version("swarm_robots")}-{study.robot_set(cell)}'
        base_dir = Path(study.source).parent if Path(study.source).is_file() else None
        laws = law_code_hash(data.get('law'), base_dir)
        if laws:            # a user's law: a change to its file is a change of the code
            tag = f'{tag}-law-{laws}'
        robot = description_hash(data, base_dir)
        if robot:           # a robot description: a change to its file is a change of the run
            tag = f'{tag}-robot-{robot}'
        for seed in study.seeds:
            out.append(Task(run_key(base, cell, seed, tag), ci, cell, seed, data, study.source, version, on,
                            study.robot_set(cell)))
    return out


def _num(v):
    if isinstance(v, (bool, np.bool_)) or v is None:
        return v if v is None else bool(v)
    if isinstance(v, (int, np.integer)):
        return int(v)
    if isinstance(v, (float, np.floating)):
        return float(v)
    return None


def run_task(task: Task) -> dict:
    """Simulate one run and return its row's results (checks and metrics; no wall time); a law
    that failed: ``{'key', 'failed': its line}`` (`run_study` raises it in the caller, so that no
    worker logs a traceback)."""
    if task.version and task.version != code_version():
        raise RuntimeError(f'this worker runs swarm_core {code_version()}, the study needs {task.version}: '
                           'install the same project version on every worker')
    scn = scenario.parse(task.data, task.source, seed=task.seed)
    simulate = registry.engine(task.engine)
    try:
        traj = simulate(scn, task.robot_set) if task.engine == ROBOTS_ENGINE else simulate(scn)
    except LawError as err:
        return {'key': task.key, 'failed': str(err)}
    series, checks = analyse(traj, scenario=scn)
    s = summary_of(scn, traj, series, checks)
    row = {'ok': s['behaviour_ok']}
    for name, res in checks.items():
        row[name] = res['passed']
        for k, v in res.items():
            if k not in ('passed', 'not_judged') and _num(v) is not None:
                row[f'{name}.{k}'] = _num(v)
    for k in ROW_METRICS:
        if k in s:
            row[k] = _num(s[k])
    for k in ROBOT_METRICS if 'robots' in s else ():
        row[k] = _num(s['robots'][k])
    # the first time the swarm has two clusters and the last time it becomes one again
    ch = s['cluster_changes']
    row['t_first_split'] = next((t for t, c in ch if c >= 2), None)
    row['t_last_one'] = next((t for t, c in reversed(ch) if c == 1), None) if ch and ch[-1][1] == 1 else None
    return {'key': task.key, 'result': row, 'wall': s['wall_seconds']}


# ------------------------------------------------------------------ executors

def _ignore_sigint():
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # the parent decides what a Ctrl-C ends
    exit_workers_leaving_no_thread()               # a law that left a thread must not hold the pool


#: what a study or a sweep says of a worker process that ended without a word
VANISHED_WORKER = ('a worker process ended without a word (a law that calls os._exit ends its process so: '
                   'nothing can catch that)')


def _local_map(todo, jobs):
    """Yield run_task results as they finish, in local processes (``jobs`` 1: in this one)."""
    if jobs <= 1:
        for t in todo:
            yield run_task(t)
        return
    pool = ProcessPoolExecutor(max_workers=jobs, initializer=_ignore_sigint)
    done = False
    try:
        futs = [pool.submit(run_task, t) for t in todo]
        for f in futures.as_completed(futs):
            try:
                yield f.result()
            except BrokenProcessPool:
                raise LawError(VANISHED_WORKER) from None
        done = True
    finally:
        if not done:                       # Ctrl-C or an error: end the runs in flight now
            procs = list((pool._processes or {}).values())
            for proc in procs:
                proc.terminate()
            for proc in procs:
                proc.join(10)
            pool.shutdown(wait=True)   # the pool sees its workers gone and fails what was left
        else:
            pool.shutdown(wait=True)


def dask_client(scheduler: str):
    """A distributed Client: ``tcp://HOST:PORT`` (an existing scheduler) or ``local:N`` (a
    local cluster of N single-threaded worker processes, ended with the client)."""
    from distributed import Client, LocalCluster
    if scheduler.startswith('local:'):
        n = int(scheduler[6:])
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None, host='127.0.0.1')
        client = Client(cluster)
        client._study_cluster = cluster
        return client
    return Client(scheduler, timeout=30)


def _dask_map(todo, scheduler):
    from distributed import as_completed
    client = dask_client(scheduler)
    try:
        futs = [client.submit(run_task, t, key=f'swarm-run-{t.key}', pure=False) for t in todo]
        try:
            for f in as_completed(futs):
                yield f.result()
        finally:
            client.cancel(futs)
    finally:
        cluster = getattr(client, '_study_cluster', None)
        client.close()
        if cluster is not None:
            cluster.close()


def _cached(cache, task):
    """The task's row if the cache holds it (None: run it); an entry that is not one (not a
    regular file, not JSON: `Cache.read`; not this run's row: `swarm_core.study.cache.row_error`) is run
    again, with one warning (which says too if the result cannot be cached there)."""
    doc, why = cache.read(task.key)
    if doc is None and why is None:
        return None
    if why is None:
        spec = placement.AgentsSpec3 if task.data.get('dim') == 3 else placement.AgentsSpec
        agents = spec.model_validate(task.data['agents']).count
        why = row_error(doc, task.cell, task.seed, agents, task.key)
    if why is None:
        return doc['result']
    kept = '' if cache.writable(task.key) else ' (its result is not cached: nothing is written through or over it)'
    warnings.warn(f'study cache {cache.path(task.key)}: {why}; running it again{kept}', stacklevel=3)
    return None


def run_study(study: Study, cache_dir, jobs=1, scheduler=None, progress=False, version=None,
              on_result=None, engine='fast'):
    """Run every task not in the cache; return (rows in cell × seed order, counts).

    ``engine``: 'fast' (default) or 'reference' (`ENGINES`); each has its own cache keys.
    ``scheduler``: None for local processes (``jobs``), else a Dask address or ``local:N``.
    ``on_result(counts)`` is called after each finished run is cached.  Ctrl-C
    (KeyboardInterrupt) leaves the finished runs in the cache and propagates; so does a
    run's law that failed (`LawError` naming it and the time)."""
    from tqdm import tqdm
    cache = Cache(cache_dir)
    all_tasks = tasks(study, version, engine)
    results = {t.key: _cached(cache, t) for t in all_tasks}      # the rows: the cache's, then each run's
    todo = [t for t in all_tasks if results[t.key] is None]
    counts = {'total': len(all_tasks), 'cached': len(all_tasks) - len(todo), 'ran': 0}
    by_key = {t.key: t for t in todo}
    bar = None
    if progress:
        bar = tqdm(total=len(all_tasks), initial=counts['cached'], unit='run', dynamic_ncols=True,
                   desc=study.name, smoothing=0.1)
    try:
        if todo:
            it = _dask_map(todo, scheduler) if scheduler else _local_map(todo, jobs)
            for out in it:
                if 'failed' in out:
                    raise LawError(out['failed'])
                t = by_key[out['key']]
                results[t.key] = out['result']
                if cache.writable(t.key):          # else: warned (`_cached`), the row kept here
                    cache.put(t.key, {'cell': t.cell, 'seed': t.seed, 'result': out['result'],
                                      'wall': out['wall']})
                counts['ran'] += 1
                if bar is not None:
                    bar.update(1)
                if on_result is not None:
                    on_result(counts)
    finally:
        if bar is not None:
            bar.close()
    rows = [{**t.cell, 'seed': t.seed, **results[t.key]} for t in all_tasks]
    return rows, counts
