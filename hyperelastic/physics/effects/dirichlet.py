from dataclasses import dataclass

import numpy as np

from ...core.errors import UserError
from ...core.expressions import Expression
from ...core.options import Row, facet_sets, needs
from .base import Spec


class Constraint:
    """Dirichlet condition on components of a set of local vertices: positions g(t). `comps` (n, 3)
    bool says which components of each vertex are held (default: all three; e.g. a symmetry plane
    x = 0 holds x only). Imposed by the system (see system.py) by elimination, not as a residual term."""
    name = "constraint"
    option = "-fix"        # the option that holds it (error lines)
    evaluates = False      # values(t) may raise (an expression not finite at some vertices)
    path_given = True      # the scene gives its nodes' paths (contact checks them before a step: seams.StepStart)

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


class HeldBody(Constraint):
    """A seam (physics/effects/seams.py): held dofs whose targets follow a body of their own, a reference point's
    motion q = (u, theta) with some components prescribed and the loaded ones (`free`) balanced around each step's
    solve (solving/rigid.py), its reaction reported about its point (`center`) and its state kept in checkpoints. Its
    nodes' paths are not the scene's to give (`path_given`). One per run (rigid.Rigid: a rigid face)."""
    path_given = False
    free = np.zeros(6, bool)        # the loaded components of q
    surface = ""                    # the facet set it holds (its name in lines and columns)

    def predict(self, h):
        """An attempt of size h begins: the loaded components predicted."""
        raise NotImplementedError

    def accept(self, h):
        """The attempt of size h is accepted."""
        raise NotImplementedError

    def state(self):
        """What a checkpoint keeps of it (an array)."""
        raise NotImplementedError

    def resume(self, state):
        """Continue from a checkpoint's `state()`."""
        raise NotImplementedError

    def center(self, q=None):
        """The reference point's position at the motion q (default: the attempt's)."""
        raise NotImplementedError

    def direction(self, j, q=None):
        """(n, 3): d(node positions)/dq_j at q."""
        raise NotImplementedError

    def imbalance(self, F, M, q, t):
        """The loaded components' equilibrium residual for the reaction (F, M about center(q)) at time t."""
        raise NotImplementedError


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
    option = "-prescribe_faces"
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


def held(space, specs):
    """(local vertices, (n, 3) held components) of [(set name, components)] (a vertex in several sets
    holds the union of their components)."""
    comps = np.zeros((space.nlv, 3), bool)
    for name, cs in specs:
        comps[np.ix_(space.set_vertices(name), ["xyz".index(c) for c in cs])] = True
    vertices = np.flatnonzero(comps.any(axis=1))
    return vertices, comps[vertices]


def _faces(option):
    return lambda p: [(option, n, "facets") for n, _ in p.faces]


@dataclass(frozen=True)
class Clamp:
    faces: tuple      # ((set name, components), ...)


def _read_fixed(opts, where):
    if not opts.has("fix"):
        raise needs(where, "fixed", "-fix faces (e.g. left)")
    return Clamp(tuple(facet_sets(opts, "fix", components=True)))


FIXED = Spec(
    "fixed", "surfaces held at their reference positions", implied_by=("fix",), read=_read_fixed,
    sets=_faces("fix"), build=lambda p, ctx: [Fixed(ctx.space.X, *held(ctx.space, p.faces))],
    rows=(Row(("fix",), "-fix S[:xyz],…", "hold surfaces at their reference positions, all components or those "
              "named: `-fix base` (clamp), `-fix symmetry:x` (roller / symmetry plane); a component may not be "
              "both fixed and prescribed on the same surface"),))


@dataclass(frozen=True)
class Motion:
    faces: tuple          # ((set name, components), ...)
    amount: float         # A of the expressions
    motion: str           # the preset, or None
    expressions: dict     # {"x"|"y"|"z": (Expression, "position" | "displacement")}


def _read_prescribed(opts, where):
    """-prescribe_faces S[:xyz],... moved by a preset (-prescribe_motion M, amount -prescribe_amount A)
    and/or per component by expressions of t, X, Y, Z, A: positions -prescribe_x/_y/_z or displacements
    -prescribe_ux/_uy/_uz (an expression replaces the preset's for its component); components
    with neither stay at their reference positions."""
    given = [k for k in ("x", "y", "z") if opts.has(f"prescribe_{k}") or opts.has(f"prescribe_u{k}")]
    if not opts.has("prescribe_faces") or not (opts.has("prescribe_motion") or given):
        raise needs(where, "prescribed", "-prescribe_faces and -prescribe_motion or expressions -prescribe_x/_ux ...")
    faces = tuple(facet_sets(opts, "prescribe_faces", components=True))
    amount = opts.real("prescribe_amount", 1.0)
    motion = opts.choice("prescribe_motion", tuple(PRESETS), None) if opts.has("prescribe_motion") else None
    exprs = {k: (text, kind, f"preset {motion}") for k, (text, kind) in PRESETS[motion].items()} if motion else {}
    held_ = set("".join(c for _, c in faces))
    for k in "xyz":
        if opts.has(f"prescribe_{k}") and opts.has(f"prescribe_u{k}"):
            raise UserError(f"options -prescribe_{k} and -prescribe_u{k}: give the position or the displacement "
                            f"of component {k}, not both")
        for kind, key in (("position", f"prescribe_{k}"), ("displacement", f"prescribe_u{k}")):
            if opts.has(key):
                if k not in held_:
                    raise UserError(f"option -{key}: component {k} is not held on any of -prescribe_faces "
                                    f"({','.join(n + ':' + c for n, c in faces)})")
                exprs[k] = (opts.string(key), kind, f"option -{key}")
    return Motion(faces, amount, motion, {k: (Expression(text, ("t", "X", "Y", "Z", "A"), w), kind)
                                          for k, (text, kind, w) in exprs.items()})


def _build_prescribed(p, ctx):
    vertices, comps = held(ctx.space, p.faces)
    return [Prescribed(ctx.space.X, vertices, p.expressions, p.amount, comps)]


PRESCRIBED = Spec(
    "prescribed", "surfaces moved as expressions of time prescribe",
    implied_by=("prescribe_motion", "prescribe_x", "prescribe_y", "prescribe_z", "prescribe_ux", "prescribe_uy",
                "prescribe_uz"),
    read=_read_prescribed, sets=_faces("prescribe_faces"), build=_build_prescribed,
    rows=(Row(("prescribe_faces", "prescribe_motion", "prescribe_amount"),
              "-prescribe_faces S[:xyz],… -prescribe_motion M -prescribe_amount A",
              f"a preset motion of the surfaces: M = {', '.join(PRESETS)} with s = A·min(t,1)"),
          Row(("prescribe_x", "prescribe_y", "prescribe_z", "prescribe_ux", "prescribe_uy", "prescribe_uz"),
              "-prescribe_x -prescribe_y -prescribe_z EXPR, -prescribe_ux -prescribe_uy -prescribe_uz EXPR",
              "per component, the position (or displacement) of the `-prescribe_faces` vertices as an expression "
              "of `t`, the reference `X, Y, Z` and `A`; replaces the preset's for that component; components "
              "with neither stay at their reference")))
