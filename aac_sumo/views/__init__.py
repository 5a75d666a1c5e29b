"""What a person looks at after a run: its pictures, timeline, animation, comparisons of runs
and the road's time budget. Views read runs (:mod:`aac_sumo.runs`); runs never import views."""
