"""Table III of the paper (emergency braking): CBF against F-CBF over the initial speed, once in
the paper's formulation (the MPC without a terminal condition, ``controller.terminal_stop =
false``) and once in ours (with it, the same for both barriers), each once per obstacle
prediction (the ``formulation`` and ``prediction`` columns; both barriers get the same ones),
``aac-sumo table braking``. With ``--sensitivity``, also each barrier over its gains on the next
block of seeds (:func:`sensitivity_table`)."""

from __future__ import annotations

from pathlib import Path

from aac_sumo import config
from aac_sumo.runs import sweep
from aac_sumo.prediction import PREDICTIONS
from aac_sumo.tables.common import _fmt, _num, check_table_sets, fill_metrics, run_grid, write_csv

BRAKING_SPEEDS = (5, 10, 15, 20, 25)
BRAKING_BARRIERS = ("cbf", "fcbf")
BRAKING_METRICS = ("infeasibility_rate", "min_distance_m", "ttc_mean_s", "collisions", "min_clearance_m")
PAPER_METRICS = ("infeasibility_rate", "min_distance_m", "ttc_mean_s")
#: Paper Table III: (infeasibility rate, min distance [m], mean TTC [s]); None where it has no value.
PAPER_TABLE_III: dict[tuple[str, int], tuple[float | None, float | None, float | None]] = {
    ("cbf", 5): (0.433, 1.50, 2.04),
    ("fcbf", 5): (0.0, 1.65, 2.10),
    ("cbf", 10): (0.333, 0.87, 2.13),
    ("fcbf", 10): (0.0, 1.05, 3.55),
    ("cbf", 15): (1.0, None, None),
    ("fcbf", 15): (0.0, 4.04, 5.62),
}
BARRIER_LABELS = {"cbf": "CBF", "fcbf": "F-CBF"}
#: ``formulation`` values, the paper's first, and the ``controller.terminal_stop`` each sets.
FORMULATIONS = {"paper": False, "ours": True}
FORMULATION_TITLES = {
    "paper": "The paper's formulation: no terminal condition (`controller.terminal_stop = false`)",
    "ours": "Ours: with the terminal stopping condition (`controller.terminal_stop = true`, the same for both barriers)",
}
#: The keys the table sets in every run.
FIXED_KEYS = ("controller.prediction", "controller.terminal_stop")


def _speed(value) -> int | float:
    v = float(value)
    return int(v) if v.is_integer() else v


def braking_rows(runs: list[dict], seeds: int) -> list[dict]:
    """One table.csv row per (speed, barrier), and per ``prediction`` when the runs carry one,
    from the per-run rows (grid keys ``braking.speed`` and ``controller.barrier``); means over the
    seeds that ran without error. The paper does not state its prediction: its values stand
    beside every prediction's rows."""
    keyed = [k for k in ("formulation", "prediction") if any(k in r for r in runs)]
    keys = keyed + ["braking.speed", "controller.barrier"]
    table = []
    for values, group in sweep.groups(runs, keys):
        speed, barrier = values[-2:]
        good = [r for r in group if r.get("status") == "ok"]
        row: dict = {"barrier": barrier, "speed": _speed(speed)} | dict(zip(keyed, values[:-2]))
        for m in BRAKING_METRICS:
            mean, std, _ = sweep.mean_std(r.get(m) for r in good)
            row[m] = mean
            if seeds > 1:
                row[f"{m}_std"] = std
        paper = PAPER_TABLE_III.get((barrier, _speed(speed)), (None,) * len(PAPER_METRICS))
        for m, value in zip(PAPER_METRICS, paper):
            row[f"paper_{m}"] = value
        row["runs"] = len(good)
        row["errors"] = len(group) - len(good)
        table.append(row)
    return table


def braking_columns(seeds: int, keyed: bool = False) -> list[str]:
    """table.csv columns; ``keyed``: with the ``formulation`` and ``prediction`` columns after
    barrier and speed."""
    cols = ["barrier", "speed"] + (["formulation", "prediction"] if keyed else [])
    for m in BRAKING_METRICS:
        cols += [m] + ([f"{m}_std"] if seeds > 1 else [])
    return cols + [f"paper_{m}" for m in PAPER_METRICS] + ["runs", "errors"]


def braking_markdown(rows: list[dict], scenario: config.Scenario, seeds: int) -> str:
    """Table III as markdown: one table per prediction (the scenario's own first), or one
    table when the rows carry no prediction."""
    c, b = scenario.data["controller"], scenario.data["braking"]
    lines = [
        "# Table III: emergency braking, CBF vs F-CBF",
        "",
        f"Ego (MPC, N = {c['horizon']}, {c['solver']}{' compiled to C' if c['codegen'] else ''}{' + ipopt retry' if c['retry_with_ipopt'] else ''}, "
        f"dt = {scenario['scenario.dt']} s, gamma = {c['gamma']}) follows a lead {b['gap']} m ahead (centre to centre) at the same speed; "
        f"the lead brakes at {b['lead_decel']} m/s² from t = {b['t_brake']} s. "
        + (f"Ours: mean ± sample std over {seeds} seeds." if seeds > 1 else "Ours: one seed.")
        + " Min distance is the smallest centre-to-centre distance between ego and lead; min clearance the"
        " smallest footprint gap (negative = overlap); mean TTC is over the steps where the ego closes in;"
        " infeasibility is the share of MPC solves that failed or were infeasible. The paper reports no"
        " values at 20 and 25 m/s, nor collisions or clearance, and does not state its prediction; — marks a missing value.",
    ]
    for formulation, part in sweep.groups(rows, ["formulation"]):
        if formulation[0] is not None:
            lines += ["", f"## {FORMULATION_TITLES[formulation[0]]}"]
        for prediction, group in sweep.groups(part, ["prediction"]):
            if prediction[0] is not None:
                default = " (the scenario's default)" if prediction[0] == c["prediction"] else ""
                lines += ["", f"{'###' if formulation[0] else '##'} Prediction: {prediction[0].replace('_', ' ')}{default}"]
            lines += ["", *braking_block(group)]
    return "\n".join(lines) + "\n"


def braking_block(rows: list[dict]) -> list[str]:
    """The markdown table lines of ``rows`` (one prediction)."""
    kinds = {"infeasibility_rate": "pct", "collisions": "count"}
    head = ["Barrier", "Speed [m/s]", "Infeasibility (ours)", "Infeasibility (paper)", "Min distance [m] (ours)",
            "Min distance [m] (paper)", "Mean TTC [s] (ours)", "Mean TTC [s] (paper)", "Collisions (ours)",
            "Min clearance [m] (ours)"]
    lines = ["| " + " | ".join(head) + " |", "|---|---:|" + "---:|" * (len(head) - 2)]
    for r in rows:
        cells = [BARRIER_LABELS.get(r["barrier"], r["barrier"]), str(r["speed"])]
        for m in ("infeasibility_rate", "min_distance_m", "ttc_mean_s"):
            kind = kinds.get(m, "f2")
            cells += [_fmt(r[m], r.get(f"{m}_std"), kind), _fmt(r[f"paper_{m}"], None, kind)]
        cells += [_fmt(r["collisions"], r.get("collisions_std"), "count"), _fmt(r["min_clearance_m"], r.get("min_clearance_m_std"))]
        if r["errors"]:
            cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
        lines.append("| " + " | ".join(cells) + " |")
    return lines


def braking_table(seeds: int, workers: int | None, out: Path, sets: list[str] | None = None,
                  progress: bool = True, scheduler: str | None = None, resume: bool = False,
                  sensitivity: bool = False) -> tuple[list[dict], str, list[dict]]:
    """Run Table III (formulations x predictions x speeds x barriers x seeds; the paper's
    formulation first, the scenario's own prediction first) and write results.csv, table.csv and
    table.md (with ``sensitivity``, also :func:`sensitivity_table`, whose markdown follows the
    table's); returns the table rows, the markdown and the per-run rows."""
    sets = list(sets or [])
    check_table_sets(sets, FIXED_KEYS, "braking")
    scenario = config.load("braking", sets)
    own = scenario["controller.prediction"]
    bundles = [((("formulation", f), ("prediction", p)), [f"controller.terminal_stop={str(stop).lower()}", f"controller.prediction={p}"])
               for f, stop in FORMULATIONS.items() for p in sorted(PREDICTIONS, key=lambda p: p != own)]
    grid = [("braking.speed", [str(s) for s in BRAKING_SPEEDS]), ("controller.barrier", list(BRAKING_BARRIERS))]
    runs = run_grid("braking", grid, seeds, workers, out, sets, progress, "table braking", scheduler, resume, bundles)
    rows = braking_rows(runs, seeds)
    write_csv(rows, braking_columns(seeds, keyed=True), out / "table.csv")
    text = braking_markdown(rows, scenario, seeds)
    (out / "table.md").write_text(text)
    if sensitivity:
        text += "\n" + sensitivity_table(seeds, workers, out, sets, progress, scheduler, resume)[1]
    return rows, text, runs


#: The sensitivity grid: every barrier over these decay rates, F-CBF also over these mu1 [s].
SENSITIVITY_GAMMAS = (0.1, 0.2, 0.3, 0.5)
SENSITIVITY_MU1 = (0.1, 0.2, 0.4)
SENSITIVITY_METRICS = ("infeasibility_rate", "collisions", "min_distance_m", "min_clearance_m")
#: The speeds [m/s] the paper reports (its claims are about these).
PAPER_SPEEDS = (5, 10, 15)


def sensitivity_settings() -> list[tuple[str, float, float | None]]:
    """``(barrier, gamma, mu1)`` of the sensitivity table (mu1 None for CBF, which has none)."""
    return ([("cbf", g, None) for g in SENSITIVITY_GAMMAS]
            + [("fcbf", g, m) for g in SENSITIVITY_GAMMAS for m in SENSITIVITY_MU1])


def sensitivity_rows(runs: list[dict], seeds: int) -> list[dict]:
    """One row per (barrier, gamma, mu1, speed): means over the seeds that ran without error."""
    keys = ["barrier", "gamma", "mu1", "braking.speed"]
    rows = []
    for values, group in sweep.groups(runs, keys):
        barrier, gamma, mu1, speed = values
        row = {"barrier": barrier, "gamma": float(gamma), "mu1": None if mu1 in (None, "") else float(mu1), "speed": _speed(speed)}
        rows.append(fill_metrics(row, group, seeds, SENSITIVITY_METRICS))
    return rows


def _setting(row: dict) -> tuple:
    return row["barrier"], row["gamma"], row["mu1"]


def best_settings(rows: list[dict]) -> dict[str, tuple]:
    """Each barrier's best setting ``(barrier, gamma, mu1)``: the fewest collisions over every
    speed, then the fewest infeasible solves, then the largest smallest distance."""
    best = {}
    for setting, group in sweep.groups(rows, ["barrier", "gamma", "mu1"]):
        key = (sum(_num(r["collisions"]) for r in group), sum(_num(r["infeasibility_rate"]) for r in group),
               -min(_num(r["min_distance_m"]) for r in group))
        if setting[0] not in best or key < best[setting[0]][0]:
            best[setting[0]] = (key, setting)
    return {barrier: setting for barrier, (_, setting) in best.items()}


def sensitivity_claims(rows: list[dict]) -> list[str]:
    """Which of the paper's claims on Table III hold over the whole grid, as sentences."""
    settings = {s: [r for r in g if r["speed"] in PAPER_SPEEDS] for s, g in sweep.groups(rows, ["barrier", "gamma", "mu1"])}
    def clean(group):
        return all(_num(r["collisions"]) == 0 and _num(r["infeasibility_rate"]) == 0 for r in group)
    fcbf = [s for s in settings if s[0] == "fcbf"]
    cbf = [s for s in settings if s[0] == "cbf"]
    lines = [f"- F-CBF with 0 % infeasible solves and 0 collisions at 5–15 m/s (the paper's claim): "
             f"{sum(clean(settings[s]) for s in fcbf)} of {len(fcbf)} settings"
             + (f"; not at {', '.join(_label(s) for s in fcbf if not clean(settings[s]))}" if not all(clean(settings[s]) for s in fcbf) else "")
             + ".",
             f"- F-CBF with 0 collisions at 5–15 m/s: {sum(all(_num(r['collisions']) == 0 for r in settings[s]) for s in fcbf)} of "
             f"{len(fcbf)} settings; CBF: {sum(all(_num(r['collisions']) == 0 for r in settings[s]) for s in cbf)} of {len(cbf)}.",
             f"- CBF with infeasible solves or collisions at 5–15 m/s (the paper's contrast): "
             f"{sum(not clean(settings[s]) for s in cbf)} of {len(cbf)} settings.",]
    fewer = []
    for g in SENSITIVITY_GAMMAS:
        c = [r for s, group in settings.items() if s[0] == "cbf" and s[1] == g for r in group]
        for m in SENSITIVITY_MU1:
            f = [r for s, group in settings.items() if s == ("fcbf", g, m) for r in group]
            if c and f:
                fewer.append((g, m, sum(_num(r["collisions"]) for r in f) <= sum(_num(r["collisions"]) for r in c)
                              and sum(_num(r["infeasibility_rate"]) for r in f) <= sum(_num(r["infeasibility_rate"]) for r in c)))
    lines.append(f"- F-CBF no worse than CBF at the same γ (collisions and infeasible solves at 5–15 m/s): "
                 f"{sum(ok for *_, ok in fewer)} of {len(fewer)} (γ, μ1) pairs"
                 + (f"; not at {', '.join(f'γ = {g:g}, μ1 = {m:g}' for g, m, ok in fewer if not ok)}" if not all(ok for *_, ok in fewer) else "")
                 + ".")
    return lines


def _label(setting: tuple) -> str:
    barrier, gamma, mu1 = setting
    return f"{BARRIER_LABELS[barrier]} γ = {gamma:g}" + ("" if mu1 is None else f", μ1 = {mu1:g}")


def sensitivity_markdown(rows: list[dict], seeds: int, first_seed: int, prediction: str) -> str:
    """The sensitivity table: every setting's rows, then each barrier at its best setting."""
    kinds = {"infeasibility_rate": "pct", "collisions": "count"}
    head = ["Barrier", "γ", "μ1 [s]", "Speed [m/s]", "Infeasibility", "Collisions", "Min distance [m]", "Min clearance [m]"]
    def block(part):
        out = ["| " + " | ".join(head) + " |", "|---|---:|---:|---:|" + "---:|" * (len(head) - 4)]
        for r in part:
            cells = [BARRIER_LABELS[r["barrier"]], f"{r['gamma']:g}", "—" if r["mu1"] is None else f"{r['mu1']:g}", str(r["speed"])]
            cells += [_fmt(r[m], None if kinds.get(m) == "pct" else r.get(f"{m}_std"), kinds.get(m, "f2")) for m in SENSITIVITY_METRICS]
            if r["errors"]:
                cells[0] += f" ({r['errors']} failed run{'s' if r['errors'] > 1 else ''})"
            out.append("| " + " | ".join(cells) + " |")
        return out
    best = best_settings(rows)
    seed_text = f"seeds {first_seed}–{first_seed + seeds - 1}" if seeds > 1 else f"seed {first_seed}"
    lines = ["# Table III sensitivity: each barrier over its gains", "",
             f"The paper's formulation (`controller.terminal_stop = false`), prediction {prediction.replace('_', ' ')}, "
             f"{seed_text} (the block after the table's own seeds, used for no choice). CBF over γ; F-CBF over γ and μ1 "
             "(μ2 and the sigmoid as in the scenario). Best setting: the fewest collisions over every speed, then the "
             "fewest infeasible solves, then the largest smallest distance.", "",
             "## Which claims hold over the whole range", "", *sensitivity_claims(rows), "",
             "## Each barrier at its own best setting", "",
             *block([r for r in rows if _setting(r) in best.values()]), "", "## Every setting", "", *block(rows)]
    return "\n".join(lines) + "\n"


def sensitivity_table(seeds: int, workers: int | None, out: Path, sets: list[str], progress: bool = True,
                      scheduler: str | None = None, resume: bool = False) -> tuple[list[dict], str]:
    """Run the sensitivity grid (:func:`sensitivity_settings` x speeds x ``seeds`` seeds, starting
    ``seeds`` after the scenario's seed: outside the table) in the paper's formulation, its runs
    into ``out/sensitivity``; write ``sensitivity.csv`` and ``sensitivity.md`` into ``out``."""
    scenario = config.load("braking", sets)
    first = int(scenario["scenario.seed"]) + seeds
    base = list(sets) + ["controller.terminal_stop=false", f"scenario.seed={first}"]
    bundles = [((("barrier", b), ("gamma", g), ("mu1", m)),
                [f"controller.barrier={b}", f"controller.gamma={g}"] + ([] if m is None else [f"controller.mu1={m}"]))
               for b, g, m in sensitivity_settings()]
    grid = [("braking.speed", [str(s) for s in BRAKING_SPEEDS])]
    runs_dir = out / "sensitivity"
    runs_dir.mkdir(parents=True, exist_ok=True)
    runs = run_grid("braking", grid, seeds, workers, runs_dir, base, progress, "table braking --sensitivity", scheduler, resume, bundles)
    rows = sensitivity_rows(runs, seeds)
    cols = ["barrier", "gamma", "mu1", "speed"] + [c for m in SENSITIVITY_METRICS for c in [m] + ([f"{m}_std"] if seeds > 1 else [])]
    write_csv(rows, cols + ["runs", "errors"], out / "sensitivity.csv")
    text = sensitivity_markdown(rows, seeds, first, scenario["controller.prediction"])
    (out / "sensitivity.md").write_text(text)
    return rows, text
