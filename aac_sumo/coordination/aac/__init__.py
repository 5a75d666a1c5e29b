"""Alternative Authority Control (paper Algorithm 1, as DESIGN.md interprets it), in two modes:
committed plans (:mod:`.committed`, the default; collision-free by construction) and the
paper's stored plans (:mod:`.stored`); :mod:`.authority` holds who plans when, shared by both,
and :mod:`.params` the settings. ``AacCoordinator(planner, tasks, ..., params)`` gives the
mode ``params.commit`` names."""

from aac_sumo.coordination.aac.authority import AacCoordinator
from aac_sumo.coordination.aac.committed import CommittedAac
from aac_sumo.coordination.aac.params import AacParams, Authorities
from aac_sumo.coordination.aac.stored import StoredPlanAac
from aac_sumo.registry import register_coordinator

register_coordinator("aac", AacCoordinator, params=AacParams, doc="one authority robot per period", label="AAC-MPC-FCBF")

__all__ = ["AacCoordinator", "AacParams", "Authorities", "CommittedAac", "StoredPlanAac"]
