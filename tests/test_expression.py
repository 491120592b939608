"""Tests for the safe velocity-profile expression evaluator."""
import ast
import math
import runpy
from pathlib import Path

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

MODULE_PATH = Path(__file__).resolve().parents[1] / "src" / "mecanum_fmu" / "models" / "blocks" / "expression.py"
from mecanum_fmu.models.blocks.expression import (ALLOWED_CONSTANTS, ALLOWED_FUNCTIONS,
                                           ExpressionError, compile_expression, evaluate)


def rejected(text):
    """Compile text, expecting ExpressionError; return its message."""
    with pytest.raises(ExpressionError) as info:
        compile_expression(text)
    return str(info.value)


# ---------------------------------------------------------------- accepted expressions

NESTED = "where(t < 2, 0.5, where(t < 4, 0, -0.5))"


@pytest.mark.parametrize("text, t, expected", [
    ("sin(t)", 0.7, math.sin(0.7)),
    ("cos(t)", 0.7, math.cos(0.7)),
    ("0", 5.0, 0.0),
    ("2*pi", 0.0, 2 * math.pi),
    ("e", 0.0, math.e),
    ("where(t<1, 1, 2)", 0.5, 1.0),
    ("where(t<1, 1, 2)", 1.5, 2.0),
    (NESTED, 1.0, 0.5), (NESTED, 3.0, 0.0), (NESTED, 5.0, -0.5),
    ("1 < t < 3", 2.0, 1.0), ("1 < t < 3", 4.0, 0.0), ("1 < t < 3", 0.0, 0.0),
    ("0 <= t <= 1 < 2", 0.5, 1.0),
    ("-2**2", 0.0, -4.0),
    ("2**3**2", 0.0, 512.0),
    ("7 % 3", 0.0, 1.0),
    ("-7 % 3", 0.0, 2.0),
    ("1 + 2 * t", 3.0, 7.0),
    ("(1 + 2) * t", 3.0, 9.0),
    ("t / 4", 1.0, 0.25),
    ("3 - t", 1.0, 2.0),
    ("+t", 3.0, 3.0),
    ("- t", 3.0, -3.0),
    ("0.5 * sin(t)", 1.0, 0.5 * math.sin(1.0)),
    ("sin(t) * 2", 1.0, math.sin(1.0) * 2),
    ("sin(t) + cos(t)", 1.0, math.sin(1.0) + math.cos(1.0)),
    ("atan2(t, 2)", 1.0, math.atan2(1.0, 2.0)),
    ("atan2(1, t)", 2.0, math.atan2(1.0, 2.0)),
    ("min(t, 2, 3)", 2.5, 2.0), ("min(t, 2)", 1.0, 1.0),
    ("max(t, 2)", 1.0, 2.0), ("max(1, 2, t, 0)", 7.0, 7.0),
    ("floor(t)", 2.7, 2.0), ("floor(t)", -2.2, -3.0),
    ("ceil(t)", 2.1, 3.0), ("ceil(t)", -2.7, -2.0),
    ("tan(t)", 0.3, math.tan(0.3)), ("asin(t)", 0.3, math.asin(0.3)),
    ("acos(t)", 0.3, math.acos(0.3)), ("atan(t)", 0.3, math.atan(0.3)),
    ("sinh(t)", 0.3, math.sinh(0.3)), ("cosh(t)", 0.3, math.cosh(0.3)),
    ("tanh(t)", 0.3, math.tanh(0.3)), ("exp(t)", 1.0, math.e),
    ("log(t)", math.e, 1.0), ("log(8, 2)", 0.0, 3.0), ("log(t, 10)", 1000.0, math.log(1000, 10)),
    ("sqrt(t)", 4.0, 2.0), ("abs(-t)", 2.0, 2.0), ("abs(t)", -2.0, 2.0),
    ("clip(t, -1, 1)", 5.0, 1.0), ("clip(t, -1, 1)", -5.0, -1.0), ("clip(t, -1, 1)", 0.5, 0.5),
    ("t == 1", 1.0, 1.0), ("t != 1", 1.0, 0.0), ("t >= 2", 1.0, 0.0), ("t <= 2", 1.0, 1.0),
    ("t > 0.5", 1.0, 1.0), ("1 < t", 2.0, 1.0), ("sin(t) > 2", 1.0, 0.0),
    ("t and 0", 1.0, 0.0), ("t and 2", 1.0, 1.0), ("t or 0", 0.0, 0.0), ("0 or t", 3.0, 1.0),
    ("not t", 0.0, 1.0), ("not t", 2.0, 0.0), ("not 0", 9.0, 1.0), ("1 and 0 or 1", 0.0, 1.0),
    ("  sin(t)\n", 0.7, math.sin(0.7)),
    ("sin(\n t)", 0.7, math.sin(0.7)),
    ("1_000 * 0x10 + 1e-3", 0.0, 16000.001),
])
def test_accepted_expressions_match_math(text, t, expected):
    value = evaluate(text, t)
    assert type(value) is float
    assert value == pytest.approx(expected, rel=1e-12, abs=1e-15)


@pytest.mark.parametrize("text", ["t", "t + 1", "floor(t)", "t < 1", "min(t, 5)", "-t", "+t"])
def test_result_is_always_a_plain_float(text):
    assert type(evaluate(text, 3)) is float
    assert type(evaluate(text, True)) is float


def test_compiled_function_is_reusable_and_pure():
    f = compile_expression(NESTED)
    assert [f(x) for x in (0.0, 2.0, 3.9, 4.0, 100.0)] == [0.5, 0.0, 0.0, -0.5, -0.5]
    assert [f(x) for x in (0.0, 2.0)] == [0.5, 0.0]


def test_public_api():
    assert issubclass(ExpressionError, ValueError)
    assert ALLOWED_CONSTANTS == {"pi": math.pi, "e": math.e}
    assert isinstance(ALLOWED_FUNCTIONS, tuple)
    assert set(ALLOWED_FUNCTIONS) == {
        "sin", "cos", "tan", "asin", "acos", "atan", "atan2", "sinh", "cosh", "tanh", "exp",
        "log", "sqrt", "abs", "min", "max", "floor", "ceil", "where", "clip"}


@pytest.mark.parametrize("name", ALLOWED_FUNCTIONS)
def test_every_allowed_function_is_callable(name):
    args = {"atan2": "t, 1", "min": "t, 1", "max": "t, 1", "where": "t, 1, 2", "clip": "t, 0, 1"}
    assert type(evaluate("%s(%s)" % (name, args.get(name, "t")), 0.5)) is float


# ---------------------------------------------------------------- laziness / folding

@pytest.mark.parametrize("text, t, expected", [
    ("where(t > 0, log(t), 0)", 0.0, 0.0),
    ("where(t <= 0, 0, log(t))", 0.0, 0.0),
    ("where(t > 0, 1, 1/0)", 1.0, 1.0),
    ("t > 0 and log(t) > -100", 0.0, 0.0),
    ("t <= 0 or log(t)", 0.0, 1.0),
    ("0 < t < log(t)", -1.0, 0.0),  # chained comparison stops at the first false link
])
def test_only_the_taken_branch_is_evaluated(text, t, expected):
    assert evaluate(text, t) == expected


def test_constant_subtree_errors_are_deferred_to_run_time():
    f = compile_expression("where(t > 0, 1, 1/0)")  # must not fail while compiling
    with pytest.raises(ExpressionError, match=r"at t=0\.0: .*division by zero"):
        f(0.0)


# ---------------------------------------------------------------- rejections

@pytest.mark.parametrize("text, snippet", [
    pytest.param("sin(t).__class__", ".__class__", id="attribute"),
    pytest.param("t.real", ".real", id="attribute-on-t"),
    pytest.param("x", "'x'", id="unknown-name"),
    pytest.param("__import__", "'__import__'", id="dunder-name"),
    pytest.param("os", "'os'", id="os-name"),
    pytest.param("(lambda: 1)()", "lambda: 1", id="call-of-non-name"),
    pytest.param("1(2)", "'1'", id="call-of-number"),
    pytest.param("sin(t, x=1)", "x=1", id="keyword-argument"),
    pytest.param("max(t, **k)", "**k", id="double-star-argument"),
    pytest.param("sin(*t)", "*t", id="starred-argument"),
    pytest.param("lambda t: t", "lambda t: t", id="lambda"),
    pytest.param("[t for t in (1,)]", "[t for t in (1,)]", id="list-comprehension"),
    pytest.param("{t for t in (1,)}", "{t for t in (1,)}", id="set-comprehension"),
    pytest.param("{t: 1 for t in (1,)}", "{t: 1 for t in (1,)}", id="dict-comprehension"),
    pytest.param("sum(t for t in (1,))", "sum", id="generator-in-unknown-call"),
    pytest.param("(t for t in (1,))", "t for t in (1,)", id="generator"),
    pytest.param("t[0]", "t[0]", id="subscript"),
    pytest.param("'abc'", "'abc'", id="string"),
    pytest.param("f'{t}'", "f'{t}'", id="f-string"),
    pytest.param("b'x'", "b'x'", id="bytes"),
    pytest.param("1j", "1j", id="complex"),
    pytest.param("True", "True", id="bool-literal"),
    pytest.param("None", "None", id="none"),
    pytest.param("...", "...", id="ellipsis"),
    pytest.param("(y := 1)", "y := 1", id="walrus"),
    pytest.param("1 if t else 2", "1 if t else 2", id="ternary"),
    pytest.param("[1, 2]", "[1, 2]", id="list"),
    pytest.param("(1, 2)", "(1, 2)", id="tuple"),
    pytest.param("{1: 2}", "{1: 2}", id="dict"),
    pytest.param("{1, 2}", "{1, 2}", id="set"),
    pytest.param("[*t]", "[*t]", id="starred-in-list"),
    pytest.param("await t", "await t", id="await"),
    pytest.param("(yield t)", "yield t", id="yield"),
    pytest.param("(yield from t)", "yield from t", id="yield-from"),
    pytest.param("7 // 2", "//", id="floordiv"),
    pytest.param("t @ t", "@", id="matmul"),
    pytest.param("t << 1", "<<", id="shift"),
    pytest.param("t | 1", "|", id="bitor"),
    pytest.param("~t", "~", id="invert"),
    pytest.param("t in t", "'in'", id="in"),
    pytest.param("t is t", "'is'", id="is"),
    pytest.param("1e999", "1e999", id="infinite-literal"),
    pytest.param("9" * 400, "9" * 400, id="huge-int-literal"),
])
def test_rejected_constructs_name_the_offending_part(text, snippet):
    message = rejected(text)
    assert snippet in message
    assert message.startswith("expression %r: " % text)


def test_rejection_message_says_what_is_allowed():
    message = rejected("sin(t).__class__")
    assert "attribute access '.__class__'" in message
    assert "allowed: numbers, t" in message and "where" in message


def test_ternary_points_to_where():
    assert "where(" in rejected("1 if t > 0 else 2")


@pytest.mark.parametrize("text, snippet", [
    ("foo(t)", "unknown function 'foo'; did you mean 'floor'?"),
    ("sinn(t)", "did you mean 'sin'?"),
    ("getattr(t, 'x')", "unknown function 'getattr'"),
    ("tt", "did you mean 't'?"),
    ("sin", "function 'sin' must be called"),
])
def test_unknown_names_get_suggestions(text, snippet):
    assert snippet in rejected(text)


@pytest.mark.parametrize("text, snippet", [
    ("where(t, 1)", "where() takes 3 arguments, got 2"),
    ("sin()", "sin() takes 1 argument, got 0"),
    ("sin(t, t)", "sin() takes 1 argument, got 2"),
    ("atan2(t)", "atan2() takes 2 arguments, got 1"),
    ("min(t)", "min() takes at least 2 arguments, got 1"),
    ("log(1, 2, 3)", "log() takes 1 to 2 arguments, got 3"),
    ("clip(t, 1)", "clip() takes 3 arguments, got 2"),
])
def test_arity_is_checked(text, snippet):
    assert snippet in rejected(text)


@pytest.mark.parametrize("payload", [
    "__import__('os').system('touch {path}')",
    "open('{path}', 'w')",
    "exec(\"open('{path}', 'w')\")",
    "eval(\"open('{path}', 'w')\")",
    "[c for c in ().__class__.__base__.__subclasses__()] and open('{path}', 'w')",
    "where(1, open('{path}', 'w'), 0)",
])
def test_code_injection_is_refused_without_side_effects(tmp_path, payload):
    target = tmp_path / "pwned"
    with pytest.raises(ExpressionError):
        compile_expression(payload.format(path=target))
    assert not target.exists()


# ---------------------------------------------------------------- input limits

@pytest.mark.parametrize("text", [1.0, 0, None, b"t", ["t"]])
def test_non_string_input_is_rejected(text):
    with pytest.raises(ExpressionError, match="must be a string"):
        compile_expression(text)


@pytest.mark.parametrize("text", ["", "   ", "\n\t "])
def test_empty_expression_is_rejected(text):
    assert "empty" in rejected(text)


@pytest.mark.parametrize("text, snippet", [
    ("sin(t", "'(' was never closed"),
    ("1 +", "column"),
    ("1 +\n 2", "syntax error"),
    ("t\x00", "null bytes"),
    ("t = 1", "syntax error"),
])
def test_syntax_errors_become_expression_errors(text, snippet):
    assert snippet in rejected(text)


def test_length_limit():
    assert evaluate("1." + "0" * 998, 0.0) == 1.0  # exactly 1000 characters is fine
    message = rejected("1." + "0" * 999)
    assert "1001 characters, limit is 1000" in message
    assert len(message) < 300  # the overlong text itself is not echoed in full


def test_length_is_checked_before_parsing():
    # would make ast.parse allocate a lot / recurse; must be refused up front
    assert "limit is 1000" in rejected("(" * 100_000)


def test_depth_limit():
    assert evaluate("-" * 45 + "t", 1.0) == -1.0
    assert "deeper than 50" in rejected("-" * 60 + "t")
    assert "deeper than 50" in rejected("sin(" * 60 + "t" + ")" * 60)
    assert "deeper than 50" in rejected("+".join(["t"] * 60))


@pytest.mark.parametrize("text", ["-" * 999 + "1", "(" * 300 + "t" + ")" * 300, "[" * 500])
def test_parser_recursion_is_contained(text):
    rejected(text)


@pytest.mark.parametrize("text", ["10**10**10", "9**9**9**9", "t**t**t", "2**t"])
def test_huge_powers_fail_fast(text):
    f = compile_expression(text)  # no integer arithmetic at compile time
    with pytest.raises(ExpressionError, match="range"):
        f(2000.0)  # float arithmetic overflows at once; int ** int would run for ever


# ---------------------------------------------------------------- evaluation errors

@pytest.mark.parametrize("text, t, snippet", [
    ("log(t)", 0, "expression 'log(t)' at t=0: math domain error"),
    ("1/t", 0.0, "expression '1/t' at t=0.0: float division by zero"),
    ("t % 0", 1.0, "at t=1.0: float modulo"),
    ("sqrt(t)", -1.0, "at t=-1.0: math domain error"),
    ("acos(t)", 2.0, "at t=2.0: math domain error"),
    ("exp(t)", 1000.0, "at t=1000.0: math range error"),
    ("t ** 0.5", -8.0, "at t=-8.0: math domain error"),
    ("0 ** t", -1.0, "at t=-1.0"),
    ("log(8, t)", 1.0, "at t=1.0"),
    ("t * 1e308", 10.0, "at t=10.0: result inf is not finite"),
    ("t * 1e308 - t * 1e308", 10.0, "result nan is not finite"),
    ("1e308 * 10", 1.5, "at t=1.5: result inf is not finite"),
])
def test_evaluation_errors_carry_t(text, t, snippet):
    f = compile_expression(text)
    with pytest.raises(ExpressionError) as info:
        f(t)
    assert snippet in str(info.value)


# ---------------------------------------------------------------- module hygiene

def test_module_is_self_contained_and_never_evals():
    tree = ast.parse(MODULE_PATH.read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    assert imported <= {"ast", "difflib", "math", "operator", "warnings"}
    assert not [n for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
    forbidden = {"eval", "exec", "compile", "__import__", "getattr", "setattr"}
    called = {n.func.id if isinstance(n.func, ast.Name) else getattr(n.func, "attr", None)
              for n in ast.walk(tree) if isinstance(n, ast.Call)}
    assert not called & forbidden
    names = runpy.run_path(str(MODULE_PATH))  # works outside the package, as when inlined
    assert names["compile_expression"]("sin(t)")(1.0) == math.sin(1.0)


def test_evaluation_does_not_parse_again(monkeypatch):
    # Speed lives in bench/; here only the structural guarantee: compiled once, never re-parsed.
    funcs = [compile_expression(text) for text in ("0", "sin(t)", NESTED)]
    def no_parse(*args, **kwargs):
        raise AssertionError("ast.parse called during evaluation")
    monkeypatch.setattr(ast, "parse", no_parse)
    assert [f(1.0) for f in funcs] == [0.0, math.sin(1.0), 0.5]


# ---------------------------------------------------------------- properties

def _check_only_expression_error(text):
    try:
        f = compile_expression(text)
    except ExpressionError:
        return
    for t in (0.0, 0.5, -3.0, 1e6):
        try:
            value = f(t)
        except ExpressionError:
            continue
        assert type(value) is float and math.isfinite(value)


@settings(max_examples=500, deadline=1000)
@given(st.text(st.characters(min_codepoint=0, max_codepoint=0x2FF), max_size=300))
def test_random_text_only_raises_expression_error(text):
    _check_only_expression_error(text)


TOKENS = ["t", "1", "0", "2.5", "1e308", "pi", "+", "-", "*", "/", "**", "%", "(", ")", ",",
          "<", "==", "and", "or", "not", "sin(", "log(", "where(", "min(", "floor(", "x", ".",
          "[", "]", "'", ":", "lambda", "if", "else", "=", "__import__", "9**9**9"]


@settings(max_examples=1000, deadline=1000)
@given(st.lists(st.sampled_from(TOKENS), max_size=40).map(" ".join))
def test_token_soup_only_raises_expression_error(text):
    _check_only_expression_error(text)


def _leaf():
    # negative literals in parentheses: "-1 ** t" would parse as -(1 ** t)
    numbers = st.integers(-10, 10).map(lambda n: ("(%d)" % n, lambda t, v=float(n): v, 1))
    return st.one_of(st.just(("t", lambda t: t, 1)), numbers)


def _extend(children):
    binops = {"+": lambda a, b: a + b, "-": lambda a, b: a - b, "*": lambda a, b: a * b,
              "/": lambda a, b: a / b, "%": lambda a, b: a % b, "**": math.pow}
    funcs = {"sin": math.sin, "sqrt": math.sqrt, "log": math.log, "abs": math.fabs}

    def binop(op, a, b):
        fn, fa, fb = binops[op], a[1], b[1]
        return ("(%s %s %s)" % (a[0], op, b[0]), lambda t: fn(fa(t), fb(t)), 1 + max(a[2], b[2]))

    def call(name, a):
        fn, fa = funcs[name], a[1]
        return ("%s(%s)" % (name, a[0]), lambda t: fn(fa(t)), 1 + a[2])

    def where(c, a, b):
        fc, fa, fb = c[1], a[1], b[1]
        return ("where(%s < 0, %s, %s)" % (c[0], a[0], b[0]),
                lambda t: fa(t) if fc(t) < 0 else fb(t), 3 + max(c[2], a[2], b[2]))
    return st.one_of(
        st.builds(binop, st.sampled_from(sorted(binops)), children, children),
        st.builds(call, st.sampled_from(sorted(funcs)), children),
        st.builds(where, children, children, children))


@settings(max_examples=500, deadline=1000, suppress_health_check=[HealthCheck.too_slow])
@given(st.recursive(_leaf(), _extend, max_leaves=12), st.floats(-5, 5))
def test_generated_expressions_match_a_python_reference(tree, t):
    text, reference, depth = tree
    assume(depth <= 40)
    try:
        expected = reference(t)
        ok = math.isfinite(expected)
    except (ArithmeticError, ValueError):
        ok = False
    f = compile_expression(text)
    if ok:
        assert f(t) == expected
    else:
        with pytest.raises(ExpressionError):
            f(t)


@pytest.mark.parametrize("text, hint", [("2^t", "use ** for a power"), ("t & 1", "use and"),
                                        ("t | 1", "use or"), ("~t", "use not or -")])
def test_bitwise_operators_suggest_what_was_meant(text, hint):
    """Issue 24: `^` is refused with the power operator suggested (Python's ^ is xor)."""
    with pytest.raises(ExpressionError) as info:
        compile_expression(text)
    assert f"is not allowed; {hint}" in str(info.value), str(info.value)
