"""The MPC problem's functions compiled to C: the shared library that
:class:`~aac_sumo.mpc.problem.MpcProblem` loads when ``controller.codegen`` is on (cached per
problem shape, see :func:`~aac_sumo.mpc.problem.library_path`)."""

from __future__ import annotations

import os
import subprocess
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca

#: gcc's flags for the generated C. At -Og the problem's functions compile about three times
#: faster than at -O1, whose register allocation takes most of its time in these long
#: straight-line functions, and a solve takes 1-1.5 % longer; -O0 compiles a little faster
#: still but makes a solve 20-55 % slower. No flag here changes a floating-point result (no
#: -ffast-math; the default x86-64 target has no fused multiply-add): the solves are -O1's bit
#: for bit (docs/benchmarks.md).
CFLAGS = ("-Og",)


def compile_library(solver: ca.Function, library: Path) -> None:
    """Compile what ``solver`` evaluates into the shared library ``library``: its oracle ``nlp``
    and the functions it derived from it at construction (objective, constraints, their
    derivatives, the Lagrangian's Hessian, and ``nlp_grad``, which casadi evaluates after every
    solve for the parameters' multipliers and, with fatrop, for ``f`` and ``g``): none can go.

    Each function's generated C is a translation unit of its own, and the units are compiled by
    as many gcc processes at once as this process may use cores, largest first, then linked. The
    library appears by an atomic rename of a finished file: another process never loads a
    half-written one, and two processes compiling the same library at once each rename a whole
    one over it. A compile that fails or is interrupted removes its temporary folder (a killed
    process leaves it behind) and leaves the cache as it was."""
    library.parent.mkdir(parents=True, exist_ok=True)
    functions = [solver.oracle()] + [solver.get_function(name) for name in solver.get_function()]
    with tempfile.TemporaryDirectory(dir=library.parent) as tmp:
        units = []
        for f in functions:
            generator = ca.CodeGenerator(f"{f.name()}.c")
            generator.add(f)
            units.append(Path(generator.generate(f"{tmp}/")))
        units.sort(key=lambda unit: unit.stat().st_size, reverse=True)
        with ThreadPoolExecutor(max_workers=len(os.sched_getaffinity(0))) as pool:
            objects = list(pool.map(_compile_unit, units))
        built = Path(tmp) / "mpc.so"
        subprocess.run(["gcc", "-shared", *map(str, objects), "-o", str(built), "-lm"], check=True)
        os.replace(built, library)


def _compile_unit(unit: Path) -> Path:
    """The object file of the C file ``unit``, compiled with :data:`CFLAGS` beside it."""
    built = unit.with_suffix(".o")
    subprocess.run(["gcc", "-fPIC", *CFLAGS, "-c", str(unit), "-o", str(built)], check=True)
    return built
