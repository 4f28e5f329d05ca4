import numpy as np

from .base import Effect, timed


class Gravity(Effect):
    """Body force rho g: f_a = int rho g N_a dV = rho g V/4 per cell vertex (constant)."""
    name = "gravity"
    constant = True

    def __init__(self, kernels, rho, g, nlv):
        super().__init__()
        share = np.zeros(nlv)
        np.add.at(share, kernels.cells.ravel(), np.repeat(rho * kernels.vol / 4.0, 4))
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
