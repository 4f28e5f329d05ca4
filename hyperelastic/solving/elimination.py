"""Dirichlet conditions by elimination, the part of the System (system.py) that holds dofs.

Constrained dofs c with prescribed positions g: the residual of a free dof is evaluated with x_c replaced by g, and
R_c = s (x_c - g_c). Then dR_f/dx_c = 0 and J = [[J_ff, 0], [0, s I]] exactly, for every Jacobian mode including
PETSc's MFFD, and J stays symmetric when J_ff is. The scale s is the mean diagonal of J at the initial state
(computed once, in the System's constructor), so the constrained block does not spoil conditioning."""
import numpy as np
from mpi4py import MPI

from ..core.errors import UserError
from ..physics.effects.dirichlet import HeldBody


class Elimination:
    """The held dofs of the constraints on a space: their mask and positions (local `cdofs`, owned `c_owned_pos`),
    their targets g (local) and g_owned_c (the owned rows'), the rows' scale s, and the rigid faces among them."""

    def hold(self, space, constraints):
        self.constraints = constraints
        n = 3 * space.nlv
        mask = np.zeros(n, bool)
        for c in constraints:
            mask[c.dofs] = True
        self.cmask = mask
        self.cdofs = np.flatnonzero(mask)
        self.rigid = [c for c in constraints if isinstance(c, HeldBody)]    # rigid faces (their loads: rigid.py)
        owned_mask = mask.reshape(-1, 3)[space.lvid_of_owned].ravel()
        self.c_owned_pos = np.flatnonzero(owned_mask)          # positions in the global (owned) array
        self.g = np.zeros(n)                                    # prescribed positions (local)
        self.g_owned_c = np.zeros(len(self.c_owned_pos))
        self.scale = 1.0

    def targets(self, t):
        """The held dofs' targets at time t (an expression not finite at some rank's vertices: one UserError on every
        rank where a constraint evaluates expressions, else on the rank that found it)."""
        err = None
        for c in self.constraints:
            try:
                self.g[c.dofs] = c.values(t)
            except UserError as e:
                err = err or str(e)
        if any(c.evaluates for c in self.constraints):    # raised on every rank, or none waits
            errs = [e for e in self.space.mpi.allgather(err) if e]
            if errs:
                raise UserError(errs[0])
        elif err:
            raise UserError(err)
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]   # targets of the owned rows

    def set_held(self, values):
        """The targets of every held dof (local, in the order of cdofs) set to `values` (the linearized predictor)."""
        self.g[self.cdofs] = values
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]

    def retarget(self, constraint, positions):
        """The held targets of one constraint set to (n, 3) positions of its vertices (a rigid face whose reference
        point moved inside a step: solving/rigid.py)."""
        self.g[constraint.dofs] = positions[constraint.comps]
        self.g_owned_c = self.space.owned_array(self.g)[self.c_owned_pos]

    def moves_prescribed(self, x):
        """Whether the step begun (begin_step) moves a prescribed dof away from its place in the local positions x,
        on some rank. Collective."""
        c = self.cdofs
        moved = bool(len(c)) and not np.array_equal(self.g[c], x[c])
        return self.space.mpi.allreduce(moved, op=MPI.LOR)

    def impose(self, x):
        """x (local array) with constrained dofs set to their prescribed positions."""
        x[self.cdofs] = self.g[self.cdofs]
        return x

    def impose_global(self, X):
        X.getArray()[self.c_owned_pos] = self.g_owned_c

    def _dirichlet_rows(self, Xa, Ra):
        """The constrained rows of the residual, Ra[c] = s (Xa[c] - g_c) (owned rows; global arrays)."""
        Ra[self.c_owned_pos] = self.scale * (Xa[self.c_owned_pos] - self.g_owned_c)

    def _constrained_rows(self, V, Y):
        if len(self.c_owned_pos):
            Y.getArray()[self.c_owned_pos] = self.scale * V.getArray(readonly=True)[self.c_owned_pos]

    def set_scale(self, D):
        """s = mean |diag J| over the free owned dofs (D: a global vector to use as workspace)."""
        self.scale = 1.0
        self.diagonal(D)
        a = np.abs(D.getArray(readonly=True))
        free = np.ones(len(a), bool)
        free[self.c_owned_pos] = False
        tot = self.space.mpi.allreduce(np.array([a[free].sum(), free.sum()]), op=MPI.SUM)
        self.scale = float(tot[0] / max(tot[1], 1)) or 1.0
