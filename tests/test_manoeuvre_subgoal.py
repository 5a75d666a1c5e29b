"""A manoeuvre's subgoal (``aac.manoeuvre_subgoal``): a stalled robot far from its goal that finds
no way to the goal itself (here: walled in) searches one to the point that far along the straight
line to it, drives its first metres, and plans again from there."""

from __future__ import annotations

import numpy as np

from aac_sumo.coordination.aac import AacCoordinator, AacParams
from aac_sumo.coordination.regions import Fleet
from aac_sumo.dynamics import BicycleModel, VehicleLimits
from aac_sumo.geometry import rect_clearance_rows
from aac_sumo.kernels.motion import footprint_rows
from aac_sumo.mpc.planner import MpcPlanner
from aac_sumo.mpc.settings import MpcConfig
from aac_sumo.references import PathReference
from aac_sumo.world import Obstacle, RobotSpec, WorldState

GOAL = np.array([8.0, 0.0])
#: A box of thin walls round the goal, 1 m each side of it: no way in.
WALLS = [((GOAL[0], GOAL[1] + 1.0), 2.2, 0.2), ((GOAL[0], GOAL[1] - 1.0), 2.2, 0.2), ((GOAL[0] - 1.0, GOAL[1]), 0.2, 2.2),
         ((GOAL[0] + 1.0, GOAL[1]), 0.2, 2.2)]


def manoeuvres(subgoal: float):
    """A standing robot at the origin, facing its walled-in goal 8 m away, counted as stalled:
    whether it commits to a manoeuvre, and its commitment."""
    robot = RobotSpec("robot0", 0.6, 0.4, BicycleModel(0.45, VehicleLimits(a_min=-2.0, a_max=1.0, steer_max=0.6, v_min=-1.0, v_max=1.5)))
    state = np.array([[0.0, 0.0, 0.0, 0.0]])
    walls = [Obstacle(f"wall{k}", "static", np.array(c), np.zeros(2), 0.0, length, width) for k, (c, length, width) in enumerate(WALLS)]
    params = AacParams(commit=True, manoeuvre=True, manoeuvre_subgoal=subgoal)
    aac = AacCoordinator(MpcPlanner(MpcConfig(horizon=5, dt=0.1)), [PathReference([state[0, :2], GOAL], 1.0)], params=params)
    aac.fleet = Fleet([robot])
    world = WorldState(0.0, state, [robot], walls)
    aac.decide(world)
    aac.jammed[0] = True  # stalled: as the jam rule would say after manoeuvre_time
    statics = np.array([o.footprint() for o in walls])
    committed = aac.manoeuvre(world, 0, aac.period, statics)
    return committed, aac.book.items[0]


def test_a_walled_in_goal_gives_no_manoeuvre_without_a_subgoal():
    committed, _ = manoeuvres(0.0)
    assert not committed


def test_with_a_subgoal_it_drives_out_towards_the_goal_and_stops_short_of_the_walls():
    committed, c = manoeuvres(3.0)
    assert committed
    end = c.states[-1]
    assert end[3] == 0.0  # from standstill to standstill
    assert 0.5 < end[0] <= 3.0 + 0.5  # towards the goal, at most to within the subgoal's tolerance of it
    assert abs(end[1]) < 0.5
    walls = np.array([[*centre, length, width, 0.0] for centre, length, width in WALLS])
    rows = footprint_rows(c.states[None], np.array([0.225]), np.array([0.6]), np.array([0.4]))[0]
    assert rect_clearance_rows(rows[:, None], walls[None]).min() >= 0.05  # every period's footprint keeps the margin from the walls
