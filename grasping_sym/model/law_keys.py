"""A control law's definition as text, read without running it: what ``gs.build`` keys a cached
model by when the scene's whole definition is unchanged (``pipeline.stages``), so that a
rebuild of a cached scene never runs the law, builds its expressions or hashes them.

A preset (``model.controllers``) is its name and parameters (its code is the package's,
which the cache key covers). A law of the user's own (``gs.controllers.law(fn)``) is its
function's code, read from the code object: its bytecode, constants and names, its defaults,
the values its closure holds and the values of the globals it names, followed into the
functions and laws it calls. Only values whose text fixes them are read: numbers, strings,
``None``, tuples, lists and dicts of them, NumPy arrays, SymPy expressions, functions (their own
definitions), laws, and the modules of libraries whose contents the user does not edit
(``FIXED_MODULES``: by name and version). Anything else (an object of the user's, a module of
the user's, a value that cannot be read) gives no definition (``None``): the build then keys
the law by its expressions, as it always may.
"""
from __future__ import annotations

import builtins
import hashlib
import sys
import types
from collections.abc import Callable

import numpy as np

__all__ = ["FIXED_MODULES", "function_definition", "value_definition"]

#: Top-level packages whose modules a law may name and be keyed by name and version.
FIXED_MODULES = frozenset({"casadi", "numpy", "math", "cmath", "sympy", "grasping_sym"})

_PLAIN = (type(None), bool, int, float, complex, str, bytes)


def function_definition(fn: Callable, _seen: frozenset = frozenset()) -> str | None:
    """The text of ``fn``'s definition (the module's docstring), or None where it cannot be
    read whole."""
    code = getattr(fn, "__code__", None)
    if not isinstance(code, types.CodeType):
        return None
    if id(fn) in _seen:  # a function that calls itself: its text is already being read
        return f"<recursion {code.co_qualname}>"
    seen = _seen | {id(fn)}
    parts = [_code_text(code)]
    for name, cell in zip(code.co_freevars, fn.__closure__ or ()):
        try:
            value = cell.cell_contents
        except ValueError:  # an empty cell
            return None
        text = value_definition(value, seen)
        if text is None:
            return None
        parts.append(f"closure {name}={text}")
    for label, values in (("defaults", fn.__defaults__ or ()),
                          ("kwdefaults", tuple(sorted((fn.__kwdefaults__ or {}).items())))):
        text = value_definition(values, seen)
        if text is None:
            return None
        parts.append(f"{label}={text}")
    namespace = getattr(fn, "__globals__", {})
    for name in sorted(_names(code)):
        if name in namespace:
            text = value_definition(namespace[name], seen)
            if text is None:
                return None
            parts.append(f"global {name}={text}")
        elif hasattr(builtins, name):
            parts.append(f"builtin {name}")
        # else: an attribute's name (``ca.tanh``): fixed by the value it is read from
    return "\n".join(parts)


def value_definition(value, _seen: frozenset = frozenset()) -> str | None:
    """The text of a value a law reads (the module's docstring), or None."""
    if isinstance(value, _PLAIN):
        return f"{type(value).__name__}:{value!r}"
    if isinstance(value, (tuple, list)):
        items = [value_definition(v, _seen) for v in value]
        if any(t is None for t in items):
            return None
        return f"{type(value).__name__}({', '.join(items)})"
    if isinstance(value, dict):
        items = [(value_definition(k, _seen), value_definition(v, _seen)) for k, v in value.items()]
        if any(k is None or v is None for k, v in items):
            return None
        return "dict(" + ", ".join(f"{k}: {v}" for k, v in sorted(items)) + ")"
    if isinstance(value, np.ndarray):
        if value.dtype.hasobject:
            return None
        digest = hashlib.sha256(np.ascontiguousarray(value).tobytes()).hexdigest()
        return f"ndarray({value.dtype.str}, {value.shape}, {digest})"
    if isinstance(value, np.generic):
        return f"{type(value).__name__}:{value.item()!r}"
    if isinstance(value, types.ModuleType):
        top = value.__name__.partition(".")[0]
        if top not in FIXED_MODULES:
            return None
        version = getattr(sys.modules.get(top), "__version__", "")
        return f"module {value.__name__} {version}"
    if isinstance(value, types.FunctionType):
        text = function_definition(value, _seen)
        return None if text is None else f"function {value.__qualname__}:\n{text}"
    if isinstance(value, types.BuiltinFunctionType):
        module = getattr(value, "__module__", None) or ""
        if module.partition(".")[0] not in FIXED_MODULES | {"builtins", "_operator", "operator"}:
            return None
        return f"builtin {module}.{value.__qualname__}"
    definition = getattr(value, "definition", None)
    if definition is not None and type(value).__module__ == "grasping_sym.model.controllers":
        return f"law {definition}"  # a Controller: its own definition
    sympy = sys.modules.get("sympy")
    if sympy is not None and isinstance(value, sympy.Basic):
        return f"sympy {sympy.srepr(value)}"
    return None


def _code_text(code: types.CodeType) -> str:
    """A code object's bytecode, constants (nested code objects read the same way) and names."""
    consts = []
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            consts.append(f"<code {_code_text(c)}>")
        else:
            consts.append(repr(c))
    return (f"code {code.co_qualname} {code.co_code.hex()} consts=({', '.join(consts)}) "
            f"names={code.co_names} vars={code.co_varnames} free={code.co_freevars} "
            f"cell={code.co_cellvars}")


def _names(code: types.CodeType) -> set[str]:
    """The names ``code`` and the code nested in it look up: globals, and attributes."""
    names = set(code.co_names)
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            names |= _names(c)
    return names
