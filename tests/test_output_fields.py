"""Stress, principal stresses, strain and node-averaged fields on request (-output_fields, issue 34): exact on a
homogeneous state and against the run's own reaction force, read by meshio and VTK's XDMF reader, the same on
1 and 2 ranks and on quadratic cells."""
import json
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, run_ok

ALL = "default,stress,principal_stress,strain,stress_nodal,von_mises_nodal,strain_nodal"


@pytest.fixture(scope="module")
def cube(tmp_path_factory):
    path = tmp_path_factory.mktemp("cube") / "cube.msh"
    run_ok(["mesh", f"{ROOT}/examples/cube.geo", "--size", 0.35, "-o", path])
    return path


def uniaxial(cube, out, *extra, nprocs=1):
    """The cube on rollers (xmin:x, ymin:y, zmin:z) stretched by 10% in z (its top held in z only): a
    homogeneous uniaxial state, every lateral face free."""
    scene = out.parent / "plain.opts"
    scene.write_text("-final_time 1\n")
    run_ok(["run", scene, "-mesh", cube, "-quiet", "-output", out, "-fix", "xmin:x,ymin:y,zmin:z",
            "-prescribe_faces", "zmax:z", "-prescribe_uz", "0.1*min(t, 1)*Z", "-material", "stvk", "-quasistatic",
            "-dt", 0.5, "-final_time", 1, "-effects", "elasticity", "-snes_rtol", 1e-14, "-snes_atol", 1e-13,
            "-ksp_rtol", 1e-14, "-output_fields", ALL, *extra], nprocs=nprocs)
    f = h5py.File(out, "r")
    last = f["frames"][str(len(f["time"]) - 1)]
    return f, last


def test_uniaxial_stress_strain_exact_and_balanced_by_the_reaction(cube, tmp_path):
    f, g = uniaxial(cube, tmp_path / "u.h5")
    with f:
        X, x = f["mesh/points"][:], f["x"][-1]
        lam = np.ptp(x, axis=0) / np.ptp(X, axis=0)                    # the stretches
        assert abs(lam[2] - 1.1) < 1e-12 and abs(lam[0] - lam[1]) < 1e-12 and lam[0] < 1
        E = g["strain"][:]
        want = [(lam[0] ** 2 - 1) / 2, 0, 0, (lam[1] ** 2 - 1) / 2, 0, (lam[2] ** 2 - 1) / 2]
        assert np.abs(E - want).max() < 1e-12
        s = g["stress"][:]
        szz = s[:, 5]
        assert np.ptp(szz) < 1e-9 * szz.max() and szz.max() > 0
        assert np.abs(s[:, :5]).max() < 1e-9 * szz.max()             # lateral faces free: uniaxial
        # sigma_zz times the current area is the force the top face carries: the run's reaction there
        forces = json.loads(f.attrs["forces"])["forces"]
        Fz = [r["F"][2] for r in forces if r["kind"] == "reaction" and r["name"] == "zmax"][0]
        area = np.ptp(x[:, 0]) * np.ptp(x[:, 1])
        assert abs(szz.mean() * area / abs(Fz) - 1) < 1e-9, (szz.mean() * area, Fz)
        ps = g["principal_stress"][:]
        assert np.abs(ps - [szz.mean(), 0, 0]).max() < 1e-9 * szz.max()
    # plot names principal values 1, 2, 3 (largest first; the largest by default: their magnitude would mean nothing)
    for spec, want in (("", szz.mean()), (":1", szz.mean()), (":3", 0.0)):
        p = run_ok(["plot", tmp_path / "u.h5", "--field", f"principal_stress{spec}", "-o", tmp_path / "p.png"])
        lo, hi = (float(v.rstrip(",")) for v in p.stdout.split(" from ")[1].split(",")[0].split(" to "))
        assert f"field principal_stress:{spec[1:] or '1'} " in p.stdout, p.stdout
        assert abs(hi - want) <= 1e-5 * szz.max(), p.stdout                  # (the line prints 6 digits)
    q = hyperelastic(["plot", tmp_path / "u.h5", "--field", "principal_stress:x", "-o", tmp_path / "q.png"])
    assert q.returncode == 2 and "are 1, 2, 3" in q.stderr
    with h5py.File(tmp_path / "u.h5", "r") as f:
        g = f["frames"][str(len(f["time"]) - 1)]
        assert np.abs(g["von_mises"][:] - szz).max() < 1e-9 * szz.max()
        nodal = g["stress_nodal"][:]
        assert nodal.shape == (len(X), 6) and np.abs(nodal - s[0]).max() < 1e-9 * szz.max()
        assert np.abs(g["von_mises_nodal"][:] - szz.mean()).max() < 1e-9 * szz.max()


VTK_ARRAYS = r"""
import sys, vtk
r = vtk.vtkXdmfReader()
r.SetFileName(sys.argv[1])
r.UpdateInformation()
times = r.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
r.UpdateTimeStep(times[-1])
o = r.GetOutputDataObject(0)
for kind, d in (("point", o.GetPointData()), ("cell", o.GetCellData())):
    for i in range(d.GetNumberOfArrays()):
        a = d.GetArray(i)
        print(kind, a.GetName(), a.GetNumberOfTuples(), a.GetNumberOfComponents())
"""


def test_readers_see_the_tensors(cube, tmp_path):
    """meshio and VTK's XDMF reader (ParaView's) read every requested field with its centre and components."""
    import meshio
    out = tmp_path / "r.h5"
    f, g = uniaxial(cube, out)
    with f:
        nv, nc = f["mesh/points"].shape[0], f["mesh/tetra"].shape[0]
        stress = g["stress"][:]
    with meshio.xdmf.TimeSeriesReader(str(out.with_suffix(".xdmf"))) as reader:
        reader.read_points_cells()
        _, pd, cd = reader.read_data(reader.num_steps - 1)
    assert {k: v.shape for k, v in pd.items()} == {"displacement": (nv, 3), "velocity": (nv, 3),
                                                   "stress_nodal": (nv, 6), "strain_nodal": (nv, 6),
                                                   "von_mises_nodal": (nv,)}
    assert cd["stress"][0].shape == (nc, 6) and cd["principal_stress"][0].shape == (nc, 3)
    assert np.array_equal(cd["stress"][0], stress)
    p = subprocess.run([sys.executable, "-c", VTK_ARRAYS, str(out.with_suffix(".xdmf"))], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0 and "rror" not in p.stderr, p.stderr
    arrays = {tuple(line.split()[:2]): tuple(map(int, line.split()[2:])) for line in p.stdout.splitlines()}
    # (VTK expands XDMF's Tensor6 to the full symmetric tensor: 9 components, as ParaView shows it)
    assert arrays[("cell", "stress")] == (nc, 9) and arrays[("cell", "principal_stress")] == (nc, 3)
    assert arrays[("cell", "strain")] == (nc, 9) and arrays[("point", "stress_nodal")] == (nv, 9)
    assert arrays[("point", "von_mises_nodal")] == (nv, 1)


def test_quadratic_and_two_ranks(cube, tmp_path):
    """On quadratic cells (the bottom clamped, so the stress varies) 2 ranks write the 1-rank fields, nodal
    averages included (formed on rank 0 in the input numbering on one rank; on two by each rank on its own cells,
    the shared nodes' sums added over the ranks)."""
    from conftest import read_h5
    args = ("-order", 2, "-fix", "zmin")
    fa, _ = uniaxial(cube, tmp_path / "a.h5", *args)
    fb, _ = uniaxial(cube, tmp_path / "b.h5", *args, nprocs=2)
    fa.close(), fb.close()
    a, b = (read_h5(tmp_path / n, frames=True)["frames"][-1] for n in ("a.h5", "b.h5"))
    assert a["stress"].shape[0] == len(read_h5(tmp_path / "a.h5")["tetra"])
    assert np.ptp(a["stress"][:, 5]) > 0.01 * np.abs(a["stress"][:, 5]).max()      # not homogeneous
    for name in ("stress", "principal_stress", "strain", "stress_nodal", "von_mises_nodal", "strain_nodal"):
        u, w = a[name], b[name]
        assert np.abs(u - w).max() <= 1e-8 * np.abs(u).max(), name


def test_default_output_unchanged_and_bad_names_refused(cube, tmp_path):
    out = tmp_path / "d.h5"
    scene = tmp_path / "plain.opts"
    scene.write_text("-final_time 0.02\n")
    run_ok(["run", scene, "-mesh", cube, "-quiet", "-output", out, "-fix", "zmin"])
    with h5py.File(out) as f:
        assert sorted(f["frames/1"]) == ["J", "displacement", "energy_density", "velocity", "von_mises"]
    p = hyperelastic(["run", scene, "-mesh", cube, "-output", tmp_path / "e.h5", "-output_fields", "stres"])
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "-output_fields: unknown field 'stres'" in lines[0]
    assert not (tmp_path / "e.h5").exists()


def test_report_prints_the_run_forces_and_material_points(cube, tmp_path):
    """`hyperelastic report`: the run's line, the forces table the run printed, the displacement and the cell
    fields at a material point (interpolated: exact for this affine state), the watch quantities; bad
    input one line; it writes nothing."""
    out = tmp_path / "u.h5"
    f, g = uniaxial(cube, out)
    with f:
        forces = json.loads(f.attrs["forces"])
        szz = g["stress"][0, 5]
        X, x = f["mesh/points"][:], f["x"][-1]
        lam = np.ptp(x, axis=0) / np.ptp(X, axis=0)
    before = sorted(p.name for p in tmp_path.iterdir())
    p = run_ok(["report", out, "--at", "0.5,0.5,1", "--watch", "u_z:0.5,0.5,1", "--watch", "reaction_z:zmax"])
    lines = p.stdout.splitlines()
    assert lines[0].startswith(f"{out}: scene plain") and "finished" in lines[0] and "3 frames to t = 1" in lines[0]
    assert lines[1].startswith("forces at t = 1") and any(ln.startswith("  reaction zmax (holds ") for ln in lines)
    at = [ln for ln in lines if ln.startswith("at (0.5, 0.5, 1), frame 2 (t = 1): u = (")][0]
    u = [float(v) for v in at.split("u = (")[1].split(")")[0].split(",")]
    assert np.allclose(u, [(lam[0] - 1) * 0.5, (lam[1] - 1) * 0.5, 0.1], rtol=1e-5, atol=1e-9), (u, lam)
    assert "stress (" in at and f"{szz:.6g})" in at, at
    Fz = [r["F"][2] for r in forces["forces"] if r["name"] == "zmax"][0]
    assert float(lines[-2].split(" = ")[1]) == pytest.approx(0.1, rel=1e-12)
    assert float(lines[-1].split(" = ")[1]) == pytest.approx(Fz, rel=1e-12)
    for args, words in ((["report", tmp_path / "none.h5"], "does not exist"),
                        (["report", out, "--at", "3,0,0"], "lies outside the mesh"),
                        (["report", out, "--at", "1,2"], "three finite coordinates"),
                        (["report", out, "--at", "0,0,0", "--frame", 7], "out of range (0..2)"),
                        (["report", out, "--watch", "u_w:0,0,0"], "unknown quantity")):
        q = hyperelastic(args)
        assert q.returncode == 2 and len(q.stderr.strip().splitlines()) == 1 and words in q.stderr, q.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == before
