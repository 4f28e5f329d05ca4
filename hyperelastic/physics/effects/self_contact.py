"""Self-contact (issue 46): the contact surfaces may touch themselves and each other (a body folding onto itself,
separate pieces of one mesh pressed together) but never pass through, with the IPC Toolkit (`ipctk`, the IPC authors'
library: Li et al., "Incremental Potential Contact", ACM Trans. Graph. 39(4), 2020) for what it is built for: the
broad phase, the point-triangle / edge-edge (and degenerate) distance pairs within dhat and their barrier's gradient
and PSD-projected Hessian, and continuous collision detection along a straight move.

Energy: ipctk's BarrierPotential with area weighting and the improved max approximator (an integral over the surface,
independent of the mesh) and its "physical" barrier b(d^2; dhat^2)/dhat^3, whose stiffness is a pressure: kappa_self =
kappa dhat / (2 W), kappa the obstacles' barrier stiffness [Pa/m] and W = 1.1 (measured on two flat, finely meshed
faces) so that two faces at a gap d << dhat press on each other as a face and an obstacle plane do at the same gap
(tests/test_contact.py checks the ratio). A quadratic facet is split into its four linear triangles by its edge nodes.

In parallel: the contact surface (O(N^2/3) of the mesh) is gathered to every rank once, by input ids (so its vertices
and triangles are in the same order on any rank count); positions are gathered (Allgatherv of each rank's owned
surface nodes) at each evaluation; every rank evaluates the whole surface's barrier and keeps its owned rows. The
energy is counted on rank 0. The Hessian's blocks on the diagonal go into the assembled tangent (the cell pattern
holds them: the preconditioner sees them); the blocks between two surface nodes, which the cell pattern does not
join, are applied beside the assembled operator (jacobians.Coupled) or in the matrix-free tangent's apply.
What a distributed version would need: each rank's surface with a halo of the owned surface within dhat + the largest
Newton move (a spatial exchange); the pairs' blocks between nodes are already a matrix in global numbering, set again
after each linearization (coupling_entries), so only its rows' columns travel in a product.

Never through: each Newton update is stopped at ipctk's collision-free step size (additive CCD, which stops 0.9 of the
way to the first collision; the same pre-check as the obstacles' and the inversion guard's); a step's start (the integrator's guess) is taken only if the straight
move from the step's start to it is collision-free (`undefined_at`); a start state whose surface intersects itself or
touches (distance 0) is refused in one line. ipctk runs on one thread (MPI ranks are the parallelism; one thread also
fixes the order of its sums)."""
from typing import NamedTuple

import numpy as np
from mpi4py import MPI

from ...core.errors import UserError
from .base import NodeBlocks, timed
from .obstacles import linear_motion
from .seams import (PUSH_LIMIT, SELF_STATUS, AdaptiveStiffness, Couplings, DomainCheck, Results, ResultRow, StepLimiter,
                    StepStart)

KAPPA_WEIGHT = 1.1           # W above: the area weights' sum per unit area of two facing faces (measured)


class Pairs(NamedTuple):
    """The contact pairs at a state (SelfContact._pairs_of)."""
    V: np.ndarray
    g: np.ndarray
    near: list
    g_self: np.ndarray
    selfed: set


def _reached(p, d, T, pad):
    """Per point of p (n, 3): whether the segment p -> p + d crosses a triangle of T (m, 3, 3) (Moller and Trumbore,
    J. Graphics Tools 2, 1997), the points tested only where near the triangles' box swept by d (pad: a margin)."""
    lo = np.minimum(T.min(axis=(0, 1)), T.min(axis=(0, 1)) - d) - pad
    hi = np.maximum(T.max(axis=(0, 1)), T.max(axis=(0, 1)) - d) + pad
    near = np.flatnonzero(((p >= lo) & (p <= hi)).all(axis=1))
    out = np.zeros(len(p), bool)
    if not len(near) or not len(T):
        return out
    e1, e2 = T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]                        # (m, 3)
    h = np.cross(d, e2)                                                    # (m, 3)
    a = (e1 * h).sum(axis=1)
    ok = np.abs(a) > 1e-300
    for i in near:
        s = p[i] - T[:, 0]
        with np.errstate(all="ignore"):
            u = (s * h).sum(axis=1) / a
            q = np.cross(s, e1)
            v = (q @ d) / a
            t = (e2 * q).sum(axis=1) / a
        out[i] = bool((ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t >= 0) & (t <= 1)).any())
    return out


def _ipctk():
    import ipctk
    ipctk.set_num_threads(1)
    ipctk.set_logger_level(ipctk.LoggerLevel.error)
    return ipctk


def linear_triangles(tris):
    """(n, 3) triangles: linear facets as they are, a quadratic facet (corners, then the nodes of edges (0,1), (1,2),
    (0,2)) as its four linear triangles, oriented as the facet."""
    tris = np.asarray(tris, np.int64)
    if tris.shape[1] == 3:
        return tris
    a, b, c, ab, bc, ac = tris.T
    return np.concatenate([np.c_[a, ab, ac], np.c_[ab, b, bc], np.c_[ac, bc, c], np.c_[ab, bc, ac]])


class SelfContact(NodeBlocks, StepLimiter, DomainCheck, StepStart, AdaptiveStiffness, Couplings, Results):
    """The barrier between all pairs of the contact surface's primitives within dhat (the whole surface on every
    rank, this rank's owned rows)."""
    name = "contact"
    linear = False
    conservative = True
    symmetric = True
    domain = True
    end_state = True          # (generalized-alpha: acts at the step's end, System._end_state)

    def __init__(self, space, tris, dhat, kappa, obstacles=(), mu=0.0, eps_v=1e-3, eps_d=None, projection=False,
                 numbers=None):
        """obstacles: triangulated rigid obstacles (obstacles.Obstacle of kind mesh): their triangles join the collision
        mesh as vertices that are not unknowns, placed by their translation at each step's end. mu, eps_v: Coulomb
        friction (IPC's smoothed, lagged: ipctk's TangentialCollisions and FrictionPotential on the step's
        displacements, smoothed below a slip of eps_v h; of eps_d a step in a quasi-static run). projection: the
        obstacle pairs' tangent projected as the surface's own pairs are (-hessian_projection; else exact:
        _barrier_hessian)."""
        super().__init__()
        self.projection = bool(projection)
        ip = self.ip = _ipctk()
        sp = self.space = space
        self.mpi = sp.mpi
        self.dhat, self.kappa = float(dhat), float(kappa)
        self.mu, self.eps_v, self.eps_d = float(mu), float(eps_v), eps_d
        self.tangential = None       # the step's lagged friction pairs (begin_step), and its potential
        self.friction = None
        # additive CCD (Li et al. 2021, "Codimensional IPC"): ~1000x faster than Tight-Inclusion's on surfaces that
        # rest within dhat of each other (5 s -> 2 ms a call on 88 facets pressed together), stopping 0.9 of the way
        # to the first collision (its conservative rescaling)
        self.ccd = ip.AdditiveCCD()
        faces = self._number_surface(tris)
        self.obstacles = tuple(obstacles)
        self.numbers = tuple(numbers or range(1, len(self.obstacles) + 1))     # (each one's place in -obstacle)
        self.moving = any(o.motion is not None for o in self.obstacles)
        offset = len(self.ids)                               # (obstacle vertices follow the surface's)
        for o in self.obstacles:
            faces = np.concatenate([faces, o.surface[1] + offset])
            offset += len(o.surface[0])
        self.fixed = self._obstacles_at(0.0)                     # the obstacles' vertices now (not unknowns)
        X = self._V(sp.X)
        self.mesh = ip.CollisionMesh(X, ip.edges(faces), faces)
        E = self.mesh.edges[(self.mesh.edges < len(self.ids)).all(axis=1)]          # (the surface's own edges)
        shortest = np.full(len(self.ids), np.inf)
        for end in (0, 1):
            np.minimum.at(shortest, E[:, end], np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1))
        self.edge = shortest[self.own_s]                     # this rank's nodes' shortest surface edge (pushed)
        # each surface node's reference area, a third of its triangles' (the obstacles' results)
        F = faces[(faces < len(self.ids)).all(axis=1)]
        a = 0.5 * np.linalg.norm(np.cross(X[F[:, 1]] - X[F[:, 0]], X[F[:, 2]] - X[F[:, 0]]), axis=1)
        self.node_area = np.zeros(len(self.ids))
        np.add.at(self.node_area, F, np.repeat(a[:, None] / 3, 3, axis=1))
        self._pairs = None                                   # (the last _pairs_of)
        self.set_kappa(self.kappa)
        self.blocks = np.zeros((len(self.nodes), 3, 3))
        self.coupling = None                                 # csr (3 n_own, 3 n_surface): the off-diagonal blocks
        self.coupled = False                                 # some rank has coupling entries (collective)
        self.start = self.last = X                          # the step's start; the last state reached from it
        self.held_mesh = None                                # (the held triangles' collision mesh: hold)
        self._cache = []                                     # [(V, its collision set)], the latest first
        self._check_start(X)

    def _number_surface(self, tris):
        """The contact surface's numbering, the same on every rank: its vertices by input id (`ids`), this rank's
        surface nodes (`nodes`, their surface ids `own_s`, owned-array dofs `own_cols`), the gathered rows and the
        global dofs of the coupling's rows and columns; returns the surface's triangles in surface ids."""
        sp = self.space
        ids = sp.orig[linear_triangles(tris)]                                      # input ids: rank-independent
        every = np.concatenate(self.mpi.allgather(ids)).reshape(-1, 3)
        every = every[np.lexsort(every.T[::-1])]
        self.ids = np.unique(every)                                                # the surface's vertices
        faces = np.searchsorted(self.ids, every)
        own_lv = sp.lvid_of_owned
        mine = np.isin(sp.orig[own_lv], self.ids)
        own_pos = np.flatnonzero(mine)                       # positions in the owned array of this rank's surface nodes
        self.nodes = own_lv[mine]                            # their local ids
        self.own_s = np.searchsorted(self.ids, sp.orig[self.nodes])                # and surface ids
        self.counts = np.array(self.mpi.allgather(len(self.nodes)), np.int64)
        self.rows = np.concatenate(self.mpi.allgather(self.own_s))                # gathered rows -> surface ids
        self.own_dofs = (3 * self.own_s[:, None] + np.arange(3)).ravel()
        self.own_cols = (3 * own_pos[:, None] + np.arange(3)).ravel()            # (owned-array dofs)
        # the global dofs of this rank's surface rows (the coupling's rows, in own_dofs' order) and of every surface
        # node (its columns): the coupling as a matrix of the global vectors (coupling_entries)
        own_global = sp.node_global()[self.nodes]
        self.surface_global = np.empty(len(self.ids), np.int64)
        self.surface_global[self.rows] = np.concatenate(self.mpi.allgather(own_global))
        self.global_rows = (3 * own_global[:, None] + np.arange(3)).ravel()
        return faces

    def _check_start(self, X):
        """One line where the start state is not free of intersections or of contact."""
        ip = self.ip
        what = "option -contact_self" if not self.obstacles else "options -contact_faces and -obstacle mesh:FILE"
        if ip.has_intersections(self.mesh, X):
            raise UserError(f"{what}: the contact surface intersects itself or an obstacle at the start ("
                            f"{self.first_intersection(X)}): a start state must be free of intersections")
        dmin = self._collisions(X).compute_minimum_distance(self.mesh, X) if len(X) else np.inf
        if dmin <= 0:
            raise UserError(f"{what}: two parts of the contact surface (or it and an obstacle) touch at the start: "
                            "a start state must be free of contact")

    def set_kappa(self, kappa):
        self.kappa = float(kappa)
        self.potential_fn = self.ip.BarrierPotential(self.dhat, self.kappa * self.dhat / (2 * KAPPA_WEIGHT), True)

    def barrier_gradient(self, x, r):
        """r += the barrier's gradient per unit kappa at local positions x (this rank's rows; no friction)."""
        V = self._V(x)
        c = self._collisions(V)
        if len(c):
            g = self.potential_fn.gradient(c, self.mesh, V) / self.kappa
            r.reshape(-1, 3)[self.nodes] += g[self.own_dofs].reshape(-1, 3)

    def hold(self, held):
        """held: per local node, whether the scene prescribes all three of its components. The triangles whose
        vertices are all held (or an obstacle's) form a collision mesh of their own, whose path is given: held_collision
        checks it before a step is solved."""
        flags = self.gather(np.repeat(np.asarray(held, float)[self.nodes, None], 3, axis=1))[:, 0] > 0.5
        if self.obstacles:
            flags = np.concatenate([flags, np.ones(len(self.fixed), bool)])
        F = self.mesh.faces
        F = F[flags[F].all(axis=1)]
        self.held_v = np.unique(F)
        self.held_mesh = None
        n = len(self.ids)
        if (self.held_v < n).any():                      # (some held triangle of the body's)
            F = np.searchsorted(self.held_v, F)
            self.held_mesh = self.ip.CollisionMesh(self._V(self.space.X)[self.held_v], self.ip.edges(F), F)
            if self.obstacles:                           # (obstacles do not collide with each other here)
                body = self.held_v < n
                self.held_mesh.can_collide = lambda i, j: bool(body[i] or body[j])

    def held_collision(self, x0, x1):
        """The first fraction s of the straight move of the held triangles from local positions x0 (the step's start,
        the obstacles where the last step left them) to x1 (their targets, the obstacles at the step's end) at which
        two of them meet, with them in words; None if none do. The same on every rank (collective)."""
        if self.held_mesh is None:
            return None
        a = self.start[self.held_v]                       # (x0 gathered at the step's start: begin_step)
        b = self._V(x1)[self.held_v]
        # (the additive CCD stops 0.9 of the way to the first impact: repeated from there, the fraction comes to the
        # time of impact to 0.1^6; a stop short of a near miss is followed by a clear rest. Tight-Inclusion CCD, exact
        # to its tolerance, took minutes on two parallel faces that meet all at once, invert's end faces)
        s = 0.0
        for _ in range(6):
            ds = float(self.ip.compute_collision_free_stepsize(self.held_mesh, a + s * (b - a), b, 0.0, None,
                                                               self.ccd))
            if ds >= 1.0:
                return None
            s += ds * (1.0 - s)
        body = self.held_v[self.held_v < len(self.ids)]
        return s, f"held triangles of the contact surface ({len(body)} held nodes from node {int(self.ids[body[0]])})"

    def moves_linearly(self, t0, t1):
        return linear_motion(self.obstacles, t0, t1)

    def first_intersection(self, V):
        """In words, the first edge of the collision mesh (in its order) that crosses one of its triangles at positions
        V: the same on every rank (the collision mesh is)."""
        ip, E, F = self.ip, self.mesh.edges, self.mesh.faces
        grid = ip.HashGrid()
        grid.build(V, E, F, 0.0)
        for e, f in sorted((c.edge_id, c.face_id) for c in grid.detect_edge_face_candidates()):
            if set(E[e]) & set(F[f]):
                continue                                          # (neighbours share a vertex: not a crossing)
            if ip.is_edge_intersecting_triangle(*V[E[e]], *V[F[f]]):
                return f"the edge {self._named(E[e], V)} crosses the triangle {self._named(F[f], V)}"
        return "no single edge crossing a triangle found"

    def _named(self, vertices, V):
        """Collision-mesh vertices in words: nodes by input id and position, or an obstacle's vertices by number."""
        n = len(self.ids)
        if vertices[0] < n:
            return "of nodes " + ", ".join(f"{int(self.ids[v])} {np.round(V[v], 6).tolist()}" for v in vertices)
        k = np.asarray(vertices) - n
        for o in self.obstacles:
            if k[0] < len(o.surface[0]):
                return f"of obstacle {o.text}'s vertices {', '.join(str(int(i)) for i in k)}"
            k = k - len(o.surface[0])
        return str(list(vertices))

    # --- the surface's positions on every rank --------------------------------------------------------------------
    def gather(self, own):
        """(n_surface, 3) of the ranks' owned surface rows `own` (n_own, 3), in the surface's order."""
        own = np.ascontiguousarray(own, float)
        if self.mpi.size == 1:
            out = np.empty_like(own)
            out[self.rows] = own
            return out
        buf = np.empty((int(self.counts.sum()), 3))
        self.mpi.Allgatherv(own, [buf, 3 * self.counts])
        out = np.empty_like(buf)
        out[self.rows] = buf
        return out

    def _obstacles_at(self, t):
        return np.concatenate([np.zeros((0, 3))] + [o.surface[0] + o.shift(t) for o in self.obstacles])

    def _V(self, x, fixed=None):
        V = self.gather(x.reshape(-1, 3)[self.nodes])
        return V if not self.obstacles else np.concatenate([V, self.fixed if fixed is None else fixed])

    # the collision sets of the last states: a Newton iteration evaluates the residual and the tangent at its iterate,
    # then the line search's objective the energy at the trial state and at the iterate, then the residual at the
    # trial state (the next iterate): with one set kept, 3.6 builds per Newton iteration (a third of a self-contact
    # run's time: BENCHMARKS.md), with two 1.9 (a third saves none: the other states are each seen once)
    CACHED_SETS = 2

    def _collisions(self, V):
        for i, (key, c) in enumerate(self._cache):
            if np.array_equal(key, V):
                self._cache.insert(0, self._cache.pop(i))
                return c
        c = self.ip.NormalCollisions()
        c.use_area_weighting = True
        c.collision_set_type = self.ip.NormalCollisions.CollisionSetType.IMPROVED_MAX_APPROX
        c.build(self.mesh, V, self.dhat)
        self._cache = [(V.copy(), c)] + self._cache[:self.CACHED_SETS - 1]
        return c

    # --- energy, residual, tangent --------------------------------------------------------------------------------
    def potential(self, x):
        V = self._V(x)
        if self.mpi.rank != 0:
            return 0.0
        out = float(self.potential_fn(self._collisions(V), self.mesh, V))
        if self._has_friction():
            out += float(self.friction(self.tangential, self.mesh, V - self.start))
        return out

    @timed("evals")
    def residual(self, x, r):
        V = self._V(x)
        c = self._collisions(V)
        self.undefined = 0
        if self.moving:
            # (moving obstacles: the state must be reachable from the step's start without a collision — a triangle
            # is unsigned, so a body it moved through at once feels nothing; checked along the evaluated states)
            if not self.ip.is_step_collision_free(self.mesh, self.last, V, 0.0, None, self.ccd):
                self.undefined = 1
                return
            self.last = V
        g = None
        if len(c):
            if c.compute_minimum_distance(self.mesh, V) <= 0:
                self.undefined = 1
            g = self.potential_fn.gradient(c, self.mesh, V)
        if self._has_friction():
            f = self.friction.gradient(self.tangential, self.mesh, V - self.start)
            g = f if g is None else g + f
        if g is not None:
            r.reshape(-1, 3)[self.nodes] += g[self.own_dofs].reshape(-1, 3)

    def result_rows(self, x, t):
        """Per triangulated obstacle: its force on the body, the barrier's and friction's (the sum of the potential's
        gradient over the obstacle's vertices: each pair's is translation invariant, so it is minus the body's part
        from the pairs with that obstacle), the reference area of the body's surface nodes in a pair with it, its
        translation at t. Then the surface's pairs with itself, as `self`: the sum of their barrier forces over the
        surface (zero but for round-off: they balance), half the reference area of the surface nodes in such a pair
        (the patch has two sides, each counted), no translation, and the force they carry, half the sum of the
        magnitudes of those nodal forces (each pair pushes its two sides apart with equal and opposite forces, shared
        by its nodes with weights of one sign). On rank 0
        alone (the collision mesh is the whole surface on every rank); zeros elsewhere. Collective (the positions are
        gathered)."""
        first = self.mpi.rank == 0
        pairs = self._pairs_of(x)
        g = pairs.g
        if first and self._has_friction():
            g = g + self.friction.gradient(self.tangential, self.mesh, pairs.V - self.start).reshape(-1, 3)
        rows, lo = [], len(self.ids)
        for k, (o, number) in enumerate(zip(self.obstacles, self.numbers)):
            hi = lo + len(o.surface[0])
            force = g[lo:hi].sum(axis=0) if first else np.zeros(3)
            area = float(self.node_area[sorted(pairs.near[k])].sum()) if first else 0.0
            rows.append(ResultRow(f"obstacle{number}", force, area, o.shift(t)))
            lo = hi
        own = pairs.g_self if first else np.zeros((0, 3))
        area = 0.5 * float(self.node_area[sorted(pairs.selfed)].sum()) if first else 0.0     # (both sides' nodes)
        carried = 0.5 * float(np.linalg.norm(own, axis=1).sum()) if first else 0.0
        rows.append(ResultRow("self", own.sum(axis=0) if first else np.zeros(3), area, np.zeros(3), carried))
        return rows

    def point_values(self, x):
        """contact_pressure: the barrier's force at each surface node in a pair with a triangulated obstacle or with the
        surface itself, over the node's reference area (Abaqus' CPRESS); contact_status: the number (in -obstacle's
        order) of the first obstacle it is in a pair with, else SELF_STATUS where it is in a pair with the surface
        itself, 0 where none. Every rank its own nodes (the collision set is every rank's)."""
        n = len(x) // 3
        pressure, status = np.zeros(n), np.zeros(n)
        pairs = self._pairs_of(x)
        hit = np.isin(self.own_s, sorted(pairs.selfed))
        status[self.nodes[hit]] = SELF_STATUS
        for number, touched in reversed(list(zip(self.numbers, pairs.near))):
            hit = np.isin(self.own_s, sorted(touched))
            status[self.nodes[hit]] = number
        pressed = np.zeros(len(self.ids), bool)
        pressed[sorted(set().union(pairs.selfed, *pairs.near))] = True
        own = pressed[self.own_s]
        pressure[self.nodes[own]] = np.linalg.norm(pairs.g[self.own_s[own]], axis=1) / self.node_area[self.own_s[own]]
        return {"contact_pressure": pressure, "contact_status": status}

    def _pairs_of(self, x):
        """Pairs(V, the barrier's gradient over the collision mesh's vertices (n, 3), per obstacle the surface nodes in
        a pair with it, the gradient of the surface's pairs with itself over the surface (n_surface, 3), the surface
        nodes in such a pair) at local positions x: a frame's point_values and the step's result_rows ask at the same
        state, so the last one is kept."""
        V = self._V(x)
        if self._pairs is not None and np.array_equal(self._pairs.V, V):
            return self._pairs
        c = self._collisions(V)
        g = self.potential_fn.gradient(c, self.mesh, V).reshape(-1, 3) if len(c) else np.zeros_like(V)
        self._pairs = Pairs(V, g, *self._sorted_pairs(c, V, g))
        return self._pairs

    def _sorted_pairs(self, c, V, g):
        """(per obstacle the set of the surface's nodes (collision-mesh ids) in a pair with one of its vertices, the
        gradient of the surface's pairs with itself (n_surface, 3), the set of nodes in such a pair); g: the gradient
        of all the pairs, which is the surface's own where there is no obstacle (else each of its own pairs' gradient
        is summed apart)."""
        n = len(self.ids)
        bounds = np.cumsum([n] + [len(o.surface[0]) for o in self.obstacles])
        out = [set() for _ in self.obstacles]
        g_self, selfed = (np.zeros((n, 3)) if self.obstacles else g[:n]), set()
        E, F = self.mesh.edges, self.mesh.faces
        for i in range(len(c)):
            pair = c[i]
            ids = np.asarray(pair.vertex_ids(E, F))
            ids = ids[ids >= 0]                   # (the stencil's vertices first, in its dof order; -1 after them)
            body = ids[ids < n]
            if len(body) == len(ids):
                if self.obstacles:
                    g_self[ids] += self.potential_fn.gradient(pair, pair.dof(V, E, F)).reshape(-1, 3)
                selfed.update(int(b) for b in ids)
                continue
            for k in set(np.searchsorted(bounds, ids[ids >= n], side="right") - 1):
                out[k].update(int(b) for b in body)
        return out, g_self, selfed

    def undefined_at(self, x):
        """1 where the straight move from the step's start to x passes the surface through itself (or touches)."""
        V = self._V(x)
        ok = self.ip.is_step_collision_free(self.mesh, self.start, V, 0.0, None, self.ccd)
        return 0 if ok else 1

    def crossing(self, x):
        if not self.undefined_at(x):
            return ""
        if self.moving:
            return (f"the contact surface crosses itself or a triangulated obstacle moving within the step "
                    f"({'; '.join(o.text for o in self.obstacles if o.motion is not None)})")
        return "the contact surface passes through itself along the straight move from the step's start"

    def begin_step(self, t, h, xn, vn):
        self.start = self.last = self._V(xn, self._obstacles_at(t - h)) if xn is not None else self.start
        self.fixed = self._obstacles_at(t)
        if self.mu > 0 and xn is not None:
            # (lagged: the pairs, their normal forces and tangent bases at the step's start; the slip is the step's
            # displacement, smoothed below eps_v h)
            self.tangential = self.ip.TangentialCollisions()
            self.tangential.build(self.mesh, self.start, self._collisions(self.start), self.potential_fn, self.mu)
            self.friction = self.ip.FrictionPotential(self.eps_v * h if self.eps_d is None else self.eps_d)

    def _has_friction(self):
        """Whether the step has friction pairs (built at its start)."""
        return self.tangential is not None and len(self.tangential) > 0

    def pushed(self, x, base=None):
        """(x with this rank's surface nodes that a moving triangulated obstacle reaches within the step carried along
        by its translation, whether every such push stays within PUSH_LIMIT of the node's shortest surface edge): the
        integrator's start where the last step's rate does not carry the body along (the first step of a plate
        pressing from rest: it was rejected 6 times, down to h/64, where the plate had moved less than its gap). A
        node is reached where its straight path relative to the obstacle (x, back by the translation) crosses one of
        the obstacle's triangles at the step's start; carried by the whole translation it keeps its distance to them."""
        out = x.copy()
        on = out.reshape(-1, 3)
        ok = True
        first = 0                                            # (each obstacle's first vertex among the obstacles')
        for o in self.obstacles:
            P = self.start[len(self.ids) + first:len(self.ids) + first + len(o.surface[0])]
            u = self.fixed[first] - P[0]                     # (its translation over the step: begin_step's ends)
            first += len(o.surface[0])
            if not np.any(u):
                continue
            hit = _reached(on[self.nodes], -u, P[o.surface[1]], self.dhat)
            ok = ok and bool((np.linalg.norm(u) <= PUSH_LIMIT * self.edge[hit]).all())
            on[self.nodes[hit]] += u
        return out, ok

    def linearize(self, x):
        V = self._V(x)
        c = self._collisions(V)
        self.blocks[:] = 0.0
        self.coupling = None
        H = self._barrier_hessian(c, V) if len(c) else None
        if self._has_friction():
            F = self.friction.hessian(self.tangential, self.mesh, V - self.start,
                                      self.ip.PSDProjectionMethod.CLAMP).tocsr()
            H = F if H is None else H + F
        if H is not None:
            Hr = H[self.own_dofs].tocoo()
            node_r, node_c = Hr.row // 3, Hr.col // 3
            diag = node_c == self.own_s[node_r]
            np.add.at(self.blocks, (node_r[diag], Hr.row[diag] % 3, Hr.col[diag] % 3), Hr.data[diag])
            off = ~diag & (Hr.data != 0)
            if off.any():
                from scipy.sparse import csr_matrix
                self.coupling = csr_matrix((Hr.data[off], (Hr.row[off], Hr.col[off])), shape=Hr.shape)
        self.coupled = bool(self.mpi.allreduce(self.coupling is not None, op=MPI.LOR))

    COLLISION_KINDS = ("vv_collisions", "ev_collisions", "ee_collisions", "fv_collisions")

    def _barrier_hessian(self, c, V):
        """The barrier's Hessian (csr, 3 |V| square) at V. A pair within the contact surface is projected to positive
        semi-definite over its whole stencil, as IPC does. The pairs with an obstacle's triangles are summed exact
        (with -hessian_projection, or once the solver switches it on, projected as the others): the obstacle's
        vertices are not unknowns, and projecting each pair's whole stencil changed the body's block — Newton
        converged linearly, 38-55 iterations a step pressing the bar with a two-triangle plate where the plane takes
        3-7 (exact: 3). Their sum is what is exact: a pair's own block is far from semi-definite (the improved max
        approximation's pairs of one face cancel), so no projection pair by pair would do."""
        ip, n, E, F = self.ip, len(self.ids), self.mesh.edges, self.mesh.faces
        if self.projection or not self.obstacles:
            return self.potential_fn.hessian(c, self.mesh, V, ip.PSDProjectionMethod.CLAMP).tocsr()
        own = {a: [] for a in self.COLLISION_KINDS}
        obstacle = {a: [] for a in self.COLLISION_KINDS}
        for a in self.COLLISION_KINDS:
            for col in getattr(c, a):
                (obstacle if max(col.vertex_ids(E, F)) >= n else own)[a].append(col)
        H = self.potential_fn.hessian(self._subset(own), self.mesh, V, ip.PSDProjectionMethod.CLAMP)
        return (H + self.potential_fn.hessian(self._subset(obstacle), self.mesh, V, ip.PSDProjectionMethod.NONE)).tocsr()

    def _subset(self, lists):
        """A collision set of the given pairs ({kind attribute: [pairs]})."""
        s = self.ip.NormalCollisions()
        s.use_area_weighting = True
        s.collision_set_type = self.ip.NormalCollisions.CollisionSetType.IMPROVED_MAX_APPROX
        for a, pairs in lists.items():
            setattr(s, a, pairs)
        return s

    def scale_tangent(self, f):
        super().scale_tangent(f)
        if self.coupling is not None:
            self.coupling = self.coupling * f

    def couple(self, own_v):
        """The off-diagonal blocks' product at this rank's surface rows (n_own*3) of v given by the owned rows `own_v`
        (n_own, 3) of every rank (collective; None where no rank has such blocks)."""
        if not self.coupled:
            return None
        v = self.gather(own_v).ravel()
        if self.obstacles:
            v = np.concatenate([v, np.zeros(3 * len(self.fixed))])      # (obstacles do not move with v)
        return self.coupling @ v if self.coupling is not None else np.zeros(3 * len(self.nodes))

    @timed("applies")
    def apply(self, v, y):
        yn = self.block_product(v)
        c = self.couple(v.reshape(-1, 3)[self.nodes])
        if c is not None:
            yn += c.reshape(-1, 3)
        y.reshape(-1, 3)[self.nodes] += yn

    def coupling_entries(self, constrained):
        """The off-diagonal blocks as (rows, columns, values) of a matrix of the global vectors (this rank's rows; an
        obstacle's columns, which do not move, left out; `constrained`: a mask of the owned dofs held, whose rows and
        columns are left out). Collective."""
        held = self.gather(constrained[self.own_cols].reshape(-1, 3).astype(float)).ravel() > 0.5
        if self.coupling is None:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)
        C = self.coupling.tocoo()
        keep = C.col < len(held)
        keep[keep] &= ~held[C.col[keep]]
        keep &= ~constrained[self.own_cols][C.row]
        col = C.col[keep]
        return (self.global_rows[C.row[keep]], 3 * self.surface_global[col // 3] + col % 3, C.data[keep])

    def max_step(self, x, dx):
        """The largest fraction (<= 1) of the update dx from x along which the surface stays free of itself: ipctk's
        collision-free step size (the same on every rank)."""
        V0 = self._V(x)
        V1 = self._V(x + dx)
        return float(self.ip.compute_collision_free_stepsize(self.mesh, V0, V1, 0.0, None, self.ccd))

    def energy(self, x, v):
        V = self._V(x)
        c = self._collisions(V)
        d = float(np.sqrt(c.compute_minimum_distance(self.mesh, V))) if len(c) else np.inf
        first = self.mpi.rank == 0
        return {"contact_energy": float(self.potential_fn(c, self.mesh, V)) if first else 0.0,
                "contact_pairs": len(c) if first else 0, "contact_dmin": d, "contact_kappa": self.kappa}
