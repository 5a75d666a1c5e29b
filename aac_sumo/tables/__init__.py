"""The published tables: ``aac-sumo table NAME`` (:mod:`~aac_sumo.tables.build`) and the
generators of ``docs/results/`` (:mod:`~aac_sumo.tables.results`, :mod:`~aac_sumo.tables.cbf_qp`)."""
