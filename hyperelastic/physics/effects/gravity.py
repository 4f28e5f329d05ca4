from dataclasses import dataclass

import numpy as np

from ...core.options import Row, needs
from .base import Effect, Energy, Spec, timed


class Gravity(Effect):
    """Body force rho g: f_a = int rho g N_a dV = rho g V/4 per cell vertex (constant)."""
    name = "gravity"
    constant = True

    def __init__(self, cells, rho, g, nlv):
        super().__init__()
        share = np.zeros(nlv)
        np.add.at(share, cells.cells.ravel(), cells.load_shares(rho).ravel())
        self.f = (share[:, None] * np.asarray(g, float)[None, :]).ravel()
        self.g = np.asarray(g, float)

    @timed("evals")
    def residual(self, x, r):
        self.add_constant(r)

    def add_constant(self, r):
        r -= self.f

    def potential(self, x):
        return -float(self.f @ x)

    def energy(self, x, v):
        # potential energy of gravity, -f.x (reference: x = 0)
        return {"gravity_potential": -float(self.f @ x)}


@dataclass(frozen=True)
class Acceleration:
    g: tuple          # [m/s^2]


def _read(opts, where):
    g = opts.vector("gravity")
    if g is None:
        raise needs(where, "gravity", "-gravity gx,gy,gz")
    return Acceleration(tuple(g))


SPEC = Spec(
    "gravity", "body force rho g on every cell", implied_by=("gravity",), read=_read,
    build=lambda p, ctx: [Gravity(ctx.cells, ctx.density, p.g, ctx.space.nlv)],
    rows=(Row(("gravity",), "-gravity gx,gy,gz", "body force ρg [m/s²] on the whole body (each region's ρ)"),),
    energies=(Energy("gravity_potential", 1, "potential of gravity -f.x [J] (scenes with gravity)"),))
