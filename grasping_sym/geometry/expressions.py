"""Formulas given as text, read without running them, in bounded time and memory.

``sympy.sympify("...")`` evaluates its argument as Python: a contour ``x="__import__('os')
.system(...)"`` would run. Here a formula is split into Python's tokens and read by an
operator-precedence parser of its own (no recursion, Python's precedence and associativity:
``-2**2 == -4``, ``2**-1 == 0.5``, ``2**3**2 == 2**9``), accepting only numbers, the named
variables, ``pi`` and ``E``, ``+ - * / **`` and a fixed list of smooth functions; anything
else is refused by name. Nothing in the text is ever executed.

Every formula within the limits below reads in milliseconds and little memory, whatever it
holds; beyond them :class:`ExpressionError` names the limit and the fix:

- at most :data:`MAX_LENGTH` characters;
- nested at most :data:`MAX_DEPTH` deep (function calls, powers, products and sums inside
  one another; a long sum or product of many terms is one level, and a run of signs
  ``- - x`` is one sign);
- every number within a double's range (magnitude below 1.8e308), and exact numbers
  (integers, numerators and denominators of fractions) of at most :data:`MAX_BITS` bits:
  ``10**10**10`` or ``9**9**9**9`` is refused at once instead of being computed digit by digit;
- no division by zero or other non-finite value (``1/0``, ``log(0)``).

A part without variables nested deeper than :data:`NUMERIC_DEPTH` (``2**-2**-2**-2**-2``) is
computed once, as a floating-point number: SymPy would evaluate a deep tower of irrational
numbers at ever higher precision.

:func:`parse_expression` builds the SymPy expression (exact: ``pi/6`` stays ``pi/6``);
:func:`evaluate_number` computes a formula without variables as a Python float, with
Python's float arithmetic (``"pi / 6" == math.pi / 6``), for files of numbers.
"""
from __future__ import annotations

import ast
import io
import keyword
import math
import tokenize

import sympy as sp

from grasping_sym.errors import ExpressionError

__all__ = ["FUNCTIONS", "MAX_BITS", "MAX_DEPTH", "MAX_LENGTH", "NUMERIC_DEPTH", "ExpressionError",
           "evaluate_number", "parse_expression", "to_expression"]

#: The functions a formula may call, by name.
FUNCTIONS = {
    "sin": sp.sin, "cos": sp.cos, "tan": sp.tan, "asin": sp.asin, "acos": sp.acos,
    "atan": sp.atan, "atan2": sp.atan2, "sinh": sp.sinh, "cosh": sp.cosh, "tanh": sp.tanh,
    "asinh": sp.asinh, "acosh": sp.acosh, "atanh": sp.atanh, "exp": sp.exp, "log": sp.log,
    "sqrt": sp.sqrt, "cbrt": sp.cbrt,
}
#: The longest formula read (characters).
MAX_LENGTH = 10_000
#: The deepest nesting read (module docstring).
MAX_DEPTH = 100
#: Exact integers, numerators and denominators have at most this many bits (module docstring).
MAX_BITS = 1100
#: A part without variables nested deeper is computed once in floating point.
NUMERIC_DEPTH = 6
_DOUBLE_BITS = 1024  # every number is below 2**1024 (1.8e308), the largest double

_CONSTANTS = {"pi": sp.pi, "E": sp.E}
_HYPERBOLIC = {"sinh", "cosh", "tanh"}
_FLOAT_CONSTANTS = {"pi": math.pi, "E": math.e}
_BINARY_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2, "**": 4}
_SIGN_PRECEDENCE = 3  # a sign binds looser than ** on its right, tighter than * / + -
_SEQUENTIAL = 32      # chains up to this long are folded left to right, as Python does
_CHUNK = 16           # longer ones are added (multiplied) 16 at a time, each step checked
_OPS = {"+", "-", "*", "/", "**", "(", ")", ","}
_APPLY = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
          "/": lambda a, b: a / b}
_SKIP = {tokenize.NL, tokenize.COMMENT, tokenize.ENDMARKER, tokenize.DEDENT}


class _NotOurs(Exception):
    """The text is not a formula of the grammar: Python's parser names what it is."""


# ------------------------------------------------------------------------------- public
def parse_expression(text: str, variables: dict[str, sp.Symbol]) -> sp.Expr:
    """The SymPy expression that ``text`` writes, in the given ``variables`` (name ->
    symbol). Raises :class:`ExpressionError` naming what is not allowed, or the limit
    (module docstring) that the formula exceeds."""
    return _read(text, variables, _Symbolic(text))


def evaluate_number(text: str) -> float:
    """The value of a formula without variables (``"pi / 6"``, ``"0.03 / 2"``), computed in
    Python's float arithmetic. Raises :class:`ExpressionError` for anything
    :func:`parse_expression` refuses, and for a value that is not a finite real number
    (``"sqrt(-1)"``, ``"1e300 * 1e300"``)."""
    value = _read(text, {}, _Numeric(text))
    return float(value)


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


# ------------------------------------------------------------------------------- reading
def _allowed(variables) -> str:
    return (f"numbers, {', '.join(sorted(variables)) or 'no variables'}, pi, E, + - * / **, "
            f"and the functions {', '.join(FUNCTIONS)}")


def _read(text: str, variables: dict, backend):
    if not isinstance(text, str):
        raise ExpressionError(f"a formula must be text, got {type(text).__name__}")
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"the formula has {len(text)} characters: at most {MAX_LENGTH}; "
                              "split it, or build the expression in Python")
    allowed = _allowed(variables)
    try:
        rpn = _postfix(_tokens(text.strip()), variables, backend, text, allowed)
        return backend.run(rpn)
    except _NotOurs:
        raise _diagnosis(text, variables, allowed) from None
    except ExpressionError:
        raise
    except (ArithmeticError, ValueError, TypeError) as exc:  # SymPy's or Python's arithmetic
        raise ExpressionError(f"{text!r} cannot be computed ({type(exc).__name__}: {exc}); write "
                              "a formula with a finite value") from None


def _tokens(text: str) -> list[tuple[str, object]]:
    """``(kind, value)`` pairs: ``("num", int | float)``, ``("name", str)``, ``("op", str)``."""
    out: list[tuple[str, object]] = []
    ended = False
    try:
        for tok in tokenize.generate_tokens(io.StringIO(text).readline):
            if tok.type in _SKIP:
                continue
            if tok.type == tokenize.NEWLINE:
                ended = True
                continue
            if ended:
                raise _NotOurs
            if tok.type == tokenize.NUMBER:
                try:
                    value = ast.literal_eval(tok.string)
                except (ValueError, SyntaxError, MemoryError, RecursionError):
                    raise _NotOurs from None
                if not isinstance(value, (int, float)):
                    raise _NotOurs  # complex
                out.append(("num", value))
            elif tok.type == tokenize.NAME and not keyword.iskeyword(tok.string):
                out.append(("name", tok.string))
            elif tok.type == tokenize.OP and tok.string in _OPS:
                out.append(("op", tok.string))
            else:
                raise _NotOurs
    except (tokenize.TokenError, SyntaxError):
        raise _NotOurs from None
    return out


def _postfix(tokens, variables, backend, text, allowed) -> list[tuple]:
    """The formula in postfix order (shunting-yard; no recursion): ``("val", value)``,
    ``("bin", op)``, ``("neg",)``, ``("call", name, n_args)``."""
    out: list[tuple] = []
    stack: list[list] = []  # ["bin", op] | ["sign", negative] | ["(", None] | ["call", name, n]
    operand = True          # an operand (or a sign, or "(") comes next
    after_sign = after_comma = False
    i = 0
    while i < len(tokens):
        kind, value = tokens[i]
        nxt = tokens[i + 1] if i + 1 < len(tokens) else None
        i += 1
        if operand:
            if kind == "num":
                out.append(("val", backend.number(value)))
                operand = False
            elif kind == "name" and nxt == ("op", "("):
                if value not in FUNCTIONS:
                    raise ExpressionError(f"{text!r}: a call of {value!r} is not allowed in a "
                                          f"formula; allowed are {allowed}")
                stack.append(["call", value, 0])
                i += 1
                after_comma = True  # a call may close at once: sin()
                after_sign = False
                continue
            elif kind == "name":
                out.append(("val", backend.name(value, variables, allowed)))
                operand = False
            elif value in ("+", "-"):
                if after_sign:  # - - x: one sign
                    stack[-1][1] ^= value == "-"
                else:
                    stack.append(["sign", value == "-"])
                after_sign = True
                after_comma = False
                continue
            elif value == "(":
                stack.append(["(", None])
            elif value == ")" and after_comma and stack and stack[-1][0] == "call":
                _close(stack, out, counted=False)
                operand = False
            else:
                raise _NotOurs
            after_sign = after_comma = False
            continue
        # an operator comes next
        if kind == "op" and value in _BINARY_PRECEDENCE:
            prec = _BINARY_PRECEDENCE[value]
            while stack and stack[-1][0] in ("bin", "sign"):
                top = stack[-1]
                top_prec = _SIGN_PRECEDENCE if top[0] == "sign" else _BINARY_PRECEDENCE[top[1]]
                if top_prec > prec or (top_prec == prec and value != "**"):
                    out.append(_emit(stack.pop()))
                else:
                    break
            stack.append(["bin", value])
            operand = True
        elif value == ")":
            _pop_operators(stack, out)
            if not stack:
                raise _NotOurs
            _close(stack, out, counted=True)
        elif value == ",":
            _pop_operators(stack, out)
            if not stack or stack[-1][0] != "call":
                raise _NotOurs  # a tuple
            stack[-1][2] += 1
            operand = after_comma = True
        else:
            raise _NotOurs
    if operand:
        raise _NotOurs
    _pop_operators(stack, out)
    if stack:
        raise _NotOurs  # an unclosed "("
    return out


def _emit(entry: list) -> tuple:
    return ("bin", entry[1]) if entry[0] == "bin" else (("neg",) if entry[1] else ("pos",))


def _pop_operators(stack: list, out: list) -> None:
    while stack and stack[-1][0] in ("bin", "sign"):
        out.append(_emit(stack.pop()))


def _close(stack: list, out: list, counted: bool) -> None:
    """Close the innermost "(" or call; ``counted``: an argument precedes the ")"."""
    entry = stack.pop()
    if entry[0] == "call":
        out.append(("call", entry[1], entry[2] + (1 if counted else 0)))
    elif not counted:
        raise _NotOurs  # "()"


def _diagnosis(text: str, variables: dict, allowed: str) -> ExpressionError:
    """What Python's own parser makes of a text that is not a formula, as a named error."""
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        return ExpressionError(f"cannot read {text!r}: {exc.msg}; write a formula of {allowed}")
    except (RecursionError, MemoryError):
        return ExpressionError(f"cannot read {text!r}: it is not a formula and it is nested too "
                               f"deeply to say what it is; write a formula of {allowed}")
    todo = [tree.body]
    while todo:  # depth first, left to right, without recursion
        node = todo.pop()
        what = None
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                what = f"the constant {node.value!r}"
        elif isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.BitXor):
                return ExpressionError(f"{text!r}: '^' is not a power here; write '**'")
            if not isinstance(node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)):
                what = f"the operator {type(node.op).__name__}"
        elif isinstance(node, ast.UnaryOp):
            if not isinstance(node.op, (ast.USub, ast.UAdd)):
                what = f"the operator {type(node.op).__name__}"
        elif isinstance(node, ast.Call):
            if not (isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS):
                what = f"a call of {ast.unparse(node.func)!r}"
            elif node.keywords:
                what = f"a call of {node.func.id!r} with a keyword argument"
        elif isinstance(node, ast.Attribute):
            what = f"an attribute ({ast.unparse(node)!r})"
        elif not isinstance(node, ast.Name):
            what = type(node).__name__
        if what is not None:
            return ExpressionError(f"{text!r}: {what} is not allowed in a formula; allowed are "
                                   f"{allowed}")
        todo.extend(reversed([c for c in ast.iter_child_nodes(node) if isinstance(c, ast.expr)]))
    return ExpressionError(f"cannot read {text!r}: write a formula of {allowed}")


# ------------------------------------------------------------------------------- evaluating
class _Chain:
    """A sum (or product) being gathered: its ``(op, term)`` pairs (``op`` one of ``+ -``, or
    ``* /``), the depth it will have, and whether all its terms are numbers (no variable)."""

    __slots__ = ("op", "items", "depth", "numeric")

    def __init__(self, op: str, items: list, depth: int, numeric: bool):
        self.op, self.items, self.depth, self.numeric = op, items, depth, numeric


class _Backend:
    """Evaluate a postfix formula with a value stack (no recursion). A value on the stack is
    ``(value, depth, numeric)`` (``numeric``: it holds no variable), or a :class:`_Chain`."""

    def __init__(self, text: str):
        self.text = text

    def fail(self, why: str) -> ExpressionError:
        return ExpressionError(f"{self.text!r}: {why}")

    def run(self, rpn: list[tuple]):
        stack: list = []
        for item in rpn:
            kind = item[0]
            if kind == "val":
                stack.append(item[1])
            elif kind == "neg":
                value, depth, numeric = self.finish(stack.pop())
                depth = self.deeper(depth)
                stack.append((self.settle(self.negate(value), depth, numeric), depth, numeric))
            elif kind == "pos":
                pass
            elif kind == "call":
                n = item[2]
                args = [self.finish(a) for a in stack[len(stack) - n:]] if n else []
                del stack[len(stack) - n:]
                depth = self.deeper(max((a[1] for a in args), default=0))
                numeric = all(a[2] for a in args)
                value = self.call(item[1], [a[0] for a in args], numeric)
                stack.append((self.settle(value, depth, numeric), depth, numeric))
            else:
                op = item[1]
                right = stack.pop()
                left = stack.pop()
                if op == "**":
                    (base, d1, n1), (exponent, d2, n2) = self.finish(left), self.finish(right)
                    depth, numeric = self.deeper(max(d1, d2)), n1 and n2
                    value = self.power(base, exponent, numeric)
                    stack.append((self.settle(value, depth, numeric), depth, numeric))
                    continue
                chain_op = "+" if op in "+-" else "*"
                value, depth, numeric = self.finish(right)
                if isinstance(left, _Chain) and left.op == chain_op:
                    left.items.append((op, value))
                    left.depth = max(left.depth, self.deeper(depth))
                    left.numeric = left.numeric and numeric
                    stack.append(left)
                else:
                    first, d0, n0 = self.finish(left)
                    stack.append(_Chain(chain_op, [(chain_op, first), (op, value)],
                                        self.deeper(max(d0, depth)), n0 and numeric))
        return self.result(self.finish(stack.pop())[0])

    def deeper(self, depth: int) -> int:
        """The depth of an operation on operands at most ``depth`` deep (checked)."""
        if depth + 1 > MAX_DEPTH:
            raise self.fail(f"the formula is nested more than {MAX_DEPTH} deep (calls, powers, "
                            "products and sums inside one another): write it in steps, or build "
                            "the expression in Python")
        return depth + 1

    def finish(self, entry) -> tuple:
        """``(value, depth, numeric)`` of a stack entry, a gathered chain evaluated."""
        if not isinstance(entry, _Chain):
            return entry
        value = self.chain(entry.op, entry.items)
        return self.settle(value, entry.depth, entry.numeric), entry.depth, entry.numeric

    def settle(self, value, depth: int, numeric: bool):
        return value


class _Numeric(_Backend):
    """Python floats: every operation O(1); a complex or non-finite value is refused."""

    _FUNCTIONS = {
        "sin": math.sin, "cos": math.cos, "tan": math.tan, "asin": math.asin, "acos": math.acos,
        "atan": math.atan, "atan2": math.atan2, "sinh": math.sinh, "cosh": math.cosh,
        "tanh": math.tanh, "asinh": math.asinh, "acosh": math.acosh, "atanh": math.atanh,
        "exp": math.exp, "log": math.log, "sqrt": math.sqrt,
        "cbrt": lambda x: x ** (1 / 3),  # the principal root, as SymPy's cbrt: complex for x < 0
    }

    def number(self, value) -> tuple:
        value = float(value) if abs(value) < 2 ** MAX_BITS else math.inf
        return self.check(value, "a number"), 1, True

    def name(self, name, variables, allowed) -> tuple:
        if name in _FLOAT_CONSTANTS:
            return _FLOAT_CONSTANTS[name], 1, True
        raise self.fail(f"unknown name {name!r}; allowed are {allowed}")

    def check(self, value, what: str):
        if isinstance(value, complex):
            raise self.fail(f"{what} is not a real number ({value:.6g}): write a formula with a "
                            "real value")
        if not math.isfinite(value):
            raise self.fail(f"{what} is not a finite number (beyond a double's range, 1.8e308): "
                            "write a smaller number")
        return value

    def negate(self, value):
        return -value

    def power(self, base, exponent, numeric):
        what = f"the power {base:.6g}**{exponent:.6g}"
        try:
            value = base ** exponent
        except OverflowError:
            raise self.fail(f"{what} is beyond a double's range (1.8e308): write a smaller "
                            "number") from None
        except ZeroDivisionError:
            raise self.fail(f"{what} divides by zero") from None
        return self.check(value, what)

    def call(self, name, args, numeric):
        what = f"{name}({', '.join(f'{a:.6g}' for a in args)})"
        try:
            value = self._FUNCTIONS[name](*args)
        except TypeError as exc:
            raise self.fail(f"{name}: {exc}") from None
        except ValueError:
            raise self.fail(f"{what} is not a real number (outside its domain)") from None
        except OverflowError:
            raise self.fail(f"{what} is beyond a double's range (1.8e308)") from None
        return self.check(value, what)

    def chain(self, op, items):
        value = items[0][1]
        for o, v in items[1:]:  # left to right, as Python computes it
            if o == "/" and v == 0:
                raise self.fail("divides by zero")
            value = _APPLY[o](value, v)
        return self.check(value, "a sum" if op == "+" else "a product")

    def result(self, value):
        return self.check(value, "the formula")


class _Symbolic(_Backend):
    """SymPy, exact, with every number checked (each node once): exact numbers of at most
    :data:`MAX_BITS` bits and every number within a double's range, so that no operation
    computes a huge integer or a huge float. A part without variables nested deeper than
    :data:`NUMERIC_DEPTH` becomes a floating-point number (SymPy would evaluate a deep tower
    of irrational numbers at ever higher precision)."""

    #: Functions whose value can be far larger than their argument's.
    _GROWING = {"exp", "sinh", "cosh", "tan"}

    def __init__(self, text: str):
        super().__init__(text)
        self.checked: set = set()  # nodes whose numbers are known to be within the limits

    def number(self, value) -> tuple:
        if isinstance(value, float):
            if not math.isfinite(value):
                raise self.fail(f"{value} is not a finite number")
            return self.check(sp.Float(repr(value))), 1, True
        return self.check(sp.Integer(value)), 1, True

    def name(self, name, variables, allowed) -> tuple:
        if name in variables:
            return variables[name], 1, False
        if name in _CONSTANTS:
            return _CONSTANTS[name], 1, True
        raise self.fail(f"unknown name {name!r}; allowed are {allowed}")

    def check(self, expr):
        """``expr``, after checking every number in it not yet checked (each node once)."""
        todo = [expr]
        checked = self.checked
        while todo:
            node = todo.pop()
            if node in checked:
                continue
            checked.add(node)
            if node.is_Rational:
                bits = max(abs(node.p).bit_length(), node.q.bit_length())
                large = abs(node.p).bit_length() - node.q.bit_length() >= _DOUBLE_BITS - 1
                if bits > MAX_BITS or (large and not math.isfinite(float(node))):
                    raise self.fail(f"the exact number {_short(node)} is beyond a double's range "
                                    f"(1.8e308) or the limit of {MAX_BITS} bits on integers, "
                                    "numerators and denominators: write a smaller number")
            elif node.is_Float:
                _sign, man, exp, bc = node._mpf_
                if man and exp + bc > _DOUBLE_BITS:
                    raise self.fail(f"a number here is about 2**{_short(exp + bc, 12)}, beyond a double's range "
                                    "(1.8e308): write a smaller number")
            elif node is sp.zoo or node is sp.nan or node is sp.oo or node is sp.S.NegativeInfinity:
                raise self.fail(f"a part of the formula is {node} (a division by zero, log(0), "
                                "...): write a formula with a finite value")
            elif node is sp.I:
                raise self.fail("a part of the formula is not a real number (the square root of a "
                                "negative number, acosh below 1, ...): write a formula with a "
                                "real value")
            else:
                todo.extend(node.args)
        return expr

    def settle(self, value, depth: int, numeric: bool):
        if numeric and depth > NUMERIC_DEPTH and not value.is_Atom:
            approx = value.evalf(15)
            self.check(approx)
            return approx
        return value

    def negate(self, value):
        return self.check(-value)

    def power(self, base, exponent, numeric):
        if exponent.is_Rational and abs(exponent.p) > 1:
            grows = _power_bits(base) * abs(exponent.p) / exponent.q
            if grows > MAX_BITS:
                raise self.fail(f"the power ({_short(base)})**({_short(exponent)}) would hold a "
                                f"number of about 2**{grows:.3g}: beyond a double's range "
                                "(1.8e308); write a smaller power")
        value = self.check(base ** exponent)
        if numeric and not value.is_Atom:
            self.check(value.evalf(15))  # pi**1000, (1 + sqrt(2))**1000: within a double's range
        return value

    def call(self, name, args, numeric):
        # SymPy's sinh, cosh and tanh ask of an argument that may not be real for its real and
        # imaginary parts, which takes time exponential in their nesting (tanh 8 deep around
        # log(t): 5 s): they are built as written, unevaluated, unless their argument is a number
        options = {"evaluate": False} if name in _HYPERBOLIC and not numeric else {}
        try:
            value = FUNCTIONS[name](*args, **options)
        except TypeError as exc:  # a function given the wrong number of arguments
            raise self.fail(f"{exc}") from None
        value = self.check(value)
        if numeric and name in self._GROWING and not value.is_Atom:
            self.check(value.evalf(15))  # exp(1000): within a double's range
        return value

    def chain(self, op, items):
        if any(o == "/" and v.is_Number and v.is_zero for o, v in items):
            raise self.fail("divides by zero")
        if len(items) <= _SEQUENTIAL:  # as Python would: left to right
            value = items[0][1]
            for o, v in items[1:]:
                value = self.check(_APPLY[o](value, v))
            return value
        terms = [v if o in "+*" else self.check(-v if o == "-" else sp.Pow(v, -1))
                 for o, v in items]
        many = sp.Add if op == "+" else sp.Mul
        while len(terms) > 1:  # 16 at a time: each step's numbers within the limits
            terms = [self.check(many(*terms[k:k + _CHUNK])) for k in range(0, len(terms), _CHUNK)]
        return terms[0]

    def result(self, value):
        return value


def _power_bits(base) -> float:
    """log2 of the largest exact number that raising ``base`` to an integer would raise with
    it (SymPy distributes a power over a product and multiplies exponents)."""
    if base.is_Rational:
        return max(_log2(abs(base.p)), _log2(base.q))
    if base.is_Mul:
        return max(_power_bits(a) for a in base.args)
    if base.is_Pow and base.exp.is_Rational:
        return _power_bits(base.base) * abs(base.exp.p) / base.exp.q
    return 0.0


def _log2(n: int) -> float:
    return math.log2(n) if n > 1 else 0.0


def _short(value, limit: int = 60) -> str:
    text = str(value)
    return text if len(text) <= limit else f"{text[:limit]}..."
