"""p-multigrid for quadratic tetrahedra: `-pc_type mg` on an order-2 run (issue 49, item 1; options/pmg.opts).

Two levels on the same mesh: the P2 space (fine) and the P1 space of its vertices (coarse). The interpolation P
from P1 to P2 is exact and local: a vertex node takes its vertex's value, an edge node the mean of its edge's two
ends (the P1 function's value there; on curved cells too, as the element is isoparametric: the reference
coordinates of an edge node are its ends' mean). P is assembled once (block size 3, identity blocks), the
coarse operator is the Galerkin product P^T A P (formed here, with the coarse rigid-body modes attached: PCMG's own
-pc_mg_galerkin cannot attach them), the P2 level is smoothed
(Chebyshev/Jacobi by default: options/pmg.opts) and the P1 level is solved by what -mg_coarse_* says (smoothed-
aggregation GAMG, which reads the rigid-body modes from the coarse operator). With a P2 smoother that reads SBAIJ
(Jacobi, the default) the tangent is kept only as SBAIJ (jacobians.AssembledSBAIJ) and the coarse operator is summed
from the cells' blocks as they are filled (GalerkinCells): no AIJ of the P2 tangent at all. Ratel's and deal.II's
matrix-free high-order solvers use the same hierarchy: p-coarsening to the linear element, then algebraic multigrid.

Options the user gives win; this module supplies what PCMG cannot know (the interpolation, the coarse operator
with its near null space), the levels' count, and, each where it is not given, the smoothers and coarse solve of
options/pmg.opts (DEFAULTS): with PETSc's own (SOR smoothing, a redundant direct solve of the P1 level) a 509k-dof P2
step took 134 s against GAMG's 81 s and gained 1.11x on 2 ranks (16-core machine, BENCHMARKS.md)."""
import numpy as np
from petsc4py import PETSc

from ..core.arrays import unique
from ..core.errors import UserError
from ..discretization import aij
from ..discretization.kernels import p1_galerkin
from ..element.reference import EDGES


# The coarse GAMG drops graph edges weaker than 0.05 of the diagonal when it aggregates: the Galerkin P1 operator of a
# P2 tangent has weak long couplings that made its aggregates partition-dependent (CG iterations 108 on 1 rank, 134 on
# 2 at 374k dofs; with the threshold 92 and 86, the 2-rank step 1.36x faster; BENCHMARKS.md, 2026-11-27).
DEFAULTS = {"mg_levels_ksp_type": "chebyshev", "mg_levels_ksp_max_it": "2", "mg_levels_pc_type": "jacobi",
            "mg_coarse_ksp_type": "preonly", "mg_coarse_pc_type": "gamg", "mg_coarse_pc_gamg_type": "agg",
            "mg_coarse_pc_gamg_agg_nsmooths": "1", "mg_coarse_pc_gamg_threshold": "0.05",
            "mg_coarse_mg_levels_ksp_type": "chebyshev",
            "mg_coarse_mg_levels_pc_type": "jacobi"}      # (as options/pmg.opts; a test checks they agree)


def applies(space):
    """Whether the run can use the P2 -> P1 levels: quadratic tetrahedra."""
    return space.element.order == 2


# the P2 level's preconditioners that read an SBAIJ matrix (PETSc's SOR takes no SBAIJ of block size 3, ILU none)
SBAIJ_SMOOTHERS = ("jacobi", "none")


def requested(space, prefix=""):
    """Whether the options ask for p-multigrid (-PREFIXpc_type mg) on quadratic tetrahedra with a P2-level
    preconditioner that reads SBAIJ (Jacobi, the default, or none): then the P2 tangent needs no AIJ (the Krylov
    method and the smoother multiply by its SBAIJ, the P1 operator is summed from the cells: GalerkinCells,
    jacobians.AssembledSBAIJ). Another P2-level preconditioner (-mg_levels_pc_type sor, ilu) keeps the AIJ."""
    opts = PETSc.Options(prefix)
    if not applies(space) or opts.getString("pc_type", "") != "mg":
        return False
    return all(opts.getString(k, "jacobi") in SBAIJ_SMOOTHERS for k in ("mg_levels_pc_type", "mg_levels_1_pc_type"))


def before_options(space, prefix=""):
    """Where the options ask for -pc_type mg (-PREFIXpc_type mg: the mixed formulation's displacement split gives
    fieldsplit_u_): on an order-2 run two levels (P2, P1), the coarse operator formed here; on an order-1 run one
    clear line (there is no coarser element on the same mesh)."""
    opts = PETSc.Options(prefix)
    if opts.getString("pc_type", "") != "mg":
        return
    levels = opts.getInt("pc_mg_levels", 2)
    if not applies(space):
        if levels != 1:
            raise UserError(f"option -{prefix}pc_type mg: p-multigrid needs quadratic tetrahedra (-order 2: P2 "
                            "smoothed, P1 solved); on linear ones use -pc_type gamg (options/gamg.opts)")
        return
    if levels != 2:
        raise UserError(f"option -{prefix}pc_mg_levels {levels}: p-multigrid has two levels on one mesh (P2 and P1); "
                        f"the coarser ones are GAMG's inside the P1 solve (-{prefix}mg_coarse_pc_type gamg)")
    if opts.getString("pc_mg_galerkin", "none") != "none":
        raise UserError(f"option -{prefix}pc_mg_galerkin {opts.getString('pc_mg_galerkin')}: p-multigrid forms the "
                        "P1 operator itself (P^T A P with the rigid-body modes GAMG needs): leave it out")
    opts.setValue("pc_mg_levels", "2")
    for name, value in DEFAULTS.items():
        if not opts.hasName(name):
            opts.setValue(name, value)


def coarse_numbers(space):
    """(the owned vertex nodes (local ids), each local node's coarse (P1) global number, -1 for an edge node): the
    owned vertices of each rank numbered consecutively in rank order, the ghosts' numbers from their owners (one
    global-to-local scatter of the fine space)."""
    vertex = np.zeros(space.nlv, bool)
    vertex[unique(space.cells[:, :4])] = True
    owned_v = np.flatnonzero(vertex & space.owned)
    first = space.mpi.exscan(len(owned_v)) or 0
    local = np.zeros(3 * space.nlv)
    local[3 * owned_v] = first + np.arange(len(owned_v)) + 1.0          # (0: not a vertex)
    g, lv = space.global_vec(), space.local_vec()
    g.getArray()[:] = space.owned_array(local)
    space.to_local(g, lv)
    num = lv.getArray(readonly=True)[0::3].round().astype(np.int64) - 1
    g.destroy()
    lv.destroy()
    return owned_v, num


def prolongation(space, numbers=None):
    """(P: the (3 n_P2) x (3 n_P1) interpolation, block size 3; the owned coarse vertices' coordinates in their
    global order) on the space's mesh (numbers: its coarse_numbers, where the caller has them)."""
    owned_v, num = numbers or coarse_numbers(space)
    n_fine, n_coarse = 3 * space.n_owned, 3 * len(owned_v)
    fine_dof = space.lgmap.getIndices().reshape(-1, 3)[:, 0] // 3          # global node of each local node
    rows_n, cols_n, vals = [], [], []
    owned = space.owned
    is_vertex = num >= 0
    v_own = np.flatnonzero(owned & is_vertex)
    rows_n.append(fine_dof[v_own])
    cols_n.append(num[v_own])
    vals.append(np.ones(len(v_own)))
    cells = space.cells.astype(np.int64)
    edge_nodes = cells[:, 4:].ravel()
    ends = cells[:, np.asarray(EDGES)].reshape(-1, 2)
    nodes, first = np.unique(edge_nodes, return_index=True)
    keep = owned[nodes]
    nodes, ends = nodes[keep], ends[first[keep]]
    for j in (0, 1):
        rows_n.append(fine_dof[nodes])
        cols_n.append(num[ends[:, j]])
        vals.append(np.full(len(nodes), 0.5))       # 1/2 of each end (element.reference.p1_at_nodes, per cell)
    rn, cn, w = (np.concatenate(a) for a in (rows_n, cols_n, vals))
    if (cn < 0).any():
        raise RuntimeError("p-multigrid: a node's coarse vertex has no number")
    rows = (3 * rn[:, None] + np.arange(3)).ravel()
    cols = (3 * cn[:, None] + np.arange(3)).ravel()
    P = PETSc.Mat().create(comm=space.comm)
    P.setSizes(((n_fine, PETSc.DETERMINE), (n_coarse, PETSc.DETERMINE)), bsize=3)
    P.setType(PETSc.Mat.Type.AIJ)
    P.setPreallocationCOO(rows.astype(PETSc.IntType), cols.astype(PETSc.IntType))
    P.setValuesCOO(np.repeat(w, 3), addv=PETSc.InsertMode.INSERT_VALUES)
    P.assemble()
    order = np.argsort(num[owned_v])
    coords = np.ascontiguousarray(space.X[owned_v[order]])
    return P, coords


class VertexSpace:
    """The P1 space on a P2 space's vertices, as far as the assembled fill needs a space (aij.exact_pattern,
    aij.CellMap, aij.BoundaryExchange): the local vertex nodes numbered compactly (`loc`: fine local node -> coarse
    local vertex, -1 for an edge node), their cells, their global numbers (coarse_numbers: each rank's owned vertices
    consecutive in rank order, the layout of P's columns) and which are owned."""

    def __init__(self, space, numbers):
        owned_v, num = numbers                  # (coarse_numbers(space))
        cv = np.flatnonzero(num >= 0)
        loc = np.full(space.nlv, -1, np.int64)
        loc[cv] = np.arange(len(cv))
        self.loc, self.mpi, self.comm = loc, space.mpi, space.comm
        self.cells = np.ascontiguousarray(loc[space.cells[:, :4]], dtype=PETSc.IntType)
        self.lgmap = PETSc.LGMap().create(num[cv].astype(PETSc.IntType), bsize=3, comm=space.comm)
        self.nlv, self.n_owned = len(cv), len(owned_v)
        self.lvid_of_owned = loc[owned_v]
        self.nv_total = space.mpi.allreduce(len(owned_v))
        # each fine local node's two coarse vertices and weights (a vertex node: itself twice, weights 1 and 0)
        cells = space.cells.astype(np.int64)
        edge_nodes = cells[:, 4:].ravel()
        self.to = np.stack([loc, loc], axis=1)
        self.w = np.tile([1.0, 0.0], (space.nlv, 1))
        for j in (0, 1):
            self.to[edge_nodes, j] = loc[cells[:, [e[j] for e in EDGES]]].ravel()
        self.w[edge_nodes] = 0.5


class GalerkinCells:
    """p-multigrid's P1 operator P^T K P summed from the P2 cells' blocks as the tangent is filled (P_e^T K_e P_e per
    cell, kernels.p1_galerkin; the cells' P_e are the rows of P on their nodes, so the sum is P^T K P exactly), into
    the P1 tangent's own fill on the vertices (aij.CellFill on a VertexSpace: `begin`, `add`, `finish` as the fine
    fill calls them), then `close` with the effects' own entries and the constrained diagonal through P entry by
    entry. For a fine tangent kept only as SBAIJ (jacobians.AssembledSBAIJ), which PETSc's PtAP does not take.
    `wanted`: fill it at the next tangent's fill (a Jacobian that sets the preconditioner up)."""

    def __init__(self, space, chunk, numbers):
        vs = self.vs = VertexSpace(space, numbers)
        self.fill = aij.CellFill(vs, vs.cells)
        self.mat = self.fill.A
        self.buf = np.empty((min(chunk, max(len(vs.cells), 1)), 12, 12))
        self.wanted = False

    def begin(self):
        self.fill.begin()

    def add(self, vals, lo, hi):
        """The P1 blocks of the P2 cells lo..hi-1 (vals: their blocks, constrained rows and columns zeroed)."""
        if len(self.buf) < hi - lo:
            self.buf = np.empty((hi - lo, 12, 12))
        kc = self.buf[:hi - lo]
        p1_galerkin(EDGES, vals, kc)
        self.fill.add(kc, lo, hi)

    def finish(self):
        self.fill.finish()

    def close(self, entries):
        """entries: [(fine local rows, columns, values)] (each (n, 1)) added to the fine tangent beside its cells';
        each through P to up to four coarse entries (a node's two coarse vertices and weights: VertexSpace.to, .w)."""
        to, w = self.vs.to, self.vs.w
        for r, c, v in entries:
            r, c, v = r.ravel().astype(np.int64), c.ravel().astype(np.int64), v.ravel()
            nr, nc_ = r // 3, c // 3
            for s, t in ((0, 0), (0, 1), (1, 0), (1, 1)):
                wt = w[nr, s] * w[nc_, t]
                k = wt != 0.0
                if k.any():
                    rows = (3 * to[nr[k], s] + r[k] % 3).astype(PETSc.IntType)[:, None]
                    cols = (3 * to[nc_[k], t] + c[k] % 3).astype(PETSc.IntType)[:, None]
                    self.mat.setValuesLocalRCV(rows, cols, (wt[k] * v[k])[:, None], PETSc.InsertMode.ADD_VALUES)
        self.mat.assemble()
        self.wanted = False


class Levels:
    """The two levels of a run's PCMG: the interpolation P and the coarse operator P^T B P of the fine
    preconditioning matrix B, formed here so that it carries the coarse vertices' rigid-body modes as its near null
    space (GAMG reads them from the matrix when it is set up; PCMG's own Galerkin product would carry none, and it
    fails on an SBAIJ operator). Where the fine tangent is kept only as SBAIJ (an operator that `fills_coarse`:
    jacobians.AssembledSBAIJ), the coarse operator is summed from its cells as it is filled (GalerkinCells, asked
    for by `prepare` before the fill)."""

    def __init__(self, pc, space, op=None):
        numbers = coarse_numbers(space)
        self.galerkin = None
        if op is not None and op.fills_coarse:
            self.galerkin = op.coarse = GalerkinCells(space, op.chunk, numbers)
        self.P, coords = prolongation(space, numbers)
        pc.setMGInterpolation(1, self.P)
        self.coarse = pc.getMGCoarseSolve()
        self.Ac = self.Aa = None
        v = self.P.createVecs("right")
        v.setBlockSize(3)
        v.getArray()[:] = coords.ravel()
        self.nullspace = PETSc.NullSpace().createRigidBody(v)
        self.shell = PETSc.DMShell().create(comm=space.comm)     # the coarse level's DM, with its vectors' layout
        self.shell.setGlobalVector(v)
        self.coarse.setDM(self.shell)
        self.coarse.setDMActive(PETSc.KSP.DMActive.ALL, False)
        v.destroy()

    def prepare(self):
        """Before a tangent's fill whose Jacobian sets the PC up: where the coarse operator is summed from the cells,
        ask for it."""
        if self.galerkin is not None:
            self.galerkin.wanted = True

    def update(self, B, add=None):
        """The coarse operator of the fine matrix B as it is now (at a Jacobian where the PC is set up again; where
        it is summed from the cells, as the fill after `prepare` left it); add(P): a matrix added to it (the mixed
        formulation's augmented Lagrangian: formulations/mixed/operators.Augmented.coarse_term)."""
        if self.galerkin is not None:
            if self.Ac is None:
                self.Ac = self.galerkin.mat
                self.Ac.setNearNullSpace(self.nullspace)
        elif self.Ac is None:
            self.Ac = B.ptap(self.P)
            self.Ac.setNearNullSpace(self.nullspace)
        else:
            B.ptap(self.P, result=self.Ac)
        A = self.Ac
        if add is not None:
            term = add(self.P)
            if self.Aa is None:              # (the sum's pattern: both patterns, made once)
                self.Aa = self.Ac.copy()
                self.Aa.axpy(1.0, term, structure=PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
                self.Aa.setNearNullSpace(self.nullspace)
            else:
                self.Aa.zeroEntries()
                self.Aa.axpy(1.0, self.Ac, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
                self.Aa.axpy(1.0, term, structure=PETSc.Mat.Structure.SUBSET_NONZERO_PATTERN)
            A = self.Aa
        self.coarse.setOperators(A, A)


def configure(pc, space, op=None):
    """After the PC has read the options: where it is PCMG on an order-2 run, the Levels (the caller updates their
    coarse operator at every Jacobian that sets the PC up); else None. op: the Jacobian operator (one that
    `fills_coarse` gets the Levels' GalerkinCells)."""
    if pc.getType() != "mg" or not applies(space):
        return None
    return Levels(pc, space, op)
