"""Safe evaluator for velocity-profile expressions of time ``t``, e.g. ``where(t < 2, 0.5, -0.5)``.

The text comes from scenario files and FMU string parameters, so it is untrusted: it is only
``ast.parse``-d, checked against a whitelist and turned into a tree of small closures (one per
node, each a function of t).  Nothing is ever passed to eval/exec/compile.  Standard library
only, no package imports: this source is inlined verbatim into the standalone FMU script.
"""
import ast
import difflib
import math
import operator
import warnings

_EXPR_MAX_LENGTH = 1000  # characters; checked before ast.parse
_EXPR_MAX_DEPTH = 50  # AST levels; keeps parsing/closure recursion bounded


class ExpressionError(ValueError):
    """An expression is malformed, uses something not allowed, or fails at some t."""


ALLOWED_CONSTANTS = {"pi": math.pi, "e": math.e}


# name -> (implementation, min args, max args or None); where() is built lazily in _expr_call.
# floor/ceil wrap math.floor/ceil because those return int and every result must be a float.
_EXPR_FUNCS = {
    "sin": (math.sin, 1, 1), "cos": (math.cos, 1, 1), "tan": (math.tan, 1, 1),
    "asin": (math.asin, 1, 1), "acos": (math.acos, 1, 1), "atan": (math.atan, 1, 1),
    "atan2": (math.atan2, 2, 2), "sinh": (math.sinh, 1, 1), "cosh": (math.cosh, 1, 1),
    "tanh": (math.tanh, 1, 1), "exp": (math.exp, 1, 1), "log": (math.log, 1, 2),
    "sqrt": (math.sqrt, 1, 1), "abs": (math.fabs, 1, 1), "min": (min, 2, None),
    "max": (max, 2, None), "floor": (lambda x: float(math.floor(x)), 1, 1),
    "ceil": (lambda x: float(math.ceil(x)), 1, 1),
    "clip": (lambda x, lo, hi: min(max(x, lo), hi), 3, 3), "where": (None, 3, 3),
}
ALLOWED_FUNCTIONS = tuple(_EXPR_FUNCS)

_EXPR_HELP = ("allowed: numbers, t, pi, e, + - * / ** %, comparisons, and/or/not, "
              "functions " + " ".join(ALLOWED_FUNCTIONS))
# Binary and unary operators.  math.pow, not float.__pow__: negative ** fractional raises
# ValueError instead of returning a complex.  'not' gives 1.0/0.0 like comparisons do.
_EXPR_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
             ast.Div: operator.truediv, ast.Mod: operator.mod, ast.Pow: math.pow,
             ast.USub: operator.neg, ast.UAdd: operator.pos, ast.Not: lambda x: 0.0 if x else 1.0}
_EXPR_CMPOPS = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt,
                ast.GtE: operator.ge, ast.Eq: operator.eq, ast.NotEq: operator.ne}
_EXPR_BAD_OPS = {ast.FloorDiv: "//", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>",
                 ast.BitOr: "|", ast.BitXor: "^", ast.BitAnd: "&", ast.Invert: "~",
                 ast.In: "in", ast.NotIn: "not in", ast.Is: "is", ast.IsNot: "is not"}
_EXPR_BAD_NODES = {
    ast.Lambda: "lambda", ast.ListComp: "comprehension", ast.SetComp: "comprehension",
    ast.DictComp: "comprehension", ast.GeneratorExp: "comprehension",
    ast.Subscript: "subscript", ast.JoinedStr: "f-string", ast.NamedExpr: "walrus",
    ast.IfExp: "conditional expression", ast.List: "list",
    ast.Tuple: "tuple", ast.Dict: "dict", ast.Set: "set", ast.Starred: "starred",
    ast.Await: "await", ast.Yield: "yield", ast.YieldFrom: "yield", ast.Slice: "slice",
}
_EXPR_BAD_CONSTS = {bool: "boolean literal", str: "string", bytes: "bytes",
                    complex: "complex number"}


# What a user most likely meant by an operator that is not allowed.
_EXPR_OP_HINTS = {ast.BitXor: "; use ** for a power (2**t, t**2)", ast.BitAnd: "; use and",
                  ast.BitOr: "; use or", ast.Invert: "; use not or -"}


def _expr_quote(text):
    return repr(text) if len(text) <= _EXPR_MAX_LENGTH else repr(text[:40]) + "..."


def _expr_error(text, message):
    return ExpressionError("expression %s: %s" % (_expr_quote(text), message))


def _expr_reject(text, node, what, hint=""):
    segment = ast.get_source_segment(text, node) or type(node).__name__
    return _expr_error(text, "%s %r is not allowed%s (%s)" % (what, segment, hint, _EXPR_HELP))


def _expr_suggest(name, choices):
    close = difflib.get_close_matches(name, choices, n=1)
    return "; did you mean %r?" % close[0] if close else ""


def _expr_lift(node):
    """Turn any compiled node into a plain function of t."""
    kind, value = node
    return (lambda t: value) if kind == "c" else value


def _expr_fold(fn, children):
    """Precompute fn when it does not depend on t; errors are left for run time (they report t)."""
    if all(kind == "c" for kind, _ in children):
        try:
            return ("c", fn(0.0))
        except (ArithmeticError, ValueError):
            pass
    return ("f", fn)


def _expr_apply(fn, args):
    """Closure for fn(*args); t and constants are captured directly to save a call per step."""
    if len(args) == 1:
        if args[0][0] == "t":
            return ("f", fn)  # e.g. sin(t) is math.sin itself
        a = _expr_lift(args[0])
        return _expr_fold(lambda t: fn(a(t)), args)
    if len(args) == 2:
        (ka, a), (kb, b) = args
        if ka == "t" and kb == "c":
            return ("f", lambda t: fn(t, b))
        if ka == "c" and kb == "t":
            return ("f", lambda t: fn(a, t))
        if kb == "c":
            fa = _expr_lift(args[0])
            return _expr_fold(lambda t: fn(fa(t), b), args)
        if ka == "c":
            fb = _expr_lift(args[1])
            return _expr_fold(lambda t: fn(a, fb(t)), args)
        fa, fb = _expr_lift(args[0]), _expr_lift(args[1])
        return _expr_fold(lambda t: fn(fa(t), fb(t)), args)
    fs = [_expr_lift(a) for a in args]
    return _expr_fold(lambda t: fn(*[f(t) for f in fs]), args)


def _expr_compare(ops, nodes):
    if len(ops) == 1 and nodes[0][0] == "t" and nodes[1][0] == "c":
        op, c = ops[0], nodes[1][1]  # the common where(t < 2, ...) case
        return ("f", lambda t: 1.0 if op(t, c) else 0.0)
    first = _expr_lift(nodes[0])
    pairs = list(zip(ops, [_expr_lift(n) for n in nodes[1:]]))

    def chain(t):  # a < b < c: each operand evaluated once, stop at the first false link
        left = first(t)
        for op, f in pairs:
            right = f(t)
            if not op(left, right):
                return 0.0
            left = right
        return 1.0
    return _expr_fold(chain, nodes)


def _expr_boolop(is_and, nodes):
    fs = [_expr_lift(n) for n in nodes]
    stop, stop_value = (False, 0.0) if is_and else (True, 1.0)

    def boolop(t):  # short-circuit: 'and' stops at the first false, 'or' at the first true
        for f in fs:
            if bool(f(t)) is stop:
                return stop_value
        return 1.0 - stop_value
    return _expr_fold(boolop, nodes)


def _expr_call(text, node, sub):
    func = node.func
    if isinstance(func, ast.Attribute):
        return sub(func)  # rejected there as attribute access
    if not isinstance(func, ast.Name):
        raise _expr_reject(text, func, "calling", "; call functions by name, e.g. sin(t)")
    name = func.id
    if name not in _EXPR_FUNCS:
        raise _expr_error(text, "unknown function %r%s (%s)" % (
            name, _expr_suggest(name, ALLOWED_FUNCTIONS), _EXPR_HELP))
    for kw in node.keywords:
        raise _expr_reject(text, kw, "keyword argument", "; pass arguments by position")
    for arg in node.args:
        if isinstance(arg, ast.Starred):
            raise _expr_reject(text, arg, "starred argument")
    fn, lo, hi = _EXPR_FUNCS[name]
    n = len(node.args)
    if n < lo or (hi is not None and n > hi):
        want = ("%d argument%s" % (lo, "s" * (lo != 1)) if lo == hi else
                "at least %d arguments" % lo if hi is None else "%d to %d arguments" % (lo, hi))
        raise _expr_error(text, "%s() takes %s, got %d in %r" % (
            name, want, n, ast.get_source_segment(text, node)))
    args = [sub(a) for a in node.args]
    if name != "where":
        return _expr_apply(fn, args)
    if args[0][0] == "c":  # constant condition: keep only the taken branch
        return args[1] if args[0][1] else args[2]
    cond, yes, no = (_expr_lift(a) for a in args)
    return ("f", lambda t: yes(t) if cond(t) else no(t))  # lazy: untaken branch never runs


def _expr_node(text, node, depth):
    """Validate one AST node and compile it to ("c", float) | ("t" | "f", fn of t)."""
    if depth > _EXPR_MAX_DEPTH:
        raise _expr_error(text, "nested deeper than %d levels" % _EXPR_MAX_DEPTH)

    def sub(child):
        return _expr_node(text, child, depth + 1)
    tp = type(node)
    if tp is ast.Constant:
        if type(node.value) not in (int, float):
            what = _EXPR_BAD_CONSTS.get(type(node.value), "constant")
            raise _expr_reject(text, node, what, "; use int/float numbers")
        try:
            value = float(node.value)  # floats only: int ** int could run for ages
        except OverflowError:
            value = math.inf
        if not math.isfinite(value):
            raise _expr_reject(text, node, "non-finite number")
        return ("c", value)
    if tp is ast.Name:
        if node.id == "t":
            return ("t", lambda t: t)  # kind "t" lets callers skip this call entirely
        if node.id in ALLOWED_CONSTANTS:
            return ("c", ALLOWED_CONSTANTS[node.id])
        if node.id in _EXPR_FUNCS:
            raise _expr_error(text, "function %r must be called, e.g. %s(t)" % (node.id, node.id))
        names = ["t", *ALLOWED_CONSTANTS, *ALLOWED_FUNCTIONS]
        raise _expr_reject(text, node, "name", _expr_suggest(node.id, names))
    if tp is ast.Attribute:
        raise _expr_reject(text, node, "attribute access '.%s' in" % node.attr)
    if tp is ast.BinOp or tp is ast.UnaryOp:
        op = _EXPR_OPS.get(type(node.op))
        if op is None:
            raise _expr_reject(text, node, "operator '%s' in" % _EXPR_BAD_OPS.get(type(node.op)),
                               _EXPR_OP_HINTS.get(type(node.op), ""))
        operands = [node.left, node.right] if tp is ast.BinOp else [node.operand]
        return _expr_apply(op, [sub(n) for n in operands])
    if tp is ast.Compare:
        ops = []
        for op in node.ops:
            if type(op) not in _EXPR_CMPOPS:
                raise _expr_reject(text, node, "operator '%s' in" % _EXPR_BAD_OPS.get(type(op)))
            ops.append(_EXPR_CMPOPS[type(op)])
        return _expr_compare(ops, [sub(n) for n in [node.left, *node.comparators]])
    if tp is ast.BoolOp:
        return _expr_boolop(isinstance(node.op, ast.And), [sub(v) for v in node.values])
    if tp is ast.Call:
        return _expr_call(text, node, sub)
    hint = "; use where(cond, a, b)" if tp is ast.IfExp else ""
    raise _expr_reject(text, node, _EXPR_BAD_NODES.get(tp, tp.__name__), hint)


def compile_expression(text):
    """Validate ``text`` and return a fast ``f(t) -> float``; ExpressionError if not allowed."""
    if not isinstance(text, str):
        raise ExpressionError("expression must be a string, got %s" % type(text).__name__)
    if len(text) > _EXPR_MAX_LENGTH:
        raise _expr_error(text, "too long (%d characters, limit is %d)"
                          % (len(text), _EXPR_MAX_LENGTH))
    source = text.strip()  # leading blanks would be an IndentationError
    if not source:
        raise _expr_error(text, "empty expression")
    try:
        with warnings.catch_warnings():  # e.g. SyntaxWarning for '1(2)'; we report our own errors
            warnings.simplefilter("ignore")
            tree = ast.parse(source, mode="eval")
    except SyntaxError as exc:
        col = (exc.offset or 0) + (len(text) - len(text.lstrip()) if exc.lineno == 1 else 0)
        raise _expr_error(text, "syntax error at column %d: %s" % (col, exc.msg)) from None
    except (ValueError, RecursionError, MemoryError) as exc:  # null bytes, absurd nesting
        raise _expr_error(text, "cannot parse (%s)" % (str(exc) or type(exc).__name__)) from None
    kind, value = _expr_node(source, tree.body, 1)
    if kind == "c" and math.isfinite(value):
        return lambda t: value
    fn = _expr_lift((kind, value))
    quoted = _expr_quote(text)

    def expression(t):
        try:
            v = fn(float(t))  # float(t) keeps results plain floats even for int/numpy t
        except (ArithmeticError, ValueError) as exc:
            raise ExpressionError("expression %s at t=%r: %s" % (
                quoted, t, str(exc) or type(exc).__name__)) from None
        if v - v == 0.0:  # false for inf and nan
            return v
        raise ExpressionError("expression %s at t=%r: result %r is not finite" % (quoted, t, v))
    return expression


def evaluate(text, t):
    """Compile and evaluate once; compile_expression() once for repeated use."""
    return compile_expression(text)(t)
