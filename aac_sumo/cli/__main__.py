"""``python -m aac_sumo.cli ARGS`` is ``aac-sumo ARGS``."""

from aac_sumo.cli import main

raise SystemExit(main())
