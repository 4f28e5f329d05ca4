"""The mixed displacement-pressure formulation (-formulation mixed), its spec: quadratic displacements and a continuous
linear pressure at the vertices (Taylor-Hood P2-P1, inf-sup stable: Brezzi & Fortin, Mixed and Hybrid Finite
Element Methods, 1991, sec. VI.6; Boffi, Brezzi & Fortin 2013, sec. 8.8).

A material with an isochoric/volumetric split (materials: `volumetric`, `split`) psi = psi_iso(F) + U(G),
G = J - 1 (the split Neo-Hookean, Mooney-Rivlin) or G = tr eps (linear, whose psi_iso is mu dev eps:dev eps),
takes the perturbed Lagrangian (Simo, Taylor & Pister, CMAME 51, 1985; Zienkiewicz & Taylor, vol. 2, ch. 5)

    Pi(u, p) = int [ psi_iso(F) + p G(F) - U*(p) ] dV  - (the loads' work),

U* the Legendre transform of U: U*(p) = p G_p - U(G_p) with U'(G_p) = p. Stationarity in p gives G = U*'(p),
i.e. p = U'(G), so eliminating p returns psi_iso + U exactly, at any bulk modulus: the mixed and the
displacement formulations are the same continuous problem, and p is the mean Cauchy stress (positive in
tension: sigma = sigma_iso + p I). For U = kappa/4 (J^2 - 1 - 2 ln J), U'(J) = kappa/2 (J - 1/J), so
J_p = s + sqrt(1 + s^2), s = p/kappa, U*'(p) = J_p - 1 and U*''(p) = 1 / U''(J_p) = 2 / (kappa (1 + J_p^-2));
for U = kappa/2 G^2, U* = p^2 / (2 kappa). The incompressible limit (-incompressible) is U* = 0: G = 0.

Discrete: with N_a the P2 shape functions (physical gradients g_a), M_b the P1 ones, h_a = F^-T g_a,
    r_u[a,i] += int p dG/dF : (e_i x g_a)          (J h_a,i for G = J - 1; g_a,i for tr eps)
    r_p[b]    = int (G - U*'(p)) M_b
    K_uu      += int p d2G[(e_i x g_a), (e_k x g_b)]  (J (h_a,i h_b,k - h_b,i h_a,k); 0 for tr eps)
    K_up[(a,i), b] = int dG/dF : (e_i x g_a) M_b,   K_pu = K_up^T,   K_pp[b,c] = -int U*''(p) M_b M_c
(the isochoric part is the material's own kernel with its volumetric modulus set to zero). The tangent is
symmetric and indefinite (a saddle point): Newton's line search uses the residual norm, and the linear
solver is a Schur-complement field split (solver.py) preconditioned by the pressure mass matrix scaled by
-(1/mu + 1/kappa) (Silvester & Wathen 1994; Elman, Silvester & Wathen 2014, ch. 4).

Unknowns: one global vector, on each rank its owned displacement dofs followed by its owned pressures
(`MixedSystem.is_u`, `is_p`); every effect sees the displacement part as before.

Here: its spec (what it takes and refuses, the choice of -formulation auto, its system). fields.py: the pressure,
its law and its terms; system.py: the unknown and the residual; operators.py: the tangent; solver.py: its solver.
"""
import math

import numpy as np

from ...core.errors import UserError
from ...core.options import Row
from ...mesh.sets import MATERIAL_LABEL
from ...physics import materials
from ..base import Formulation
from .fields import PressureCoupling, PressureSpace, Volumetric
from .solver import FieldSplitPlan
from .system import MixedSystem

# -formulation auto takes the mixed formulation from this bulk-to-shear ratio kappa/mu up (nu >= 0.495), where the
# element order and the solver allow it: measured on Lame's cylinder, docs/mixed.md "Which formulation by default"
AUTO_RATIO = 100.0


def split_materials():
    """The names of the materials with an isochoric/volumetric split (Material.volumetric), in registry order."""
    return [m.name for m in materials.MATERIALS.values() if m.volumetric]


def iso_constants(solid):
    """The kernel's parameter block of a solid in the mixed formulation: its isochoric part where it has a split
    (the pressure carries the rest), else its own (a compressible region beside a mixed one)."""
    return solid.material.split(solid.values)[0] if solid.material.volumetric else solid.constants


def bulk_to_shear(solid):
    """kappa/mu of a solid: its split's moduli where it has one, else from E and nu."""
    if solid.material.volumetric:
        _, mu, kappa = solid.material.split(solid.values)
        return kappa / mu
    nu = solid.values["nu"]
    return 2 * (1 + nu) / (3 * (1 - 2 * nu))


# A converged state's volume check (issue 47: a quasi-static step of a rubber at kappa/mu = 1e4 was accepted at J_min
# 0.107, J_max 2.05). A solid's pressure kappa |ln J| is held by its shear stresses and the loads, a few mu to a few
# hundred mu in any rubber part (a pressure of 1000 mu is 500 MPa in a rubber of mu = 0.5 MPa); and where the volume is a
# constraint (the mixed formulation, -incompressible), J is 1 up to the discretization: 1 +- 1% on the rod's 588 P2
# tets at kappa/mu = 1e4. So a state with |ln J| beyond max(0.5, VOLUME_LIMIT / (kappa/mu)) in some cell is refused
# (step control retries it smaller). For the most compressible solid of the run; compressible solids (nu = 0.3:
# |ln J| <= 460) are never refused.
VOLUME_LIMIT = 1000.0


def volume_bound(problem, incompressible=False):
    """(the largest |ln J| a converged state may have, kappa/mu it follows from: the most compressible solid's)."""
    ratio = min(math.inf if incompressible and sol.material.volumetric else bulk_to_shear(sol)
                for _, sol in problem.solids)
    return max(0.5, VOLUME_LIMIT / ratio), ratio


class Mixed(Formulation):
    name = "mixed"
    summary = ("a continuous linear pressure beside quadratic displacements (Taylor–Hood P2–P1, needs `-order 2`) "
               "for nearly incompressible materials with an isochoric/volumetric split (" + ", ".join(split_materials())
               + "); the pressure p is the mean Cauchy stress (an output field); GMRES with a Schur-complement field "
               "split by default. `auto` takes it where a material with a split has κ/μ ≥ "
               f"{AUTO_RATIO:g} (ν ≥ 0.495) on quadratic tetrahedra and the run allows it")
    rows = (Row(("incompressible",), "-incompressible", "the mixed formulation's incompressible limit (bulk modulus "
                "→ ∞: J = 1, or tr ε = 0 for `linear`)", "off"),
            Row(("mixed_augment",), "-mixed_augment G", "the field split's augmented Lagrangian, γ = G μ of each "
                "material: the preconditioner is built from the system with γ BᵀW⁻¹B added to its displacement "
                "block (W the lumped pressure mass; the solution unchanged; on p-multigrid's P1 level the cells' "
                "grad-div), the Schur complement preconditioned by −(1/(μ + γ) + 1/κ) W, the upper factorization, "
                "GMRES preconditioned on the right: Krylov iterations that do not grow on thin walls (the rubber "
                "bracket 48 → 22 per Newton step in 0.76–0.88× the time, Cook's membrane 27 → 18 in 0.95–1.03×). "
                "Needs p-multigrid in the displacement split (the default; with `-fieldsplit_u_pc_type gamg` or "
                "another Schur factorization it is off). 0: the scaled pressure mass matrix and the lower "
                "factorization", "3"),)
    auto_rank = 10
    point_fields = ("pressure",)

    def read(self, opts, scene):
        scene.incompressible = opts.flag("incompressible", scene.incompressible)
        if scene.incompressible and scene.formulation == "auto":
            scene.formulation = self.name
        if scene.incompressible and scene.formulation != self.name:
            raise UserError("option -incompressible: the incompressible limit needs a pressure field "
                            "(-formulation mixed)")

    def refusal(self, problem):
        """The paths it does not take, each one line."""
        sc, order = problem.scene, problem.element.order
        what = "option -incompressible (a pressure field)" if sc.incompressible else "option -formulation mixed"
        if order != 2:
            return (f"{what}: needs quadratic tetrahedra (-order 2: Taylor-Hood P2-P1); equal-order P1-P1 is not "
                    "inf-sup stable")
        if sc.jacobian != "assembled":
            return (f"{what}: the tangent is assembled (-jacobian assembled; -snes_mf_operator works), not -jacobian "
                    f"{sc.jacobian}")
        if sc.matrix_free == "mf":
            return (f"{what}: -snes_mf leaves the saddle point without a preconditioner (GMRES breaks down); "
                    "-snes_mf_operator keeps the field split")
        if sc.integrator != "beuler":
            return f"{what}: quasi-static and backward Euler runs (-integrator beuler), not -integrator {sc.integrator}"
        if not any(sol.material.volumetric for _, sol in problem.solids):
            where = ", ".join(f"{w} {sol.name}" for w, sol in problem.solids)
            return (f"{what}: no isochoric/volumetric split in the cells' materials ({where}); use "
                    + ", ".join(split_materials()))
        return None

    def claims(self, problem):
        """Where some material the cells have is nearly incompressible (kappa/mu >= AUTO_RATIO) and has a split, on
        quadratic tetrahedra, in a run it takes (else a note says why not)."""
        ratio = max(bulk_to_shear(sol) for _, sol in problem.solids)
        if ratio < AUTO_RATIO:
            return False, None
        nu = (3 * ratio - 2) / (2 * (3 * ratio + 1))
        what = f"nearly incompressible (kappa/mu = {ratio:.3g}, nu = {nu:.5g})"
        if problem.element.order != 2:
            return False, (f"{what}: linear tetrahedra lock (too stiff); -order 2 takes the mixed "
                           "displacement-pressure formulation (docs/mixed.md)")
        why = self.refusal(problem)
        if why:
            return False, f"{what}, displacements alone; not the mixed formulation: {why.split(': ', 1)[1]}"
        return True, (f"{what}: -formulation auto takes the mixed displacement-pressure formulation (-formulation "
                      "displacement: displacements alone)")

    def cell_constants(self, solid):
        return iso_constants(solid)

    def system(self, problem, space, kernels, effects, constraints, x0, v0):
        pspace = PressureSpace(space)
        couplings = pressure_couplings(problem.scene, space, kernels.geometry, pspace)
        return MixedSystem(space, effects + couplings, constraints, x0, v0, problem.scene.dt, couplings, pspace)

    def point_values(self, system):
        return lambda x: {"pressure": system.pressure_nodal()}

    def solver_plan(self, system):
        return FieldSplitPlan()

    def describe(self, scene):
        return self.name + (" (incompressible)" if scene.incompressible else "")


def pressure_couplings(scene, space, geometry, pspace):
    """The pressure terms: one PressureCoupling per material with an isochoric/volumetric split, on its cells (all of
    them without -regions; a region's, or the cells in none, with); the same list on every rank, a coupling with no
    local cells included."""
    solids = [scene.solid] + [r.solid for r in scene.regions]
    which = space.cell_values(MATERIAL_LABEL) if scene.regions else None
    out = []
    for i, sol in enumerate(solids):
        if not sol.material.volumetric:
            continue
        _, mu, kappa = sol.material.split(sol.values)
        law = Volumetric(sol.material.volumetric, math.inf if scene.incompressible else kappa)
        idx = None if which is None else np.flatnonzero(which == i)
        out.append(PressureCoupling(geometry, law, pspace.nlp, mu, idx))
    return out


FORMULATION = Mixed()
