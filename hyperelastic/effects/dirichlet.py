import numpy as np

from .base import ramp


class Constraint:
    """Dirichlet condition on all three components of a set of local vertices: positions g(t).
    Imposed by the system (see system.py) by elimination, not as a residual term."""
    name = "constraint"

    def __init__(self, X, vertices):
        self.vertices = np.asarray(vertices, np.int64)
        self.X0 = X[self.vertices]
        self.evals = self.applies = 0
        self.seconds = 0.0

    def positions(self, t):
        raise NotImplementedError


class Fixed(Constraint):
    """Vertices held at their reference positions."""
    name = "fixed"

    def positions(self, t):
        return self.X0


class Prescribed(Constraint):
    """Prescribed time-dependent positions of the thesis framework's scenes, with s = amount*min(t,1):
    rotate_x (about the x axis through the origin by angle s), rotate_y (about the y axis),
    squeeze_x (x = X/(1+s), y = Y, z = Z) and stretch_x (x = X (1+s))."""
    name = "prescribed"
    MOTIONS = ("rotate_x", "rotate_y", "squeeze_x", "stretch_x")

    def __init__(self, X, vertices, motion, amount):
        super().__init__(X, vertices)
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
