"""How long a world listens for another run before it starts (`runinfo.discovery_settle`): 3 s,
or the environment's SWARM_DISCOVERY_SETTLE (0 on a domain held for one run alone); anything
else is one error naming the variable."""
from __future__ import annotations

import pytest

from swarm_ros import runinfo


@pytest.mark.parametrize('text, want', [(None, runinfo.DISCOVERY_SETTLE), ('', runinfo.DISCOVERY_SETTLE),
                                        ('0', 0.0), (' 1.5 ', 1.5), ('60', 60.0)])
def test_the_settle_is_the_default_or_the_environments(monkeypatch, text, want):
    if text is None:
        monkeypatch.delenv(runinfo.SETTLE_ENV, raising=False)
    else:
        monkeypatch.setenv(runinfo.SETTLE_ENV, text)
    assert runinfo.discovery_settle() == want


@pytest.mark.parametrize('text', ['-1', '61', 'nan', 'inf', 'soon'])
def test_a_bad_settle_names_the_variable(monkeypatch, text):
    monkeypatch.setenv(runinfo.SETTLE_ENV, text)
    with pytest.raises(ValueError, match=rf"SWARM_DISCOVERY_SETTLE='{text}': want wall seconds in \[0, 60\]"):
        runinfo.discovery_settle()
