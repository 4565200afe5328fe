"""Load a compiled model library (CasADi code + the C driver in ``c/``, built by
``toolchain/library.py``) and call it fast.

Two call paths exist:

* **fast path** -- if the library was built with ``c/pyfast.c``, it is also a CPython
  extension module: :meth:`CompiledLibrary.rhs`, ``rhs_batch``, ``outputs`` and
  ``outputs_batch`` are bound directly to its ``METH_FASTCALL`` functions (about 0.3 us per
  call), and :meth:`CompiledLibrary.radau5` / :meth:`CompiledLibrary.dopri5` /
  :meth:`CompiledLibrary.dop853` call the C loop
  through it (about 1 us of call overhead instead of ctypes' ~8 us);
* **ctypes path** -- always available; used for :meth:`CompiledLibrary.rk4`,
  :meth:`CompiledLibrary.constraints` and
  :meth:`CompiledLibrary.project`, and as the fallback of everything else.

The integrators (whole loop in C, GIL released; argument checks and error translation in
``runtime/c_loops.py``) can project every step onto the model's constraints (``proj_mask``,
``proj_tol``; see ``c/project.c::gs_project`` and ``runtime/projection.py``).

Both paths have the same semantics: inputs are converted with
``np.ascontiguousarray(dtype=float)``, shapes are checked (``ValueError`` naming
the expected shape) and every call returns a fresh array owned by the caller.
"""
from __future__ import annotations

import contextlib
import ctypes
import math
import threading
from collections.abc import Sequence
from importlib.machinery import ExtensionFileLoader
from importlib.util import module_from_spec, spec_from_file_location
from pathlib import Path
from typing import Any

import numpy as np

from grasping_sym.errors import IntegratorError
from grasping_sym.runtime import c_loops, interrupt
from grasping_sym.runtime.c_loops import NSTIFF, as_vector

#: The wraps one loop records (``CompiledLibrary.wrapping``): past them it stops at the bound,
#: where ``runtime.atlas`` wraps the coordinates as it does the charts' changes.
WRAP_CAPACITY = 256
#: The columns of a slot's row in ``c/wrap.c`` (``runtime.atlas``'s ``_wrap_slot``): a library
#: whose rows differ (an older version's) wraps nothing, its loops stop at the bound.
WRAP_COLS = 16

__all__ = ["NSTIFF", "CompiledLibrary"]

_dp = ctypes.c_void_p
_long = ctypes.c_long
_double = ctypes.c_double


def _as_matrix(a: Any, n: int, name: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != n:
        raise ValueError(f"{name} must have shape (n, {n}), got shape {arr.shape}")
    return arr


def _with_default_p(fn, default_p):
    """The extension's ``fn(x, p=None)`` with ``default_p`` where no ``p`` is given (the bare
    extension function when there is no default)."""
    if default_p is None:
        return fn

    def call(x, p=None):
        return fn(x, default_p if p is None else p)

    call.__doc__ = fn.__doc__
    return call


class CompiledLibrary:
    """A compiled model: closed-loop right-hand side, outputs, constraints and integrators in C.

    Parameters
    ----------
    path : Path
        Shared library built from a CasADi file and the C driver (e.g. by
        :func:`grasping_sym.toolchain.library.build_library`).
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

    def __init__(self, path: Path | str, state_names: Sequence[str] | None = None, use_fast: bool = True,
                 default_p: Any = None):
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
        self._c_dop853 = lib.gs_dop853
        self._c_dop853.argtypes = adaptive + [_long] + tail
        self._c_dop853.restype = _long
        self._c_batch = getattr(lib, "gs_batch", None)  # (libraries of older versions lack it)
        if self._c_batch is not None:
            self._c_batch.argtypes = ([ctypes.c_int, _long, _long, _long, _dp, _double, _long, _long,
                                       _dp, _dp, _long, _double, _double, _double, _long, _long,
                                       _dp, _dp, _dp, _double, _double, ctypes.c_int]
                                      + [_dp] * 7)
            self._c_batch.restype = _long
        # the SUNDIALS step budget (c/budget.c; libraries of older versions lack it)
        self.has_budget = hasattr(lib, "gs_step_budget")
        if self.has_budget:
            lib.gs_budget_begin.argtypes = [ctypes.c_longlong]
            lib.gs_budget_begin.restype = None
            lib.gs_budget_count.restype = ctypes.c_longlong
            lib.gs_budget_hit.restype = ctypes.c_int
            lib.gs_budget_last_t.restype = _double
        lib.gs_set_time_limit.argtypes = [_double]
        lib.gs_set_time_limit.restype = None
        lib.gs_stop_cause.restype = ctypes.c_int
        if hasattr(lib, "gs_stop_bind"):  # Ctrl-C stops the C loops: one owner (c/stop.c)
            interrupt.bind(lib)
        self.can_watch = hasattr(lib, "gs_watch_witnesses")  # (libraries of older versions lack it)
        # (c/wrap.c; libraries of older versions lack it, or read rows of other columns)
        self.can_wrap = hasattr(lib, "gs_wrap_cols")
        if self.can_wrap:
            lib.gs_wrap_cols.restype = _long
            self.can_wrap = int(lib.gs_wrap_cols()) == WRAP_COLS
        if self.can_wrap:
            lib.gs_wrap_set.argtypes = [_long, _dp, _dp, _long]
            lib.gs_wrap_set.restype = ctypes.c_int
            lib.gs_wrap_count.restype = _long
        #: ``watch``'s arguments to the C call, per its arguments (a run's segments repeat them)
        self._watched: dict = {}
        if hasattr(lib, "gs_rows"):  # a helper function at many rows (``rows``)
            lib.gs_rows.argtypes = [_dp, _long, _dp, _long, _dp, _dp, _long, _dp, _dp, _dp, _dp]
            lib.gs_rows.restype = ctypes.c_int
        if self.can_watch:
            lib.gs_watch_witnesses.argtypes = [_long, _dp, _dp, _dp, _dp, _dp, _dp, _long, _long, _double, _double]
            lib.gs_watch_witnesses.restype = ctypes.c_int
            lib.gs_watch_clear.restype = None
            lib.gs_watch_resume.restype = None
            lib.gs_watch_result.argtypes = [_dp]
            lib.gs_watch_result.restype = None
            lib.gs_watch_refine.argtypes = [ctypes.c_int, _dp, _dp, _double, _double, _long, _dp, _dp,
                                            _double, _long, _dp, _dp, _dp]
            lib.gs_watch_refine.restype = ctypes.c_int
        # the run-time checks' watch (runtime.watch): libraries of older versions lack it
        self.can_watch_batch = hasattr(lib, "gs_watch_batch") and hasattr(lib, "gs_watch_span")
        if self.can_watch_batch:
            lib.gs_watch_batch.argtypes = [_long, _dp, _dp, _dp, _long, _dp, _dp, _dp, _long, _long, _double,
                                           _double, _double]
            lib.gs_watch_span.argtypes = [_double]
            lib.gs_watch_span.restype = ctypes.c_int
            lib.gs_watch_batch.restype = ctypes.c_int
            lib.gs_watch_batch_cancel.restype = None
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

        #: ``p`` used when a call passes none (the model's run-time and start values)
        self.default_p = None if default_p is None else as_vector(default_p, self.np, "default_p")
        self.fast = False
        self._ext = None
        self._mask_checked: np.ndarray | None = None
        if use_fast and hasattr(lib, "PyInit__gs_fast"):
            self._ext = self._load_extension()
            names = ["rhs", "rhs_batch"] + (["outputs", "outputs_batch"] if self.has_outputs else [])
            for name in names:
                setattr(self, name, _with_default_p(getattr(self._ext, name), self.default_p))
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
        if p is None and self.default_p is not None:
            return self.default_p
        if p is None:
            if self.np:
                raise ValueError(f"this model has np = {self.np} parameters: pass p of shape ({self.np},)")
            return None
        return as_vector(p, self.np, "p")

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
        x = as_vector(x, self.nx, "x")
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
        x = as_vector(x, self.nx, "x")
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

    # -- the SUNDIALS step budget (c/budget.c) -------------------------------------
    def budget_begin(self, limit: int) -> None:
        """This thread's next SUNDIALS run may attempt ``limit`` steps in total (0: no limit)."""
        if self.has_budget:
            self._lib.gs_budget_begin(int(limit))

    def budget_hit(self) -> int:
        """What stopped this thread's last SUNDIALS run in the budget: 0 nothing, 1 its step
        limit, 2 Ctrl-C or the wall-time limit (``gs_stop_cause`` says which)."""
        return int(self._lib.gs_budget_hit()) if self.has_budget else 0

    def budget_last_t(self) -> float:
        """The time of the last step attempt the budget counted."""
        return float(self._lib.gs_budget_last_t()) if self.has_budget else math.nan

    def budget_count(self) -> int:
        """The step attempts counted since ``budget_begin`` (-1 without the budget)."""
        return int(self._lib.gs_budget_count()) if self.has_budget else -1

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
        time_limit: float | None = None,
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
            component leaves its bounds (reason ``"<name> = <value> left
            [lo, hi]"``).  ``err.t`` and ``err.x`` are the last good time and
            state (the failing step starts there); ``err.t_rejected``,
            ``err.x_rejected`` hold the rejected step's end, and
            ``err.trajectory`` the stored ``(t, X)`` up to ``err.t``.
        """
        return c_loops.rk4(self, x0, t0, t_final, h, stride, p, lo, hi, proj_mask, proj_tol, stats,
                           time_limit)

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
        time_limit: float | None = None,
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
            ``select_initial_step`` without its cap at 100 explicit-Euler probes, which
            starts a system at rest with steps of ~1e-8 s; see ``c/gs_internal.h``).
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
            and of the complex matrix counts one), ``h_last`` and ``wall_time`` (s),
            ``second_order_rows`` (the last Jacobian's rows ``x_i' = x_{i+m}``, m of them,
            by which the linear systems were reduced: Hairer's M1 = M2, ``c/radau5.c``);
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
        return c_loops.adaptive(self, "radau", x0, t_out, p, rtol, atol, h0, max_steps, lo, hi,
                                proj_mask, proj_tol, time_limit=time_limit)

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
        time_limit: float | None = None,
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
        return c_loops.adaptive(self, "dopri5", x0, t_out, p, rtol, atol, h0, max_steps, lo,
                                hi, proj_mask, proj_tol, nstiff=int(nstiff), time_limit=time_limit)

    def dop853(
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
        time_limit: float | None = None,
    ) -> tuple[np.ndarray, np.ndarray, dict]:
        """Integrate with adaptive Dormand-Prince 8(5,3), entirely in C (GIL released).

        Hairer's DOP853 (*Solving ODEs I*, II.5 and II.10): eighth-order steps of 12 stages,
        an error estimate from embedded solutions of orders 5 and 3, the seventh-order
        continuous extension at ``t_out`` (three more evaluations, made only for a step with
        an output time inside it) and DOP853's stiffness detection (``h |lambda|`` above 6.1
        on 15 steps stops the run, as :meth:`dopri5` does above 3.25). Fewer steps than
        :meth:`dopri5` at tight tolerances, twice the evaluations per step.

        Parameters, returns and errors as :meth:`dopri5` (``h0 = 0``: the initial step for
        error order 7; ``n_stiff_tests`` counts the tests above 6.1).
        """
        return c_loops.adaptive(self, "dop853", x0, t_out, p, rtol, atol, h0, max_steps, lo,
                                hi, proj_mask, proj_tol, nstiff=int(nstiff), time_limit=time_limit)

    def _call_adaptive(self, method: str, t_arr: np.ndarray, x0: np.ndarray, p: np.ndarray | None,
                       rtol: float, atol: float, h0: float, max_steps: int, nstiff: int,
                       lo: np.ndarray | None, hi: np.ndarray | None, mask: np.ndarray | None,
                       proj_tol: float, out: np.ndarray, stats: np.ndarray) -> tuple[int, float]:
        """Run gs_radau5 / gs_dopri5 / gs_dop853 on checked, contiguous arrays: ``(rc, t_fail)``."""
        if self._ext is not None:
            return self._ext.adaptive(c_loops.ADAPTIVE_CODES[method], t_arr, x0, p, rtol, atol, h0,
                                      max_steps, nstiff, lo, hi, mask, proj_tol, out, stats)
        t_fail = _double(math.nan)
        head = (float(t_arr[0]), t_arr.size, t_arr.ctypes.data, x0.ctypes.data, self._ptr(p),
                rtol, atol, h0, max_steps)
        tail = (self._ptr(lo), self._ptr(hi), self._ptr(mask), proj_tol, out.ctypes.data,
                stats.ctypes.data, ctypes.byref(t_fail))
        if method == "radau":
            rc = self._c_radau(*head, *tail)
        elif method == "dopri5":
            rc = self._c_dopri(*head, nstiff, *tail)
        else:
            rc = self._c_dop853(*head, nstiff, *tail)
        return int(rc), t_fail.value

    # -- further CasADi-generated functions ------------------------------------------------
    def _casadi_signature(self, symbol: str) -> tuple:
        """``(address, n_x, n_p, n_out, work sizes)`` of the library's CasADi-generated
        ``symbol`` of two dense inputs ``(x, p)`` and one dense output (CasADi's C interface,
        casadi_int as emit/cwriter.py writes it: ``long long``)."""
        ci = ctypes.c_longlong
        sizes = []
        for kind in ("in", "in", "out"):
            sparsity = getattr(self._lib, f"{symbol}_sparsity_{kind}")
            sparsity.restype, sparsity.argtypes = ctypes.POINTER(ci), [ci]
            shape = sparsity(len(sizes) if kind == "in" else 0)
            sizes.append(int(shape[0]) * int(shape[1]))
        sz = [ci() for _ in range(4)]
        getattr(self._lib, symbol + "_work")(*map(ctypes.byref, sz))
        work = (max(int(sz[0].value), 2), max(int(sz[1].value), 1), max(int(sz[2].value), 1),
                max(int(sz[3].value), 1))
        return ctypes.cast(getattr(self._lib, symbol), ctypes.c_void_p).value, *sizes, work

    def function(self, symbol: str):
        """The library's CasADi-generated function ``symbol`` of two dense inputs ``(x, p)``
        (``nx`` and ``len(p)`` entries) and one dense output, as ``f(x, p) -> ndarray``
        called through ctypes (no CasADi loaded). Each thread's CasADi work arrays are made at
        its first call and kept (a switch of contact modes calls it once, from cold caches:
        making them each time was half its cost)."""
        addr, n_x, n_p, n_out, (sz_arg, sz_res, sz_iw, sz_w) = self._casadi_signature(symbol)
        lib, local = self._lib, threading.local()

        def call(x, p) -> np.ndarray:
            xa = np.ascontiguousarray(x, dtype=float)
            pa = np.ascontiguousarray(p, dtype=float)
            if xa.shape != (n_x,) or pa.shape != (n_p,):
                raise ValueError(f"{symbol} takes x of {n_x} and p of {n_p} entries, got shapes "
                                 f"{xa.shape} and {pa.shape}")
            work = getattr(local, "work", None)
            if work is None:
                kept = ((ctypes.c_void_p * sz_arg)(), (ctypes.c_void_p * sz_res)(),
                        np.zeros(sz_iw, dtype=np.int64), np.zeros(sz_w))
                work = local.work = (ctypes.addressof(kept[0]), ctypes.addressof(kept[1]),
                                     kept[2].ctypes.data, kept[3].ctypes.data, kept)
            y = np.empty(n_out)
            if lib.gs_rows(addr, 1, xa.ctypes.data, n_x, pa.ctypes.data, y.ctypes.data, n_out, *work[:4]):
                raise FloatingPointError(f"{symbol} failed at the state {xa.tolist()!r:.200}")
            return y

        return call

    def rows(self, symbol: str):
        """``function(symbol)`` at every row of ``X``: ``f(X, p) -> Y`` (``gs_rows``, one C call)."""
        addr, n_x, n_p, n_out, (sz_arg, sz_res, sz_iw, sz_w) = self._casadi_signature(symbol)
        lib = self._lib

        def call(X, p) -> np.ndarray:
            Xa = np.ascontiguousarray(X, dtype=float)
            pa = np.ascontiguousarray(p, dtype=float)
            if Xa.ndim != 2 or Xa.shape[1] != n_x or pa.shape != (n_p,):
                raise ValueError(f"{symbol} takes rows of x of {n_x} and p of {n_p} entries, got shapes "
                                 f"{Xa.shape} and {pa.shape}")
            Y = np.empty((len(Xa), n_out))
            arg, res = (ctypes.c_void_p * sz_arg)(), (ctypes.c_void_p * sz_res)()
            iw, w = np.zeros(sz_iw, dtype=np.int64), np.zeros(sz_w)
            if lib.gs_rows(addr, len(Xa), Xa.ctypes.data, n_x, pa.ctypes.data, Y.ctypes.data, n_out,
                           ctypes.addressof(arg), ctypes.addressof(res), iw.ctypes.data, w.ctypes.data):
                raise FloatingPointError(f"{symbol} failed at one of the states {Xa.tolist()!r:.200}")
            return Y

        return call

    # -- witnesses watched along a run (c/watch.c) ---------------------------------------
    def watch(self, terms: Sequence[Sequence[tuple]], tol: Sequence[float],
              inputs: tuple[int, int] = (0, 0), dt: float = 0.0, probe: Sequence[bool] = (),
              safety: float = 0.0, span: float | None = None) -> None:
        """Watch witnesses in this thread's next radau5 / dopri5 / dop853 runs until
        :meth:`unwatch`: witness k is ``sum(c * y[i] for i, c in terms[k])`` over the compiled
        outputs ``y``, less ``sqrt(sum((c * y[i])**2))`` over its terms given as
        ``(i, c, True)`` (the norm's: a cone's ``|F_t|``); an armed witness (once > ``tol[k]``)
        reaching <= 0, or, when ``tol[k] > 0``, an unarmed one below ``-tol[k]``, stops the
        run at its event, located on the dense output (the run's ``stats["event"]``: ``t``,
        ``x`` there, ``x_step`` its step's start; :meth:`watch_result` the rest). ``inputs``:
        ``(k, m)``, the inputs' ``(a, b)`` at ``p[k:k + 2m]``, taken at each watched time;
        watched points at most ``dt`` apart; ``probe[k]``: an unarmed witness k's firing
        interval is probed on the dense output for a time it was above ``tol[k]`` (default
        none). ``safety`` > 0:
        a step's end is left unwatched while every witness, at ``safety`` times its last
        rate, would still be above 0 there (``c/watch.c``); 0: every step's end is watched.
        ``span``: the longest time a point may be left after the last watched one (None: 16
        ``dt``; 0: no bound but the prediction's, ``gs_watch_span``)."""
        if not self.can_watch:
            raise RuntimeError(f"{self.path} has no gs_watch_witnesses: rebuild the model")
        key = (tuple(tuple(t) for t in terms), tuple(tol), tuple(inputs), dt, tuple(probe), safety)
        args = self._watched.get(key)
        if args is None:
            if len(self._watched) >= 64:  # a sliding contact's witnesses change with its direction
                self._watched.clear()
            args = self._watched[key] = self._watch_args(terms, tol, inputs, dt, probe, safety)
        rc = self._lib.gs_watch_witnesses(*args[0])
        if not rc and span is not None:
            rc = self._lib.gs_watch_span(float(span)) if self.can_watch_batch else 1
        if rc:
            raise ValueError(f"gs_watch_witnesses refused {len(terms)} witnesses (terms {list(terms)!r:.200}, "
                             f"tol {list(tol)}, inputs {inputs}, dt {dt}, safety {safety}): at "
                             "most 64 witnesses of 512 terms in all, indices of the outputs, finite "
                             "numbers, dt and safety >= 0")

    @staticmethod
    def _watch_args(terms, tol, inputs, dt, probe, safety) -> tuple:
        """``gs_watch_witnesses``' arguments for ``watch``'s, and the arrays they point into."""
        ptr = np.zeros(len(terms) + 1, dtype=np.int64)
        ptr[1:] = np.cumsum([len(t) for t in terms])
        flat = [term for t in terms for term in t]
        idx = np.array([term[0] for term in flat] or [0], dtype=np.int64)
        coef = np.array([term[1] for term in flat] or [0.0], dtype=float)
        norm = np.array([int(len(term) > 2 and bool(term[2])) for term in flat] or [0], dtype=np.int64)
        tols = np.ascontiguousarray(tol if len(tol) else [0.0], dtype=float)
        probes = np.array([int(bool(v)) for v in probe] + [0] * (len(terms) - len(probe)) or [0], dtype=np.int64)
        arrays = (ptr, idx, coef, norm, tols, probes)
        return (len(terms), *(a.ctypes.data for a in arrays), int(inputs[0]), int(inputs[1]), float(dt),
                float(safety)), arrays

    def _watch_batch(self, n: int, terms, coef: np.ndarray, inputs: tuple[int, int], dt: float,
                     safety: float, span: float) -> tuple:
        """``gs_watch_batch``: every run of this thread's next ``gs_batch`` watches the witnesses
        ``terms`` (as :meth:`watch` takes them, the coefficients of run i ``coef[i]``, ``(n,
        n_terms)``; ``tol`` 0; ``span`` as :meth:`watch`'s); the arrays the C code reads, to keep
        until the batch returns."""
        if not self.can_watch_batch:
            raise RuntimeError(f"{self.path} has no gs_watch_batch: rebuild the model")
        coef = np.ascontiguousarray(coef, dtype=float)
        args, arrays = self._watch_args(terms, [0.0] * len(terms), inputs, dt, (), safety)
        if coef.shape != (n, len(arrays[2])) or not np.all(np.isfinite(coef)):
            raise ValueError(f"watched coefficients of shape {coef.shape}: expected ({n}, {len(arrays[2])}), finite")
        ptr, idx, _, norm, tols, probes = arrays
        rc = self._lib.gs_watch_batch(len(terms), ptr.ctypes.data, idx.ctypes.data, coef.ctypes.data,
                                      coef.shape[1], norm.ctypes.data, tols.ctypes.data, probes.ctypes.data,
                                      int(inputs[0]), int(inputs[1]), float(dt), float(safety), float(span))
        if rc:
            raise ValueError(f"gs_watch_batch refused {len(terms)} witnesses (terms {list(terms)!r:.200})")
        return args, arrays, coef

    def watch_resume(self) -> None:
        """The next run continues the last watched one (a piece of a table of inputs): its
        witnesses keep what they were armed by."""
        self._lib.gs_watch_resume()

    def wrapping(self, slots: np.ndarray | None, into: list):
        """Around this thread's radau5 / dopri5 / dop853 loops: a contact's coordinates that
        reach their bound are wrapped a period round at the step, in the loop (``c/wrap.c``;
        ``slots``: ``runtime.atlas.Atlases.wrap_slots``, None: nothing is wrapped), or their
        chart changed where a slot allows it; on exit, whatever the loops raised, each one's
        ``(t, slot, u, v, u', v', chart, chart', delta)`` is appended to ``into``. A library of
        an older version wraps nothing (its loops stop at the bound). Nothing to wrap: a null
        context (a run calls this around every piece of a table of inputs)."""
        if slots is None or not self.can_wrap:
            return contextlib.nullcontext()
        return self._wrapping(slots, into)

    @contextlib.contextmanager
    def _wrapping(self, slots: np.ndarray, into: list):
        slots = np.ascontiguousarray(slots, dtype=float)
        if slots.ndim != 2 or slots.shape[1] != WRAP_COLS:
            raise ValueError(f"wrapping: slots of shape {slots.shape}, expected (n, {WRAP_COLS}) "
                             "(runtime.atlas.Atlases.wrap_slots)")
        records = np.empty((WRAP_CAPACITY, 9))
        if self._lib.gs_wrap_set(len(slots), slots.ctypes.data, records.ctypes.data, WRAP_CAPACITY):
            raise ValueError(f"gs_wrap_set refused the slots {slots.tolist()!r:.300}")
        try:
            yield
        finally:
            into.extend(records[:int(self._lib.gs_wrap_count())].tolist())
            self._lib.gs_wrap_set(0, None, None, 0)

    def unwatch(self) -> None:
        """Stop watching (:meth:`watch`)."""
        if self.can_watch:
            self._lib.gs_watch_clear()

    def watch_result(self) -> dict:
        """The last event of this thread's watched run: ``which`` witness (-1: none), ``armed``
        (else it fell below ``-tol``), the watched points ``t_lo``, ``t_hi`` around it,
        the dense output's ``slope`` of the witness there, ``t_step`` its step's start; the
        points ``watched`` and those ``left`` unwatched since :meth:`watch`; the witnesses
        ``fired`` at the end of the event's step when it was left unwatched (else 0)."""
        out = np.zeros(9)
        self._lib.gs_watch_result(out.ctypes.data)
        return {"which": int(out[0]), "armed": bool(out[1]), "t_lo": float(out[2]),
                "t_hi": float(out[3]), "slope": float(out[4]), "t_step": float(out[5]),
                "watched": int(out[6]), "left": int(out[7]), "fired": int(out[8])}

    def watch_refine(self, method: str, x_step: Any, p: Any, rtol: float, atol: float, max_steps: int,
                     lo: np.ndarray | None, hi: np.ndarray | None, ttol: float,
                     steps: int) -> tuple[float, np.ndarray, float] | None:
        """The last watched event located on the trajectory integrated again from its step's
        start (state ``x_step``) by the run's loop (``method``, ``p``, tolerances, bounds):
        secant steps from the dense output's root, each trial one step from the step's start,
        stopped when the next would be below ``ttol`` s (``gs_watch_refine``; what
        ``runtime.events.refine`` does, in C). ``(t, x)``, or None when ``steps`` secant steps
        do not converge, the sign change is not there, or an integration fails (the caller
        takes the slower way); ``(t, x, g)`` with ``g`` the witness there less its level (0
        armed, ``-tol`` not)."""
        x0 = c_loops.as_vector(x_step, self.nx, "x_step")
        pa = self._p(p)
        t, g = _double(math.nan), _double(math.nan)
        x = np.empty(self.nx)
        rc = self._lib.gs_watch_refine(c_loops.ADAPTIVE_CODES[method], x0.ctypes.data, self._ptr(pa),
                                       float(rtol), float(atol), int(max_steps), self._ptr(lo), self._ptr(hi),
                                       float(ttol), int(steps), ctypes.byref(t), x.ctypes.data, ctypes.byref(g))
        return (t.value, x, g.value) if rc == 0 else None

    # -- constraints and projection -------------------------------------------------
    def batch(self, method: str, t_out: np.ndarray, X0: np.ndarray, P: np.ndarray | None, *,
              threads: int, rtol: float = 0.0, atol: float = 0.0, h0: float = 0.0,
              max_steps: int = 1, nstiff: int = 0, rk4: tuple[float, int, int] | None = None,
              lo: np.ndarray | None = None, hi: np.ndarray | None = None,
              proj_mask: np.ndarray | None = None, proj_tol: float = 0.0,
              time_limit: float | None = None, keep: bool = False, outputs: bool = False,
              initial: bool = False, initial_outputs: bool = True, watch: tuple | None = None) -> dict:
        """``gs_batch`` (``c/batch.c``): one run per row of ``X0`` (shape ``(N, nx)``) with the
        parameters ``P`` (``(N, np)``, one row per run), over the common
        output times ``t_out``, on ``threads`` threads with the GIL released: each run is the
        single loop's (``radau5``, ``dopri5``, ``dop853``, ``rk4``) call with the same arguments, bit for bit.

        The arguments are expected already validated (``runtime.batch`` does that); returned:
        ``X`` (``(N, m, nx)`` with ``keep``, else the final states ``(N, nx)``; NaN after a
        failure), ``Y`` (the outputs there, with ``outputs``), ``Y0`` and ``CD0`` (the outputs
        and max|Cdot| at ``X0``, with ``initial``; the outputs not with ``initial_outputs``
        False), ``status`` (each loop's return value),
        ``t_fail``, ``stats`` (``(N, NSTATS)``) and ``rc`` (runs that succeeded, or an error
        code). Ctrl-C raises ``interrupt.interrupted``'s exception, KeyboardInterrupt unless the
        process's SIGINT handler is the user's (carrying what finished as ``.batch``)."""
        if self._c_batch is None:
            raise RuntimeError(f"{self.path.name} has no gs_batch (built by an older grasping_sym): "
                               "rebuild the model with gs.build(scene, force=True)")
        n, m = X0.shape[0], t_out.shape[0]
        rows = (n, m) if keep else (n,)
        res = {"X": np.empty((*rows, self.nx)), "status": np.zeros(n, dtype=np.int64),
               "t_fail": np.empty(n), "stats": np.empty((n, c_loops.NSTATS))}
        if outputs:
            self._need_outputs()
            res["Y"] = np.empty((*rows, self.ny))
        if initial:  # (initial_outputs False: a law reading the time, its outputs need t)
            res["Y0"] = np.empty((n, self.ny)) if self.has_outputs and initial_outputs else None
            res["CD0"] = np.empty(n) if self.has_constraints else None
        h, nsteps, stride = rk4 or (0.0, 0, 0)
        code = {"radau": 0, "dopri5": 1, "rk4": 2, "dop853": 3}[method]
        held = None if watch is None or not n else self._watch_batch(n, *watch)  # alive until it returns
        try:
            with c_loops.stoppable(self, None):
                rc = self._c_batch(
                    code, int(threads), n, m, t_out.ctypes.data, float(h), int(nsteps), int(stride),
                    X0.ctypes.data, self._ptr(P), 0 if P is None else self.np, float(rtol),
                    float(atol), float(h0), int(max_steps), int(nstiff), self._ptr(lo), self._ptr(hi),
                    self._ptr(proj_mask), float(proj_tol), float(time_limit or 0.0), int(keep),
                    res["X"].ctypes.data, self._ptr(res.get("Y")), self._ptr(res.get("Y0")), self._ptr(res.get("CD0")),
                    res["status"].ctypes.data, res["t_fail"].ctypes.data, res["stats"].ctypes.data)
        finally:
            if held is not None:
                self._lib.gs_watch_batch_cancel()  # (taken by gs_batch when it ran)
        res["rc"] = int(rc)
        del held
        if rc == c_loops.ERR_INTERRUPT and self._lib.gs_stop_cause() == 1:
            err = interrupt.interrupted(f"simulate_many stopped by Ctrl-C ({int(np.sum(res['status'] == m))} "
                                        f"of {n} runs had finished)")
            err.batch = res  # type: ignore[attr-defined]
            raise err
        if rc == c_loops.ERR_ARGS:
            raise ValueError(f"gs_batch rejected its arguments (method {method!r}, {n} runs, "
                             f"{m} output times, threads = {threads})")
        return res

    def _need_constraints(self) -> None:
        if not self.has_constraints:
            raise ValueError(f"{self.path.name} was built without a constraints function "
                             "(<name>_constraints): regenerate the model with this version of "
                             "grasping_sym (gs.build(scene, force=True)) to project")

    def _mask(self, proj_mask: Any, proj_tol: float) -> np.ndarray | None:
        """The projection mask as int32 (None: no projection), validated."""
        if proj_mask is None:
            return None
        if proj_mask is self._mask_checked and math.isfinite(proj_tol) and proj_tol != 0:
            return proj_mask  # the int32 array validated last time (models reuse theirs)
        self._need_constraints()
        mask = np.ascontiguousarray(proj_mask, dtype=np.int32)
        if mask.shape != (self.nx,) or not np.all((mask >= 0) & (mask <= 2)):
            raise ValueError(f"proj_mask must have shape ({self.nx},) with entries 0 (keep), "
                             f"1 (position) or 2 (velocity); got {proj_mask!r}")
        if not (math.isfinite(proj_tol) and proj_tol != 0):
            raise ValueError(f"proj_tol must be finite and not 0 with a proj_mask (< 0: the steps "
                             f"only, to -proj_tol), got {proj_tol}")
        self._mask_checked = mask
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
        dCdot_dv : shape (nc, nx)
            The columns of dCdot/dx for the velocity states (the manifest's
            ``constraints["velocity_states"]``), zero elsewhere.
        """
        self._need_constraints()
        x = as_vector(x, self.nx, "x")
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
        xa = as_vector(x, self.nx, "x").copy()
        pa = self._p(p)
        if not (math.isfinite(proj_tol) and proj_tol > 0):
            raise ValueError(f"proj_tol must be finite and > 0, got {proj_tol}")
        mask = self._mask(proj_mask, float(proj_tol))
        stats_a = np.zeros(c_loops.NSTATS)
        rc = self._c_project(xa.ctypes.data, self._ptr(pa), mask.ctypes.data, float(proj_tol),
                             stats_a.ctypes.data)
        if rc == c_loops.ERR_PROJECT:
            err = IntegratorError(math.nan, xa, c_loops.projection_reason(stats_a, proj_tol, ""),
                                  self.state_names)
            err.code = int(rc)  # type: ignore[attr-defined]
            raise err
        if rc:
            raise RuntimeError(f"gs_project returned {rc}")
        return xa, c_loops.projection_stats(stats_a)
