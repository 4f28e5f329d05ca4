"""Contact with rigid obstacles (issue 46, its first part): the kinds of obstacles.py (planes, spheres, boxes), each
moving by a translation of t, that the body's boundary may touch and press on but never pass through. What it needs of
the solver beyond a residual and a tangent it declares (seams.py): a step limiter (continuous collision detection), a
domain check, a say in each step's start (held paths, pushes by moving obstacles) and an adaptive stiffness.

Energy: IPC's barrier (Li et al., "Incremental Potential Contact", ACM Trans. Graph. 39(4), 2020, eq. 6) of each
contact node's distance d to each obstacle,
    b(d) = -(d - dhat)^2 ln(d / dhat) for 0 < d < dhat, 0 beyond (C2 at dhat, infinite as d -> 0),
weighted by the node's share A_a of the contact surface's reference area: E = kappa sum_a A_a sum_k b(d_ak), so that
-kappa b'(d) is a contact pressure, independent of the mesh. Residual kappa A_a b'(d) grad d; tangent
kappa A_a (b'' g g^T + b' H_d) with g = grad d: a plane's H_d is 0 (exact), and so is a box's opposite a face; a
sphere's (I - g g^T)/rho and a box's curvature opposite an edge or corner have the negative factor b' and are dropped
(the positive semi-definite projection IPC makes), so each node adds one 3x3 block
on the diagonal: the cell pattern already holds it, every Jacobian mode takes it.
Never through: the energy is +infinity at d <= 0 (the SNES objective refuses such an iterate, the residual reports a
domain error) and `max_step` gives the largest fraction of a Newton update that keeps every node at least
(1 - CCD_MARGIN) of the way to its first contact along the update (a node moving on a line against a fixed plane or
sphere: the exact time of impact), which the solver's line-search pre-check applies as it applies the inversion
guard. An obstacle moves between steps only (its position at the step's end time), so an obstacle that moves into a
node within one step makes that step's start infeasible and the step is retried shorter.
Defaults: dhat 1e-3 of the part's bounding-box diagonal (IPC's), kappa = KAPPA_SCALE E / dhat (E the largest Young's
modulus of the solids): the pressure at d = dhat/2 is then 0.12 E, at dhat/10 1.2 E.
Each rank sums its owned nodes: the same answer on any rank count, no surface gathered (a node meets an analytic
obstacle alone). Self-contact, contact between pieces of the mesh (-contact_self) and triangulated obstacles
(-obstacle mesh:FILE): self_contact.py, built by the same spec. Friction (-contact_friction): IPC's smoothed, lagged
Coulomb friction (`mollifier`, `_slips`). Under -integrator ts contact acts at the step's end state (`end_state`,
System._end_state); with -energy_momentum the barrier is a discrete gradient (`residual_discrete_gradient`)."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ...core.errors import UserError, raise_agreed
from ...core.expressions import TimeFunction
from ...core.options import Row, facet_sets
from .base import Energy, NodeBlocks, Spec, timed
from .obstacles import KINDS, kinds_help, linear_motion, parse
from .seams import PUSH_LIMIT, AdaptiveStiffness, DomainCheck, Results, ResultRow, StepLimiter, StepStart

CCD_MARGIN = 0.1            # a Newton update stops this fraction short of the first contact along it
KAPPA_SCALE = 0.1           # kappa = KAPPA_SCALE E / dhat by default
DHAT_SCALE = 1e-3           # dhat = DHAT_SCALE x the bounding-box diagonal by default
DHAT_MAX = 0.1              # and at most DHAT_MAX x it (-contact_dhat 1e20 ran to a 587 km displacement: issue 73)
ADAPTIVE_RANGE = 100.0      # -contact_kappa adaptive: kappa in [kappa_min, ADAPTIVE_RANGE kappa_min] (IPC's ratio)
EPS_V = 1e-3                # -contact_friction_eps [m/s]: dynamic runs' smoothing speed (IPC's epsilon_v)
SLIP_SCALE = 0.1            # quasi-static runs' smoothing slip a step, -contact_friction_slip: SLIP_SCALE dhat



def barrier(d, dhat):
    """(b, b', b'') of IPC's barrier at distances d (0 where d >= dhat; b = +inf where d <= 0)."""
    d = np.asarray(d, float)
    on = d < dhat
    s = np.where(on & (d > 0), d, dhat)
    ln, e = np.log(s / dhat), s - dhat
    b = np.where(on, -e * e * ln, 0.0)
    b1 = np.where(on, -2 * e * ln - e * e / s, 0.0)
    b2 = np.where(on, -2 * ln - 4 * e / s + e * e / (s * s), 0.0)
    bad = on & (d <= 0)
    return np.where(bad, np.inf, b), np.where(bad, np.nan, b1), np.where(bad, np.nan, b2)


def mollifier(y, eps):
    """(f0, f1/y, (f1' y - f1)/y^2) of IPC's smoothed Coulomb friction at slip lengths y >= 0 (Li et al. 2020, eq. 14:
    f1(y) = 2y/eps - y^2/eps^2 below eps, 1 beyond; f0' = f1, f0(eps) = eps), all finite at y = 0. The energy
    mu lam f0(|u|) has the gradient mu lam (f1/y) u and the Hessian mu lam ((f1/y) T + (f1' y - f1)/y^2 u u^T / y)."""
    y = np.asarray(y, float)
    low = y < eps
    yb = np.maximum(y, eps)                                        # (the branch beyond eps, where it is used)
    f0 = np.where(low, -y ** 3 / (3 * eps * eps) + y * y / eps + eps / 3, y)
    f1y = np.where(low, 2 / eps - y / (eps * eps), 1 / yb)
    f2 = np.where(low, -1 / (eps * eps), -1 / (yb * yb))
    return f0, f1y, f2


class Contact(NodeBlocks, StepLimiter, DomainCheck, StepStart, AdaptiveStiffness, Results):
    """The barrier of the contact nodes (this rank's owned nodes of the contact surfaces) against the obstacles."""
    name = "contact"
    linear = False
    conservative = True
    symmetric = True
    domain = True            # undefined (d <= 0) is counted as the elastic kernels count inverted cells
    end_state = True         # (generalized-alpha: acts at the step's end, System._end_state)
    discrete_gradient = True  # (-energy_momentum: residual_discrete_gradient)

    def __init__(self, nodes, area, X, input_ids, obstacles, dhat, kappa, edge=None, mu=0.0, eps_v=EPS_V, eps_d=None,
                 mpi=None, numbers=None):
        """mu: Coulomb's friction coefficient (0: frictionless); eps_v [m/s]: the slip speed below which friction is
        smoothed (IPC's epsilon_v; a slip length of eps_v h a step); eps_d [m]: in a quasi-static run, the slip a step
        below which it is smoothed instead (time there is a load parameter: a speed in it means nothing). mpi: the
        ranks that build it together (the start check is theirs: a node inside an obstacle is one rank's)."""
        super().__init__()
        self.mu, self.eps_v, self.eps_d = float(mu), float(eps_v), eps_d
        self.friction = []        # per obstacle, lagged at the step's start: (normal force, tangent projector, x^n, move)
        self.nodes, self.area = np.asarray(nodes, np.int64), np.asarray(area, float)
        self.edge = np.full(len(self.nodes), np.inf) if edge is None else np.asarray(edge, float)
        self.obstacles, self.dhat, self.kappa = tuple(obstacles), float(dhat), float(kappa)
        self.numbers = tuple(numbers or range(1, len(self.obstacles) + 1))     # (each one's place in -obstacle)
        self.input_ids = np.asarray(input_ids, np.int64)
        self.now = self.before = [o.at(0.0) for o in self.obstacles]
        self.moving = any(o.motion is not None for o in self.obstacles)
        self.blocks = np.zeros((len(self.nodes), 3, 3))
        self.held = np.zeros(0, np.int64)     # (the contact nodes whose path the scene gives: hold)
        x = np.asarray(X, float).reshape(-1, 3)[self.nodes]
        inside = None
        for o, v in zip(self.obstacles, self.now):                       # a start inside an obstacle: one line
            d = o.form.distances(v, x)[0]
            if len(d) and d.min() <= 0 and inside is None:
                i = int(np.argmin(d))
                inside = (f"-obstacle {o.text}: node {int(input_ids[i])} of the contact surface at {x[i].tolist()} "
                          f"lies {'inside' if d[i] < 0 else 'on'} it at the start (distance {d[i]:.3g}): a start "
                          "state must be free of contact")
        raise_agreed(mpi, inside)

    def begin_step(self, t, h, xn, vn):
        self.before = [o.at(t - h) for o in self.obstacles]       # (where the step starts: an attempt's retry too)
        self.now = [o.at(t) for o in self.obstacles]
        if self.mu > 0 and xn is not None:
            # lagged friction (IPC sec. 5): each node's normal force kappa A |b'(d)| and tangent plane at the step's
            # start, the slip u = T (x - x^n - the obstacle's move), smoothed below eps_v h (quasi-static: eps_d)
            xc = np.asarray(xn).reshape(-1, 3)[self.nodes]
            self.slip_eps = self.eps_v * h if self.eps_d is None else self.eps_d
            self.friction = []
            for o, old in zip(self.obstacles, self.before):
                d, g = o.form.distances(old, xc)
                lam = np.nan_to_num(-self.kappa * self.area * barrier(d, self.dhat)[1], nan=0.0)
                T = np.eye(3) - g[:, :, None] * g[:, None, :]
                self.friction.append((lam, T, xc.copy(), o.shift(t) - o.shift(t - h)))

    def _slips(self, x):
        """Per obstacle with friction: (lagged normal force, tangent projector, slip u (n, 3), |u|)."""
        xc = x.reshape(-1, 3)[self.nodes]
        out = []
        for lam, T, x0, move in self.friction:
            u = np.einsum("nij,nj->ni", T, xc - x0 - move)
            out.append((lam, T, u, np.linalg.norm(u, axis=1)))
        return out

    def _friction_potential(self, x):
        return sum(float(self.mu * (lam * mollifier(y, self.slip_eps)[0]).sum()) for lam, _, _, y in self._slips(x))

    def pushed(self, x, base=None):
        """(x with every contact node that the obstacles' move since the step's start brought within dhat moved out
        along the distance's gradient, to its distance at the step's start (base, default x) where that was within
        dhat (a node in contact moves with the obstacle), else to dhat (a node the obstacle reaches: just out of the
        barrier's range); whether
        every push stays within PUSH_LIMIT of the node's shortest surface edge): the integrator's start where the last
        step's rate does not carry the body along (a plate moved into the gap pushes the nodes it would reach, and
        only those; the cells beside them take the strain until Newton relaxes it: Starts.pushed refuses a start
        that would invert one)."""
        out = x.copy()
        on = out.reshape(-1, 3)
        ok = True
        for o, old, new in zip(self.obstacles, self.before, self.now):
            if o.motion is None:
                continue
            xc = on[self.nodes]
            d_old = np.minimum(o.form.distances(old, xc if base is None else base.reshape(-1, 3)[self.nodes])[0],
                               self.dhat)
            d_new, g = o.form.distances(new, xc)
            closer = d_new < d_old
            push = (d_old - d_new)[closer]
            ok = ok and bool((push <= PUSH_LIMIT * self.edge[closer]).all())
            on[self.nodes[closer]] += push[:, None] * g[closer]
        return out, ok

    def _terms(self, x):
        """Per obstacle: (d, g) of the contact nodes at local positions x."""
        xc = x.reshape(-1, 3)[self.nodes]
        return [o.form.distances(v, xc) for o, v in zip(self.obstacles, self.now)]

    def _potential(self, terms):
        return sum(float(self.kappa * (self.area * barrier(d, self.dhat)[0]).sum()) for d, _ in terms)

    def potential(self, x):
        return self._potential(self._terms(x)) + (self._friction_potential(x) if self.friction else 0.0)

    @timed("evals")
    def residual(self, x, r):
        self.undefined = 0
        rn = r.reshape(-1, 3)
        for d, g in self._terms(x):
            self.undefined += int((d <= 0).sum())
            b1 = barrier(d, self.dhat)[1]
            np.add.at(rn, self.nodes, (self.kappa * self.area * b1)[:, None] * g)
        self._friction_forces(x, rn)

    def _friction_forces(self, x, rn):
        """rn += the friction potential's gradient mu lam (f1/y) u at the slips of x (none without friction)."""
        for lam, _, u, y in self._slips(x) if self.friction else ():
            np.add.at(rn, self.nodes, (self.mu * lam * mollifier(y, self.slip_eps)[1])[:, None] * u)

    def undefined_at(self, x):
        return sum(int((d <= 0).sum()) for d, _ in self._terms(x))

    def crossing(self, x):
        xc = x.reshape(-1, 3)[self.nodes]
        for o, (d, _) in zip(self.obstacles, self._terms(x)):
            if len(d) and d.min() <= 0:
                i = int(np.argmin(d))
                return (f"-obstacle {o.text} reaches contact node {int(self.input_ids[i])} at "
                        f"{np.round(xc[i], 6).tolist()} ({d[i]:.3g} inside it)")
        return ""

    def residual_discrete_gradient(self, x, base, r):
        """-energy_momentum's midpoint stage x: r += a discrete gradient of the barrier from the step's start base to
        x1 = 2 x - base, node by node (Gonzalez's form with the ends' gradients): G = (p(x1) - p(x0)) D/|D|^2 +
        (I - D D^T/|D|^2) (g(x0) + g(x1))/2, so that G . D = p(x1) - p(x0) exactly (the barrier's energy change is
        the work of its force over the step) and G -> the gradient as D -> 0. Friction, which dissipates, is added
        at x1. Only the ends are evaluated: they are where the pre-check keeps the body off the obstacles."""
        x1 = 2 * x - base
        self.undefined = 0
        rn = r.reshape(-1, 3)
        a, b = base.reshape(-1, 3)[self.nodes], x1.reshape(-1, 3)[self.nodes]
        D = b - a
        DD = (D * D).sum(axis=1)
        moved = DD > 1e-300
        for (d0, g0), (d1, g1) in zip(self._terms(base), self._terms(x1)):
            self.undefined += int((d1 <= 0).sum())
            b0, b1 = barrier(d0, self.dhat)[:2], barrier(d1, self.dhat)[:2]
            p0, p1 = self.kappa * self.area * b0[0], self.kappa * self.area * b1[0]
            G0, G1 = (self.kappa * self.area * b0[1])[:, None] * g0, (self.kappa * self.area * b1[1])[:, None] * g1
            mean = 0.5 * (G0 + G1)
            along = np.where(moved, (p1 - p0 - (mean * D).sum(axis=1)) / np.where(moved, DD, 1.0), 0.0)
            np.add.at(rn, self.nodes, mean + along[:, None] * D)
        self._friction_forces(x1, rn)

    def linearize(self, x):
        self.blocks[:] = 0.0
        for d, g in self._terms(x):
            b2 = np.nan_to_num(barrier(d, self.dhat)[2], nan=0.0)
            self.blocks += (self.kappa * self.area * b2)[:, None, None] * g[:, :, None] * g[:, None, :]
        for lam, T, u, y in self._slips(x) if self.friction else ():
            # mu lam (f1/y T + (f1' y - f1)/y^3 u u^T): positive semi-definite as it is (eigenvalues 2/eps - 2y/eps^2
            # along u and f1/y across it below eps; 0 and 1/y beyond)
            _, f1y, f2 = mollifier(y, self.slip_eps)
            uu = u[:, :, None] * u[:, None, :] / np.maximum(y, 1e-300)[:, None, None]     # (u u^T / y: 0 at u = 0)
            self.blocks += (self.mu * lam)[:, None, None] * (f1y[:, None, None] * T + f2[:, None, None] * uu)

    def max_step(self, x, dx):
        """The largest fraction (<= 1) of the update dx from x that no contact node crosses an obstacle along: each
        node stops CCD_MARGIN short of its time of impact (this rank's nodes; the solver takes the ranks' minimum)."""
        xc, dc = x.reshape(-1, 3)[self.nodes], dx.reshape(-1, 3)[self.nodes]
        s = 1.0
        for o, v in zip(self.obstacles, self.now):
            toi = o.form.time_of_impact(v, xc, dc)
            if len(toi):
                s = min(s, (1.0 - CCD_MARGIN) * float(toi.min()))
        return s

    def barrier_gradient(self, x, r):
        """r += the barrier's gradient per unit kappa at local positions x (no friction)."""
        rn = r.reshape(-1, 3)
        for d, g in self._terms(x):
            np.add.at(rn, self.nodes, np.nan_to_num(self.area * barrier(d, self.dhat)[1])[:, None] * g)

    def hold(self, held):
        """held: per local node, whether the scene prescribes all three of its components (its path is given)."""
        self.held = np.flatnonzero(np.asarray(held, bool)[self.nodes])

    def held_collision(self, x0, x1):
        """The first fraction s of the straight move of the held contact nodes from local positions x0 (the step's
        start, the obstacles where begin_step found them) to x1 (their targets, the obstacles at the step's end) at
        which one meets an obstacle, with the node in words; None if none does (this rank's nodes)."""
        first = None
        if not len(self.held):
            return None
        a = x0.reshape(-1, 3)[self.nodes[self.held]]
        b = x1.reshape(-1, 3)[self.nodes[self.held]]
        for o, old, new in zip(self.obstacles, self.before, self.now):
            s = o.form.impact_moving(old, new, a, b)
            if len(s) and s.min() <= 1 and (first is None or s.min() < first[0]):
                i = int(np.argmin(s))
                first = (float(s[i]), f"-obstacle {o.text} and the held node at {np.round(a[i], 6).tolist()}")
        return first

    def moves_linearly(self, t0, t1):
        return linear_motion(self.obstacles, t0, t1)

    def point_values(self, x):
        """contact_pressure: -kappa b'(d) summed over the obstacles at each contact node (the barrier's force per unit
        of the node's reference area: Abaqus' CPRESS); contact_status: the number (in -obstacle's order, from 1) of the
        nearest obstacle a node is within dhat of, 0 where none."""
        n = len(x) // 3
        pressure, status = np.zeros(n), np.zeros(n)
        nearest = np.full(len(self.nodes), np.inf)
        for k, (d, _) in enumerate(self._terms(x)):
            b1 = np.nan_to_num(barrier(d, self.dhat)[1], nan=0.0)
            pressure[self.nodes] += -self.kappa * b1
            closer = (d < self.dhat) & (d < nearest)
            status[self.nodes[closer]] = k + 1
            nearest = np.where(closer, d, nearest)
        return {"contact_pressure": pressure, "contact_status": status}

    def result_rows(self, x, t):
        """Per obstacle (named by its place in -obstacle, from 1): its force on the body (the barrier's and
        friction's: what the forces table's `load contact` sums), the reference area of the contact nodes within dhat
        of it, its translation at t."""
        rows = []
        slips = self._slips(x) if self.friction else [None] * len(self.obstacles)
        for k, (o, (d, g), slip) in enumerate(zip(self.obstacles, self._terms(x), slips)):
            b1 = np.nan_to_num(barrier(d, self.dhat)[1], nan=0.0)
            force = -((self.kappa * self.area * b1)[:, None] * g).sum(axis=0)
            if slip is not None:
                lam, _, u, y = slip
                force = force - ((self.mu * lam * mollifier(y, self.slip_eps)[1])[:, None] * u).sum(axis=0)
            rows.append(ResultRow(f"obstacle{self.numbers[k]}", force, float(self.area[d < self.dhat].sum()),
                                  o.shift(t)))
        return rows

    def energy(self, x, v):
        terms = self._terms(x)
        active = sum(int((d < self.dhat).sum()) for d, _ in terms)
        dmin = min((float(d.min()) for d, _ in terms if len(d)), default=np.inf)
        out = {"contact_energy": self._potential(terms), "contact_nodes": active, "contact_dmin": dmin,
               "contact_kappa": self.kappa}
        if self.mu > 0:                        # (nodes pressed at the step's start that slid more than eps_v h)
            out["contact_sliding"] = sum(int(((lam > 0) & (y >= self.slip_eps)).sum())
                                         for lam, _, _, y in self._slips(x)) if self.friction else 0
        return out


@dataclass(frozen=True)
class ContactParams:
    obstacles: tuple          # Obstacle, in the order -obstacle lists them
    faces: tuple              # the contact surfaces ((set, components) as facet_sets gives them)
    dhat: float               # None: DHAT_SCALE x the bounding-box diagonal
    kappa: float              # None: KAPPA_SCALE E / dhat
    self_contact: bool = False  # -contact_self: the contact surfaces against themselves (self_contact.py)
    mu: float = 0.0           # -contact_friction: Coulomb's coefficient
    eps_v: float = None       # -contact_friction_eps [m/s] (dynamic runs; None: EPS_V)
    adaptive: bool = False    # -contact_kappa adaptive: IPC's balance at each step's start (System._adapt_contact)
    eps_d: float = None       # -contact_friction_slip [m] (quasi-static runs; None: SLIP_SCALE dhat)


def split_top(text, sep):
    """text split at `sep` outside parentheses (an expression's own commas stay)."""
    out, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if ch == sep and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    return out + [cur]


def _read(opts, where):
    texts = [t for t in split_top(opts.string("obstacle", "") or "", ";") if t.strip()]
    self_contact = opts.flag("contact_self", False)
    if not texts and not self_contact:
        raise UserError(f"{where}: effect 'contact' needs -obstacle (" +
                        f"{kinds_help()}) or -contact_self")
    motions = [None] * len(texts)
    if opts.has("obstacle_motion"):
        given = split_top(opts.string("obstacle_motion"), ";")
        if len(given) != len(texts):
            raise UserError(f"option -obstacle_motion: {len(given)} translations for {len(texts)} obstacles (one "
                            "'EX,EY,EZ' of t per obstacle, separated by ';')")
        for i, g in enumerate(given):
            parts = split_top(g, ",")
            if len(parts) != 3:
                raise UserError(f"option -obstacle_motion: '{g}' is not three expressions of t (EX,EY,EZ)")
            motions[i] = tuple(TimeFunction(p, "option -obstacle_motion") for p in parts)
            for f in motions[i]:
                f(0.0)
    obstacles = tuple(parse(t, m) for t, m in zip(texts, motions))
    faces_ = tuple(facet_sets(opts, "contact_faces", default="boundary"))
    mu = opts.real("contact_friction", 0.0, minimum=0, exclusive=False)
    eps_v = opts.real("contact_friction_eps", None, minimum=0)
    eps_d = opts.real("contact_friction_slip", None, minimum=0)
    adaptive = opts.has("contact_kappa") and opts.string("contact_kappa").strip().lower() == "adaptive"
    try:
        kappa = None if adaptive else opts.real("contact_kappa", None, minimum=0)
    except UserError as e:
        raise UserError(f"{e} (or 'adaptive')") from None
    return ContactParams(obstacles, faces_, opts.real("contact_dhat", None, minimum=0), kappa, self_contact, mu, eps_v,
                         adaptive, eps_d)


def build_contact(p, ctx):
    sp = ctx.space
    tris = sp.set_triangles([n for n, _ in p.faces])
    X = sp.X.reshape(-1, 3)
    corners = tris[:, :3]
    area = 0.5 * np.linalg.norm(np.cross(X[corners[:, 1]] - X[corners[:, 0]], X[corners[:, 2]] - X[corners[:, 0]]),
                                axis=1) if len(tris) else np.zeros(0)
    share = np.zeros(len(X))
    np.add.at(share, tris, np.repeat((area / tris.shape[1])[:, None], tris.shape[1], axis=1) if len(tris) else 0)
    owned_share = sp.sum_owned(share[:, None]).ravel()          # every rank's facets at a node, in its owner's row
    nodes = sp.lvid_of_owned[owned_share > 0]
    edge = np.full(len(X), np.inf)                                # each node's shortest edge among this rank's facets
    for a, b in ((0, 1), (1, 2), (2, 0)):
        length = np.linalg.norm(X[corners[:, a]] - X[corners[:, b]], axis=1)
        for end in (a, b):
            np.minimum.at(edge, corners[:, end], length)
    if tris.shape[1] == 6:                                        # (a quadratic facet's edge nodes: half an edge)
        for k, (a, b) in enumerate(((0, 1), (1, 2), (0, 2))):
            np.minimum.at(edge, tris[:, 3 + k], 0.5 * np.linalg.norm(X[corners[:, a]] - X[corners[:, b]], axis=1))
    lo, hi = sp.bbox
    diagonal = float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))
    dhat = p.dhat if p.dhat is not None else DHAT_SCALE * diagonal
    if dhat > DHAT_MAX * diagonal:
        raise UserError(f"option -contact_dhat {dhat:g}: the barrier's reach must be under {DHAT_MAX:g} of the part's "
                        f"size (its bounding-box diagonal {diagonal:.4g}; the default is {DHAT_SCALE:g} of it): beyond, "
                        "the obstacles push the part from afar")
    kappa = p.kappa if p.kappa is not None else KAPPA_SCALE * ctx.modulus / dhat
    analytic = tuple(o for o in p.obstacles if o.form.analytic)
    meshes = tuple(o for o in p.obstacles if not o.form.analytic)
    number = {id(o): i + 1 for i, o in enumerate(p.obstacles)}          # (each one's place in -obstacle: its rows)
    eps_v, eps_d = friction_smoothing(p, ctx.quasistatic, dhat)
    out = [Contact(nodes, owned_share[owned_share > 0], X, sp.orig[nodes], analytic, dhat, kappa, edge[nodes],
                   p.mu, eps_v, eps_d, sp.mpi, [number[id(o)] for o in analytic])] if analytic else []
    if p.self_contact or meshes:
        from .self_contact import SelfContact
        out.append(SelfContact(sp, tris, dhat, kappa, meshes, p.mu, eps_v, eps_d, ctx.projection,
                               [number[id(o)] for o in meshes]))
    for o in p.obstacles:
        points, every = o.inside_test(0.0)
        inside = _inside_part(sp, points)
        if len(points) and (inside.all() if every else inside.any()):
            at = ", ".join(f"{c:.6g}" for c in points[np.argmax(inside)])
            raise UserError(f"-obstacle {o.text}: it lies inside the part (its point ({at}) does, and no node of the "
                            "part lies inside it): it would never be touched")
    for e in out:
        e.kappa_range = (kappa, ADAPTIVE_RANGE * kappa) if p.adaptive else None
    return out


def _inside_part(space, points, tol=1e-12):
    """Per point (k, 3): whether it lies in a cell of the part (any rank's; collective)."""
    X, cells = space.X.reshape(-1, 3), space.cells[:, :4]
    hit = np.zeros(len(points), bool)
    if len(cells) and len(points):
        lo, hi = X.min(axis=0), X.max(axis=0)
        X0 = X[cells[:, 0]]
        for i, p in enumerate(points):
            if np.all(p >= lo) and np.all(p <= hi):
                lam = np.einsum("cij,cj->ci", space.Dminv, p - X0)
                hit[i] = bool(((lam >= -tol).all(axis=1) & (lam.sum(axis=1) <= 1 + tol)).any())
    if len(points) and space.mpi.size > 1:      # (the buffer form: the pickled allreduce's MAX of arrays is refused)
        flags = hit.astype(np.int8)
        space.mpi.Allreduce(MPI.IN_PLACE, flags, op=MPI.MAX)
        hit = flags.astype(bool)
    return hit


def friction_smoothing(p, quasistatic, dhat):
    """(eps_v, eps_d) of the friction's smoothing: a dynamic run's slip speed (-contact_friction_eps, EPS_V: IPC's, a
    slip of eps_v h a step), or a quasi-static run's slip a step (-contact_friction_slip, SLIP_SCALE dhat: time is a
    load parameter there, and a speed in it means nothing; eps_d None in a dynamic run). The option of the other kind
    of run is refused in one line."""
    if quasistatic and p.eps_v is not None:
        raise UserError("option -contact_friction_eps: a slip speed means nothing in a quasi-static run (its time is a "
                        "load parameter); give the smoothing's slip a step, -contact_friction_slip d [m]")
    if not quasistatic and p.eps_d is not None:
        raise UserError("option -contact_friction_slip: a dynamic run smooths friction below a slip speed, "
                        "-contact_friction_eps v [m/s]; -contact_friction_slip is for quasi-static runs")
    eps_v = EPS_V if p.eps_v is None else p.eps_v
    return eps_v, ((SLIP_SCALE * dhat if p.eps_d is None else p.eps_d) if quasistatic else None)


def _uses(p):
    return [("contact_faces", name, "facets") for name, _ in p.faces]


SPEC = Spec(
    "contact", "rigid obstacles (planes, spheres) and self-contact: the boundary touches but never passes through "
    "(IPC barrier)",
    implied_by=("obstacle", "contact_self", "contact_dhat", "contact_kappa", "contact_faces", "contact_friction"),
    read=_read, sets=_uses,
    build=build_contact,
    energies=(Energy("contact_energy", 1, "the contact barrier's energy"),
              Energy("contact_nodes", 0, "contact nodes within dhat of an obstacle"),
              Energy("contact_pairs", 0, "self-contact pairs (point-triangle, edge-edge, ...) within dhat"),
              Energy("contact_sliding", 0, "contact nodes sliding (a step's slip over the smoothing's: eps_v h, "
                     "quasi-static eps_d) on an obstacle (friction)"),
              Energy("contact_kappa", 0, "the barrier's stiffness [Pa/m] (-contact_kappa adaptive: as balanced at the "
                     "step's start)", combine="max"),
              Energy("contact_dmin", 0, "the smallest distance of a contact node to an obstacle (or of two parts of the "
                     "contact surface within dhat)", combine="min")),
    rows=(Row(("obstacle", "obstacle_motion"), "-obstacle KIND:VALUES[;…]",
              "rigid obstacles: " + "; ".join(f"`{k}:{c.values.split(': ', 1)[0]}` ({c.values.split(': ', 1)[1]})"
                                              for k, c in KINDS.items()) +
              "; `-obstacle_motion EX,EY,EZ[;…]`: each one's translation, expressions of "
              "t. The boundary never passes through them (IPC's barrier in the energy, each Newton update stopped "
              "short of the first impact); frictionless unless -contact_friction"),
          Row(("contact_self",), "-contact_self",
              "self-contact: the contact surfaces touch themselves and each other (a body folding onto itself, "
              "separate pieces of the mesh) but never pass through (IPC's barrier over point-triangle and edge-edge "
              "pairs, each Newton update stopped short of the first collision: the IPC Toolkit); the surface is "
              "gathered to every rank; with -formulation mixed too (on the displacements)"),
          Row(("contact_faces",), "-contact_faces S1,S2,…", "the surfaces that touch the obstacles", "boundary"),
          Row(("contact_friction", "contact_friction_eps", "contact_friction_slip"),
              "-contact_friction μ -contact_friction_eps v -contact_friction_slip d",
              "Coulomb friction on obstacles and in self-contact (IPC's smoothed, lagged friction: each step's normal "
              "forces and tangent planes from its start; static below the slip speed v [m/s], i.e. a slip of v h a "
              "step, in dynamic runs, and below the slip d [m] a step in quasi-static ones, where time is a load "
              "parameter)",
              "0 (frictionless), v = 1e-3, d = 0.1 dhat"),
          Row(("contact_dhat", "contact_kappa"), "-contact_dhat d -contact_kappa k|adaptive",
              "the barrier's reach [m] (default 1e-3 of the bounding box's diagonal: forces act at distances below "
              "it, so it is the contact's accuracy) and stiffness [Pa/m] (default 0.1 E / dhat: a pressure of "
              "0.12 E at dhat/2); adaptive: IPC's choice, balanced against the other forces at each step's start "
              "between that default and 100 times it (the contact_kappa statistic)")))
