import numpy as np

from .base import ramp


class Constraint:
    """Dirichlet condition on components of a set of local vertices: positions g(t). `comps` (n, 3)
    bool says which components of each vertex are held (default: all three; e.g. a symmetry plane
    x = 0 holds x only). Imposed by the system (see system.py) by elimination, not as a residual term."""
    name = "constraint"
    evaluates = False      # values(t) may raise (an expression not finite at some vertices)

    def __init__(self, X, vertices, comps=None):
        self.vertices = np.asarray(vertices, np.int64)
        self.comps = np.ones((len(self.vertices), 3), bool) if comps is None else np.asarray(comps, bool)
        self.X0 = X[self.vertices]
        self.dofs = (3 * self.vertices[:, None] + np.arange(3))[self.comps]      # local dofs, row-major
        self.evals = self.applies = 0
        self.seconds = 0.0

    def positions(self, t):
        raise NotImplementedError

    def values(self, t):
        """Prescribed positions of the held dofs (in the order of self.dofs)."""
        return self.positions(t)[self.comps]


class Fixed(Constraint):
    """Vertices (or some of their components) held at their reference positions."""
    name = "fixed"

    def positions(self, t):
        return self.X0


# The thesis framework's prescribed motions as expressions of t and the reference coordinates X, Y, Z,
# with s = A min(t,1) (A = -prescribe_amount): rotations about the x and y axes through the origin by
# the angle s, a squeeze x = X/(1+s) and a stretch x = X (1+s). Components not listed stay at X.
_S = "(A*min(t, 1))"
PRESETS = {
    "rotate_x": {"y": f"cos{_S}*Y - sin{_S}*Z", "z": f"sin{_S}*Y + cos{_S}*Z"},
    "rotate_y": {"x": f"cos{_S}*X + sin{_S}*Z", "z": f"-sin{_S}*X + cos{_S}*Z"},
    "squeeze_x": {"x": f"X/(1 + {_S})"},
    "stretch_x": {"x": f"X*(1 + {_S})"},
}
PRESETS = {m: {k: (e, "position") for k, e in d.items()} for m, d in PRESETS.items()}


class Prescribed(Constraint):
    """Time-dependent positions of a set: per component an expression (expressions.Expression in t,
    X, Y, Z and the amount A) giving the position or the displacement; evaluated vectorized over the
    set's vertices. The presets above are the thesis' four motions."""
    name = "prescribed"
    evaluates = True

    def __init__(self, X, vertices, expressions, amount=1.0, comps=None):
        """expressions: {"x"|"y"|"z": (Expression, "position" | "displacement")}."""
        super().__init__(X, vertices, comps)
        self.expressions = expressions
        self.amount = float(amount)

    def positions(self, t):
        X = self.X0
        out = X.copy()
        if not len(X):
            return out
        for k, (expr, kind) in self.expressions.items():
            i = "xyz".index(k)
            val = expr(t=t, X=X[:, 0], Y=X[:, 1], Z=X[:, 2], A=self.amount)
            out[:, i] = val if kind == "position" else X[:, i] + val
        return out
