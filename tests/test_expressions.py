"""The formula reader (grasping_sym.geometry.expressions): Python's meaning for what it reads,
a named error for everything else, and bounded time and memory on any text within its limits.

The property tests give it random text, random expression trees, long chains and deep
nestings: every call returns a SymPy expression (or, for ``evaluate_number``, a finite float)
or raises ``ExpressionError``, in less than 2 s of CPU time, and the process's peak memory
grows by less than 256 MB over all of them.
"""
from __future__ import annotations

import math
import resource
import tempfile
import time

import pytest
import sympy as sp
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.configuration import set_hypothesis_home_dir

from grasping_sym.errors import GraspingSymError
from grasping_sym.geometry.expressions import (
    FUNCTIONS,
    MAX_DEPTH,
    MAX_LENGTH,
    ExpressionError,
    evaluate_number,
    parse_expression,
)

T = sp.Symbol("t")  # not declared real: the harder case for SymPy's assumptions
VARS = {"t": T}
MEMORY_MB = 256

SECONDS = 2.0  # of CPU time one call may take (CPU time: other processes on the machine don't count)

BOUNDED = settings(deadline=None, database=None, derandomize=True,
                   suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                         HealthCheck.function_scoped_fixture])


# Hypothesis' own files (constants, unicode tables) go to a temporary directory, not to
# .hypothesis/ in the working tree; set before any test is collected
set_hypothesis_home_dir(tempfile.mkdtemp(prefix="grasping-sym-hypothesis-"))


@pytest.fixture(scope="module", autouse=True)
def _warm():
    parse_expression("sin(t)**2 + 2**-2**-2 + cosh(t) / 3", VARS)  # SymPy's first-call imports


def _peak_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


@pytest.fixture
def memory_bound():
    """The process's peak resident memory grows by less than MEMORY_MB during the test."""
    before = _peak_mb()
    yield
    assert _peak_mb() - before < MEMORY_MB


def _bounded(fn, text):
    """``fn(text)``, or None for ExpressionError (anything else fails the test), in SECONDS."""
    start = time.process_time()
    try:
        return fn(text)
    except ExpressionError:
        return None
    finally:
        spent = time.process_time() - start
        assert spent < SECONDS, f"{spent:.2f} s of CPU for {text[:100]!r}"


def _check_both(text: str) -> None:
    assume(len(text) <= MAX_LENGTH)
    expr = _bounded(lambda s: parse_expression(s, VARS), text)
    assert expr is None or isinstance(expr, sp.Expr)
    value = _bounded(evaluate_number, text)
    assert value is None or (isinstance(value, float) and math.isfinite(value))


# ------------------------------------------------------------------ strategies
_ATOMS = st.one_of(
    st.integers(min_value=-10**400, max_value=10**400).map(str),
    st.integers(min_value=0, max_value=12).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
    st.sampled_from(["t", "pi", "E", "x", "1e308", "1e-320", "0", "0.0", "2", "10", "9"]),
)


def _extend(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**", "**-", "^", "//"]),
                       children).map(lambda p: f"{p[0]}{p[1]}{p[2]}")
    unary = st.tuples(st.sampled_from(["-", "+", "- -", "--"]), children).map("".join)
    paren = children.map(lambda c: f"({c})")
    call = st.tuples(st.sampled_from(sorted(FUNCTIONS) + ["open", "t"]),
                     st.lists(children, min_size=0, max_size=3)).map(
        lambda p: f"{p[0]}({', '.join(p[1])})")
    return st.one_of(binary, unary, paren, call)


TREES = st.recursive(_ATOMS, _extend, max_leaves=30)

_WRAPPERS = ["-", "- ", "+", "(", "sin(", "exp(", "2**", "9**", "t**", "-2**", "2**-", "t+", "t*",
             "1/", "sqrt(", "pi**", "E**", "cosh(", "log(", "10**"]


@st.composite
def deep(draw):
    """A wrapper repeated up to thousands of times around an atom, closed if it opened."""
    wrapper = draw(st.sampled_from(_WRAPPERS))
    inner = draw(st.sampled_from(["t", "2", "10", "9", "0.5", "pi"]))
    n = draw(st.integers(min_value=1, max_value=(MAX_LENGTH - 10) // (len(wrapper) + 1)))
    closing = ")" * n if wrapper.endswith("(") else ""
    return wrapper * n + inner + closing


CHAINS = st.tuples(st.sampled_from(["+", "-", "*", "/", "**"]),
                   st.lists(st.sampled_from(["t", "2", "3", "0.5", "pi", "1/3", "sqrt(2)", "sin(t)",
                                             "10**300", "7**300", "x"]), min_size=2, max_size=1500)
                   ).map(lambda p: p[0].join(p[1]))

TEXT = st.text(alphabet=st.sampled_from(list("0123456789.e+-*/()^,_ tpiEsncoqrxlhab\n#'[]=j")),
               max_size=300)


# ------------------------------------------------------------------ properties
@settings(BOUNDED, max_examples=100)
@given(TEXT)
def test_any_text_gives_an_expression_or_a_named_error(memory_bound, text):
    _check_both(text)


@settings(BOUNDED, max_examples=200)
@given(TREES)
def test_any_expression_tree_gives_an_expression_or_a_named_error(memory_bound, text):
    _check_both(text)


@settings(BOUNDED, max_examples=20)
@given(deep())
def test_deep_nesting_is_bounded(memory_bound, text):
    _check_both(text)


@settings(BOUNDED, max_examples=25)
@given(CHAINS)
def test_long_sums_and_products_are_bounded(memory_bound, text):
    _check_both(text)


# ------------------------------------------------------------------ the cases of issue 25
@pytest.mark.parametrize("text", ["10**10**10", "9**9**9**9", "2**(10**10)", "(2*t)**(10**10)", "2**1024",
                                  "sqrt(2)**(10**9)", "pi**(10**300)", "exp(exp(700))",
                                  "10**400", "2.0**(10**10)"])
def test_huge_powers_are_refused_at_once(text):
    with pytest.raises(ExpressionError, match="beyond a double's range") as exc:
        parse_expression(text, VARS)
    assert isinstance(exc.value, GraspingSymError) and "smaller" in str(exc.value)
    with pytest.raises(ExpressionError, match="beyond a double's range"):
        evaluate_number(text.replace("(2*t)", "(2*2)"))


def test_values_that_are_not_real_are_refused_when_parsed():
    t = sp.Symbol("t")
    for text in ("sqrt(-1)", "acosh(0)", "acosh(" * 30 + "2" + ")" * 30, "log(-1)"):
        with pytest.raises(ExpressionError, match="not a real number"):
            parse_expression(text, {"t": t})
    assert parse_expression("sqrt(t) + acosh(2)", {"t": t}).is_real is None  # real where t is


def test_long_sums_and_sign_runs_work_without_recursion():
    assert parse_expression("+".join(["t"] * 3000), VARS) == 3000 * T
    assert parse_expression("-" * 5000 + "t", VARS) == T
    assert parse_expression("-" * 4999 + "t", VARS) == -T
    assert parse_expression("*".join(["t"] * 4900), VARS) == T ** 4900
    assert evaluate_number("+".join(["0.5"] * 2000)) == 1000.0


def test_nesting_beyond_the_limit_is_refused_by_name():
    text = "sin(" * (MAX_DEPTH + 1) + "t" + ")" * (MAX_DEPTH + 1)
    with pytest.raises(ExpressionError, match=f"nested more than {MAX_DEPTH} deep"):
        parse_expression(text, VARS)
    ok = "sin(" * (MAX_DEPTH - 2) + "t" + ")" * (MAX_DEPTH - 2)
    assert parse_expression(ok, VARS).has(sp.sin)
    with pytest.raises(ExpressionError, match="characters: at most"):
        parse_expression("t+" * MAX_LENGTH + "t", VARS)


@pytest.mark.parametrize("text", ["-2**2", "2**-1", "2**3**2", "-t**2", "2*-t**2", "2**-t*3",
                                  "-2**-t*3", "t - t - t", "1/3*3", "(t+1)*2*3", "t/2/3",
                                  "2**2**-1", "sqrt(2)**4", "sin(t,)", "1_000 + 0x10",
                                  "0.02*cos(t) + 1e-3*sin(2*t)**2", "atan2(t, 1)", "(t\n+ 1)",
                                  "cbrt(t) - log(t)", "- - - t"])
def test_formulas_mean_what_python_makes_of_them(text):
    """SymPy objects under Python's own parser and precedence (integers as SymPy Integers)."""
    import ast

    class Sympify(ast.NodeTransformer):
        def visit_Constant(self, node):
            return ast.Call(ast.Name("S", ast.Load()), [node], []) if isinstance(node.value, int) \
                else ast.Call(ast.Name("F", ast.Load()), [ast.Constant(repr(node.value))], [])

    tree = ast.fix_missing_locations(Sympify().visit(ast.parse(text.strip(), mode="eval")))
    names = {"t": T, "pi": sp.pi, "E": sp.E, "S": sp.Integer, "F": sp.Float, **FUNCTIONS}
    expected = eval(compile(tree, "<formula>", "eval"), {"__builtins__": {}}, names)  # noqa: S307
    assert parse_expression(text, VARS) == expected


def test_numbers_are_python_floats():
    assert evaluate_number("pi / 6") == math.pi / 6
    assert evaluate_number("pi + 0.3") == math.pi + 0.3
    assert evaluate_number("2.0 / 3.0 * 3") == 2.0 / 3.0 * 3
    assert evaluate_number("-2**0.5") == -(2 ** 0.5)
    for text, why in (("sqrt(-1)", "not a real number"), ("1e300 * 1e300", "not a finite number"),
                      ("1/0", "divides by zero"), ("cbrt(-8)", "not a real number"),
                      ("t", "unknown name 't'")):
        with pytest.raises(ExpressionError, match=why):
            evaluate_number(text)


@pytest.mark.parametrize("text, why", [
    ("t^2", r"write '\*\*'"), ("lambda: 1", "Lambda"), ("t.real", "attribute"),
    ("open('x')", "a call of 'open'"), ("[t]", "List"), ("(t", "never closed"),
    ("1/0", "divides by zero"), ("log(0)", "zoo"), ("sin(t, t)", "exactly 1 argument"),
    ("sin(x=1)", "keyword argument"), ("1j", "the constant 1j"), ("t % 2", "Mod"),
    ("__import__('os').system('true')", "a call of .__import__"), ("open('x')", "a call of 'open'"),
])
def test_what_is_not_a_formula_is_named(text, why):
    with pytest.raises(ExpressionError, match=why):
        parse_expression(text, VARS)
