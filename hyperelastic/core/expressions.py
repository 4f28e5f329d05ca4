"""Arithmetic expressions of time and reference coordinates from options, evaluated safely and
vectorized: the text is parsed once with Python's `ast` and only a whitelist of nodes is accepted
(numbers, the variables a use allows, + - * / % **, comparisons, and/or/not, `a if c else b`, calls of
the functions below); evaluation walks that tree with numpy. Nothing is ever passed to eval/exec, and
no attribute, subscript, name lookup or call outside the whitelist can be expressed.

    Expression("0.1*sin(2*pi*t)*X", ("t", "X", "Y", "Z"))(t=0.5, X=X, Y=Y, Z=Z)
"""
import ast
import operator

import numpy as np

from .errors import UserError

MAX_LENGTH = 2000
FUNCTIONS = {
    "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1), "asin": (np.arcsin, 1),
    "acos": (np.arccos, 1), "atan": (np.arctan, 1), "atan2": (np.arctan2, 2), "sinh": (np.sinh, 1),
    "cosh": (np.cosh, 1), "tanh": (np.tanh, 1), "exp": (np.exp, 1), "log": (np.log, 1),
    "sqrt": (np.sqrt, 1), "abs": (np.abs, 1), "sign": (np.sign, 1), "floor": (np.floor, 1),
    "ceil": (np.ceil, 1), "min": (np.minimum, 2), "max": (np.maximum, 2), "where": (np.where, 3),
}
CONSTANTS = {"pi": np.pi, "e": np.e}
BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
          ast.Mod: np.mod, ast.Pow: np.power}
UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos, ast.Not: np.logical_not}
COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater, ast.GtE: np.greater_equal,
           ast.Eq: np.equal, ast.NotEq: np.not_equal}


# every expression of t alone made in this process (-obstacle_motion, -rigid_uy, -NAME_time, ...): a run checks them
# at its steps' ends before it writes anything (check_times)
TIME_EXPRESSIONS = []


def check_times(times):
    """Every expression of t alone is finite at `times` (a run's step ends): else one line naming the first such time,
    before any output (issue 73: 'log(0.015-t)' failed at the second step, after the run had replaced the previous
    output of its name)."""
    t = np.asarray(times, np.float64)
    for e in TIME_EXPRESSIONS:
        with np.errstate(all="ignore"):
            v = np.broadcast_to(np.asarray(e._eval(e.tree, {"t": t}), np.float64), t.shape)
        bad = np.flatnonzero(~np.isfinite(v))
        if len(bad):
            raise UserError(f"{e.where}: '{e.text}' is not finite at t={t[bad[0]]:g} (a step of this run ends there)")


class Expression:
    """A parsed, checked expression in the given variables; call it with their values (scalars or
    arrays, broadcast together). `where` names the option in error lines."""

    def __init__(self, text, variables, where="expression"):
        self.text, self.variables, self.where = str(text), tuple(variables), where
        if not self.text.strip():
            raise UserError(f"{where}: empty expression")
        if len(self.text) > MAX_LENGTH:
            raise UserError(f"{where}: expression longer than {MAX_LENGTH} characters")
        try:
            tree = ast.parse(self.text.strip(), mode="eval")
        except SyntaxError as e:
            raise UserError(f"{where}: '{self.text}' is not an expression ({e.msg}, column {e.offset})") from None
        except (RecursionError, MemoryError, ValueError):
            raise UserError(f"{where}: '{self.text[:60]}' is nested too deeply") from None
        try:
            self._check(tree.body)
        except RecursionError:
            raise UserError(f"{where}: '{self.text[:60]}' is nested too deeply") from None
        self.tree = tree.body
        self.uses = sorted({n.id for n in ast.walk(tree) if isinstance(n, ast.Name)} & set(self.variables))
        if self.variables == ("t",):
            TIME_EXPRESSIONS.append(self)

    def _fail(self, what):
        raise UserError(f"{self.where}: {what} in '{self.text}' (allowed: numbers, {', '.join(self.variables)}, "
                        f"pi, e, + - * / % **, comparisons, and/or/not, a if c else b, "
                        f"{', '.join(FUNCTIONS)})")

    def _check(self, node):
        if isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                self._fail(f"'{ast.unparse(node)}' is not a number")
            try:
                finite = np.isfinite(float(node.value))
            except OverflowError:
                finite = False
            if not finite:
                self._fail(f"the number {str(node.value)[:20]} is not finite")
        elif isinstance(node, ast.Name):
            if node.id not in self.variables and node.id not in CONSTANTS:
                self._fail(f"unknown name '{node.id}'")
        elif isinstance(node, ast.BinOp):
            if type(node.op) not in BINARY:
                self._fail(f"operator '{ast.unparse(node)}' is not allowed")
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp):
            if type(node.op) not in UNARY:
                self._fail(f"operator '{ast.unparse(node)}' is not allowed")
            self._check(node.operand)
        elif isinstance(node, ast.Compare):
            if any(type(op) not in COMPARE for op in node.ops):
                self._fail(f"comparison '{ast.unparse(node)}' is not allowed")
            for n in [node.left, *node.comparators]:
                self._check(n)
        elif isinstance(node, ast.BoolOp):
            for n in node.values:
                self._check(n)
        elif isinstance(node, ast.IfExp):
            for n in (node.test, node.body, node.orelse):
                self._check(n)
        elif isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
                self._fail(f"'{ast.unparse(node.func)}' is not a known function")
            if node.keywords or any(isinstance(a, ast.Starred) for a in node.args):
                self._fail(f"'{node.func.id}' takes plain arguments")
            arity = FUNCTIONS[node.func.id][1]
            if len(node.args) != arity:
                self._fail(f"'{node.func.id}' takes {arity} argument{'s' if arity > 1 else ''}, not {len(node.args)}")
            for n in node.args:
                self._check(n)
        else:
            self._fail(f"'{ast.unparse(node)}' is not allowed")

    def _eval(self, node, env):
        if isinstance(node, ast.Constant):
            return np.float64(node.value)
        if isinstance(node, ast.Name):
            return env[node.id] if node.id in env else np.float64(CONSTANTS[node.id])
        if isinstance(node, ast.BinOp):
            return BINARY[type(node.op)](self._eval(node.left, env), self._eval(node.right, env))
        if isinstance(node, ast.UnaryOp):
            return UNARY[type(node.op)](self._eval(node.operand, env))
        if isinstance(node, ast.Compare):
            left, out = self._eval(node.left, env), True
            for op, n in zip(node.ops, node.comparators):
                right = self._eval(n, env)
                out = np.logical_and(out, COMPARE[type(op)](left, right))
                left = right
            return out
        if isinstance(node, ast.BoolOp):
            combine = np.logical_and if isinstance(node.op, ast.And) else np.logical_or
            vals = [self._eval(n, env) for n in node.values]
            out = vals[0]
            for v in vals[1:]:
                out = combine(out, v)
            return out
        if isinstance(node, ast.IfExp):
            return np.where(self._eval(node.test, env), self._eval(node.body, env), self._eval(node.orelse, env))
        fn = FUNCTIONS[node.func.id][0]
        return fn(*[self._eval(n, env) for n in node.args])

    def __call__(self, **values):
        """The value (float64, broadcast over the array arguments); a UserError when it is not finite."""
        env = {k: (np.float64(v) if np.ndim(v) == 0 else np.asarray(v, np.float64)) for k, v in values.items()}
        with np.errstate(all="ignore"):
            out = np.asarray(self._eval(self.tree, env), np.float64)
        if not np.isfinite(out).all():
            at = ", ".join(f"{k}={v:g}" for k, v in values.items() if np.ndim(v) == 0)
            raise UserError(f"{self.where}: '{self.text}' is not finite" + (f" at {at}" if at else ""))
        return out

    def __repr__(self):
        return self.text


class TimeFunction:
    """A load's factor as an expression of t (-NAME_time), e.g. "min(t/0.5, 1)" or "sin(2*pi*t)"."""

    def __init__(self, text, where):
        self.expression = Expression(text, ("t",), where)

    def __call__(self, t):
        return float(self.expression(t=t))

    def __repr__(self):
        return self.expression.text
