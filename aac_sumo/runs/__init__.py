"""Running scenarios: one run (:mod:`~aac_sumo.runs.runner`), its record and files, many runs
(:mod:`~aac_sumo.runs.sweep` through :mod:`~aac_sumo.runs.executor`), the solver benchmark, and
the provenance every run writes."""
