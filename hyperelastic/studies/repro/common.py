"""What every thesis experiment needs: a mesh at a simulated state, the elastic force k(x), the
exact K(x) v and M v, the thesis' seed formulas and PETSc's MFFD applied to k, and the test vectors.

All of it is serial (one rank) and works on arrays in the input mesh's vertex order; the state
comes from a real `hyperelastic run` of the scene.

Test vector families (thesis sec. 7.1):
  e   unit vectors e_i (distinct, random i)
  r   N(0, 1) entries
  t   "real" vectors mu + sigma * randn, with mu, sigma the mean and standard deviation of the
      simulated displacement's entries: eq. 7.3 as intended (the sampling we use everywhere)
  tw  eq. 7.3 as printed, mu * randn + sigma; kept as a diagnostic: with mu ~ 0 such a vector is
      nearly the constant sigma (1, 1, ..., 1), a rigid translation, which k does not see
"""
import os

import argparse

import h5py
import numpy as np
from petsc4py import PETSc

from ...physics import materials
from ..experiments import table
from ..experiments.runner import command, run_hyperelastic
from ...solving.jacobians import PetscMFFD, seed_difference
from ...discretization.kernels import CellKernels
from ...discretization.space import reference_geometry

FAMILIES = ("e", "r", "t", "tw")
FAMILY_LABELS = {"e": "unit e", "r": "N(0,1) r", "t": "real t = mu + sigma randn",
                 "tw": "eq. 7.3 as printed: mu randn + sigma"}
SEED_OPS = ("seed_fd", "seed_fd2")
MFFD_OPS = ("mffd_wp", "mffd_ds")
OPERATORS = SEED_OPS + MFFD_OPS
OP_LABELS = {"seed_fd": "thesis 1st order (5.19)", "seed_fd2": "thesis 2nd order (7.8)",
             "mffd_wp": "PETSc MFFD wp", "mffd_ds": "PETSc MFFD ds", "exact": "exact K v"}
THESIS_MATERIALS = ("linear", "stvk")


def petsc():
    return PETSc


def simulate_state(out_dir, level=1, final_time=0.2, scene="squeeze", extra=()):
    """(points, tets, x, t): the last frame of `hyperelastic run scene` on mesh level `level` with the
    exact tangent, written to (and reused from) out_dir/states/."""
    d = os.path.join(out_dir, "states")
    os.makedirs(d, exist_ok=True)
    tag = "_".join([scene, f"L{level}", f"t{final_time:g}"] + [str(a).lstrip("-") for a in extra])
    path = os.path.join(d, tag + ".h5")
    if not os.path.isfile(path):
        tmp = f"{path}.{os.getpid()}.part.h5"      # scripts running side by side do not collide
        args = ["run", scene, "-level", level, "-final_time", final_time, "-jacobian", "assembled", "-output", tmp,
                "-quiet", *extra]
        rc, err, _ = run_hyperelastic(args, tmp, timeout=None)
        if rc != 0:
            raise RuntimeError(f"{' '.join(command(args))} failed: {err.strip()}")
        os.replace(tmp, path)
        if os.path.exists(tmp[:-3] + ".xdmf"):          # the XDMF index of the temporary name
            os.remove(tmp[:-3] + ".xdmf")
    with h5py.File(path, "r") as f:
        return f["mesh/points"][:], f["mesh/tetra"][:], f["x"][-1], float(f["time"][-1])


class Bench:
    """k, K v, M v, the seed formulas and PETSc's MFFD on one mesh at one state x.

    The material is switched with set_material; k(x) and the MFFD base point are refreshed then."""

    def __init__(self, points, tets, x, rho=1000.0):
        self.X = np.ascontiguousarray(points, dtype=np.float64)
        self.x = np.ascontiguousarray(x, dtype=np.float64).ravel().copy()
        self.n = self.x.size
        self.nc = len(tets)
        Dminv, vol = reference_geometry(self.X, np.asarray(tets))
        self.kern = CellKernels(tets, Dminv, vol, materials.get("linear"), (1.0, 1.0))
        self.rho = float(rho)
        u = self.x - self.X.ravel()
        self.mu_real, self.sigma_real = float(u.mean()), float(u.std())
        self._mffd = {}
        self.k0 = None

    def set_material(self, name, E, nu):
        solid = materials.default_solid(name, E, nu)
        self.kern.set_material(solid.material, solid.constants)
        self.material, self.E, self.nu = name, E, nu
        self.k0 = self.k(self.x)
        for m, _, _ in self._mffd.values():
            m.rebase()

    # --- the exact operators ------------------------------------------------------------------
    def k(self, x):
        f = np.zeros(self.n)
        self.kern.forces(np.ascontiguousarray(x), f)
        return f

    def Kv(self, v):
        y = np.zeros(self.n)
        self.kern.kv(self.x, np.ascontiguousarray(v), y)
        return y

    def Mv(self, v):
        y = np.zeros(self.n)
        self.kern.geometry.mass_apply(self.rho, np.ascontiguousarray(v), y)
        return y

    # --- approximations of K v ----------------------------------------------------------------
    def seed(self, v, order=1):
        """The thesis' formulas (5.19, 7.8), as `-jacobian seed_fd` / `seed_fd2` apply them."""
        return seed_difference(self.k, self.x, v, self.k0, np.linalg.norm(v), order)

    def _mffd_op(self, kind):
        if kind not in self._mffd:
            PETSc = petsc()
            X = PETSc.Vec().createSeq(self.n, comm=PETSc.COMM_SELF)
            X.getArray()[:] = self.x

            def function(xv, fv):
                f = fv.getArray()
                f[:] = 0.0
                self.kern.forces(np.ascontiguousarray(xv.getArray(readonly=True)), f)

            self._mffd[kind] = (PetscMFFD(function, X, kind.split("_")[1], prefix=f"repro_{kind}_"),
                                X.duplicate(), X.duplicate())
        return self._mffd[kind]

    def mffd(self, v, kind="mffd_wp"):
        """PETSc's MFFD (what -snes_mf builds) for F = k: (k(x + eps v) - k(x))/eps, eps chosen by
        -mat_mffd_type wp or ds."""
        m, V, Y = self._mffd_op(kind)
        V.getArray()[:] = v
        m.mat.mult(V, Y)
        return Y.getArray().copy()

    def approx(self, op, v):
        if op == "seed_fd":
            return self.seed(v, 1)
        if op == "seed_fd2":
            return self.seed(v, 2)
        if op in MFFD_OPS:
            return self.mffd(v, op)
        if op == "exact":
            return self.Kv(v)
        raise ValueError(op)

    # --- test vectors -------------------------------------------------------------------------
    def vectors(self, family, count, rng):
        n = self.n
        if family == "e":
            V = np.zeros((count, n))
            V[np.arange(count), rng.choice(n, count, replace=count > n)] = 1.0
            return V
        if family == "r":
            return rng.standard_normal((count, n))
        if family == "t":
            return self.mu_real + self.sigma_real * rng.standard_normal((count, n))
        if family == "tw":
            return self.mu_real * rng.standard_normal((count, n)) + self.sigma_real
        raise ValueError(family)


def measure(bench, V, ops):
    """Per test vector v (rows of V) and operator: the numbers every error measure needs.
    Returns {op: array (count, 6)} with columns D_INF ||a - Kv||_inf, D2 ||a - Kv||_2, and the
    shared KV2 ||Kv||^2, MV2 ||Mv||^2, MK Mv.Kv, KVINF ||Kv||_inf."""
    out = {op: np.empty((len(V), 6)) for op in ops}
    for i, v in enumerate(V):
        kv, mv = bench.Kv(v), bench.Mv(v)
        shared = (kv @ kv, mv @ mv, mv @ kv, np.abs(kv).max())
        for op in ops:
            d = bench.approx(op, v) - kv
            out[op][i] = (np.abs(d).max(), np.linalg.norm(d), *shared)
    return out


D_INF, D2, KV2, MV2, MK, KVINF = range(6)


def delta(m, h):
    """The thesis' error (eqs. 7.7, Alg. 1): max over vectors of ||h^2 (approx - K v)||_inf, for each h."""
    return np.asarray(h, dtype=float) ** 2 * m[:, D_INF].max()


def rel_K(m):
    """Relative error of the approximation of K v: max over vectors of ||approx - Kv|| / ||Kv||."""
    return float((m[:, D2] / np.sqrt(m[:, KV2])).max())


def rel_J(m, h):
    """Relative error of the whole Newton operator J = M + h^2 K (thesis eq. 5.18b, no damping):
    max over vectors of h^2 ||approx - Kv|| / ||M v + h^2 K v||, for each h."""
    h2 = np.asarray(h, dtype=float)[:, None] ** 2
    den = np.sqrt(np.maximum(m[:, MV2] + 2 * h2 * m[:, MK] + h2 ** 2 * m[:, KV2], 1e-300))
    return (h2 * m[:, D2] / den).max(axis=1)


def largest_feasible(h, err, tol):
    """The largest h of the grid with err <= tol (the thesis' blue/red points), or NaN."""
    ok = np.asarray(err) <= tol
    return float(np.max(np.asarray(h)[ok])) if ok.any() else float("nan")


def write_csv(path, rows, fields=None):
    return table.write_csv(path, rows, fields)


def read_csv(path):
    return table.read_csv(path)


def outdir(path):
    os.makedirs(path, exist_ok=True)
    return path


def parser(description, **extra):
    """The command line every reproduction script shares: OUTPUT_DIR, --full, --seed and friends."""
    ap = argparse.ArgumentParser(description=description)
    ap.add_argument("output_dir", help="folder for the CSV and PNG files (created if missing)")
    ap.add_argument("--full", action="store_true", help="the thesis' grid (minutes) instead of the quick default")
    ap.add_argument("--seed", type=int, default=7, help="seed of the test vectors (default 7)")
    ap.add_argument("--level", type=int, default=1, help="mesh level for the E and nu experiments (default L1)")
    ap.add_argument("--state_time", type=float, default=0.2,
                    help="the linearization state is the squeeze scene at this time (default 0.2 s)")
    for name, kw in extra.items():
        ap.add_argument(name, **kw)
    return ap
