"""Effects: each adds its terms to the backward-Euler residual
    R(x) = M (x - x^n - h v^n)/h^2 + C (x - x^n)/h + k(x) - f
and to its Jacobian J = M/h^2 + C/h + K (or the quasi-static R = k(x) - f, J = K).
A conservative effect also gives its part of the incremental potential
    E(x) = 1/2 h^-2 (x - x^)^T M (x - x^) + 1/2 h^-1 (x - x^n)^T C (x - x^n) + Psi(x) - f^T x,
x^ = x^n + h v^n, whose gradient is R (the SNES objective: backward Euler as energy minimization).

Under PETSc TS (ts_integrator.py) the same effects give the second-order form
    F(t, x, v, a) = M a + C v + k(x) - f(t)
with Jacobian K + shift_v C + shift_a M: an effect of `order` 1 (damping) or 2 (inertia) adds its
operator applied to v or a (`rate_residual`), and its Jacobian weight becomes the shift (`set_weight`)
instead of 1/h or 1/h^2; the effects of order 0 are used as they are, at the stage time.

All arrays are local (owned + ghost vertices, 3 dofs each); contributions are additive over the
cells a rank owns, so summing local arrays into the global vector assembles them.
"""
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np


@dataclass(frozen=True)
class Energy:
    """An energy an effect reports every step (Effect.energy): a statistics column (stats.py) and its
    part in energy_total (sign +1 or -1; 0: not an energy, e.g. J_min). `work`: the work of a load,
    left out where a check wants the energy of the body alone. `combine`: how the values of several
    instances and of the ranks combine (sum, min, max)."""
    column: str
    sign: int
    meaning: str
    work: bool = False
    combine: str = "sum"


@dataclass(frozen=True)
class LoadKind:
    """How an effect serves as a kind of named load (-loads NAME with -NAME_KIND VALUE, loads.py): its value read as
    a "vector" or a "real" (at least `minimum` where given), whether its faces may name components (`S:z`) and
    whether it has a time function; `params` (value, faces, scale) -> the effect's own parameters, which its Spec
    builds; `help` its part of -help's line for -loads."""
    value: str
    params: Callable
    help: str
    components: bool = False
    timed: bool = True
    minimum: float = None


@dataclass(frozen=True)
class Spec:
    """Everything the application knows of an effect, declared once in its module (effects/NAME.py) and
    listed in effects.REGISTRY: the scene reader, the option catalog (-help, the options reference, the
    unknown-option check), the set labels, `effects.build`, the statistics columns and the energy totals
    all loop over the registry.
      name       the name -effects lists
      summary    one line for -help
      rows       its options (options.Row), as -help and the options reference list them
      shares     options of another effect's rows that it reads too (the follower twist's surfaces)
      implied_by the options whose presence switches the effect on (see scene.read_effects)
      read       (opts, where) -> its parameters (a dataclass), read and checked; None: it has none
      active     parameters -> whether they leave the effect on (-damping 0 switches damping off)
      sets       parameters -> [(option, set name, "facets" | "tets")]: the surfaces and volumes it uses
      build      (parameters, effects.Context) -> [Effect or dirichlet.Constraint]
      dynamic    left out of -quasistatic runs (inertia, damping)
      energies   the Energy columns its instances report
      load       LoadKind: it is also a kind of named load (-loads), or None"""
    name: str
    summary: str
    build: Callable
    rows: tuple = ()
    shares: tuple = ()
    implied_by: tuple = ()
    read: Callable = None
    active: Callable = None
    sets: Callable = None
    dynamic: bool = False
    energies: tuple = ()
    load: LoadKind = None

    def parameters(self, opts, where):
        return None if self.read is None else self.read(opts, where)

    def is_active(self, params):
        return True if self.active is None else bool(self.active(params))

    def set_uses(self, params):
        return [] if self.sets is None else list(self.sets(params))


def cell_blocks(effects, vals, lo=0, hi=None):
    """vals = the sum of the effects' blocks of cells lo..hi-1, in their order: the first writes (set_cell_blocks),
    the others add; zero where there are none. The same values as adding them all to zeros."""
    if not effects:
        vals.fill(0.0)
        return
    effects[0].set_cell_blocks(vals, lo, hi)
    for e in effects[1:]:
        e.add_cell_blocks(vals, lo, hi)


def timed(kind):
    """Decorator counting calls and wall time of an effect method (kind: 'evals' or 'applies')."""
    def deco(fn):
        def wrapper(self, *a, **k):
            t0 = time.perf_counter()
            try:
                return fn(self, *a, **k)
            finally:
                self.seconds += time.perf_counter() - t0
                setattr(self, kind, getattr(self, kind) + 1)
        wrapper.__name__ = fn.__name__
        wrapper.__doc__ = fn.__doc__
        return wrapper
    return deco


class Effect:
    name = "effect"
    linear = True          # residual affine in x (seed_fd differences only the nonlinear effects)
    conservative = True    # the residual is the gradient of `potential` (the SNES objective, see system.py)
    cell_blocks = False    # contributes 12x12 blocks on the cell pattern
    symmetric = True
    order = 0              # 0: acts on positions; 1: on velocities (damping); 2: on accelerations (inertia)
    constant = False       # residual independent of x, changed only by begin_step (dead loads): add_constant
    domain = False         # counts the cells where its material is undefined (`undefined`, after a residual)
    undefined = 0
    discrete_gradient = False  # has residual_discrete_gradient (the energy-momentum force, -energy_momentum)
    kernels = None         # the cell kernels of its material (elasticity): the domain and inversion checks
    internal = False       # internal forces (they sum to zero over the body): not a load in the forces table
    end_state = False      # in a generalized-alpha stage, acts at the step's end state (contact; System._end_state)
    projection = None      # a tangent that can be projected to positive semi-definite per cell (elasticity): whether it
                           # is (-hessian_projection; the solver may switch it on: Solver.project_hessians)

    def __init__(self):
        self.evals = 0       # residual evaluations
        self.applies = 0     # Jacobian applications / assemblies
        self.seconds = 0.0

    # time dependence: called once per step before the solve
    def begin_step(self, t, h, xn, vn):
        pass

    def begin_stage(self, t_stage, h, xn, vn, alpha_f):
        """A generalized-alpha stage at t_stage = t_n + alpha_f h of a step of h from (xn, vn) (System.begin_stage,
        after begin_step at the step's end): an effect on positions acts at the stage's time (its loads there),
        unless it acts at the step's end (end_state)."""
        if self.order == 0 and not self.end_state:
            self.begin_step(t_stage, h, xn, vn)

    def residual(self, x, r):
        """r += this effect's residual at local positions x."""

    def add_constant(self, r):
        """r += this effect's residual, for an effect whose residual does not depend on x (`constant`):
        System.residual sums these once per step (after begin_step) instead of at every evaluation."""
        raise NotImplementedError(f"{self.name} is not constant")

    def rate_residual(self, u, r):
        """r += this effect's operator applied to u (v for order 1, a for order 2; TS form)."""
        raise NotImplementedError(f"{self.name} has no rate form")

    def set_weight(self, w):
        """The Jacobian weight of an order 1 or 2 effect (1/h or 1/h^2 in backward Euler; TS: the shift)."""

    def linearize(self, x):
        """Remember the linearization point for apply/diag/values."""

    def apply(self, v, y):
        """y += J_effect v (at the linearization point)."""

    def diag(self, d):
        """d += diag(J_effect)."""

    def add_cell_blocks(self, vals, lo=0, hi=None):
        """vals (hi-lo, 3nn, 3nn) += this effect's blocks of cells lo..hi-1 (nn nodes per cell: 12x12 for P1,
        30x30 for P2), default all (only if cell_blocks)."""

    def set_cell_blocks(self, vals, lo=0, hi=None):
        """vals = this effect's blocks of cells lo..hi-1 (overwritten); an effect whose kernels can write its blocks
        (elasticity) spares the zeroing."""
        vals.fill(0.0)
        self.add_cell_blocks(vals, lo, hi)

    def coo_pattern(self):
        """Extra COO entries (rows, cols) in local dof numbering, beyond the cell pattern."""
        return np.zeros(0, np.int64), np.zeros(0, np.int64)

    def coo_values(self, out):
        """Fill the values of the extra COO entries."""

    def potential(self, x):
        """This effect's part of the incremental potential at local positions x, whose gradient is its
        residual (additive over ranks like the residual). Only for conservative effects."""
        raise NotImplementedError(f"{self.name} has no potential")

    def energy(self, x, v):
        """Contribution to the step's statistics: dict of name -> value (summed over ranks)."""
        return {}

    def accept_step(self, x, h):
        """The step of size h that ends at local positions x was accepted (an effect with a state of its own: the
        viscoelastic stresses)."""

    def cell_state(self):
        """{name (core.files.CHECKPOINT_CELLS): local rows per cell} of its state beyond the positions at the last
        accepted step, for a checkpoint."""
        return {}

    def check_resume(self, state, path):
        """UserError where a checkpoint's state (files.read_checkpoint) cannot continue in this effect: checked before
        the run is set up."""

    def resume_cells(self, state, space):
        """Continue from a checkpoint's state (files.read_checkpoint; space.read_cell_state reads its rows)."""


class QuadraticEffect(Effect):
    """An effect whose energy is quadratic about an origin x0 with a constant symmetric operator A: residual
    A (x - x0), potential 1/2 (x - x0)^T A (x - x0), tangent A. A subclass gives `_apply(v, y)` (y += A v) and
    `origin()` (x0: a spring's rest positions, the step's start of Rayleigh damping)."""

    def _apply(self, v, y):
        raise NotImplementedError

    def origin(self):
        raise NotImplementedError

    @timed("evals")
    def residual(self, x, r):
        self._apply(x - self.origin(), r)

    def potential(self, x):
        d = x - self.origin()
        y = np.zeros_like(d)
        self._apply(d, y)
        return 0.5 * float(d @ y)

    @timed("applies")
    def apply(self, v, y):
        self._apply(v, y)


class NodeBlocks(Effect):
    """An effect whose tangent is one 3x3 block per node of `nodes` (this rank's local ids, each once) in `blocks`,
    set by linearize: its product, diagonal and COO entries (the cell pattern already holds a node's own block).
    Contact with obstacles and self-contact (whose pairs add couplings beside these blocks)."""

    def block_product(self, v):
        """(n, 3): each node's block times v's values there (v a local array)."""
        return np.einsum("nij,nj->ni", self.blocks, v.reshape(-1, 3)[self.nodes])

    @timed("applies")
    def apply(self, v, y):
        np.add.at(y.reshape(-1, 3), self.nodes, self.block_product(v))

    @timed("applies")
    def diag(self, d):
        np.add.at(d.reshape(-1, 3), self.nodes, np.einsum("nii->ni", self.blocks))

    def coo_pattern(self):
        dofs = 3 * self.nodes[:, None] + np.arange(3)                      # (n, 3)
        rows = np.broadcast_to(dofs[:, :, None], (len(self.nodes), 3, 3))
        cols = np.broadcast_to(dofs[:, None, :], (len(self.nodes), 3, 3))
        return rows.ravel().copy(), cols.ravel().copy()

    def coo_values(self, out):
        out[:] = self.blocks.ravel()

    def scale_tangent(self, f):
        self.blocks *= f


def load_factor(scale, t):
    """A load's factor at time t: 1 without a time function; `scale` a number A: the ramp A min(t,1);
    a callable (a time function of -NAME_time): its value."""
    if scale is None:
        return 1.0
    return float(scale(t)) if callable(scale) else ramp(t, scale)


def ramp(t, scale, ramp_time=1.0):
    """Load factor scale * min(t / ramp_time, 1) (the thesis framework's min(t,1) ramps)."""
    return scale * min(t / ramp_time, 1.0)


class DeadLoad(Effect):
    """A load independent of the positions: the nodal forces f0 (a local array) scaled by a time function
    (load_factor), potential -s f0.x, reported as the work s f0.x in the column `work_column`."""
    constant = True
    work_column = "load_work"

    def __init__(self, f0, scale=None):
        super().__init__()
        self.f0 = f0
        self.loaded = np.flatnonzero(self.f0)            # the loaded dofs: the residual touches only them
        self.f0_loaded = self.f0[self.loaded]
        self.scale_param = scale
        self.s = 1.0

    def begin_step(self, t, h, xn, vn):
        self.s = load_factor(self.scale_param, t)

    @timed("evals")
    def residual(self, x, r):
        self.add_constant(r)

    def add_constant(self, r):
        r[self.loaded] -= self.s * self.f0_loaded

    def potential(self, x):
        return -self.s * float(self.f0 @ x)

    def energy(self, x, v):
        return {self.work_column: self.s * float(self.f0 @ x)}
