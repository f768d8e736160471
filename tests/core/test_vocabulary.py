"""The vocabulary (ird_core.vocabulary): one definition per name, plain strings on the wire."""

from __future__ import annotations

import json

import pytest

from ird_core import planning
from ird_core import vocabulary as V
from ird_core.designer import queries
from ird_core.experiments import active, trials
from ird_core.posterior import likelihoods
from ird_core.worlds import lavaland, terrain

ENUMS = (V.ZMethod, V.PlanMode, V.Baseline, V.RiskStatistic, V.QueryStrategy, V.Condition, V.QueryEvent,
         V.TerrainName)


@pytest.mark.parametrize("enum", ENUMS)
def test_members_are_their_wire_strings(enum: type) -> None:
    for member in enum:
        assert member == member.value and f"{member}" == member.value and hash(member) == hash(member.value)
        assert json.loads(json.dumps(member)) == member.value
        assert V.parse(enum, member.value, "field") is member


@pytest.mark.parametrize("enum", ENUMS)
@pytest.mark.parametrize("bad", ["", "nope", None, 3, b"maxent_z"])
def test_parse_refuses_unknown_names_naming_the_field(enum: type, bad: object) -> None:
    with pytest.raises(ValueError, match=r"^my_field: expected one of \("):
        V.parse(enum, bad, "my_field")


def test_every_module_uses_the_one_definition() -> None:
    """The tuples other modules expose are the vocabulary's own objects, not copies."""
    assert likelihoods.METHODS is V.METHODS
    assert planning.MODES is V.MODES and planning.BASELINES is V.BASELINES
    assert queries.STRATEGIES is V.STRATEGIES and active.STRATEGIES is V.STRATEGIES
    assert lavaland.CONDITIONS is V.CONDITIONS and lavaland.ALL_CONDITIONS is V.ALL_CONDITIONS
    assert terrain.TERRAIN_NAMES is V.TERRAIN_NAMES
    assert set(trials.Z_METHODS) == set(V.METHODS)  # the report's row order, same names


def test_terrain_names_follow_the_integer_labels() -> None:
    assert [V.TerrainName(name) for name in V.TERRAIN_NAMES] == list(V.TerrainName)
    assert [t.name.lower() for t in terrain.Terrain] == list(V.TERRAIN_NAMES)
