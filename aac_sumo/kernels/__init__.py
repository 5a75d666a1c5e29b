"""Compiled inner loops (numba) of the per-period work, on plain arrays, one module a subject.

Each kernel is the loop form of a numpy definition elsewhere, or of the function it replaced,
and a test pins it to that definition: :func:`~aac_sumo.kernels.motion.rollouts` and
:func:`~aac_sumo.kernels.safety.braking_courses` step :func:`aac_sumo.dynamics.bicycle_step`
(the latter under the braking law, steering as :func:`aac_sumo.dynamics.heading_hold_steer`),
:func:`~aac_sumo.kernels.motion.footprint_rows` gives
:meth:`aac_sumo.world.WorldState.robot_footprints` along trajectories,
:func:`~aac_sumo.kernels.geometry.rect_clearance` (and ``pairwise_clearance``) is
:func:`aac_sumo.geometry.rect_clearance_rows`, and :func:`~aac_sumo.kernels.anticipation.stop_rows`
is pinned to its numpy form in ``tests/test_stop_points.py``.

- :mod:`~aac_sumo.kernels.paths`: path projection, headings, poses and lateral offsets.
- :mod:`~aac_sumo.kernels.geometry`: rectangle clearances and swept-hull ellipses.
- :mod:`~aac_sumo.kernels.motion`: bicycle-model rollouts, steering limits, braking tails, tracking.
- :mod:`~aac_sumo.kernels.safety`: the safety stop's braking courses, rule and gentler rounds.
- :mod:`~aac_sumo.kernels.commitments`: stopping courses and course-against-courses checks.
- :mod:`~aac_sumo.kernels.anticipation`: stop rows and ramped reference speeds.
- :mod:`~aac_sumo.kernels.detours`: distance field, grid path (A*) and shortcut of a detour.
- :mod:`~aac_sumo.kernels.manoeuvres`: a manoeuvre's hybrid A* over motion primitives on exact footprints.
- :mod:`~aac_sumo.kernels.walkers`: the walkers' and crossing strips' slack of the exact check.
- :mod:`~aac_sumo.kernels.metrics`: the time to collision.
- :mod:`~aac_sumo.kernels.proximity`: the proximity decision's sampled trees.

The kernels import nothing of this package but each other. Units: m, s, rad. Numba caches the
compiled code beside each module, so only the first run on a machine compiles it.
"""
