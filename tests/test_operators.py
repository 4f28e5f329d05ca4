"""The Jacobian modes apply the same operator: shell and assembled agree to 1e-12, PETSc's MFFD
to 1e-5, and the tangent is the derivative of the residual (central differences)."""
import itertools
import re

import numpy as np
import pytest

from conftest import ROOT, make_model

SCENES = ["bend", "twist", "squeeze", "sag"]


def state(petsc, scene_name, options=(), amp=0.05):
    """The scene's model linearized at a random state x (a step at small t from the reference
    configuration with a random velocity): (scene, space, system, X)."""
    m = make_model(petsc, scene_name, options)
    scene, space, system = m.scene, m.space, m.system
    rng = np.random.default_rng(3)
    x = space.X.ravel() + amp * rng.standard_normal(3 * space.nlv)
    v = 0.1 * rng.standard_normal(3 * space.nlv)
    system.begin_step(0.02, scene.dt, space.X.ravel().copy(), v)  # small t: prescribed ends move little
    X = system.global_state(x)
    system.linearize(X)
    return scene, space, system, X


def apply(mat, V):
    Y = V.duplicate()
    mat.mult(V, Y)
    return Y.getArray().copy()


def check_shell_equals_assembled(system, X):
    """Shell and assembled apply the same J to a random vector (1e-12); returns (V, J V)."""
    from hyperelastic.solving import jacobians
    a = jacobians.make(system, "assembled")
    a.update()
    A, S = a.mat, jacobians.make(system, "shell").mat
    V = X.duplicate()
    V.setRandom()
    ya, ys = apply(A, V), apply(S, V)
    assert np.abs(ya - ys).max() <= 1e-12 * np.abs(ya).max()
    return A, S, V, ys


def check_is_derivative(system, X, V, Jv):
    """J V against central differences of the residual."""
    eps = 1e-6
    Rp, Rm = X.duplicate(), X.duplicate()
    system.residual(X + eps * V, Rp)
    system.residual(X - eps * V, Rm)
    fd = (Rp.getArray() - Rm.getArray()) / (2 * eps)
    assert np.abs(Jv - fd).max() <= 1e-6 * np.abs(Jv).max()


@pytest.mark.parametrize("scene_name", SCENES)
@pytest.mark.parametrize("material", ["stvk", "neohookean", "linear"])
def test_shell_matches_assembled(petsc, scene_name, material):
    scene, space, system, X = state(petsc, scene_name, [("material", material)])
    A, S, V, _ = check_shell_equals_assembled(system, X)
    # the diagonals agree too (Jacobi sees the same preconditioner)
    Da, Ds = X.duplicate(), X.duplicate()
    A.getDiagonal(Da)
    S.getDiagonal(Ds)
    assert np.abs(Da.getArray() - Ds.getArray()).max() <= 1e-12 * np.abs(Da.getArray()).max()


# the effects and materials declared in issue 31: springs (some components), a total force, a body force,
# Mooney-Rivlin and the split Neo-Hookean
NEW = [[("spring", "3e5"), ("spring_faces", "bottom:z,back"), ("loads", "s"), ("s_spring", "1e5"), ("s_faces", "top:xy"),
        ("force", "0,-50,20"), ("force_faces", "front"), ("body_force", "0,0,-200")],
       [("material", "mooney_rivlin"), ("C01", "1e5")], [("material", "neohookean_split"), ("kappa", "5e6")]]


@pytest.mark.parametrize("options", NEW, ids=["effects", "mooney_rivlin", "neohookean_split"])
def test_new_effects_and_materials_tangents(petsc, options):
    """Shell and assembled agree (operator and diagonal) and the tangent is the residual's derivative."""
    scene, space, system, X = state(petsc, "bend", options)
    A, S, V, Jv = check_shell_equals_assembled(system, X)
    Da, Ds = X.duplicate(), X.duplicate()
    A.getDiagonal(Da)
    S.getDiagonal(Ds)
    assert np.abs(Da.getArray() - Ds.getArray()).max() <= 1e-12 * np.abs(Da.getArray()).max()
    check_is_derivative(system, X, V, Jv)


@pytest.mark.parametrize("scene_name", SCENES)
def test_tangent_is_derivative_of_residual(petsc, scene_name):
    from hyperelastic.solving import jacobians
    scene, space, system, X = state(petsc, scene_name)
    S = jacobians.make(system, "shell").mat
    V = X.duplicate()
    V.setRandom()
    check_is_derivative(system, X, V, apply(S, V))


def petsc_mffd(system, X, mffd_type="wp"):
    """PETSc's own MFFD operator (what -snes_mf builds) for our residual, with base point X."""
    from hyperelastic.solving.jacobians import PetscMFFD
    m = PetscMFFD(system.residual, X.copy(), mffd_type, prefix="mffdtest_")
    assert "mffd" in m.mat.getType()
    return m.mat, m.snes


@pytest.mark.parametrize("scene_name", SCENES)
@pytest.mark.parametrize("mffd_type", ["wp", "ds"])
def test_petsc_mffd_matches_exact(petsc, scene_name, mffd_type):
    """PETSc's MFFD ((R(x + e a) - R(x))/e with its scaled e) applied to our residual matches the
    exact tangent to 1e-5 relative: the thesis' formula has no differencing step, PETSc's does."""
    from hyperelastic.solving import jacobians
    scene, space, system, X = state(petsc, scene_name)
    S = jacobians.make(system, "shell").mat
    M, snes = petsc_mffd(system, X, mffd_type)
    for _ in range(3):
        V = X.duplicate()
        V.setRandom()
        ye, ym = apply(S, V), apply(M, V)
        assert np.linalg.norm(ym - ye) <= 1e-5 * np.linalg.norm(ye)


def test_shell_operator_is_symmetric(petsc):
    from hyperelastic.solving import jacobians
    scene, space, system, X = state(petsc, "bend")
    S = jacobians.make(system, "shell").mat
    U, V = X.duplicate(), X.duplicate()
    U.setRandom()
    V.setRandom()
    a = V.dot(_mv(S, U))
    b = U.dot(_mv(S, V))
    assert abs(a - b) <= 1e-12 * abs(a)


def _mv(A, V):
    Y = V.duplicate()
    A.mult(V, Y)
    return Y


VARIANTS = [
    [("rayleigh_alpha", "0.5"), ("rayleigh_beta", "1e-3")],
    [("mass", "lumped")],
    [("mass", "lumped"), ("rayleigh_alpha", "0.2"), ("rayleigh_beta", "1e-3")],
    [("gravity", "0,0,-9.81"), ("material", "neohookean")],
    [("quasistatic", "1")],
]


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: ",".join(f"{k}={x}" for k, x in v))
def test_effect_variants_consistent(petsc, variant):
    """Rayleigh damping, lumped mass, gravity and quasi-static: shell == assembled, and both are
    the derivative of the residual."""
    scene, space, system, X = state(petsc, "bend", variant)
    names = [e.name for e in system.effects]
    for k, _ in variant:
        if k.startswith("rayleigh"):
            assert "rayleigh" in names
    if ("quasistatic", "1") in variant:
        assert "inertia" not in names and "damping" not in names
    A, S, V, ys = check_shell_equals_assembled(system, X)
    check_is_derivative(system, X, V, ys)


def test_lumped_and_consistent_mass_have_the_same_total(petsc):
    """Both mass matrices carry the body's total mass rho * volume in each direction."""
    totals = []
    for mass in ("consistent", "lumped"):
        m = make_model(petsc, "bend", [("mass", mass)])
        space, system = m.space, m.system
        inertia = next(e for e in system.effects if e.name == "inertia")
        ones = np.zeros(3 * space.nlv)
        ones[0::3] = 1.0
        y = np.zeros_like(ones)
        inertia.M.apply(ones, y)
        totals.append(y[0::3].sum())
    assert np.isclose(totals[0], totals[1], rtol=1e-12)
    assert np.isclose(totals[0], 1000.0 * 10 * 4 * 4, rtol=1e-9)


@pytest.mark.parametrize("scene_name,options", [("bend", []), ("twist", []), ("squeeze", [("mass", "lumped")])])
def test_chunked_assembly_equals_coo(petsc, scene_name, options, monkeypatch):
    """-assembly setvalues (chunks of cells into a preallocated AIJ) gives the COO path's matrix,
    with exact preallocation on one rank; refilling it (zeroEntries) gives it again."""
    from hyperelastic.solving import jacobians
    scene, space, system, X = state(petsc, scene_name, options)
    monkeypatch.setattr(jacobians.AssembledChunked, "CHUNK", 97)     # many chunks, a ragged last one
    a = jacobians.AssembledChunked(system)
    a.assemble()
    a.assemble()
    b = jacobians.Assembled(system)
    b.assemble()
    C = a.mat.copy()
    C.axpy(-1.0, b.mat, structure=petsc.Mat.Structure.DIFFERENT_NONZERO_PATTERN)
    assert C.norm(petsc.NormType.FROBENIUS) <= 1e-13 * b.mat.norm(petsc.NormType.FROBENIUS)
    info = a.mat.getInfo()
    if space.comm.getSize() == 1:
        assert info["nz_unneeded"] == 0 and info["nz_used"] == b.mat.getInfo()["nz_used"]


@pytest.mark.parametrize("scene_name", ["bend", "squeeze"])
def test_sbaij_operator_is_the_assembled_tangent(petsc, scene_name):
    """-operator_storage sbaij: the SBAIJ copy (upper block triangle, refreshed after every fill by the
    gather map) multiplies like the AIJ it came from, after a second fill at another state too; SNES
    gets it as the operator (Amat) and the AIJ as the preconditioning matrix."""
    from hyperelastic.solving import jacobians
    from hyperelastic.solving.solver import Solver
    scene, space, system, X = state(petsc, scene_name)
    a = jacobians.AssembledChunked(system, storage="sbaij")
    assert a.operator.getType() == "seqsbaij" and a.copy.sb_o is None
    rng = np.random.default_rng(3)
    for k in range(2):
        if k:
            x = system.local(X, system.xl).copy()
            system.linearize(system.global_state(x + 1e-3 * rng.standard_normal(len(x))))
        a.assemble()
        v = a.mat.createVecRight()
        v.setArray(rng.standard_normal(v.getLocalSize()))
        y1, y2 = a.mat.createVecLeft(), a.mat.createVecLeft()
        a.mat.mult(v, y1)
        a.operator.mult(v, y2)
        assert np.abs(y1.getArray() - y2.getArray()).max() <= 1e-13 * np.abs(y1.getArray()).max()
    s = Solver(system, "assembled", storage="sbaij")
    J, P = s.snes.getKSP().getOperators()
    assert J.getType() == "seqsbaij" and P.getType() == "seqaij"


def test_operator_storage_auto(petsc):
    """-operator_storage auto (the default): sbaij for a symmetric tangent assembled by setvalues; aij
    for a follower load (twist), the COO fill, the shell and under -snes_mf_operator."""
    from hyperelastic.solving.solver import resolve_storage
    sym, unsym = state(petsc, "bend")[2], state(petsc, "twist")[2]
    assert resolve_storage("auto", sym, "assembled", "setvalues", "") == "sbaij"
    assert resolve_storage("auto", unsym, "assembled", "setvalues", "") == "aij"
    assert resolve_storage("auto", sym, "assembled", "coo", "") == "aij"
    assert resolve_storage("auto", sym, "shell", "setvalues", "") == "aij"
    assert resolve_storage("auto", sym, "assembled", "setvalues", "mf_operator") == "aij"
    assert resolve_storage("aij", sym, "assembled", "setvalues", "") == "aij"


def test_sbaij_storage_run_equals_aij(tmp_path):
    """A dynamic run with CG + GAMG (and the set-up reuse) gives the same trajectory and Krylov
    iterations with -operator_storage sbaij as with aij, on 1 and 2 ranks."""
    from conftest import read_h5, run_ok
    common = ["run", "bend", "-level", "1", "-final_time", "0.05", "-options_file", f"{ROOT}/options/gamg.opts",
              "-ksp_rtol", "1e-10", "-snes_rtol", "1e-10", "-quiet"]
    res = {}
    for st, n in (("aij", 1), ("sbaij", 1), ("sbaij", 2)):
        f = tmp_path / f"{st}{n}.h5"
        run_ok(common + ["-operator_storage", st, "-output", f], nprocs=n)
        h = read_h5(f)
        assert h["attrs"]["operator_storage"] == st
        res[st, n] = (h["x"][-1], h["stats"]["ksp_its"])
    ref, its = res["aij", 1]
    for key in (("sbaij", 1), ("sbaij", 2)):
        assert np.abs(res[key][0] - ref).max() <= 1e-9 * np.abs(ref).max(), key
    assert np.array_equal(res["sbaij", 1][1], its)


def test_chunked_assembly_pattern_exact_on_two_ranks():
    """On 2 ranks the chunked direct fill (exact pattern from both ranks' cells, preallocated before the
    first fill) equals the COO matrix, with no unused preallocated entry, and its SBAIJ copy multiplies
    like it where the tangent is symmetric (tests/mpi_assembly_check.py)."""
    from conftest import run_mpi_script
    p = run_mpi_script("mpi_assembly_check.py", ["bend", "twist", "squeeze"])
    assert p.returncode == 0, p.stdout + p.stderr
    assert ([l.split(":")[0] for l in p.stdout.splitlines() if l.startswith("ok")]
            == ["ok bend", "ok twist", "ok squeeze"]), p.stdout


def test_chunked_assembly_on_two_ranks(tmp_path):
    from conftest import read_h5, run_ok
    out = {}
    for asm in ("setvalues", "coo"):
        f = tmp_path / f"{asm}.h5"
        run_ok(["run", "twist", "-level", "1", "-final_time", "0.05", "-assembly", asm, "-output", f, "-quiet"],
               nprocs=2)
        out[asm] = read_h5(f)["x"][-1]
    assert np.abs(out["setvalues"] - out["coo"]).max() <= 1e-10


def test_gamg_setup_reused_until_the_iterations_grow(tmp_path):
    """-reuse_preconditioner auto (the default) keeps a GAMG set-up across Newton iterations and time
    steps: fewer PCSetUp calls than Jacobians, the same solution as a set-up per Jacobian to the solver
    tolerance, and a rebuild when the Krylov iterations grow (here the step control halving h changes
    the tangent's mass term)."""
    from conftest import read_h5, run_ok
    common = ["run", "bend", "-level", "1", "-final_time", "0.05", "-options_file", f"{ROOT}/options/gamg.opts",
              "-ksp_rtol", "1e-10", "-snes_rtol", "1e-10", "-quiet"]
    counts = {}
    for mode in ("never", "auto"):
        out, log = tmp_path / f"{mode}.h5", tmp_path / f"{mode}.log"
        run_ok(common + ["-reuse_preconditioner", mode, "-output", out, "-log_view", f":{log}"])
        ev = {w[0]: int(w[1]) for w in (ln.split() for ln in open(log)) if len(w) > 2 and w[0] in
              ("PCSetUp", "SNESJacobianEval")}
        counts[mode] = (ev["PCSetUp"], ev["SNESJacobianEval"], read_h5(out)["x"][-1])
    assert counts["never"][0] >= counts["never"][1] and counts["auto"][0] < counts["auto"][1] / 2
    assert np.abs(counts["auto"][2] - counts["never"][2]).max() <= 1e-8


def test_preconditioner_rebuild_rule(monkeypatch):
    """The rule of -reuse_preconditioner auto: the first solve after a set-up sets the base; a solve
    that needs more than 1.5x the base's iterations, or fails, asks for a set-up at the next Jacobian."""
    from hyperelastic.solving import solver as S
    asked = []
    monkeypatch.setattr(S, "lag_preconditioner", lambda snes, lag: asked.append(lag))

    class Ksp:
        def __init__(self, its, reason=2):
            self.its, self.reason = its, reason

        def getIterationNumber(self):
            return self.its

        def getConvergedReason(self):
            return self.reason

    s = S.Solver.__new__(S.Solver)
    s.snes, s.reuse, s.plan = None, {"base": None, "pending": True, "setups": 0}, S.SolverPlan()
    s.linear_solves = s.linear_its = 0
    solves = ((20, 2, False), (25, 2, False), (30, 2, False), (31, 2, True), (40, 2, False), (41, 2, False),
              (5, -3, True))
    for its, reason, rebuild in solves:
        asked.clear()
        s._after_linear_solve(Ksp(its, reason), None, None)
        assert (asked == [-2]) == rebuild, (its, reason, asked)
    assert s.reuse["setups"] == 2 and s.reuse["base"] == 40
    assert s.linear_solves == 7 and s.linear_its == 20 + 25 + 30 + 31 + 40 + 41 + 5

    # the mixed formulation's field split: the same rule on its displacement split's PC (PCSetReusePreconditioner:
    # kept after the first solve that follows a set-up, cleared for the next solve), never SNES's lag
    reused = []

    class SplitPc:
        def setReusePreconditioner(self, flag):
            reused.append(flag)

    class Split:
        def getPC(self):
            return SplitPc()

    class Pc:
        def getFieldSplitSubKSP(self):
            return [Split(), Split()]

    class SplitKsp(Ksp):
        def getPC(self):
            return Pc()

    from hyperelastic.formulations.mixed.solver import FieldSplitPlan
    s.plan, s.reuse = FieldSplitPlan(), {"base": None, "pending": True, "setups": 0}
    want = {20: [True], 31: [False], 40: [True], 5: [False]}
    for its, reason, _ in solves:
        asked.clear()
        reused.clear()
        s._after_linear_solve(SplitKsp(its, reason), None, None)
        assert asked == [] and reused == want.get(its, []), (its, reused)
    assert s.reuse["setups"] == 2 and s.reuse["pending"]


def test_advice_on_the_preconditioner(tmp_path):
    """The run's own Krylov iterations decide the closing note: a quasi-static run with CG + Jacobi
    (hundreds of iterations per Newton step) is pointed to GAMG, with -quiet too (it silences progress, not notes); a
    dynamic one (tens) and a GAMG run get no note."""
    from conftest import run_ok
    common = ["run", "bend", "-level", "1", "-output", tmp_path / "a.h5"]
    stiff = run_ok(common + ["-quasistatic", "-dt", "0.25", "-final_time", "0.5"]).stderr
    m = re.search(r"note: cg \+ Jacobi took (\d+) Krylov iterations per Newton step; above ~(\d+) ", stiff)
    assert m and int(m.group(1)) > int(m.group(2)), stiff
    for extra in (["-final_time", "0.02"], ["-quasistatic", "-dt", "0.25", "-final_time", "0.5", "-options_file",
                                           f"{ROOT}/options/gamg.opts"]):
        assert "note:" not in run_ok(common + extra).stderr, extra
    quiet = run_ok(common + ["-quasistatic", "-dt", "0.25", "-final_time", "0.5", "-quiet"]).stderr
    assert quiet.startswith("note: cg + Jacobi took ") and len(quiet.strip().splitlines()) == 1, quiet


def test_checkpoints_rebuild_the_preconditioner(tmp_path):
    """A checkpoint is where a restart begins: the preconditioner is set up again there in the
    uninterrupted run too (so that a restart repeats it)."""
    log = tmp_path / "r.log"
    from conftest import run_ok
    run_ok(["run", "bend", "-level", "1", "-final_time", "0.3", "-options_file", f"{ROOT}/options/gamg.opts",
            "-checkpoint_every", "10", "-quiet", "-output", tmp_path / "r.h5", "-log_view", f":{log}"])
    n = [int(ln.split()[1]) for ln in open(log) if ln.startswith("PCSetUp ")][0]
    assert n == 3           # the first step's, and after the checkpoints at steps 10 and 20 (30 is the end)


def test_constant_loads_summed_once_per_step(petsc):
    """Dead loads (gravity, a traction) do not depend on x: System.residual sums them once after each
    begin_step and copies them in. The residual still equals the sum of every effect's own residual,
    after the load factor changes too, and each of those effects counts an evaluation per residual."""
    m = make_model(petsc, "bend", [("gravity", "0,-9.81,0"), ("traction", "0,-500,0"), ("traction_time", "2*t")])
    sysm = m.system
    assert sorted(e.name for e in sysm.constant) == ["gravity", "traction"]
    rng = np.random.default_rng(3)
    X = sysm.global_state(m.x0 + 1e-3 * rng.standard_normal(m.x0.shape))
    out = []
    for t in (0.1, 0.3):
        sysm.begin_step(t, 0.01, m.x0, m.v0)
        evals = [e.evals for e in sysm.constant]
        R, ref = sysm.space.global_vec(), sysm.space.global_vec()
        sysm.residual(X, R)
        assert [e.evals for e in sysm.constant] == [n + 1 for n in evals]
        x = sysm.impose(sysm.local(X, sysm.xl).copy())
        sysm.finish(sysm.residual_local(x), X, ref)
        assert np.abs(R.getArray() - ref.getArray()).max() <= 1e-12 * np.abs(ref.getArray()).max()
        out.append(R.getArray().copy())
    assert np.abs(out[1] - out[0]).max() > 1e-6 * np.abs(out[0]).max()     # the traction grew


def test_set_up_pattern_and_maps_in_c_match_a_brute_force():
    """The set-up's C pieces (issue 74) against numpy written from their definitions, on random cells of 10 nodes
    over 60 vertices numbered globally by a random permutation: each row's neighbours (all, and the upper ones), the
    union of two patterns, the scalar pattern of 3 dofs a vertex, its upper blocks (the one-rank SBAIJ copy), and where
    each owned cell's blocks sit in it (a cell with a node not owned gets -1; a pattern with an entry removed is
    reported)."""
    from hyperelastic.discretization import kernels as K
    rng = np.random.default_rng(7)
    nlv, nc, nn = 60, 80, 10
    cells = np.array([rng.choice(nlv, nn, replace=False) for _ in range(nc)], np.int32)
    g = rng.permutation(nlv).astype(np.int64) + 1000
    rows = rng.permutation(nlv)[:45]
    for upper in (False, True):
        ptr, cols = K.adjacency(cells, g, rows, upper)
        for k, r in enumerate(rows):
            want = np.unique(g[cells[(cells == r).any(axis=1)]])
            want = want[want >= g[r]] if upper else want
            assert np.array_equal(cols[ptr[k]:ptr[k + 1]], want)
    a = (np.array([0, 2, 2, 5]), np.array([1, 4, 0, 3, 9]))
    b = (np.array([0, 1, 3, 4]), np.array([4, 2, 7, 3]))
    ic, jc = K.csr_union(a, b)
    assert np.array_equal(ic, [0, 2, 4, 7]) and np.array_equal(jc, [1, 4, 2, 7, 0, 3, 9])
    own = np.full(nlv, -1, np.int64)                        # owned: 50 of the vertices, numbered 0..49
    owned = rng.permutation(nlv)[:50]
    own[owned] = np.arange(50)
    vptr, vcols = K.adjacency(cells, own, owned)            # (the owned neighbours, by owned index: a diagonal block)
    keep = vcols >= 0
    vptr = np.concatenate([[0], np.cumsum([keep[vptr[v]:vptr[v + 1]].sum() for v in range(50)])])
    ia, ja = K.expand_pattern(vptr, vcols[keep], np.int32)
    for v in range(50):
        for a_ in range(3):
            assert np.array_equal(ja[ia[3 * v + a_]:ia[3 * v + a_ + 1]],
                                  (3 * vcols[keep][vptr[v]:vptr[v + 1]][:, None] + np.arange(3)).ravel())
    bptr, bcols, p0, L = K.upper_blocks(ia, ja)                # (the one-rank SBAIJ copy's blocks, w >= v)
    for v in range(50):
        row = vcols[keep][vptr[v]:vptr[v + 1]]
        want = [(w, ia[3 * v] + 3 * k) for k, w in enumerate(row) if w >= v]
        assert [(w, p) for w, p in zip(bcols[bptr[v]:bptr[v + 1]], p0[bptr[v]:bptr[v + 1]])] == want
        assert (L[bptr[v]:bptr[v + 1]] == ia[3 * v + 1] - ia[3 * v]).all()
    with pytest.raises(RuntimeError, match="whole 3x3 blocks"):
        K.upper_blocks(ia, np.where(np.arange(len(ja)) == 0, ja + 1, ja).astype(ja.dtype))
    base, rowlen, missing = K.cell_map(cells, own, ia, ja)
    assert missing == 0
    for e in range(nc):
        o = own[cells[e]]
        if (o < 0).any():
            assert (base[e] == -1).all()
            continue
        for a_, b_ in itertools.product(range(nn), repeat=2):
            for i, j in itertools.product(range(3), repeat=2):
                p = base[e, nn * a_ + b_] + i * rowlen[e, a_] + j
                assert ia[3 * o[a_] + i] <= p < ia[3 * o[a_] + i + 1] and ja[p] == 3 * o[b_] + j
    interior = np.flatnonzero((own[cells] >= 0).all(axis=1))
    assert len(interior)
    holed = ja.copy()
    e = interior[0]
    holed[base[e, 1]] = -5                                   # an entry of the first owned cell's block (0, 1)
    assert K.cell_map(cells, own, ia, holed)[2] == 1
    uptr, ucols = K.adjacency(cells, own, owned, upper=True)
    ucols = ucols.copy()
    pos, missing = K.upper_map(cells, own, uptr.astype(np.int32), ucols.astype(np.int32))
    assert missing == 0
    for e in interior:
        o = own[cells[e]]
        for a_, b_ in itertools.product(range(nn), repeat=2):
            p = pos[e, nn * a_ + b_]
            if o[a_] <= o[b_]:
                assert uptr[o[a_]] <= p < uptr[o[a_] + 1] and ucols[p] == o[b_]
            else:
                assert p == -1


def test_element_geometry_in_c_matches_numpy(petsc):
    """The P2 cells' geometry in C (kernels.element_geometry: J^-1 by cofactors, |det J| w) against
    element.reference.geometry (numpy's LU inverse and determinant) on a curved bar's cells."""
    from hyperelastic.discretization.kernels import element_geometry
    from hyperelastic.element.reference import TET_RULES, geometry, tet_shapes
    sp = make_model(petsc, options=[("level", "2"), ("order", "2")]).space
    X = sp.X + 0.05 * np.sin(sp.X[:, [1, 2, 0]])                # curved cells
    for deg in (2, 5):
        pts, w = TET_RULES[deg]
        dN = np.ascontiguousarray(tet_shapes(2, pts)[1])
        Jinv, wq, _ = geometry(X, sp.cells, dN, w)
        geo = element_geometry(X, sp.cells, dN, w)
        assert np.allclose(geo[..., :9], Jinv.reshape(len(sp.cells), -1, 9), rtol=0, atol=1e-13 * np.abs(Jinv).max())
        assert np.allclose(geo[..., 9], wq, rtol=1e-13, atol=0)
        assert np.array_equal(element_geometry(X, sp.cells, dN, w, full=False), geo[..., 9])
