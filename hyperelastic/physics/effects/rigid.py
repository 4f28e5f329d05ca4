"""A rigid face tied to a reference point (Abaqus' *COUPLING KINEMATIC / *RIGID BODY with a reference node, FEBio's
rigid bodies): the nodes of a surface move as one rigid body, x_a = c + R(theta) (X_a - P), about the reference point P
(default: the face's area centroid), displaced to c = P + u. Each of the reference point's six components (u_x, u_y,
u_z and the rotation vector theta_x, theta_y, theta_z: axis theta/|theta|, angle |theta|) is either prescribed as an
expression of t (-rigid_ux ..., -rigid_rx ...), loaded (-rigid_fx ... a force, -rigid_mx ... a moment about the
reference point: that component is free and found by the solve) or, given neither, held at zero (as -prescribe_faces
holds the components it is not given).

How: master-slave elimination. The face's nodes are held dofs of the Dirichlet elimination (system.py), placed by the
reference point's motion; a run with loaded components solves, around every step's solve, the reference point's
equilibrium for them (solving/rigid.py): the face's reaction (the force and the moment about c that the face needs
from outside) equals the applied force and moment. Why elimination and not Lagrange multipliers or a penalty: no
saddle point and no stiffness scale in the elastic system (CG, Jacobi, GAMG and p-multigrid see the same operator as
with a clamped face), the constraint is exact at any rotation, and the reaction is the residual at the held nodes as
for every other held surface (forces.py).

Rotations: R(theta) by Rodrigues' formula, and its variation dR = [J_l(theta) dtheta]x R with J_l the left Jacobian of
SO(3), J_l = I + (1 - cos a)/a^2 [theta]x + (a - sin a)/a^3 [theta]x^2, a = |theta| (e.g. T. D. Barfoot, State
Estimation for Robotics, 2017, sec. 7.1.5). A moment M about c does the work M . J_l dtheta: the equilibrium of a loaded
rotation component j is (J_l^T (M_reaction - M_applied))_j = 0, which for a rotation about one axis is M_j = M_applied,j.
"""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ...core.errors import UserError
from ...core.expressions import Expression
from ...core.options import Row, facet_sets, needs
from .base import Spec
from .dirichlet import HeldBody

COMPONENTS = ("ux", "uy", "uz", "rx", "ry", "rz")       # the reference point's motion: displacement, rotation vector
LOADS = ("fx", "fy", "fz", "mx", "my", "mz")            # its loads: force, moment about it


def skew(a):
    """[a]x: the matrix of a x ."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def _series(a):
    """(sin a / a, (1 - cos a)/a^2, (a - sin a)/a^3), by their Taylor series near 0."""
    if a < 1e-4:
        a2 = a * a
        return 1.0 - a2 / 6.0, 0.5 - a2 / 24.0, 1.0 / 6.0 - a2 / 120.0
    return np.sin(a) / a, (1.0 - np.cos(a)) / a ** 2, (a - np.sin(a)) / a ** 3


def rotation(theta):
    """R = exp([theta]x) (Rodrigues)."""
    K = skew(theta)
    s, c, _ = _series(float(np.linalg.norm(theta)))
    return np.eye(3) + s * K + c * K @ K


def left_jacobian(theta):
    """J_l(theta): d exp([theta]x) = [J_l dtheta]x exp([theta]x)."""
    K = skew(theta)
    _, c, s3 = _series(float(np.linalg.norm(theta)))
    return np.eye(3) + c * K + s3 * K @ K


class Rigid(HeldBody):
    """The rigid face's nodes as held dofs (all three components), placed by the reference point's motion q = (u,
    theta). q holds the attempt's values; `qn` the last accepted ones and `rate` their rate (the next attempt's
    predictor of the loaded components). Expressions are of t alone, the same on every rank."""
    name = "rigid"
    option = "-rigid"
    evaluates = True

    def __init__(self, X, vertices, surface, point, motion, loads, extent):
        """motion, loads: {component index 0..5: Expression}; extent: the face's largest distance from the point
        (on all ranks: the scale of the loaded components' perturbations)."""
        super().__init__(X, vertices)
        self.surface = surface
        self.point = np.asarray(point, float)
        self.arms = self.X0 - self.point                       # (n, 3) the nodes about the point, reference
        self.motion, self.loads = dict(motion), dict(loads)
        self.free = np.array([j in self.loads for j in range(6)])
        self.extent = float(extent) or 1.0
        self.q = np.zeros(6)
        self.qn = np.zeros(6)
        self.rate = np.zeros(6)
        self.t = 0.0

    # --- the motion ------------------------------------------------------------------------------
    def set_time(self, t):
        """The prescribed and held components of q at time t (the loaded ones keep their values)."""
        self.t = t
        for j in range(6):
            if not self.free[j]:
                self.q[j] = float(self.motion[j](t=t)) if j in self.motion else 0.0

    def place(self, q):
        """(n, 3) the face's node positions for the reference point's motion q."""
        return self.point + q[:3] + self.arms @ rotation(q[3:]).T

    def positions(self, t):
        self.set_time(t)
        return self.place(self.q)

    def center(self, q=None):
        return self.point + (self.q if q is None else q)[:3]

    def direction(self, j, q=None):
        """(n, 3) d(place)/dq_j at q: a translation e_j, or the rotation (J_l e_j) x (R arms)."""
        q = self.q if q is None else q
        if j < 3:
            w = np.zeros((len(self.vertices), 3))
            w[:, j] = 1.0
            return w
        axis = left_jacobian(q[3:])[:, j - 3]
        return np.cross(axis, self.arms @ rotation(q[3:]).T)

    # --- the loads ---------------------------------------------------------------------------------
    def applied(self, t):
        """(6,) the applied force and moment at time t (zero where a component is not loaded)."""
        return np.array([float(self.loads[j](t=t)) if j in self.loads else 0.0 for j in range(6)])

    def imbalance(self, F, M, q, t):
        """The loaded components' equilibrium residual: (F - F_applied)_j for a translation, (J_l^T (M -
        M_applied))_j for a rotation, with F, M the face's reaction (M about c)."""
        a = self.applied(t)
        e = np.concatenate([F - a[:3], left_jacobian(q[3:]).T @ (M - a[3:])])
        return e[self.free]

    # --- the step ---------------------------------------------------------------------------------
    def predict(self, h):
        """An attempt of size h begins: the loaded components from the accepted ones along their last rate."""
        self.q = np.where(self.free, self.qn + h * self.rate, self.qn)

    def accept(self, h):
        self.rate = np.where(self.free, (self.q - self.qn) / h, 0.0)
        self.qn = self.q.copy()

    def state(self):
        """What a checkpoint keeps: the accepted motion and the rate (12 numbers)."""
        return np.concatenate([self.qn, self.rate])

    def resume(self, state):
        state = np.asarray(state, float)
        self.qn, self.rate = state[:6].copy(), state[6:].copy()
        self.q = self.qn.copy()


@dataclass(frozen=True)
class Face:
    surface: str          # the facet set
    point: tuple          # the reference point, or None: the face's area centroid
    motion: dict          # {component index: Expression}
    loads: dict           # {component index: Expression}
    rtol: float           # the reference point's balance: relative to the face's force and moment scales
    max_it: int


def _read(opts, where):
    if not opts.has("rigid"):
        raise needs(where, "rigid", "-rigid SURFACE (the rigid face)")
    faces = facet_sets(opts, "rigid")
    if len(faces) != 1:
        raise UserError(f"option -rigid: one surface (the rigid face), not {len(faces)}: "
                        f"{','.join(n for n, _ in faces)}")
    motion, loads = {}, {}
    for j, (c, f) in enumerate(zip(COMPONENTS, LOADS)):
        if opts.has(f"rigid_{c}") and opts.has(f"rigid_{f}"):
            raise UserError(f"options -rigid_{c} and -rigid_{f}: a component of the reference point is either "
                            f"moved or loaded, not both")
        if opts.has(f"rigid_{c}"):
            motion[j] = Expression(opts.string(f"rigid_{c}"), ("t",), f"option -rigid_{c}")
        if opts.has(f"rigid_{f}"):
            loads[j] = Expression(opts.string(f"rigid_{f}"), ("t",), f"option -rigid_{f}")
    point = opts.vector("rigid_point")
    return Face(faces[0][0], None if point is None else tuple(point), motion, loads,
                opts.real("rigid_rtol", 1e-8, minimum=0), opts.integer("rigid_max_it", 25, minimum=1))


def centroid(space, surface):
    """The area centroid of a facet set over all ranks (each boundary facet lies on one rank), and its area."""
    tris = space.set_triangles([surface])[:, :3]
    X = space.X.reshape(-1, 3)
    a, b, c = X[tris[:, 0]], X[tris[:, 1]], X[tris[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    part = np.concatenate([[area.sum()], (area[:, None] * (a + b + c) / 3.0).sum(axis=0)])
    tot = space.mpi.allreduce(part, op=MPI.SUM)
    return tot[1:] / tot[0], tot[0]


def _build(p, ctx):
    sp = ctx.space
    if p.point is None:
        point, _ = centroid(sp, p.surface)
    else:
        point = np.asarray(p.point, float)
    vertices = sp.set_vertices(p.surface)
    X = sp.X.reshape(-1, 3)
    extent = sp.mpi.allreduce(float(np.linalg.norm(X[vertices] - point, axis=1).max(initial=0.0)), op=MPI.MAX)
    rb = Rigid(sp.X, vertices, p.surface, point, p.motion, p.loads, extent)
    rb.rtol, rb.max_it = p.rtol, p.max_it
    return [rb]


SPEC = Spec(
    "rigid", "a rigid face moved or loaded through a reference point", implied_by=("rigid",), read=_read,
    sets=lambda p: [("rigid", p.surface, "facets")], build=_build,
    rows=(Row(("rigid", "rigid_point"), "-rigid S -rigid_point X,Y,Z",
              "a rigid face: surface S moves as one rigid body with its reference point (default: S's area "
              "centroid); its forces table row is the face's reaction, the statistics' `rigid_*` columns the "
              "point's motion and the reaction about it"),
          Row(tuple(f"rigid_{c}" for c in COMPONENTS), "-rigid_ux -rigid_uy -rigid_uz -rigid_rx -rigid_ry -rigid_rz "
              "EXPR", "the reference point's displacement and rotation vector [rad] as expressions of `t` "
              "(`-rigid_rz \"pi/2*t\"`: a quarter turn about z); a component given neither a motion nor a load is "
              "held at 0"),
          Row(tuple(f"rigid_{f}" for f in LOADS) + ("rigid_rtol", "rigid_max_it"),
              "-rigid_fx -rigid_fy -rigid_fz -rigid_mx -rigid_my -rigid_mz EXPR, -rigid_rtol r, -rigid_max_it n",
              "a force [N] or a moment about the reference point [N m] on the face as expressions of `t`: that "
              "component is free and found by the step's balance of the point (Newton on the loaded components, "
              "to r of the face's force and moment scales, default 1e-8, at most n iterations, default 25; "
              "backward Euler and quasi-static runs). `-rigid_fz 0`: free in z")))
