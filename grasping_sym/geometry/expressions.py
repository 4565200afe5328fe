"""Formulas given as text, read without running them.

``sympy.sympify("...")`` evaluates its argument as Python: a contour ``x="__import__('os')
.system(...)"`` would run. :func:`parse_expression` reads a formula with Python's parser and
builds the SymPy expression from the syntax tree itself, accepting only numbers, the named
variables, ``pi`` and ``E``, the arithmetic operators and a fixed list of smooth functions;
anything else is refused by name. Nothing in the text is ever executed.
"""
from __future__ import annotations

import ast
import math

import sympy as sp

from grasping_sym.errors import ExpressionError

__all__ = ["FUNCTIONS", "ExpressionError", "parse_expression", "to_expression"]

#: The functions a formula may call, by name.
FUNCTIONS = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos,
    "atan": sp.atan, "atan2": sp.atan2, "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "asinh": sp.asinh, "acosh": sp.acosh, "atanh": sp.atanh, "exp": sp.exp, "log": sp.log,
    "sqrt": sp.sqrt, "cbrt": sp.cbrt,
}
_CONSTANTS = {"pi": sp.pi, "E": sp.E}
_BINARY = {ast.Add: lambda a, b: a + b, ast.Sub: lambda a, b: a - b,
           ast.Mult: lambda a, b: a * b, ast.Div: lambda a, b: a / b,
           ast.Pow: lambda a, b: a ** b}
_MAX_LENGTH = 10_000


def parse_expression(text: str, variables: dict[str, sp.Symbol]) -> sp.Expr:
    """The SymPy expression that ``text`` writes, in the given ``variables`` (name ->
    symbol). Raises :class:`ExpressionError` naming what is not allowed."""
    if len(text) > _MAX_LENGTH:
        raise ExpressionError(f"the formula has {len(text)} characters: at most {_MAX_LENGTH}")
    allowed = f"numbers, {', '.join(sorted(variables)) or 'no variables'}, pi, E, + - * / **, " \
              f"and the functions {', '.join(FUNCTIONS)}"
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise ExpressionError(f"cannot read {text!r}: {exc.msg}; write a formula of {allowed}") from exc

    def build(node: ast.AST) -> sp.Expr:
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            if isinstance(node.value, float) and not math.isfinite(node.value):
                raise ExpressionError(f"{text!r}: {node.value} is not a finite number")
            return sp.Integer(node.value) if isinstance(node.value, int) else sp.Float(repr(node.value))
        if isinstance(node, ast.Name):
            if node.id in variables:
                return variables[node.id]
            if node.id in _CONSTANTS:
                return _CONSTANTS[node.id]
            raise ExpressionError(f"{text!r}: unknown name {node.id!r}; allowed are {allowed}")
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            return _BINARY[type(node.op)](build(node.left), build(node.right))
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.BitXor):
            raise ExpressionError(f"{text!r}: '^' is not a power here; write '**'")
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            value = build(node.operand)
            return -value if isinstance(node.op, ast.USub) else value
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in FUNCTIONS and not node.keywords:
            return FUNCTIONS[node.func.id](*[build(a) for a in node.args])
        what = type(node).__name__
        if isinstance(node, ast.Call):
            what = f"a call of {ast.unparse(node.func)!r}"
        elif isinstance(node, ast.Attribute):
            what = f"an attribute ({ast.unparse(node)!r})"
        raise ExpressionError(f"{text!r}: {what} is not allowed in a formula; allowed are {allowed}")

    try:
        return build(tree.body)
    except TypeError as exc:  # a function given the wrong number of arguments
        raise ExpressionError(f"{text!r}: {exc}") from exc


def to_expression(value, variables: dict[str, sp.Symbol], what: str) -> sp.Expr:
    """``value`` as a SymPy expression: text through :func:`parse_expression`, a number or a
    SymPy expression as it is. Anything else raises :class:`ExpressionError` naming ``what``."""
    if isinstance(value, str):
        try:
            return parse_expression(value, variables)
        except ExpressionError as exc:
            raise ExpressionError(f"{what}: {exc}") from None
    if isinstance(value, sp.Basic):
        return value
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return sp.sympify(value)
    raise ExpressionError(f"{what} is {type(value).__name__} ({value!r}): give a SymPy expression, "
                          "a number, or a formula as text")
