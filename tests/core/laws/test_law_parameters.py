"""One declaration of the law's parameters (swarm_core.laws.paper.parameters) drives the scenario
schema, the agent's ROS parameters and the paper's laws' `param`s; one check of λ
(swarm_core.checks) is the one every boundary uses."""
from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_core.checks import LAMBDA_BOUND, Bound, InputError
from swarm_core.command.plan import check_command
from swarm_core.laws import Homotopy, from_flat_parameters, law_class
from swarm_core.laws.paper.parameters import LAW_TABLE
from swarm_core.scenario.loader import BarrierSpec, LawSpec, ScenarioError, TargetSpec, parse

BASE = dict(name='t', dt=0.1, duration=1.0, agents=dict(count=3))
SQUARE = [[0, 0], [1, 0], [1, 1], [0, 1]]
REAL = [p for p in LAW_TABLE if p.bound is not None]
#: name → (default, description, range or choices or None) of the agent node's flat parameters
SPECS = Homotopy().flat_specs()


def _section_model(p, value):
    """The schema model of ``p``'s scenario section with ``p`` set to ``value``."""
    if p.section == 'law':
        return LawSpec(**{p.scenario_key: value})
    if p.section == 'target':
        return TargetSpec(position=(0.0, 0.0), **{p.scenario_key: value})
    return BarrierSpec(points=SQUARE, **{p.scenario_key: value})


def test_every_name_appears_once_everywhere():
    names = [p.name for p in LAW_TABLE]
    assert len(set(names)) == len(names)
    assert list(SPECS) == names
    assert list(Homotopy().flat()) == names
    assert list(LawSpec.model_fields) == [p.scenario_key for p in LAW_TABLE if p.section == 'law']
    for kind in LAW_TABLE[0].choices:                       # every paper's law has them all
        assert list(law_class(kind).param_specs()) == names[1:], kind


def test_defaults_and_descriptions_come_from_the_table():
    flat = Homotopy().flat()
    for p in LAW_TABLE:
        assert flat[p.name] == p.default and type(flat[p.name]) is type(p.default), p.name
        if p.name != 'law':
            assert SPECS[p.name][:2] == (p.default, p.description) and 'eq.' in p.description, p.name
        if p.section == 'law':
            assert LawSpec.model_fields[p.scenario_key].default == p.default, p.name


@pytest.mark.parametrize('p', REAL, ids=lambda p: p.name)
def test_schema_and_ros_ranges_are_the_one_bound(p):
    lo, hi = p.bound.lo, p.bound.hi
    assert SPECS[p.name][2] == (lo, hi)                       # what the agent node declares
    for ok in (lo, hi, 0.5 * (lo + hi)):
        assert getattr(_section_model(p, ok), p.scenario_key) == ok
    for bad in (np.nextafter(lo, -math.inf), np.nextafter(hi, math.inf), math.nan, math.inf):
        with pytest.raises(ValueError):
            _section_model(p, float(bad))
    for ok in (lo, hi):
        assert p.bound.ok(ok)
    assert not p.bound.ok(float(np.nextafter(hi, math.inf)))


@pytest.mark.parametrize('p', [p for p in LAW_TABLE if p.choices and p.name != 'law'], ids=lambda p: p.name)
def test_schema_and_ros_choices_are_the_same(p):
    assert SPECS[p.name][2] == p.choices
    for c in p.choices:
        assert getattr(_section_model(p, c), p.scenario_key) == c
    with pytest.raises(ValueError):
        _section_model(p, 'magic')


def test_reunion_coupling_and_gain_are_q0_and_the_target_gain():
    from swarm_core.laws.paper.parameters import LAW_PARAMETER
    from swarm_core.scenario.loader import ReunionSpec
    for key, name in (('coupling', 'q0'), ('gain', 'target_gain')):
        b = LAW_PARAMETER[name].bound
        assert getattr(ReunionSpec(at=0, **{'for': 1, key: b.hi}), key) == b.hi
        with pytest.raises(ValueError):
            ReunionSpec(at=0, **{'for': 1, key: float(np.nextafter(b.hi, math.inf))})


def test_booleans_have_no_range():
    for p in LAW_TABLE:
        if isinstance(p.default, bool):
            assert SPECS[p.name][2] is None and p.bound is None and not p.choices


def test_each_flat_parameter_reaches_its_own_field():
    base = law_class('target')(barrier_mode='literal').flat()
    for p in REAL:
        changed = dict(base, **{p.name: 0.5 * (p.bound.lo + p.bound.hi) + 0.25 * (p.bound.hi - p.bound.lo)})
        back = from_flat_parameters(changed).flat()
        assert back == changed, p.name
    law = law_class('local')(alpha=0.1, eta=0.2, mu=0.3, r0=0.4, cutoff_radius=5.0, leader_gain=9.0, q0=0.5,
                             target_gain=0.6, target_normalised=True, barrier_gain=0.7, barrier_mode='literal')
    assert from_flat_parameters(law.flat()) == law


def test_a_scenario_sets_the_law_from_its_sections():
    law = parse({**BASE, 'law': dict(kind='target', alpha=0.3, r0=2.0),
                 'target': dict(position=[5, 5], gain=0.7, normalised=True),
                 'barrier': dict(points=SQUARE, gain=3.0, mode='literal')}).law
    assert law == law_class('target')(alpha=0.3, r0=2.0, target_gain=0.7, target_normalised=True,
                                      barrier_gain=3.0, barrier_mode='literal')
    assert parse(BASE).law == Homotopy()           # no target, no barrier: their terms are off


# ---------------------------------------------------------------- λ

LAMBDA_TEXT = 'must be a finite number in [0, 1]'


@pytest.mark.parametrize('v', [-0.1, 1.1, math.nan, math.inf, -math.inf, 'x', '0.5', True, False, None,
                               np.float64(1.5)])
def test_lambda_check_rejects_with_the_one_text(v):
    assert not LAMBDA_BOUND.ok(v)
    with pytest.raises(InputError) as err:
        LAMBDA_BOUND.check(v)
    assert str(err.value) == f'λ={v!r}: {LAMBDA_TEXT}' == LAMBDA_BOUND.error(v)


@pytest.mark.parametrize('v', [0, 1, 0.5, 0.0, 1.0, np.float64(0.25), np.int64(1)])
def test_lambda_check_accepts(v):
    assert LAMBDA_BOUND.ok(v)
    out = LAMBDA_BOUND.check(v)
    assert type(out) is float and out == float(v)


def test_the_scenario_and_the_live_commands_reject_lambda_with_that_text():
    for where, section in (('lambda.constant.value', dict(kind='constant', value=1.5)),
                           ('lambda.ramps.initial', dict(kind='ramps', initial=-0.5)),
                           ('lambda.ramps.ramps.0.to', dict(kind='ramps', ramps=[dict(at=1, to=2.0)]))):
        with pytest.raises(ScenarioError) as err:
            parse({**BASE, 'lambda': section}, 'x.yaml')
        bad = section.get('value', section.get('initial', 2.0))
        assert str(err.value) == f'x.yaml: {where}: {LAMBDA_BOUND.error(float(bad))}'
    with pytest.raises(ScenarioError, match='lambda.constant.value: λ=nan: must be a finite'):
        parse({**BASE, 'lambda': dict(kind='constant', value=math.nan)})
    with pytest.raises(ValueError) as err:
        check_command(dict(command='lambda', value=1.5), 3)
    assert str(err.value) == LAMBDA_BOUND.error(1.5)
    assert check_command(dict(command='lambda', value=1), 3)['value'] == 1.0


def test_a_bound_names_its_range():
    b = Bound('dt', 1e-6, 10.0)
    assert b.error(0.0) == 'dt=0.0: must be a finite number in [1e-06, 10]'
    assert b.check(10) == 10.0 and not b.ok(10.5)


def test_a_paper_law_checks_its_choice_and_yes_no_parameters():
    from swarm_core.laws import LawError
    target = law_class('target')
    assert target(barrier_mode='literal', target_normalised=True).barrier_mode == 'literal'
    with pytest.raises(LawError, match=r"parameter barrier_mode must be one of ahead, literal, got 'magic'"):
        target(barrier_mode='magic')
    with pytest.raises(LawError, match=r'law target: parameter target_normalised must be true or false, got 1'):
        target(target_normalised=1)
