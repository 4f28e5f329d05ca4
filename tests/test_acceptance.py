"""What a converged solve must also be before its state is accepted (issue 47: a quasi-static step of a rubber at
kappa/mu = 1e4 was accepted at J_min 0.107, J_max 2.05 and every later step failed): no cell inverted in a material
undefined there, and volume ratios a solid of its compressibility keeps (integrators.volume_refusal,
formulations.mixed.volume_bound)."""
from types import SimpleNamespace

import numpy as np

from conftest import hyperelastic, read_h5


def test_volume_refusal_follows_the_compressibility(petsc):
    from petsc4py import PETSc
    from hyperelastic.solving.integrators import volume_refusal
    rubber = SimpleNamespace(material_domain=True, volume_bound=(max(0.5, 1000 / 1e4), 1e4))
    soft = SimpleNamespace(material_domain=True, volume_bound=(1000 / 2.17, 2.17))
    stvk = SimpleNamespace(material_domain=False, volume_bound=(0.5, 1e4))
    assert volume_refusal({"J_min": 0.99, "J_max": 1.011}, rubber) == ""          # the rod's coarse P2 mesh
    assert "false convergence" in volume_refusal({"J_min": 0.107, "J_max": 2.05}, rubber)   # the step
    assert volume_refusal({"J_min": 0.107, "J_max": 2.05}, soft) == ""           # nu = 0.3 may be squeezed so
    assert "inverted" in volume_refusal({"J_min": -0.5, "J_max": 1.2}, soft)
    assert volume_refusal({"J_min": -0.5, "J_max": 1.2}, stvk) == ""             # defined when inverted
    assert volume_refusal({}, rubber) == ""                                        # no elasticity, no J
    # a solve whose residual met -snes_rtol/-snes_atol is a solution of the discrete problem: a mixed squeeze's P2-P1
    # corners (J 0.17 to 3.1 at nu = 0.4999, where the exact pressure is singular) are not refused; CONVERGED_ITS
    # (ksponly) and SNORM_RELATIVE (a small update) do not certify the residual and are
    R = PETSc.SNES.ConvergedReason
    corner = {"J_min": 0.17, "J_max": 3.07}
    assert [volume_refusal(dict(corner, snes_reason=r), rubber) == "" for r in
            (R.CONVERGED_FNORM_ABS, R.CONVERGED_FNORM_RELATIVE, R.CONVERGED_ITS, R.CONVERGED_SNORM_RELATIVE)] == \
        [True, True, False, False]
    assert "inverted" in volume_refusal({"J_min": -0.5, "J_max": 1.2, "snes_reason": R.CONVERGED_FNORM_RELATIVE}, soft)


def test_a_false_convergence_is_not_accepted(tmp_path):
    """One linear solve per step (-snes_type ksponly: SNES reports convergence after it) of a nearly incompressible
    bar whose end is turned 86 degrees: the steps whose linearized rotation inverts cells or changes their volume
    by far more than kappa/mu = 5000 allows are refused and halved, every accepted state keeps |ln J| <= 0.5, and the
    run ends with the one line that says why rather than writing such states."""
    out = tmp_path / "ks.h5"
    p = hyperelastic(["run", "bend", "-effects", "elasticity,fixed,prescribed", "-fix", "left", "-prescribe_faces",
                      "right", "-prescribe_motion", "rotate_x", "-prescribe_amount", 1.5, "-material", "neohookean",
                      "-nu", 0.4999, "-quasistatic", "-snes_type", "ksponly", "-dt", 1, "-final_time", 1,
                      "-output", out, "-quiet"])
    st = read_h5(out)["stats"]
    ok = st["rejected"] == 0
    assert ok.any() and (st["J_min"][ok] > 0).all()
    assert (np.maximum(-np.log(st["J_min"][ok]), np.log(st["J_max"][ok])) <= 0.5).all()
    bad = ~ok & (st["snes_reason"] > 0)
    assert bad.any() and ((st["J_min"][bad] <= 0) | (np.maximum(-np.log(np.abs(st["J_min"][bad])),
                                                               np.log(st["J_max"][bad])) > 0.5)).all()
    lines = [ln for ln in p.stderr.strip().splitlines() if not ln.startswith("note: ")]    # (-quiet keeps notes)
    assert p.returncode != 0 and len(lines) == 1 and "not a solution" in lines[0], p.stderr


class FakeSNES:
    def __init__(self):
        self.reason = 0

    def getConvergedReason(self):
        return self.reason

    def setConvergedReason(self, reason):
        self.reason = reason


def stops_at(history, k=3):
    """The Newton iteration at which Solver._watch_divergence ends a solve with these residual norms (None: never)."""
    from hyperelastic.solving.solver import Solver
    watcher, snes = SimpleNamespace(diverging=k, DIVERGING_FACTOR=Solver.DIVERGING_FACTOR), FakeSNES()
    for its, fnorm in enumerate(history):
        Solver._watch_divergence(watcher, snes, its, fnorm)
        if snes.reason:
            assert watcher.diverged_early
            return its
    return None


def test_diverging_full_newton_steps_stop_early():
    """Residual norms of full Newton steps measured on the rubber bracket (744 P2 tets, mixed, nu = 0.4995, load steps
    of 1/4 to 1/16 of the full load, 2026-11-26): the attempts that converged after rising 130x are not stopped; the
    ones that failed (a Krylov solve at iteration 6 or 8, each costing ~1,000 GMRES iterations) are stopped at their
    third iteration above 10x their best. Full load: 25.5 -> 17.0 s, 10,784 -> 7,731 GMRES iterations, the same
    rejections and answer (4e-12)."""
    kept = [[1.299, 170.07, 39.857, 1.0439, 1.5077, 1.0397e-2, 4.8974e-4, 4.2e-6, 1.6e-10],
            [0.6495, 25.993, 0.93448, 0.25043, 2.2065e-3, 1.3966e-6, 6.978e-10],
            [68.91, 107.94, 63.364, 25.695, 157.4]]      # (the rod's 45-degree step: its Krylov solve fails first)
    failed = [[2.5981, 403.26, 247.48, 149.54, 60.997, 217.46, 1198.4],
              [1.299, 92.473, 12.295, 183.27, 56.084, 21.615, 73.176, 19.294, 648.9]]
    assert [stops_at(h) for h in kept] == [None, None, None]
    assert [stops_at(h) for h in failed] == [3, 5]


def test_an_indefinite_tangent_switches_on_the_projection(tmp_path):
    """The README's rod twisted 45 degrees in one quasi-static step with -formulation displacement (P2, kappa/mu =
    100): CG stops at negative curvature in every Newton iteration of the attempt, which fails; the step is retried
    with -hessian_projection (said in a note and recorded) and converges to the state a run projected from the start
    reaches. With -hessian_projection given (here 0) nothing is switched: step control halves instead. (CG + Jacobi:
    with the static P2 default, p-multigrid, CG takes this step without stopping at negative curvature.)"""
    import os
    from conftest import ROOT, run_ok
    mesh = tmp_path / "rod.msh"
    run_ok(["mesh", os.path.join(ROOT, "examples", "rod.geo"), "--size", 0.005, "--order", 2, "-o", mesh])
    base = ["run", os.path.join(ROOT, "examples", "torsion.opts"), "-mesh", mesh, "-formulation", "displacement",
            "-kappa", 5e7, "-dt", 0.5, "-final_time", 0.5, "-snes_max_it", 30, "-pc_type", "jacobi"]
    auto, proj, off = (tmp_path / f"{n}.h5" for n in ("auto", "proj", "off"))
    p = run_ok(base + ["-output", auto])
    assert "retrying it with the cells' tangents projected" in p.stderr
    a = read_h5(auto)
    assert list(a["stats"]["rejected"]) == [1, 0] and a["stats"]["dt"][-1] == 0.5
    assert "retrying it with the cells' tangents projected" in a["attrs"]["notes"]
    run_ok(base + ["-output", proj, "-hessian_projection", 1, "-quiet"])
    b = read_h5(proj)
    assert np.abs(a["x"][-1] - b["x"][-1]).max() < 1e-7 * 0.01
    q = run_ok(base + ["-output", off, "-hessian_projection", 0])
    assert "projected" not in q.stderr and read_h5(off)["stats"]["dt"][-1] < 0.5


def test_peak_memory_is_the_runs_own_not_its_parents(tmp_path):
    """The output's peak_rss_mb is the run's own high-water mark (VmHWM), not getrusage's ru_maxrss, which Linux
    keeps across fork and exec: started from a process holding 600 MB, a small run read ~650 MB before. Checked
    against GNU time's figure for the same command where the machine has /usr/bin/time (its own fork is small)."""
    import shutil
    import subprocess
    import sys
    import h5py
    big = np.ones(600 * 2 ** 20 // 8)                       # 600 MB, touched: resident in this process
    out = tmp_path / "m.h5"
    cmd = [sys.executable, "-m", "hyperelastic", "run", "bend", "-level", "1", "-final_time", "0", "-quiet",
           "-output", str(out)]
    p = subprocess.run(cmd, capture_output=True, text=True)
    assert p.returncode == 0, p.stderr
    with h5py.File(out) as f:
        mb = float(f.attrs["peak_rss_mb"])
    assert 20 < mb < 400, mb
    timer = shutil.which("time", path="/usr/bin")
    if timer:
        p = subprocess.run([timer, "-f", "maxrss %M"] + cmd, capture_output=True, text=True)
        assert p.returncode == 0, p.stderr
        kib = float(p.stderr.split("maxrss")[-1].split()[0])
        assert abs(mb - kib / 1024) < 0.15 * mb, (mb, kib / 1024)
    assert big[-1] == 1.0
