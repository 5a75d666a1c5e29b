"""What every picture's title says of a run's controller and fleet."""

from __future__ import annotations

#: Scenario kinds whose robots are cars (titles count "cars", not "robots").
CAR_KINDS = ("lane_change", "braking")


def horizon_and_fleet(metrics: dict, kind: str) -> str:
    """``"horizon N=10, 15 cars"``: the MPC horizon and how many robots the run had (a bare
    "N=10" read as ten cars)."""
    n = metrics.get("n_robots")
    noun = "cars" if kind in CAR_KINDS else "robots"
    fleet = "" if n is None else f", {n} {noun[:-1] if n == 1 else noun}"
    return f"horizon N={metrics.get('horizon')}{fleet}"
