"""What an augmented-Lagrangian (grad-div) Schur preconditioner would give the mixed formulation on thin walls
(issue 49, item 2): one Newton linear system of a scene, at its start, solved by GMRES(100) to 1e-5 with the lower
Schur factorization, for the displacement block A and its augmented form A + gamma B^T W^-1 B (B = K_pu, W the
lumped pressure mass), the system transformed alike (its solution unchanged):

    [A + g B^T W^-1 B,  B^T + g B^T W^-1 K_pp] [du]   [f_u + g B^T W^-1 f_p]
    [B,                 K_pp              ] [dp] = [f_p                 ]

with the Schur complement preconditioned by -(1/(mu + g) + 1/kappa) W (Jacobi), against the default -(1/mu + 1/kappa)
M_p at g = 0. The displacement block (-upcs, a comma list) by GAMG (with the rigid-body modes), by LU (an exact
block: the Schur approximation alone), by vertex-star ASM then GAMG (`star`), or by p-multigrid (`pmg`: the
application's solving/pmg.py levels, P2 smoothed, the P1 operator P^T A P by GAMG; `pmg_star`: vertex stars on the
P2 level). -fact lower|upper: the Schur factorization; -coarse augmented|plain: p-multigrid's P1 operator from the
augmented block or from A alone; -keep drop: p-multigrid with PCMG's own level defaults (Chebyshev/SOR, an LU of
the P1 operator) instead of the application's (Chebyshev/Jacobi, GAMG); VIEW=1 in the environment prints the
displacement split's KSP. Prints the GMRES iterations of each. Not a solver of the application: the experiment
behind `-mixed_augment` (formulations/mixed/operators.Augmented; BENCHMARKS.md, 2026-11-27 tenth session).

    .venv/bin/python scripts/explore_augmented_lagrangian.py SCENE.opts MESH.msh [-option value ...] \
        [-gammas 1,10,100] [-upcs gamg,lu,star,pmg,pmg_star] [-fact upper] [-coarse plain] [-keep drop]
"""
import os
import sys
import time

import numpy as np
import petsc4py

petsc4py.init([])
from petsc4py import PETSc  # noqa: E402

sys.path.insert(0, __file__.rsplit("/scripts/", 1)[0])
from hyperelastic.app.catalog import load_scene  # noqa: E402
from hyperelastic.app.model import build_model  # noqa: E402
from hyperelastic.formulations.mixed.operators import MixedNest  # noqa: E402

DIFFERENT = PETSc.Mat.Structure.DIFFERENT_NONZERO_PATTERN


def linear_system(scene_file, mesh, extra):
    """(system, MixedNest at the first step's start, f_u, f_p): the first Newton system of the scene."""
    o = PETSc.Options()
    for k, v in [("mesh", mesh)] + [(extra[i].lstrip("-"), extra[i + 1]) for i in range(0, len(extra), 2)]:
        o.setValue(k, v)
    scene, _ = load_scene(scene_file)
    m = build_model(scene, PETSc.COMM_WORLD)
    s = m.system
    s.begin_step(0.0, m.scene.dt, m.x0, m.v0)
    X = s.global_state(m.x0)
    X.getArray()[s.nu_owned:] = 0.0
    R = X.duplicate()
    s.linearize(X)
    s.residual(X, R)
    op = MixedNest(s, "aij")
    op.update()
    return s, op, R.getSubVector(s.is_u).copy(), R.getSubVector(s.is_p).copy()


def vertex_stars(s):
    """Per vertex, the displacement dofs of its star's interior: the vertex's node and its edges' midpoint nodes (the
    patches whose solves capture the grad-div kernel: Schoeberl 1999; Farrell, Mitchell & Wechsung 2019)."""
    from hyperelastic.element.reference import EDGES
    cells = s.space.cells.astype(np.int64)
    ends = cells[:, np.asarray(EDGES)].reshape(-1, 2)
    mids = cells[:, 4:].ravel()
    nodes = {}
    for v in np.unique(cells[:, :4]):
        nodes[v] = {v}
    for (a, b), m in zip(ends, mids):
        nodes[a].add(m)
        nodes[b].add(m)
    g = np.asarray(s.space.lgmap.getIndices()).reshape(-1, 3)
    out = []
    for v, ns in nodes.items():
        idx = np.sort(np.concatenate([g[n] for n in ns]))
        out.append(PETSc.IS().createGeneral(idx.astype(PETSc.IntType), comm=PETSc.COMM_SELF))
    return out


def star_and_gamg(pc, s, A, op):
    """The displacement block's preconditioner: vertex-star ASM (exact patch solves), then GAMG (multiplicative)."""
    pc.setType("composite")
    pc.setCompositeType(PETSc.PC.CompositeType.MULTIPLICATIVE)
    pc.addCompositePCType("asm")
    pc.addCompositePCType("gamg")
    asm = pc.getCompositePC(0)
    asm.setOperators(A, A)
    stars = vertex_stars(s)
    asm.setASMLocalSubdomains(len(stars), stars)
    asm.setASMOverlap(0)
    asm.setASMType(PETSc.PC.ASMType.BASIC)
    asm.setUp()
    for k in asm.getASMSubKSP():
        k.setType("preonly")
        k.getPC().setType("lu")


VIEW = os.environ.get("VIEW")
FACT, COARSE, KEEP = "lower", "augmented", "keep"


def p_multigrid(ku, s, A, A0, star=False):
    """The displacement block by p-multigrid (solving/pmg.py: P2 smoothed by Chebyshev/Jacobi, or with star=True by
    vertex-star ASM with exact patch solves, Richardson, one step; the P1 Galerkin operator by GAMG)."""
    from hyperelastic.solving import pmg
    prefix = ku.getOptionsPrefix()
    o = PETSc.Options()
    o.setValue(prefix + "pc_type", "mg")
    pmg.before_options(s.space, prefix)
    if star:
        o.setValue(prefix + "mg_levels_ksp_type", "richardson")
        o.setValue(prefix + "mg_levels_ksp_max_it", "1")
        o.setValue(prefix + "mg_levels_pc_type", "asm")
    pc = ku.getPC()
    pc.setType("mg")
    pc.setFromOptions()
    levels = pmg.Levels(pc, s.space)
    levels.update(A if COARSE == "augmented" else A0)
    if star:
        smooth = pc.getMGSmoother(1).getPC()
        smooth.setType("asm")
        stars = vertex_stars(s)
        smooth.setASMLocalSubdomains(len(stars), stars)
        smooth.setASMOverlap(0)
        smooth.setASMType(PETSc.PC.ASMType.BASIC)
        smooth.setFromOptions()
    if KEEP != "keep":
        for name in list(o.getAll()):
            if name.startswith(prefix):
                o.delValue(name)


def solve(s, op, fu, fp, gamma_over_mu, upc):
    """GMRES iterations and seconds of the (augmented) system with the displacement block by `upc`."""
    c = s.couplings[0]
    mu, kappa = c.shear, c.law.kappa
    inv_kappa = 0.0 if np.isinf(kappa) else 1.0 / kappa
    Mp = s.pressure_mass()                                  # -(1/mu + 1/kappa) M_p
    W = Mp.getRowSum()
    W.scale(-1.0 / (1.0 / mu + inv_kappa))                  # the lumped pressure mass
    Winv = W.copy()
    Winv.reciprocal()
    g = gamma_over_mu * mu
    A, Bt, bu, Sp = op.uu.mat, op.K_up, fu, Mp
    if g > 0:
        WB = op.K_pu.copy()
        WB.diagonalScale(L=Winv)                            # W^-1 B
        A = op.uu.mat.copy()
        A.axpy(g, op.K_up.matMult(WB), structure=DIFFERENT)
        WC = op.K_pp.copy()
        WC.diagonalScale(L=Winv)
        Bt = op.K_up.copy()
        Bt.axpy(g, op.K_up.matMult(WC), structure=DIFFERENT)
        t = fp.copy()
        t.pointwiseMult(t, Winv)
        bu = fu.copy()
        tmp = fu.duplicate()
        op.K_up.mult(t, tmp)
        bu.axpy(g, tmp)
        Sp = Mp.copy()
        Sp.zeroEntries()
        Sp.setDiagonal(W)
        Sp.scale(-(1.0 / (mu + g) + inv_kappa))
    A.setNearNullSpace(op.nullspace)
    K = PETSc.Mat().createNest([[A, Bt], [op.K_pu, op.K_pp]], isrows=[s.is_u, s.is_p], iscols=[s.is_u, s.is_p])
    b = K.createVecs("left")
    for iset, part in ((s.is_u, bu), (s.is_p, fp)):
        sub = b.getSubVector(iset)
        part.copy(sub)
        b.restoreSubVector(iset, sub)
    ksp = PETSc.KSP().create()
    ksp.setOperators(K, K)
    ksp.setType("gmres")
    ksp.setGMRESRestart(100)
    ksp.setTolerances(rtol=1e-5, max_it=1000)
    pc = ksp.getPC()
    pc.setType("fieldsplit")
    pc.setFieldSplitIS(("u", s.is_u), ("p", s.is_p))
    pc.setFieldSplitType(PETSc.PC.CompositeType.SCHUR)
    pc.setFieldSplitSchurFactType(getattr(PETSc.PC.FieldSplitSchurFactType, FACT.upper()))
    pc.setFieldSplitSchurPreType(PETSc.PC.FieldSplitSchurPreType.USER, Sp)
    s.is_u.compose("nearnullspace", op.nullspace)
    ksp.setUp()
    ku, kp = pc.getFieldSplitSubKSP()
    ku.setType("preonly")
    if upc == "star":
        star_and_gamg(ku.getPC(), s, A, op)
    elif upc in ("pmg", "pmg_star"):
        p_multigrid(ku, s, A, op.uu.mat, star=upc == "pmg_star")
    else:
        ku.getPC().setType(upc)
    kp.setType("preonly")
    kp.getPC().setType("jacobi")
    x = b.duplicate()
    t0 = time.perf_counter()
    ksp.setUp()
    ksp.getPC().setUpOnBlocks()
    t1 = time.perf_counter()
    ksp.solve(b, x)
    t2 = time.perf_counter()
    if VIEW:
        ku.view()
    print(f"  (A's nonzeros {A.getInfo()['nz_used']:.0f}; set-up {t1 - t0:.3f} s, solve {t2 - t1:.3f} s)")
    return ksp.getIterationNumber(), ksp.getConvergedReason(), t2 - t0


def main():
    args = sys.argv[1:]
    gammas = "1,10,100"
    if "-gammas" in args:
        i = args.index("-gammas")
        gammas = args[i + 1]
        del args[i:i + 2]
    upcs = ("gamg", "lu", "star")
    if "-upcs" in args:
        i = args.index("-upcs")
        upcs = args[i + 1].split(",")
        del args[i:i + 2]
    for name in ("fact", "coarse", "keep"):
        if "-" + name in args:
            i = args.index("-" + name)
            globals()[name.upper()] = args[i + 1]
            del args[i:i + 2]
    s, op, fu, fp = linear_system(args[0], args[1], args[2:])
    print(f"{fu.getSize()} displacement and {fp.getSize()} pressure unknowns")
    for upc in upcs:
        for gm in [0.0] + [float(v) for v in gammas.split(",")]:
            its, reason, t = solve(s, op, fu, fp, gm, upc)
            print(f"gamma/mu = {gm:g}, displacement block by {upc}: {its} GMRES iterations (reason {reason}), "
                  f"{t:.2f} s", flush=True)


if __name__ == "__main__":
    main()
