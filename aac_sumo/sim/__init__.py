"""Simulators: where the world lives. Each offers ``observe()``, ``step(inputs)`` and ``close()``."""
