"""The seams between the solver and what an effect or a constraint needs of it beyond a residual and a tangent.

Most effects are sums over cells or nodes: the solver asks them for R(x), J(x) and an energy (base.Effect) and
nothing else. Contact with obstacles, self-contact and rigid faces need more: their own limit on a Newton update, a
check of a state the material cannot see, a say in where a step starts, a stiffness that adapts between steps,
couplings outside the cell pattern, or held dofs that follow a body of their own. Each such capability is one class
here, with defaults that do nothing; an effect offers it by subclassing it, and `solving/` iterates over the effects
that declare it (`isinstance`). Nothing in `solving/` or `formulations/` probes an effect with `hasattr`, `getattr` with a
default or a comparison of its name (tests/test_layers.py walks their syntax trees and fails on one).

| capability | what the solver does with it | declared by |
|---|---|---|
| `StepLimiter` | shortens every Newton update to the smallest `max_step` over the limiters and the ranks (the line search's pre-check); counts the cut in the limiter's statistics column | `Contact`, `SelfContact`; the inversion guard (`solving.solver.InversionGuard`) |
| `DomainCheck` | a state where `undefined_at` counts something on some rank is no solution and no step's start (besides the material's inverted cells) | `Contact`, `SelfContact` |
| `StepStart` | before a step is solved: which nodes' paths the scene gives (`hold`), whether those paths collide (`held_collision`), where a moving surrounding pushes the body (`pushed`), whether the surroundings move linearly in t (`moves_linearly`) | `Contact`, `SelfContact` |
| `AdaptiveStiffness` | at each step's start, the stiffness balanced against the other forces within `kappa_range` (`set_kappa`, `barrier_gradient`) | `Contact`, `SelfContact` (with `-contact_kappa adaptive`) |
| `Couplings` | a matrix of entries between nodes that the cell pattern does not join, multiplied beside the assembled operator (`jacobians.Coupled`) | `SelfContact` |
| `Results` | the pressure and status at the contact nodes in every frame, each obstacle's force, area and translation in every accepted step's statistics (self-contact's too) | `Contact`, `SelfContact` |
| `dirichlet.HeldBody` | held dofs whose targets follow a body of their own (a reference point balanced around each step's solve, its reaction and state its own) | `rigid.Rigid` |

A new friction law, limiter or kind of held constraint subclasses the capability and fills in its methods; nothing in
`solving/` changes (docs/design.md, "Seams").
"""
from typing import NamedTuple, Optional

import numpy as np


class StepLimiter:
    """A limit on each Newton update: the largest fraction (<= 1) of the update dx from the local positions x that
    keeps the state admissible, this rank's part (the solver takes the minimum over the limiters and the ranks)."""
    counter = "contact_cuts"    # the statistics column counting the updates this limiter shortened
    sticky = False              # True: a cut anywhere in a solve makes its step-norm stop not convergence (the
                                # inversion guard); False: only a cut in its last update does (a barrier's stiff start
                                # is cut in its first iterations, then converges quadratically)

    def max_step(self, x, dx):
        return 1.0


class DomainCheck:
    """A check of a state beyond the material's own (which counts inverted cells): where `undefined_at` counts
    something, the state is no solution and no step may start there. `domain = True` makes every residual count it as
    it counts inverted cells (base.Effect.undefined)."""
    domain = True

    def undefined_at(self, x):
        """This rank's count of where the local positions x are outside the effect's domain, as reached from the
        step's start (a contact node at or through an obstacle, the surface through itself)."""
        return 0

    def crossing(self, x):
        """In words, where the local positions x leave the domain as this rank sees it ("" where they do not): what a
        refused start names."""
        return ""


# a step's start pushes contact nodes ahead of a moving obstacle by at most this fraction of their shortest surface edge
# (else the step is retried shorter): StepStart.pushed of contact.py and self_contact.py; and Starts.pushed refuses a
# start that would invert a cell under twice its pushes (0.3 before the eighteenth session, without that check: the
# quadratic O-ring's first touch was refused at its nodes' half-edge spacing)
PUSH_LIMIT = 1.0


class StepStart:
    """A say in where a step starts. The solver tells the effect which nodes' paths the scene gives (`hold`), asks
    whether those paths run into something the effect cannot stop (`held_collision`), whether the effect moves the
    body's surroundings (`moving`), pushes the nodes they reach ahead of them (`pushed`) and moves them linearly in t
    over a step (`moves_linearly`: a collision of given paths is then certain to stay at any smaller step)."""
    moving = False              # the effect moves the body's surroundings with time (-obstacle_motion)

    def hold(self, held):
        """held: per local node, whether the scene prescribes all three of its components (its path is given)."""

    def held_collision(self, x0, x1):
        """(s, words): the first fraction s <= 1 of the straight move of the held nodes from local positions x0 (the
        step's start) to x1 (their targets) at which they meet something the effect keeps apart, and what meets; None
        where nothing does (this rank's nodes, or the same on every rank)."""
        return None

    def pushed(self, x, base=None):
        """(x', fits): x (a start of the step) with the nodes the surroundings' move since the step's start reached
        pushed ahead of them, and whether every push stays small enough for the cells beside them (this rank's nodes);
        base: the step's start state x^n the pushes keep the distances of (default x itself; a start carried along by
        the last step's rate keeps those of x^n, not its own)."""
        return x, True

    def moves_linearly(self, t0, t1):
        """Whether the surroundings' move is linear in t over [t0, t1] (checked at the midpoint)."""
        return True


class AdaptiveStiffness:
    """A stiffness (kappa) the solver may balance between steps against the other forces (IPC's adaptive barrier
    stiffness: System's begin_step), within `kappa_range` = (lo, hi); None: kept as given."""
    kappa = 1.0
    kappa_range = None

    def set_kappa(self, kappa):
        self.kappa = float(kappa)

    def barrier_gradient(self, x, r):
        """r += the gradient of the stiffness-weighted term per unit kappa at local positions x."""


class Couplings:
    """Tangent entries between nodes that the cell pattern does not join (self-contact's pairs): `coupled` says,
    after a linearization and the same on every rank, whether some rank has any; `coupling_entries` gives them."""
    coupled = False

    def coupling_entries(self, constrained):
        """(rows, cols, values) in global dof numbering of this rank's rows; `constrained`: a mask of the owned dofs
        held, whose rows and columns are left out. Collective."""
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0)


SELF_STATUS = -1      # contact_status (Results.point_values) of a node in a pair with the surface itself and no obstacle


class ResultRow(NamedTuple):
    """One contact's results at a state (Results.result_rows): its force on the body (3,) and contact area, this rank's
    part (summed over the ranks), its translation (3,) (the same on every rank), and the force it carries where the
    force on the body says nothing of it (self-contact's pairs balance: None elsewhere; summed over the ranks)."""
    name: str
    force: np.ndarray
    area: float
    translation: np.ndarray
    carried: Optional[float] = None


class Results:
    """What an effect reports of a state beyond its energies (contact: the pressure and status at its nodes, and per
    obstacle its force on the body, its contact area and its translation). `point_values(x)`: {field name: local array
    per node} for every frame (names of output/fields.py's POINT_SCALARS; several effects' arrays of one name are
    added); `result_rows(x, t)`: [ResultRow] of this rank's part, each a statistics row of every accepted step
    (stats.py: result_columns)."""

    def point_values(self, x):
        return {}

    def result_rows(self, x, t):
        return []


def declaring(items, capability):
    """The items (effects or constraints) that declare the capability, in their order."""
    return [e for e in items if isinstance(e, capability)]
