"""Compile a model library: the CasADi-generated C, the hand-written driver and, optionally,
the CPython fast-call front end (``c/pyfast.c``), into one shared library.

``driver_defines`` derives the driver's preprocessor macros from the CasADi functions (they are
stored in a model's manifest so that a cached or committed C file compiles without the CasADi
functions at hand); ``compile_model`` compiles given those macros; ``build_library`` does both.
The result is loaded by ``runtime/compiled.py::CompiledLibrary``.
"""
from __future__ import annotations

import sysconfig
import tempfile
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from grasping_sym.emit.lanes import lanes_symbol
from grasping_sym.toolchain import objects as object_cache
from grasping_sym.toolchain.compiler import compile_shared

__all__ = ["DRIVER_SOURCES", "PYFAST_C", "build_library", "compile_model", "driver_defines",
           "model_defines", "outputs_read_time", "predicted_defines", "prefetch_driver"]

_C_DIR = Path(__file__).resolve().parent.parent / "c"
#: The hand-written C driver compiled next to the CasADi-generated file (``driver.c`` first:
#: its header comment maps the macros and the other files).
DRIVER_SOURCES: tuple[Path, ...] = tuple(
    _C_DIR / f for f in ("driver.c", "project.c", "rk4.c", "radau5.c", "jac.c", "lu.c", "dopri5.c", "dop853.c",
                         "stop.c", "watch.c", "wrap.c", "batch.c", "budget.c"))
#: The optional CPython extension giving the sub-microsecond call path.
PYFAST_C: Path = _C_DIR / "pyfast.c"


def driver_defines(rhs_fn: Any, outputs_fn: Any | None = None,
                   jac_fn: Any | None = None,
                   constraints_fn: Any | None = None,
                   rhs_lanes: str | None = None) -> dict[str, str | int]:
    """Preprocessor macros of the C driver (``c/driver.c`` documents them) from the CasADi functions used.

    Parameters
    ----------
    rhs_fn : casadi.Function
        The DAE right-hand side ``<prefix>_rhs`` with inputs (t, x, z, p, u).
    outputs_fn : casadi.Function, optional
        ``<prefix>_outputs`` with inputs (x, p) and one output y.
    jac_fn : casadi.Function, optional
        ``rhs_fn.jacobian()`` (named ``jac_<prefix>_rhs``): inputs (t, x, z, p, u,
        nominal outputs...), one output block per (output, input) pair; the block
        ``jac_ode_x`` (d ode / d x, nx x nx) is used by ``gs_radau5``.  Without it
        ``gs_radau5`` falls back to a finite-difference Jacobian.
    constraints_fn : casadi.Function, optional
        ``<prefix>_constraints`` with inputs (x, p) and outputs (C, dC_dx, Cdot,
        dCdot_dv), both Jacobians dense ``nc x nx``: needed by the projection.
    rhs_lanes : str, optional
        C name of the 4-lane rhs (``codegen.lanes.rhs_lanes_c``) when the C file has it.

    Returns
    -------
    dict
        ``GS_RHS, GS_NX, GS_NP, GS_HAS_OUT, [GS_OUT, GS_NY,] GS_HAS_JAC, [GS_JAC,
        GS_JAC_NIN, GS_JAC_NOUT, GS_JAC_BLOCK,] GS_HAS_CON, [GS_CON, GS_NC,]
        GS_HAS_RHS_LANES, [GS_RHS_LANES,] GS_SZ_ARG, GS_SZ_RES, GS_SZ_IW, GS_SZ_W``; sizes
        are maxima over all the functions given; ``GS_OUT_TIME`` 1 when the outputs take the
        time as one more last entry of p. Only the work sizes are compiled into the driver:
        the sizes (``GS_NX``, ``GS_NP``, ``GS_NY``, ``GS_NC``, ``GS_OUT_TIME``), the features
        (``GS_HAS_*``, ``GS_JAC_*``) and the functions' names are the library's link file's, read
        at run time (``objects.links_c``).
    """
    fns = [rhs_fn] + [f for f in (outputs_fn, jac_fn, constraints_fn) if f is not None]
    defines: dict[str, str | int] = {
        "GS_RHS": rhs_fn.name(),
        "GS_NX": int(rhs_fn.numel_in(1)),
        "GS_NP": int(rhs_fn.numel_in(3)),
        "GS_HAS_OUT": int(outputs_fn is not None),
    }
    if outputs_fn is not None:
        n_p = defines["GS_NP"]
        if outputs_fn.numel_in(0) != defines["GS_NX"] or outputs_fn.numel_in(1) not in (n_p, n_p + 1):
            raise ValueError(
                f"outputs function {outputs_fn.name()!r} must take x[{defines['GS_NX']}], "
                f"p[{n_p}] (or p[{n_p + 1}], the time last); got x[{outputs_fn.numel_in(0)}], "
                f"p[{outputs_fn.numel_in(1)}]"
            )
        defines["GS_OUT"] = outputs_fn.name()
        defines["GS_NY"] = int(outputs_fn.numel_out(0))
        defines["GS_OUT_TIME"] = int(outputs_fn.numel_in(1) == n_p + 1)
    defines["GS_HAS_JAC"] = int(jac_fn is not None)
    if jac_fn is not None:
        nx = defines["GS_NX"]
        names_out = [jac_fn.name_out(i) for i in range(jac_fn.n_out())]
        block = names_out.index("jac_ode_x") if "jac_ode_x" in names_out else 1
        names_in = [jac_fn.name_in(i) for i in range(min(5, jac_fn.n_in()))]
        if (jac_fn.n_in() < 5 or names_in[1] != rhs_fn.name_in(1) or names_in[3] != rhs_fn.name_in(3)
                or jac_fn.n_out() <= block or jac_fn.size_out(block) != (nx, nx)):
            raise ValueError(
                f"Jacobian function {jac_fn.name()!r} must be {rhs_fn.name()!r}.jacobian(): inputs "
                f"(t, x, z, p, u, ...) and an output jac_ode_x of shape ({nx}, {nx}); got inputs "
                f"{names_in}, outputs {names_out[:3]}..."
            )
        defines.update({"GS_JAC": jac_fn.name(), "GS_JAC_NIN": int(jac_fn.n_in()),
                        "GS_JAC_NOUT": int(jac_fn.n_out()), "GS_JAC_BLOCK": int(block)})
    defines["GS_HAS_CON"] = int(constraints_fn is not None)
    if constraints_fn is not None:
        nx, nc = defines["GS_NX"], int(constraints_fn.numel_out(0))
        shapes = [constraints_fn.size_out(i) for i in range(constraints_fn.n_out())]
        dense = all(constraints_fn.sparsity_out(i).is_dense() for i in (1, 3)) if len(shapes) == 4 else False
        if (constraints_fn.n_in() != 2 or constraints_fn.numel_in(0) != nx
                or constraints_fn.numel_in(1) != defines["GS_NP"] or nc < 1
                or shapes != [(nc, 1), (nc, nx), (nc, 1), (nc, nx)] or not dense):
            raise ValueError(
                f"constraints function {constraints_fn.name()!r} must take (x[{nx}], "
                f"p[{defines['GS_NP']}]) and return (C[nc], dC_dx[nc x {nx}], Cdot[nc], "
                f"dCdot_dv[nc x {nx}]) with dense Jacobians; got outputs {shapes}"
            )
        defines.update({"GS_CON": constraints_fn.name(), "GS_NC": nc})
    defines["GS_HAS_RHS_LANES"] = int(rhs_lanes is not None)
    if rhs_lanes is not None:
        defines["GS_RHS_LANES"] = rhs_lanes
    for key, meth in (("GS_SZ_ARG", "sz_arg"), ("GS_SZ_RES", "sz_res"), ("GS_SZ_IW", "sz_iw"), ("GS_SZ_W", "sz_w")):
        defines[key] = max(int(getattr(f, meth)()) for f in fns)
    return defines


def model_defines(cm, lanes: bool) -> dict[str, str | int]:
    """The driver's macros for a model's functions (``functions.CasadiModel``), and a 4-lane
    rhs when ``lanes``. A law that reads the time gives outputs that
    take it as one more last entry of p (``GS_OUT_TIME``, the link file's ``gs_out_time``):
    the driver then calls them only to watch witnesses (``c/watch.c``; ``runtime.outputs.row``
    gives them to the caller)."""
    return driver_defines(cm.rhs, cm.outputs, jac_fn=cm.jac, constraints_fn=cm.constraints,
                          rhs_lanes=lanes_symbol(cm.rhs) if lanes else None)


def outputs_read_time(cm, n_p: int) -> bool:
    """Whether ``cm``'s outputs take the time as a last entry of p (see ``model_defines``)."""
    return cm.outputs is not None and cm.outputs.nnz_in(1) == n_p + 1


def predicted_defines() -> dict[str, str | int]:
    """The driver's macros of a model before its functions exist: ``driver_defines`` of a
    stand-in rhs (2 states, 1 parameter). The driver's objects depend on the work sizes alone
    (``objects.object_defines`` leaves the sizes, the features and the names to the link
    file), and the stand-in's are below what ``object_defines`` rounds every size up to: the
    objects are the model's whenever its own work sizes are too."""
    x, p = ca.SX.sym("x", 2), ca.SX.sym("p", 1)
    none = ca.SX(0, 1)
    rhs = ca.Function("m_rhs", [ca.SX.sym("t"), x, ca.SX.sym("z", 0), p, ca.SX.sym("u", 0)],
                      [x, none, none, none], ca.dyn_in(), ca.dyn_out())
    return driver_defines(rhs)


def prefetch_driver(defines: dict, fast: bool = True) -> None:
    """Start compiling, in the background, the driver's objects for ``defines`` when they are
    not cached (``objects.prefetch_driver_objects``)."""
    drivers, include_dirs = _driver_inputs(fast)
    object_cache.prefetch_driver_objects(drivers, defines, include_dirs)


def _driver_inputs(fast: bool) -> tuple[list[Path], list[str]]:
    """The driver's sources and include directories (``fast``: with the CPython front end)."""
    return ([*DRIVER_SOURCES] + ([PYFAST_C] if fast else []),
            [sysconfig.get_paths()["include"], np.get_include()] if fast else [])


def build_library(
    casadi_c: Path | str,
    out: Path | str,
    rhs_fn: Any,
    outputs_fn: Any | None = None,
    fast: bool = True,
    jac_fn: Any | None = None,
    constraints_fn: Any | None = None,
    rhs_lanes: str | None = None,
) -> Path:
    """Compile a CasADi-generated C file with the driver into ``out``.

    Parameters
    ----------
    casadi_c : Path
        The CasADi-generated ``<prefix>.c``.
    out : Path
        Destination shared library (replaced atomically).
    rhs_fn, outputs_fn : casadi.Function
        The functions generated into ``casadi_c`` (for names and work sizes).
    fast : bool
        Also compile ``pyfast.c`` so the library doubles as a CPython extension
        (needs ``Python.h``; the result is then tied to this interpreter's ABI,
        so include ``sys.version`` and the NumPy version in cache keys).
    jac_fn : casadi.Function, optional
        ``rhs_fn.jacobian()`` if it was generated into ``casadi_c``: used by
        :meth:`CompiledLibrary.radau5` (finite differences otherwise).
    constraints_fn : casadi.Function, optional
        ``<prefix>_constraints`` if it was generated into ``casadi_c`` (projection).
    rhs_lanes : str, optional
        C name of the 4-lane rhs (``codegen.lanes``) if ``casadi_c`` has it.

    Returns
    -------
    Path
        The library path.
    """
    return compile_model(casadi_c, out, driver_defines(rhs_fn, outputs_fn, jac_fn, constraints_fn,
                                                         rhs_lanes),
                         fast=fast)


def compile_model(casadi_c, out: Path | str, defines: dict, fast: bool = True,
                  objects: list[Path] = ()) -> Path:
    """Compile CasADi-generated C (one file, or a list of files: compiled in parallel) and
    link it with the driver, given the driver's macros.

    ``defines`` is ``driver_defines(...)`` (stored in a model's manifest, so a cached or
    committed C file compiles without the CasADi functions at hand). The driver's objects
    come from the object cache (``toolchain.objects``: compiled once per set of work sizes,
    whatever the sizes); only the model's C and a file giving the driver the model's sizes
    and forwarding its names to the model's functions are compiled here; ``objects`` (a
    structure's, ``codegen.structure_cache``) are linked in too.
    """
    generated = [Path(c) for c in casadi_c] if isinstance(casadi_c, (list, tuple)) else [Path(casadi_c)]
    drivers, include_dirs = _driver_inputs(fast)
    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=out.parent, prefix=f".{out.name}.links-") as tmp:
        links = Path(tmp) / "gs_links.c"
        links.write_text(object_cache.links_c(defines))
        # the driver's objects, when not cached, compile side by side with the model's C
        return compile_shared([*generated, links], out, objects=lambda: [
            *objects, *object_cache.driver_objects(drivers, defines, include_dirs)])
