"""A control law's definition as text, read without running it: what ``gs.build`` keys a cached
model by when the scene's whole definition is unchanged (``pipeline.stages``), so that a
rebuild of a cached scene never runs the law, builds its expressions or hashes them.

A preset (``model.controllers``) is its name and parameters (its code is the package's,
which the cache key covers). A law of the user's own (``gs.controllers.law(fn)``) is its
function's code, read from the code object: its bytecode, constants and names, its defaults,
the values its closure holds and the values of the globals it names, followed into the
functions and laws it calls (plain functions only: a bound method's instance or a partial's
arguments are not read). Only values whose text fixes them are read: numbers, strings,
``None``, tuples, lists and dicts of them, NumPy arrays, SymPy expressions, functions (their own
definitions), laws, and the modules of libraries whose contents the user does not edit
(``FIXED_MODULES``: by name and version). Anything else (an object of the user's, a module of
the user's, a value that cannot be read, an import of a module not among those, a name found
neither in the function's globals nor among the builtins, a call that reaches names at run
time: ``UNREADABLE``) gives no definition (``None``): the build then keys the law by its
expressions, as it always may.
"""
from __future__ import annotations

import builtins
import dis
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
    read whole: anything but a plain function (a bound method's instance, a partial's
    arguments are not read), a global name found neither in its globals nor among the
    builtins, an import of a module not in ``FIXED_MODULES``, a call that reaches names
    at run time (``UNREADABLE``)."""
    if not isinstance(fn, types.FunctionType):
        return None
    code = fn.__code__
    if id(fn) in _seen:  # a function that calls itself: its text is already being read
        return f"<recursion {code.co_qualname}>"
    seen = _seen | {id(fn)}
    globals_read = _globals_read(code)
    if globals_read is None:
        return None
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
    namespace = fn.__globals__
    for name in sorted(globals_read):
        if name in namespace:
            text = value_definition(namespace[name], seen)
            if text is None:
                return None
            parts.append(f"global {name}={text}")
        elif hasattr(builtins, name):
            parts.append(f"builtin {name}")
        else:  # a name the law would fail on, or find only at run time
            return None
    return "\n".join(parts)


#: Builtins that reach values by a name given at run time: a law calling one is not read.
UNREADABLE = frozenset({"globals", "vars", "locals", "eval", "exec", "compile", "__import__",
                        "getattr", "setattr", "delattr", "open", "input"})


def _globals_read(code: types.CodeType) -> set[str] | None:
    """The global names ``code`` (and the code nested in it) reads, or None when it imports a
    module not in ``FIXED_MODULES`` or reads a name of ``UNREADABLE``."""
    names: set[str] = set()
    for ins in dis.get_instructions(code):
        if ins.opname in ("LOAD_GLOBAL", "LOAD_NAME"):
            names.add(ins.argval)
        elif ins.opname == "IMPORT_NAME" and str(ins.argval).partition(".")[0] not in FIXED_MODULES:
            return None
    if names & UNREADABLE:
        return None
    for c in code.co_consts:
        if isinstance(c, types.CodeType):
            inner = _globals_read(c)
            if inner is None:
                return None
            names |= inner
    return names


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
    if type(value).__module__ == "grasping_sym.model.controllers" and hasattr(value, "definition_in"):
        text = value.definition_in(_seen)  # a Controller: its own definition
        return None if text is None else f"law {text}"
    sympy = sys.modules.get("sympy")
    if sympy is not None and isinstance(value, sympy.Basic):
        return f"sympy {sympy.srepr(value)}"
    return None


def _code_text(code: types.CodeType) -> str:
    """A code object's bytecode, constants (nested code objects read the same way, sets
    sorted: their order changes with the string hash's seed) and names."""
    return (f"code {code.co_qualname} {code.co_code.hex()} "
            f"consts=({', '.join(_const_text(c) for c in code.co_consts)}) "
            f"names={code.co_names} vars={code.co_varnames} free={code.co_freevars} "
            f"cell={code.co_cellvars}")


def _const_text(c) -> str:
    if isinstance(c, types.CodeType):
        return f"<code {_code_text(c)}>"
    if isinstance(c, (frozenset, set)):
        return f"{type(c).__name__}({{{', '.join(sorted(_const_text(v) for v in c))}}})"
    if isinstance(c, tuple):
        return f"({', '.join(_const_text(v) for v in c)},)"
    return repr(c)
