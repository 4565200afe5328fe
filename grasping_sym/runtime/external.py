"""The model's compiled functions as CasADi Functions (``Model.external_rhs``), for the
integrators that run through CasADi (CVODES, IDAS)."""
from __future__ import annotations


def load(model, symbol: str):
    """The library's C function ``symbol`` as a CasADi ``external``; without a generated
    Jacobian (the manifest's ``GS_HAS_JAC`` 0) CasADi differences it: forward differences
    (nx + 1 calls) cost a quarter of its default central scheme and, for a Newton matrix, lose
    nothing measurable (benchmarks/results/paper3d.md)."""
    import casadi as ca  # noqa: PLC0415 - loading a model needs no CasADi, only cvodes/idas

    has_jac = bool(model.manifest.get("driver_defines", {}).get("GS_HAS_JAC", 1))
    opts = {} if has_jac else {"enable_fd": True, "fd_method": "forward"}
    return ca.external(symbol, str(model.library_path), opts)
