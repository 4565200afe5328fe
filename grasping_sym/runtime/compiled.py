"""Load a compiled model library (CasADi code + ``c/driver.c``) and call it fast.

Two call paths exist:

* **fast path** -- if the library was built with ``c/pyfast.c`` (see
  :func:`build_library`), it is also a CPython extension module and
  :meth:`CompiledLibrary.rhs`, ``rhs_batch``, ``outputs`` and ``outputs_batch``
  are bound directly to its ``METH_FASTCALL`` functions (about 0.3 us per call);
* **ctypes path** -- always available; used for :meth:`CompiledLibrary.rk4` and
  :meth:`CompiledLibrary.rhs_loop_ns` (which release the GIL), and as a fallback
  for the evaluation functions (a few us per call); :meth:`CompiledLibrary.radau5`
  (adaptive Radau IIA of order 5, whole loop in C), :meth:`CompiledLibrary.dopri5`
  (adaptive Dormand-Prince 5(4) with stiffness detection, whole loop in C),
  :meth:`CompiledLibrary.constraints` and :meth:`CompiledLibrary.project` also go
  through ctypes.

The three integrators can project every step onto the model's constraints (``proj_mask``,
``proj_tol``; see ``driver.c::gs_project`` and ``runtime/projection.py``).

Both paths have the same semantics: inputs are converted with
``np.ascontiguousarray(dtype=float)``, shapes are checked (``ValueError`` naming
the expected shape) and every call returns a fresh array owned by the caller.
"""
from __future__ import annotations

import ctypes
import math
import sysconfig
from collections.abc import Sequence
from importlib.machinery import ExtensionFileLoader
from importlib.util import module_from_spec, spec_from_file_location
from pathlib import Path
from time import perf_counter as _perf_counter
from typing import Any

import numpy as np

from grasping_sym.codegen.compiler import compile_shared
from grasping_sym.errors import IntegratorError

__all__ = [
    "DRIVER_SOURCES",
    "PYFAST_C",
    "CompiledLibrary",
    "build_library",
    "driver_defines",
]

_C_DIR = Path(__file__).resolve().parent.parent / "c"
#: The hand-written C driver compiled next to the CasADi-generated file (one object each).
DRIVER_SOURCES: tuple[Path, ...] = tuple(
    _C_DIR / f for f in ("driver.c", "project.c", "rk4.c", "radau5.c", "jac.c", "lu.c", "dopri5.c"))
#: The optional CPython extension giving the sub-microsecond call path.
PYFAST_C: Path = _C_DIR / "pyfast.c"

# Return codes of gs_rk4, gs_radau5, gs_dopri5 and gs_project (see driver.c).
_ERR_NONFINITE, _ERR_BOUNDS, _ERR_EVAL, _ERR_ARGS, _ERR_STEP, _ERR_MAXSTEPS = -1, -2, -3, -4, -5, -6
_ERR_PROJECT, _ERR_STIFF = -7, -8
_RK4_EXTRA_ROWS = 2
_ADAPTIVE_EXTRA_ROWS = 1
_NSTATS = 16  # GS_NSTATS
_STATS = {"radau": ("n_steps", "n_rejected", "n_rhs", "n_jac", "n_lu", "n_newton"),
          "dopri5": ("n_steps", "n_rejected", "n_rhs")}
#: Hairer's DOPRI5 default: the stiffness test runs on every 1000th accepted step.
NSTIFF = 1000

_dp = ctypes.c_void_p
_long = ctypes.c_long
_double = ctypes.c_double


def driver_defines(rhs_fn: Any, outputs_fn: Any | None = None,
                   jac_fn: Any | None = None,
                   constraints_fn: Any | None = None) -> dict[str, str | int]:
    """Preprocessor macros for ``driver.c`` from the CasADi functions used.

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
        dCdot_dx), both Jacobians dense ``nc x nx``: needed by the projection.

    Returns
    -------
    dict
        ``GS_RHS, GS_NX, GS_NP, GS_HAS_OUT, [GS_OUT, GS_NY,] GS_HAS_JAC, [GS_JAC,
        GS_JAC_NIN, GS_JAC_NOUT, GS_JAC_BLOCK,] GS_HAS_CON, [GS_CON, GS_NC,] GS_SZ_ARG,
        GS_SZ_RES, GS_SZ_IW, GS_SZ_W``; sizes are maxima over all the functions given.
    """
    fns = [rhs_fn] + [f for f in (outputs_fn, jac_fn, constraints_fn) if f is not None]
    defines: dict[str, str | int] = {
        "GS_RHS": rhs_fn.name(),
        "GS_NX": int(rhs_fn.numel_in(1)),
        "GS_NP": int(rhs_fn.numel_in(3)),
        "GS_HAS_OUT": int(outputs_fn is not None),
    }
    if outputs_fn is not None:
        if outputs_fn.numel_in(0) != defines["GS_NX"] or outputs_fn.numel_in(1) != defines["GS_NP"]:
            raise ValueError(
                f"outputs function {outputs_fn.name()!r} must take x[{defines['GS_NX']}], "
                f"p[{defines['GS_NP']}]; got x[{outputs_fn.numel_in(0)}], p[{outputs_fn.numel_in(1)}]"
            )
        defines["GS_OUT"] = outputs_fn.name()
        defines["GS_NY"] = int(outputs_fn.numel_out(0))
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
                f"dCdot_dx[nc x {nx}]) with dense Jacobians; got outputs {shapes}"
            )
        defines.update({"GS_CON": constraints_fn.name(), "GS_NC": nc})
    for key, meth in (("GS_SZ_ARG", "sz_arg"), ("GS_SZ_RES", "sz_res"), ("GS_SZ_IW", "sz_iw"), ("GS_SZ_W", "sz_w")):
        defines[key] = max(int(getattr(f, meth)()) for f in fns)
    return defines


def _python_include_dirs() -> list[str]:
    return [sysconfig.get_paths()["include"], np.get_include()]


def build_library(
    casadi_c: Path | str,
    out: Path | str,
    rhs_fn: Any,
    outputs_fn: Any | None = None,
    fast: bool = True,
    jac_fn: Any | None = None,
    constraints_fn: Any | None = None,
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

    Returns
    -------
    Path
        The library path.
    """
    return compile_model(casadi_c, out, driver_defines(rhs_fn, outputs_fn, jac_fn, constraints_fn),
                         fast=fast)


def compile_model(casadi_c: Path | str, out: Path | str, defines: dict,
                  fast: bool = True) -> Path:
    """Compile a CasADi-generated C file with the driver, given the driver's macros.

    ``defines`` is ``driver_defines(...)`` (stored in a model's manifest, so a cached or
    committed C file compiles without the CasADi functions at hand).
    """
    sources = [Path(casadi_c), *DRIVER_SOURCES] + ([PYFAST_C] if fast else [])
    include_dirs = _python_include_dirs() if fast else []
    return compile_shared(sources, Path(out), defines, include_dirs=include_dirs)


def _as_vector(a: Any, n: int, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got shape {arr.shape}")
    return arr


def _as_matrix(a: Any, n: int, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != n:
        raise ValueError(f"{name} must have shape (n, {n}), got shape {arr.shape}")
    return arr


class CompiledLibrary:
    """A compiled model: closed-loop right-hand side, outputs, constraints and integrators in C.

    Parameters
    ----------
    path : Path
        Shared library built from a CasADi file and ``driver.c`` (e.g. by
        :func:`build_library`).
    state_names : sequence of str, optional
        Names used in integrator error messages.
    use_fast : bool
        Use the CPython-extension fast path when the library contains it.

    Attributes
    ----------
    nx, np, ny, nc : int
        Number of states, parameters, outputs (``ny == -1`` without outputs) and
        constraints (``nc == -1`` without a constraints function).
    has_outputs, has_constraints : bool
    fast : bool
        True if the extension fast path is in use.

    Notes
    -----
    Every ``gs_`` function keeps its work arrays on the stack (or in
    thread-local storage), so a library may be used from several threads.
    When the fast path is active, ``rhs``, ``rhs_batch``, ``outputs`` and
    ``outputs_batch`` are instance attributes bound to C functions; they accept
    ``(x, p=None)`` exactly like the methods documented here.
    """

    def __init__(self, path: Path | str, state_names: Sequence[str] | None = None, use_fast: bool = True):
        self.path = Path(path).absolute()
        if not self.path.is_file():
            raise FileNotFoundError(f"compiled model library not found: {self.path}")
        self.state_names = list(state_names) if state_names is not None else None
        lib = ctypes.CDLL(str(self.path))
        self._lib = lib

        lib.gs_info.argtypes = [ctypes.POINTER(_long)] * 3
        lib.gs_info.restype = ctypes.c_int
        nx, npar, ny = _long(), _long(), _long()
        self.has_outputs = bool(lib.gs_info(ctypes.byref(nx), ctypes.byref(npar), ctypes.byref(ny)))
        self.nx, self.np, self.ny = nx.value, npar.value, ny.value
        if self.state_names is not None and len(self.state_names) != self.nx:
            raise ValueError(f"state_names has {len(self.state_names)} entries, the model has nx = {self.nx}")

        self._c_rhs = lib.gs_rhs
        self._c_rhs.argtypes = [_dp, _dp, _dp]
        self._c_rhs.restype = ctypes.c_int
        self._c_rhs_batch = lib.gs_rhs_batch
        self._c_rhs_batch.argtypes = [_long, _dp, _dp, _dp]
        self._c_rhs_batch.restype = ctypes.c_int
        if self.has_outputs:
            self._c_out = lib.gs_outputs
            self._c_out.argtypes = [_dp, _dp, _dp]
            self._c_out.restype = ctypes.c_int
            self._c_out_batch = lib.gs_outputs_batch
            self._c_out_batch.argtypes = [_long, _dp, _dp, _dp]
            self._c_out_batch.restype = ctypes.c_int
        self._c_rk4 = lib.gs_rk4
        self._c_rk4.argtypes = [_double, _double, _long, _long, _dp, _dp, _dp, _dp, _dp, _double,
                                _dp, _dp, ctypes.POINTER(_double)]
        self._c_rk4.restype = _long
        adaptive = [_double, _long, _dp, _dp, _dp, _double, _double, _double, _long]
        tail = [_dp, _dp, _dp, _double, _dp, _dp, ctypes.POINTER(_double)]
        self._c_radau = lib.gs_radau5
        self._c_radau.argtypes = adaptive + tail
        self._c_radau.restype = _long
        self._c_dopri = lib.gs_dopri5
        self._c_dopri.argtypes = adaptive + [_long] + tail
        self._c_dopri.restype = _long
        lib.gs_con_info.argtypes = [ctypes.POINTER(_long)]
        lib.gs_con_info.restype = ctypes.c_int
        nc = _long()
        self.has_constraints = bool(lib.gs_con_info(ctypes.byref(nc)))
        self.nc = nc.value
        if self.has_constraints:
            self._c_con = lib.gs_constraints
            self._c_con.argtypes = [_dp] * 6
            self._c_con.restype = ctypes.c_int
            self._c_project = lib.gs_project
            self._c_project.argtypes = [_dp, _dp, _dp, _double, _dp]
            self._c_project.restype = ctypes.c_int
        self._c_loop = lib.gs_rhs_loop_ns
        self._c_loop.argtypes = [_long, _dp, _dp]
        self._c_loop.restype = _double

        self.fast = False
        self._ext = None
        if use_fast and hasattr(lib, "PyInit__gs_fast"):
            self._ext = self._load_extension()
            self.rhs = self._ext.rhs  # type: ignore[method-assign]
            self.rhs_batch = self._ext.rhs_batch  # type: ignore[method-assign]
            if self.has_outputs:
                self.outputs = self._ext.outputs  # type: ignore[method-assign]
                self.outputs_batch = self._ext.outputs_batch  # type: ignore[method-assign]
            self.fast = True

    def _load_extension(self) -> Any:
        loader = ExtensionFileLoader("_gs_fast", str(self.path))
        spec = spec_from_file_location("_gs_fast", str(self.path), loader=loader)
        assert spec is not None
        module = module_from_spec(spec)  # not registered in sys.modules
        loader.exec_module(module)
        if (module.nx, module.np) != (self.nx, self.np):
            raise RuntimeError(f"{self.path}: extension and driver disagree on sizes")
        return module

    def __repr__(self) -> str:
        return (
            f"CompiledLibrary({str(self.path)!r}, nx={self.nx}, np={self.np}, "
            f"ny={self.ny}, fast={self.fast})"
        )

    # -- helpers ---------------------------------------------------------------
    def _p(self, p: Any) -> np.ndarray | None:
        if p is None:
            if self.np:
                raise ValueError(f"this model has np = {self.np} parameters: pass p of shape ({self.np},)")
            return None
        return _as_vector(p, self.np, "p")

    @staticmethod
    def _ptr(a: np.ndarray | None) -> int | None:
        return None if a is None or a.size == 0 else a.ctypes.data

    def _need_outputs(self) -> None:
        if not self.has_outputs:
            raise AttributeError(f"{self.path.name} was built without an outputs function")

    # -- evaluation ------------------------------------------------------------
    def rhs(self, x: Any, p: Any = None) -> np.ndarray:
        """Closed-loop right-hand side ``xdot = f(x, p)`` at t = 0.

        Parameters
        ----------
        x : array_like, shape (nx,)
        p : array_like, shape (np,), optional (required when np > 0)

        Returns
        -------
        numpy.ndarray, shape (nx,)
        """
        x = _as_vector(x, self.nx, "x")
        pa = self._p(p)
        out = np.empty(self.nx)
        if self._c_rhs(x.ctypes.data, self._ptr(pa), out.ctypes.data):
            raise RuntimeError("rhs: the CasADi function reported an evaluation error")
        return out

    def rhs_batch(self, X: Any, p: Any = None) -> np.ndarray:
        """Right-hand side for many states; ``X`` shape (n, nx) -> shape (n, nx)."""
        X = _as_matrix(X, self.nx, "X")
        pa = self._p(p)
        out = np.empty((X.shape[0], self.nx))
        if self._c_rhs_batch(X.shape[0], X.ctypes.data, self._ptr(pa), out.ctypes.data):
            raise RuntimeError("rhs_batch: the CasADi function reported an evaluation error")
        return out

    def outputs(self, x: Any, p: Any = None) -> np.ndarray:
        """Outputs ``y = g(x, p)``; ``x`` shape (nx,) -> shape (ny,)."""
        self._need_outputs()
        x = _as_vector(x, self.nx, "x")
        pa = self._p(p)
        out = np.empty(self.ny)
        if self._c_out(x.ctypes.data, self._ptr(pa), out.ctypes.data):
            raise RuntimeError("outputs: the CasADi function reported an evaluation error")
        return out

    def outputs_batch(self, X: Any, p: Any = None) -> np.ndarray:
        """Outputs for many states; ``X`` shape (n, nx) -> shape (n, ny)."""
        self._need_outputs()
        X = _as_matrix(X, self.nx, "X")
        pa = self._p(p)
        out = np.empty((X.shape[0], self.ny))
        if self._c_out_batch(X.shape[0], X.ctypes.data, self._ptr(pa), out.ctypes.data):
            raise RuntimeError("outputs_batch: the CasADi function reported an evaluation error")
        return out

    def rhs_loop_ns(self, x: Any, n: int = 100_000, p: Any = None) -> float:
        """Time ``n`` evaluations of the right-hand side in a C loop.

        Returns
        -------
        float
            Nanoseconds per evaluation (wall clock, CLOCK_MONOTONIC).
        """
        x = _as_vector(x, self.nx, "x")
        pa = self._p(p)
        return float(self._c_loop(int(n), x.ctypes.data, self._ptr(pa)))

    # -- integration -------------------------------------------------------------
    def rk4(
        self,
        x0: Any,
        t0: float,
        t_final: float,
        h: float,
        stride: int = 1,
        p: Any = None,
        lo: Any = None,
        hi: Any = None,
        proj_mask: Any = None,
        proj_tol: float = 0.0,
        stats: dict | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Integrate with classic fixed-step RK4, entirely in C (GIL released).

        The number of steps is rounded up to a multiple of ``stride`` so that
        the last row is exactly ``t_final``; the step actually used is
        ``(t_final - t0) / nsteps <= h``.

        Parameters
        ----------
        x0 : array_like, shape (nx,)
            Initial state at ``t0``; must be finite and within [lo, hi].
        t0, t_final : float
            Start and end time (s), ``t_final > t0``.
        h : float
            Maximum step (s), > 0.
        stride : int
            Store every ``stride``-th step.
        p : array_like, shape (np,), optional
        lo, hi : array_like, shape (nx,), optional
            Bounds checked after every step (default -inf / +inf).
        proj_mask, proj_tol
            Project every step's end onto the constraints (see :meth:`project`);
            ``proj_mask`` None: no projection.
        stats : dict, optional
            If given, filled with ``n_steps``, ``n_rhs`` and, with projection,
            ``n_constraint_evals``, ``max_drift``, ``max_drift_rate``.

        Returns
        -------
        t : numpy.ndarray, shape (m,)
            Times (s) of the stored rows, ``t[0] == t0``, ``t[-1] == t_final``.
        X : numpy.ndarray, shape (m, nx)
            States at ``t``.

        Raises
        ------
        IntegratorError
            If a state becomes non-finite (reason mentions "non-finite") or a
            component leaves its bounds (reason ``"state component <i> left
            [lo, hi]..."``).  ``err.t`` and ``err.x`` are the last good time and
            state (the failing step starts there); ``err.t_rejected``,
            ``err.x_rejected`` hold the rejected step's end, and
            ``err.trajectory`` the stored ``(t, X)`` up to ``err.t``.
        """
        x0a = _as_vector(x0, self.nx, "x0")
        pa = self._p(p)
        lo_a = np.full(self.nx, -np.inf) if lo is None else _as_vector(lo, self.nx, "lo")
        hi_a = np.full(self.nx, np.inf) if hi is None else _as_vector(hi, self.nx, "hi")
        t0, t_final, h = float(t0), float(t_final), float(h)
        stride = int(stride)
        if not (math.isfinite(t0) and math.isfinite(t_final) and t_final > t0):
            raise ValueError(f"need finite t0 < t_final, got t0 = {t0}, t_final = {t_final}")
        if not (math.isfinite(h) and h > 0):
            raise ValueError(f"step h must be finite and > 0, got {h}")
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        mask = self._mask(proj_mask, float(proj_tol))

        bad = self._violation(x0a, lo_a, hi_a)
        if bad:
            raise IntegratorError(t0, x0a, f"initial state: {bad}", self.state_names)

        nblocks = max(1, math.ceil((t_final - t0) / (h * stride) - 1e-9))
        nsteps = nblocks * stride
        h_eff = (t_final - t0) / nsteps
        rows = nblocks + 1
        out = np.empty((rows + _RK4_EXTRA_ROWS, self.nx))
        t_fail = _double(math.nan)
        stats_a = np.zeros(_NSTATS)
        rc = self._c_rk4(
            t0, h_eff, nsteps, stride, x0a.ctypes.data, self._ptr(pa),
            lo_a.ctypes.data, hi_a.ctypes.data, self._ptr(mask), float(proj_tol),
            out.ctypes.data, stats_a.ctypes.data, ctypes.byref(t_fail),
        )
        if stats is not None:
            stats.update({"n_steps": int(stats_a[0]), "n_rhs": int(stats_a[2])})
            if mask is not None:
                stats.update(_projection_stats(stats_a))
        if rc >= 0:
            if rc != rows:
                raise RuntimeError(f"gs_rk4 wrote {rc} rows, expected {rows}")
            t = t0 + h_eff * stride * np.arange(rows)
            t[-1] = t_final
            return t, out[:rows].copy()
        if rc == _ERR_ARGS:
            raise ValueError(f"gs_rk4 rejected its arguments (h = {h_eff}, nsteps = {nsteps}, stride = {stride})")

        tf = t_fail.value
        k = int(round((tf - t0) / h_eff))
        r = k // stride + 1
        x_good = out[r].copy()
        x_bad = out[r + 1].copy()
        if rc == _ERR_NONFINITE:
            idx = np.flatnonzero(~np.isfinite(x_bad)).tolist()
            reason = f"state component(s) {idx} became non-finite in the step to t = {tf + h_eff:.6g} s"
        elif rc == _ERR_BOUNDS:
            reason = self._violation(x_bad, lo_a, hi_a) + f" in the step to t = {tf + h_eff:.6g} s"
        elif rc == _ERR_EVAL:
            reason = f"the CasADi function reported an evaluation error in the step to t = {tf + h_eff:.6g} s"
        elif rc == _ERR_PROJECT:
            reason = _projection_reason(stats_a, proj_tol, f"in the step to t = {tf + h_eff:.6g} s")
        else:
            reason = f"gs_rk4 returned unknown code {rc}"
        err = IntegratorError(tf, x_good, reason, self.state_names)
        err.t_rejected = tf + h_eff  # type: ignore[attr-defined]
        err.x_rejected = x_bad  # type: ignore[attr-defined]
        err.code = int(rc)  # type: ignore[attr-defined]
        t_stored = t0 + h_eff * stride * np.arange(r)
        err.trajectory = (t_stored, out[:r].copy())  # type: ignore[attr-defined]
        raise err

    def radau5(
        self,
        x0: Any,
        t_out: Any,
        p: Any = None,
        rtol: float = 1e-6,
        atol: float = 1e-9,
        h0: float = 0.0,
        max_steps: int = 100_000,
        lo: Any = None,
        hi: Any = None,
        proj_mask: Any = None,
        proj_tol: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, dict]:
        """Integrate with adaptive Radau IIA of order 5, entirely in C (GIL released).

        A port of scipy's ``Radau`` (Hairer & Wanner, *Solving ODEs II*, IV.8):
        simplified Newton with Jacobian reuse, embedded error estimate, predictive
        step control, collocation-polynomial dense output at ``t_out``.  The
        Jacobian is the compiled ``jac_<name>_rhs`` when the library has it (see
        :func:`driver_defines`), forward differences otherwise.

        Parameters
        ----------
        x0 : array_like, shape (nx,)
            State at ``t_out[0]`` (the start time); finite and within [lo, hi].
        t_out : array_like, shape (m,), m >= 2
            Strictly increasing output times (s); integration runs from
            ``t_out[0]`` to ``t_out[-1]``.
        p : array_like, shape (np,), optional
        rtol, atol : float
            Local error tolerances (weights ``atol + rtol * |x|``, RMS norm);
            ``rtol`` below 100 machine epsilon is raised to it.
        h0 : float
            First step (s); 0 chooses it automatically (scipy's
            ``select_initial_step``).
        max_steps : int
            Maximum number of accepted steps.
        lo, hi : array_like, shape (nx,), optional
            Bounds checked at the end of every accepted step.
        proj_mask, proj_tol
            Project every accepted step's end and every output between steps onto the
            constraints (see :meth:`project`); ``proj_mask`` None: no projection.

        Returns
        -------
        t : numpy.ndarray, shape (m,)
            ``t_out`` as floats.
        X : numpy.ndarray, shape (m, nx)
            States at ``t``.
        stats : dict
            ``n_steps, n_rejected, n_rhs, n_jac, n_lu, n_newton`` (counts;
            rejected counts error-test and Newton failures; each LU of the real
            and of the complex matrix counts one), ``h_last`` and ``wall_time`` (s);
            with projection also ``n_constraint_evals``, ``max_drift`` and
            ``max_drift_rate`` (the largest max|C| and max|Cdot| found before projecting).

        Raises
        ------
        IntegratorError
            With ``err.t`` / ``err.x`` the last accepted time and state, ``err.code``
            the C return code, ``err.trajectory`` the output rows up to ``err.t``
            and, for a non-finite or out-of-bounds state or a failed projection,
            ``err.x_rejected``.
        """
        return self._adaptive("radau", x0, t_out, p, rtol, atol, h0, max_steps, lo, hi,
                              proj_mask, proj_tol)

    def dopri5(
        self,
        x0: Any,
        t_out: Any,
        p: Any = None,
        rtol: float = 1e-6,
        atol: float = 1e-9,
        h0: float = 0.0,
        max_steps: int = 100_000,
        lo: Any = None,
        hi: Any = None,
        nstiff: int = NSTIFF,
        proj_mask: Any = None,
        proj_tol: float = 0.0,
    ) -> tuple[np.ndarray, np.ndarray, dict]:
        """Integrate with adaptive Dormand-Prince 5(4), entirely in C (GIL released).

        Hairer's DOPRI5 (*Solving ODEs I*, II.5): fifth-order steps with an embedded
        fourth-order error estimate, Lund-stabilised step control, the fourth-order
        continuous extension as dense output at ``t_out``, and DOPRI5's stiffness
        detection (*Solving ODEs II*, IV.2): when ``h |lambda|`` estimated from the last
        two stages exceeds 3.25 on 15 steps (without 6 non-stiff steps in between) the
        integration stops with an ``IntegratorError`` saying the problem is stiff
        (``err.code == -8``, ``err.t`` the start of the step where it was found).

        Parameters
        ----------
        x0, t_out, p, rtol, atol, h0, max_steps, lo, hi, proj_mask, proj_tol
            As :meth:`radau5` (``h0 = 0``: the initial step for error order 4).
        nstiff : int
            The stiffness test runs on every ``nstiff``-th accepted step (and on every
            step once a stiff one was seen); ``<= 0`` turns it off.

        Returns
        -------
        t, X, stats
            As :meth:`radau5`; ``stats``: ``n_steps, n_rejected, n_rhs, h_last, wall_time``
            (and the projection entries), ``h_lambda`` (the last stiffness estimate) and
            ``n_stiff_tests`` (tests above 3.25).

        Raises
        ------
        IntegratorError
            As :meth:`radau5`, and for a stiff problem.
        """
        return self._adaptive("dopri5", x0, t_out, p, rtol, atol, h0, max_steps, lo, hi,
                              proj_mask, proj_tol, nstiff=int(nstiff))

    def _adaptive(self, method: str, x0: Any, t_out: Any, p: Any, rtol: float, atol: float,
                  h0: float, max_steps: int, lo: Any, hi: Any, proj_mask: Any,
                  proj_tol: float, nstiff: int = 0) -> tuple[np.ndarray, np.ndarray, dict]:
        x0a = _as_vector(x0, self.nx, "x0")
        pa = self._p(p)
        t_arr = np.ascontiguousarray(t_out, dtype=float)
        if t_arr.ndim != 1 or t_arr.size < 2 or not np.all(np.isfinite(t_arr)) or np.any(np.diff(t_arr) <= 0):
            raise ValueError("t_out must be a finite, strictly increasing 1-D array of at least two times")
        lo_a = np.full(self.nx, -np.inf) if lo is None else _as_vector(lo, self.nx, "lo")
        hi_a = np.full(self.nx, np.inf) if hi is None else _as_vector(hi, self.nx, "hi")
        rtol, atol, h0 = float(rtol), float(atol), float(h0)
        if not (math.isfinite(rtol) and rtol > 0 and math.isfinite(atol) and atol >= 0):
            raise ValueError(f"need finite rtol > 0 and atol >= 0, got rtol = {rtol}, atol = {atol}")
        if not (math.isfinite(h0) and h0 >= 0):
            raise ValueError(f"h0 must be finite and >= 0 (0 = automatic), got {h0}")
        max_steps = int(max_steps)
        if max_steps < 1:
            raise ValueError(f"max_steps must be >= 1, got {max_steps}")
        mask = self._mask(proj_mask, proj_tol)
        t0 = float(t_arr[0])
        bad = self._violation(x0a, lo_a, hi_a)
        if bad:
            raise IntegratorError(t0, x0a, f"initial state: {bad}", self.state_names)

        m = t_arr.size
        out = np.empty((m + _ADAPTIVE_EXTRA_ROWS, self.nx))
        stats_a = np.zeros(_NSTATS)
        t_fail = _double(math.nan)
        common = (self._ptr(pa), rtol, atol, h0, max_steps)
        tail = (lo_a.ctypes.data, hi_a.ctypes.data, self._ptr(mask), float(proj_tol),
                out.ctypes.data, stats_a.ctypes.data, ctypes.byref(t_fail))
        start = _perf_counter()
        if method == "radau":
            rc = self._c_radau(t0, m, t_arr.ctypes.data, x0a.ctypes.data, *common, *tail)
        else:
            rc = self._c_dopri(t0, m, t_arr.ctypes.data, x0a.ctypes.data, *common, nstiff, *tail)
        wall = _perf_counter() - start
        stats: dict = {k: int(stats_a[i]) for i, k in enumerate(_STATS[method])}
        stats["h_last"] = float(stats_a[7])
        stats["wall_time"] = wall
        if mask is not None:
            stats.update(_projection_stats(stats_a))
        if method == "dopri5":
            stats["h_lambda"] = float(stats_a[13])
            stats["n_stiff_tests"] = int(stats_a[14])
        c_name = "gs_radau5" if method == "radau" else "gs_dopri5"
        if rc >= 0:
            if rc != m:
                raise RuntimeError(f"{c_name} returned {rc}, expected {m}")
            return t_arr.copy(), out[:m].copy(), stats
        if rc == _ERR_ARGS:
            raise ValueError(f"{c_name} rejected its arguments (rtol = {rtol}, atol = {atol}, "
                             f"h0 = {h0}, max_steps = {max_steps}, proj_tol = {proj_tol})")
        tf = t_fail.value
        r = int(stats_a[6])
        x_good = out[r].copy()
        x_bad = out[r + 1].copy()
        after = f"after t = {tf:.6g} s"
        if rc == _ERR_NONFINITE:
            if np.all(np.isfinite(x_bad)):
                reason = (f"{method}: the right-hand side became non-finite at the end of the "
                          f"step {after} (state {x_bad.tolist()})")
            else:
                idx = np.flatnonzero(~np.isfinite(x_bad)).tolist()
                reason = f"{method}: state component(s) {idx} became non-finite in the step {after}"
        elif rc == _ERR_BOUNDS:
            reason = f"{method}: " + self._violation(x_bad, lo_a, hi_a) + f" in the step {after}"
        elif rc == _ERR_EVAL:
            reason = f"{method}: the CasADi function reported an evaluation error in the step {after}"
        elif rc == _ERR_STEP:
            why = ("Newton iteration or error test failed repeatedly" if method == "radau"
                   else "error test failed repeatedly or the right-hand side is non-finite "
                        "inside the steps")
            reason = (f"{method}: step size fell below the minimum at t = {tf:.6g} s ({why}: "
                      "a blow-up, a singularity, or tolerances too tight)")
        elif rc == _ERR_MAXSTEPS:
            reason = (f"{method}: too many steps ({max_steps}) before reaching t = {t_arr[-1]:.6g} s "
                      f"(stopped at t = {tf:.6g} s; raise max_steps or loosen rtol/atol)")
        elif rc == _ERR_PROJECT:
            reason = f"{method}: " + _projection_reason(stats_a, proj_tol, after)
        elif rc == _ERR_STIFF:
            reason = (f"dopri5: the system is stiff at t = {tf:.6g} s: the explicit method's step "
                      f"is limited by its stability, not by accuracy (h |lambda| = "
                      f"{stats_a[13]:.3g} > 3.25 on 15 steps, h = {stats_a[7]:.3g} s; DOPRI5's "
                      "stiffness test), so it would crawl: use method='radau' or 'cvodes'")
        else:
            reason = f"{method}: {c_name} returned unknown code {rc}"
        err = IntegratorError(tf, x_good, reason, self.state_names)
        err.code = int(rc)  # type: ignore[attr-defined]
        err.stats = stats  # type: ignore[attr-defined]
        if rc in (_ERR_NONFINITE, _ERR_BOUNDS, _ERR_PROJECT):
            err.x_rejected = x_bad  # type: ignore[attr-defined]
        err.trajectory = (t_arr[:r].copy(), out[:r].copy())  # type: ignore[attr-defined]
        raise err

    # -- constraints and projection -------------------------------------------------
    def _need_constraints(self) -> None:
        if not self.has_constraints:
            raise ValueError(f"{self.path.name} was built without a constraints function "
                             "(<name>_constraints): regenerate the model with this version of "
                             "grasping_sym (gs.build(scene, force=True)) to project")

    def _mask(self, proj_mask: Any, proj_tol: float) -> np.ndarray | None:
        """The projection mask as int32 (None: no projection), validated."""
        if proj_mask is None:
            return None
        self._need_constraints()
        mask = np.ascontiguousarray(proj_mask, dtype=np.int32)
        if mask.shape != (self.nx,) or not np.all(np.isin(mask, (0, 1, 2))):
            raise ValueError(f"proj_mask must have shape ({self.nx},) with entries 0 (keep), "
                             f"1 (position) or 2 (velocity); got {proj_mask!r}")
        if not (math.isfinite(proj_tol) and proj_tol > 0):
            raise ValueError(f"proj_tol must be finite and > 0 with a proj_mask, got {proj_tol}")
        return mask

    def constraints(self, x: Any, p: Any = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The generated ``<name>_constraints`` at one state.

        Returns
        -------
        C : shape (nc,)
            Position constraints (the model's length unit, m).
        dC_dx : shape (nc, nx)
        Cdot : shape (nc,)
            dC/dt along the closed loop, ``dC_dx @ rhs(x)``.
        dCdot_dx : shape (nc, nx)
        """
        self._need_constraints()
        x = _as_vector(x, self.nx, "x")
        pa = self._p(p)
        C, Cd = np.empty(self.nc), np.empty(self.nc)
        JC, JCd = np.empty((self.nx, self.nc)), np.empty((self.nx, self.nc))  # column-major
        if self._c_con(x.ctypes.data, self._ptr(pa), C.ctypes.data, JC.ctypes.data,
                       Cd.ctypes.data, JCd.ctypes.data):
            raise RuntimeError("constraints: the CasADi function reported an evaluation error")
        return C, JC.T.copy(), Cd, JCd.T.copy()

    def project(self, x: Any, proj_mask: Any, proj_tol: float, p: Any = None) -> tuple[np.ndarray, dict]:
        """Project one state onto the constraints as the integrators do after each step.

        Gauss-Newton on ``C(x) = 0`` with the least-norm change of the states with
        ``proj_mask == 1``, until ``max|C| <= proj_tol``; then on ``Cdot(x) = 0`` with the
        states with ``proj_mask == 2``, until ``max|Cdot| <= proj_tol``; states with
        ``proj_mask == 0`` are not changed.

        Returns
        -------
        x : numpy.ndarray, shape (nx,)
            The projected state (a new array).
        stats : dict
            ``n_constraint_evals``, ``max_drift`` (max|C| before), ``max_drift_rate``
            (max|Cdot| at the projected positions, before the velocity step).

        Raises
        ------
        IntegratorError
            The projection did not converge (``err.code == -7``).
        """
        xa = _as_vector(x, self.nx, "x").copy()
        pa = self._p(p)
        mask = self._mask(proj_mask, float(proj_tol))
        stats_a = np.zeros(_NSTATS)
        rc = self._c_project(xa.ctypes.data, self._ptr(pa), mask.ctypes.data, float(proj_tol),
                             stats_a.ctypes.data)
        if rc == _ERR_PROJECT:
            err = IntegratorError(math.nan, xa, _projection_reason(stats_a, proj_tol, ""),
                                  self.state_names)
            err.code = int(rc)  # type: ignore[attr-defined]
            raise err
        if rc:
            raise RuntimeError(f"gs_project returned {rc}")
        return xa, _projection_stats(stats_a)

    @staticmethod
    def _violation(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> str:
        """Empty string if ``x`` is finite and in bounds, else the reason."""
        nonfinite = np.flatnonzero(~np.isfinite(x))
        if nonfinite.size:
            return f"state component(s) {nonfinite.tolist()} are non-finite"
        out = np.flatnonzero((x < lo) | (x > hi))
        if out.size:
            i = int(out[0])
            return f"state component {i} left [{lo[i]:g}, {hi[i]:g}] (value {x[i]:.6g})"
        return ""


def _projection_stats(stats_a: np.ndarray) -> dict:
    return {"n_constraint_evals": int(stats_a[8]), "max_drift": float(stats_a[9]),
            "max_drift_rate": float(stats_a[10])}


def _projection_reason(stats_a: np.ndarray, tol: float, after: str) -> str:
    what = ("the position constraints C" if stats_a[11] == 1
            else "the velocity constraints Cdot")
    where = f" {after}" if after else ""
    return (f"the projection onto {what} failed{where}: max residual {stats_a[12]:.3g} > "
            f"tolerance {tol:.3g} after Gauss-Newton (not converging, a singular constraint "
            "Jacobian, or non-finite values): the contact configuration is singular, or the "
            "tolerance is below the rounding level of the constraints (use a larger "
            "projection tolerance, e.g. simulate(..., project=1e-10))")
