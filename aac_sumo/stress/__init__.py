"""Randomized stress campaigns: ``aac-sumo stress`` (:mod:`~aac_sumo.stress.campaign`)."""
