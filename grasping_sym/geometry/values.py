"""Numbers given by the user to the geometry: any real type, read the same way everywhere.

A radius may come as a Python ``float``, a NumPy scalar (``np.float32`` from an array,
``np.int64``), a 0-d array or a SymPy number; all are one real number. Booleans, complex
numbers and strings are not (``float("1")`` would quietly accept a string).
"""
from __future__ import annotations

import numbers

import numpy as np
import sympy as sp

__all__ = ["as_real", "as_component"]


def as_real(value, keep_python: bool = False) -> float | int | None:
    """``value`` as a Python ``float`` when it is one real number, else ``None``.

    Accepts ``int``, ``float``, NumPy's real scalars (``np.float32``, ``np.float16``,
    ``np.int64``, ...), SymPy's numbers and 0-d real arrays; refuses booleans, complex numbers,
    strings and everything else. NaN and infinities are returned (the caller decides whether
    they are allowed). With ``keep_python``, a Python ``int`` or ``float`` is returned as it is
    (so that expressions built from it, and their content hashes, do not change).
    """
    if isinstance(value, (bool, np.bool_)):
        return None
    if keep_python and type(value) in (int, float):
        return value
    if isinstance(value, np.ndarray):
        if value.ndim != 0 or value.dtype.kind not in "iuf":
            return None
        value = value[()]
    if not isinstance(value, numbers.Real):
        return None
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return None


def as_component(value):
    """A coordinate given as a NumPy number (``np.float32(0.01)``, ``np.int64(2)``, a 0-d
    array) as the SymPy number it means; anything else unchanged (formulas, SymPy
    expressions, Python numbers go on to ``expressions.to_expression``)."""
    if isinstance(value, (np.generic, np.ndarray)) and as_real(value) is not None:
        if isinstance(value, np.ndarray):
            value = value[()]
        return sp.Integer(int(value)) if isinstance(value, numbers.Integral) else sp.Float(float(value))
    return value
