import numpy as np

from .base import ramp


class Constraint:
    """Dirichlet condition on components of a set of local vertices: positions g(t). `comps` (n, 3)
    bool says which components of each vertex are held (default: all three; e.g. a symmetry plane
    x = 0 holds x only). Imposed by the system (see system.py) by elimination, not as a residual term."""
    name = "constraint"

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


class Prescribed(Constraint):
    """Prescribed time-dependent positions of the thesis framework's scenes, with s = amount*min(t,1):
    rotate_x (about the x axis through the origin by angle s), rotate_y (about the y axis),
    squeeze_x (x = X/(1+s), y = Y, z = Z) and stretch_x (x = X (1+s))."""
    name = "prescribed"
    MOTIONS = ("rotate_x", "rotate_y", "squeeze_x", "stretch_x")

    def __init__(self, X, vertices, motion, amount, comps=None):
        super().__init__(X, vertices, comps)
        self.motion = motion
        self.amount = float(amount)

    def positions(self, t):
        s = ramp(t, self.amount)
        X = self.X0
        out = X.copy()
        c, sn = np.cos(s), np.sin(s)
        if self.motion == "rotate_x":
            out[:, 1] = c * X[:, 1] - sn * X[:, 2]
            out[:, 2] = sn * X[:, 1] + c * X[:, 2]
        elif self.motion == "rotate_y":
            out[:, 0] = c * X[:, 0] + sn * X[:, 2]
            out[:, 2] = -sn * X[:, 0] + c * X[:, 2]
        elif self.motion == "squeeze_x":
            out[:, 0] = X[:, 0] / (1.0 + s)
        elif self.motion == "stretch_x":
            out[:, 0] = X[:, 0] * (1.0 + s)
        return out
