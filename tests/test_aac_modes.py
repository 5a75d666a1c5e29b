"""AAC's two modes behind one constructor, and the typed authorities setting."""

from __future__ import annotations

import copy

import pytest

from aac_sumo.coordination.aac import AacCoordinator, AacParams, Authorities, CommittedAac, StoredPlanAac
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.references import PathReference


@pytest.mark.parametrize("commit, mode", [(True, CommittedAac), (False, StoredPlanAac)])
def test_the_constructor_gives_the_mode_commit_names_and_copies_keep_it(commit, mode):
    task = PathReference([[0.0, 0.0], [10.0, 0.0]], 1.0)
    aac = AacCoordinator(MpcPlanner(MpcConfig()), [task], params=AacParams(commit=commit))
    assert type(aac) is mode and isinstance(aac, AacCoordinator) and aac.name == "aac"
    assert type(copy.deepcopy(aac)) is mode
    assert hasattr(aac, "book") is commit and hasattr(aac, "used") is not commit


def test_authorities_parse_the_scenario_value_and_refuse_anything_else():
    assert Authorities.parse(1).single and not Authorities.parse(3).single
    assert Authorities.parse(3).count == 3 and not Authorities.parse(3).per_cluster
    assert Authorities.parse("clusters").per_cluster and not Authorities.parse("clusters").single
    for bad in (0, -2, "cluster", 1.5, True):
        with pytest.raises(ValueError):
            Authorities.parse(bad)
    with pytest.raises(ValueError):
        AacParams(authorities="clusters")
