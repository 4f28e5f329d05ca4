from dataclasses import dataclass

import numpy as np

from ...core.options import Row, needs
from .base import QuadraticEffect, Spec, timed
from .mass import MassOperator, WeightedMass


class ViscousDamping(WeightedMass):
    """Viscous damping C (x - x^n)/h, C = c int N^T N dV (thesis eqs. 4.15, 4.40); Jacobian C/h.
    Under PETSc TS: C v, Jacobian weight shift_v."""
    name = "damping"
    order = 1

    def target_of(self, h, xn, vn):
        return xn


class RayleighDamping(QuadraticEffect):
    """Rayleigh damping (alpha M + beta K(x^n)) (x - x^n)/h. The stiffness is frozen at the start
    of the step, so the residual is affine in x and its Jacobian (alpha M + beta K(x^n))/h is exact.
    Under PETSc TS: (alpha M + beta K(x^n)) v, x^n the state at the start of the step, weight shift_v."""
    name = "rayleigh"
    cell_blocks = True
    order = 1

    def __init__(self, kernels, cells, rho, alpha, beta, lumped, nlv):
        super().__init__()
        self.k = kernels
        self.alpha, self.beta = alpha, beta
        self.M = MassOperator(cells, alpha * rho, lumped, nlv)

    def begin_step(self, t, h, xn, vn):
        self.h = h
        self.w, self.bw = 1.0 / h, self.beta / h     # weights of M and K(x^n)
        self.xn = xn.copy()

    def set_weight(self, w):
        self.w, self.bw = w, self.beta * w

    def _apply(self, v, y, w=None, bw=None):
        self.M.apply(v, y, self.w if w is None else w)
        if self.beta:
            tmp = np.zeros_like(y)
            self.k.kv(self.xn, v, tmp)
            y += (self.bw if bw is None else bw) * tmp

    @timed("evals")
    def rate_residual(self, v, r):
        """r += (alpha M + beta K(x^n)) v (TS form)."""
        self._apply(v, r, 1.0, self.beta)

    def origin(self):
        return self.xn

    @timed("applies")
    def diag(self, d):
        self.M.add_diag(d, self.w)
        if self.beta:
            tmp = np.zeros_like(d)
            self.k.tangent_diag(self.xn, tmp)
            d += self.bw * tmp

    @timed("applies")
    def add_cell_blocks(self, vals, lo=0, hi=None):
        self.M.add_blocks(vals, self.w, lo, hi)
        if self.beta:
            k = self.k if lo == 0 and hi in (None, self.k.nc) else self.k.part(lo, hi)
            K, _ = k.tangent(self.xn)             # scaled by beta/h, so not accumulated in place
            vals += self.bw * K

    def coo_pattern(self):
        return self.M.coo_pattern()

    def coo_values(self, out):
        self.M.coo_values(out, self.w)


@dataclass(frozen=True)
class Viscous:
    c: float          # C = c int N^T N dV [kg/(m^3 s)]


def _read_viscous(opts, where):
    c = opts.real("damping", None, minimum=0, exclusive=False)
    if c is None:
        raise needs(where, "damping", "-damping c")
    return Viscous(c)


SPEC = Spec(
    "damping", "viscous damping C = c int N^T N dV", implied_by=("damping",), read=_read_viscous,
    active=lambda p: p.c != 0, dynamic=True,
    build=lambda p, ctx: [ViscousDamping(ctx.cells, p.c, ctx.lumped, ctx.space.nlv)],
    rows=(Row(("damping",), "-damping c", "viscous damping C = c∫NᵀN (0 removes the effect)"),))


@dataclass(frozen=True)
class Rayleigh:
    alpha: float      # of the mass matrix [1/s]
    beta: float       # of the stiffness K(x^n) [s]


def _read_rayleigh(opts, where):
    return Rayleigh(opts.real("rayleigh_alpha", 0.0, minimum=0, exclusive=False),
                    opts.real("rayleigh_beta", 0.0, minimum=0, exclusive=False))


RAYLEIGH = Spec(
    "rayleigh", "Rayleigh damping (alpha M + beta K(x^n))", implied_by=("rayleigh_alpha", "rayleigh_beta"),
    read=_read_rayleigh, active=lambda p: p.alpha != 0 or p.beta != 0, dynamic=True,
    build=lambda p, ctx: [RayleighDamping(ctx.kernels.unscaled(), ctx.cells, ctx.density, p.alpha, p.beta, ctx.lumped,
                                          ctx.space.nlv)],
    rows=(Row(("rayleigh_alpha", "rayleigh_beta"), "-rayleigh_alpha a -rayleigh_beta b",
              "Rayleigh damping (αM + βK(xⁿ))"),))
