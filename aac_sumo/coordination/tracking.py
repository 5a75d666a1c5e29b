"""The simple tracking law of robots that hold no usable plan: pure pursuit on the reference
path plus a proportional speed loop. No obstacle avoidance; it only keeps robots on their task."""

from __future__ import annotations

import numpy as np

from aac_sumo.references import PathReference
from aac_sumo.world import RobotSpec


def track(robot: RobotSpec, state: np.ndarray, task: PathReference, lookahead: float, speed_gain: float,
          previous_steer: float, dt: float, offset: float = 0.0, target_speed: float | None = None) -> np.ndarray:
    """Input ``[accel, steer]`` steering the rear axle toward the path point ``lookahead`` [m]
    ahead of its projection (moved ``offset`` [m] to the right of the path) and driving the
    speed toward the reference speed there (or ``target_speed`` [m/s] when given); within the task's ``approach`` distance of its
    goal, toward the goal at the speed that stops there. It brakes at most at the robot's
    comfort deceleration, and its steering keeps the vehicle limits (angle, lateral
    acceleration, and rate from ``previous_steer`` [rad], the steering applied the period ``dt``
    [s] before)."""
    s0, _ = task.project(state[:2])
    pose = task.pose_at(min(s0 + lookahead, task.length) if task.stop_at_end else s0 + lookahead)[0]
    target = pose[:2] + offset * np.array([np.sin(pose[2]), -np.cos(pose[2])])
    goal_rel = task.points[-1] - state[:2]
    near_goal = task.stop_at_end and float(np.hypot(*goal_rel)) <= task.approach
    if near_goal:  # within the approach distance: straight at the goal, as the reference does
        target = task.points[-1]
    rel = target - state[:2]
    dist = float(np.hypot(*rel))
    lim = robot.model.limits
    if dist < 1e-6:
        steer = 0.0
    else:
        alpha = np.arctan2(rel[1], rel[0]) - state[2]
        steer = float(np.arctan2(2.0 * robot.model.wheelbase * np.sin(alpha), dist))
    speed = min(task.speed, float(np.sqrt(2.0 * task.decel * dist))) if near_goal else float(task.speed_at(s0))
    if target_speed is not None and not near_goal:
        speed = target_speed
    accel = min(max(speed_gain * (speed - state[3]), -lim.comfort_decel), lim.a_max)
    return np.array([accel, float(robot.model.limit_steer(steer, state[3], previous_steer, dt, accel))])
