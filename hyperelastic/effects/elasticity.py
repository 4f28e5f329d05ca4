from .base import Effect, timed


class Elasticity(Effect):
    """Internal elastic force k(x) (thesis eq. 4.41) and its exact tangent K = dk/dx."""
    name = "elasticity"
    linear = False
    cell_blocks = True

    def __init__(self, kernels, material):
        super().__init__()
        self.k = kernels
        self.material = material
        self.linear = material.name == "linear"
        self.x = None
        self.undefined = 0   # cells where the material was undefined at the last evaluation

    @timed("evals")
    def residual(self, x, r):
        self.undefined = self.k.forces(x, r)

    def linearize(self, x):
        self.x = x.copy()

    @timed("applies")
    def apply(self, v, y):
        self.k.kv(self.x, v, y)

    @timed("applies")
    def diag(self, d):
        self.k.tangent_diag(self.x, d)

    @timed("applies")
    def add_cell_blocks(self, vals):
        self.k.tangent(self.x, vals, accumulate=True)

    def energy(self, x, v):
        W, jmin, jmax, bad = self.k.energy(x)
        return {"elastic": W, "J_min": jmin, "J_max": jmax}
