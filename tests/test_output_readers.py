"""The output as real tools read it (issue 14): meshio's XDMF TimeSeriesReader, VTK's XDMF reader (what
ParaView uses), an off-screen pyvista render, and the application reading its own output as a mesh."""
import os
import subprocess
import sys

import numpy as np
import pytest

from conftest import hyperelastic, read_h5, run_ok

RUN = ["run", "bend", "-level", 1, "-final_time", 0.06, "-quiet"]


@pytest.fixture(scope="module")
def bend_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("readers") / "bend.h5"
    run_ok([*RUN, "-output", out])
    return out


def test_meshio_reads_every_frame_and_field(bend_out):
    import meshio
    r = read_h5(bend_out)
    with meshio.xdmf.TimeSeriesReader(str(bend_out.with_suffix(".xdmf"))) as reader:
        points, cells = reader.read_points_cells()
        assert np.array_equal(points, r["points"]) and np.array_equal(cells[0].data, r["tetra"])
        assert reader.num_steps == len(r["time"]) == 3
        for k in range(reader.num_steps):
            t, pd, cd = reader.read_data(k)
            assert t == r["time"][k]
            assert set(pd) == {"displacement", "velocity"}
            assert set(cd) == {"region", "J", "energy_density", "von_mises"}
            assert np.array_equal(pd["displacement"], r["x"][k] - r["points"])
            assert np.all(cd["region"][0] == 1)                     # the bar's Physical Volume("bar", 1)
            J = cd["J"][0]
            assert J.shape == (len(r["tetra"]),) and np.all(np.abs(J - 1) < 0.05)
    assert np.abs(pd["velocity"]).max() > 0 and np.nanmax(cd["von_mises"][0]) > 0
    assert np.all(cd["energy_density"][0] >= 0)


def test_cell_fields_match_the_material(bend_out):
    """J and the strain-energy density of the last frame recomputed from the positions."""
    from hyperelastic.physics.materials import get, lame
    from hyperelastic.mesh.sets import signed_volumes
    import h5py
    r = read_h5(bend_out)
    X, x, T = r["points"], r["x"][-1], r["tetra"]
    with h5py.File(bend_out) as f:
        J, psi = f["frames/2/J"][:], f["frames/2/energy_density"][:]
    assert np.allclose(J, signed_volumes(x, T) / signed_volumes(X, T), rtol=1e-12, atol=0)
    Dm = np.stack([X[T[:, i]] - X[T[:, 0]] for i in (1, 2, 3)], axis=-1)
    Ds = np.stack([x[T[:, i]] - x[T[:, 0]] for i in (1, 2, 3)], axis=-1)
    lam, mu = lame(1e6, 0.3)
    ref = get("stvk").psi(Ds @ np.linalg.inv(Dm), (mu, lam))        # (the energy of nearly unstrained cells is
    assert np.allclose(psi, ref, rtol=1e-10, atol=1e-12 * np.abs(ref).max())   # E = (F^T F - I)/2 cancelling)


VTK_SCRIPT = r"""
import sys, vtk
r = vtk.vtkXdmfReader()
r.SetFileName(sys.argv[1])
r.UpdateInformation()
times = r.GetOutputInformation(0).Get(vtk.vtkStreamingDemandDrivenPipeline.TIME_STEPS())
for t in times:
    r.UpdateTimeStep(t)
    o = r.GetOutputDataObject(0)
    pd, cd = o.GetPointData(), o.GetCellData()
    print(t, o.GetNumberOfPoints(), o.GetNumberOfCells(),
          ",".join(sorted(pd.GetArrayName(i) for i in range(pd.GetNumberOfArrays()))),
          ",".join(sorted(cd.GetArrayName(i) for i in range(cd.GetNumberOfArrays()))))
"""


def test_vtk_xdmf_reader_reads_every_frame_without_errors(bend_out):
    p = subprocess.run([sys.executable, "-c", VTK_SCRIPT, str(bend_out.with_suffix(".xdmf"))],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0 and "ERR" not in p.stderr and "rror" not in p.stderr, p.stderr
    r = read_h5(bend_out)
    rows = [line.split() for line in p.stdout.strip().splitlines()]
    assert [float(row[0]) for row in rows] == list(r["time"])
    for row in rows:
        assert row[1:] == [str(len(r["points"])), str(len(r["tetra"])), "displacement,velocity",
                           "J,energy_density,region,von_mises"]


RENDER_SCRIPT = r"""
import sys
import numpy as np
import pyvista as pv
pv.OFF_SCREEN = True
r = pv.get_reader(sys.argv[1])
r.set_active_time_point(r.number_time_points - 1)
m = r.read().warp_by_vector("displacement")
p = pv.Plotter(off_screen=True, window_size=(320, 240))
p.add_mesh(m, scalars="displacement", cmap="viridis")
img = p.screenshot(sys.argv[2], return_img=True)
print(len(np.unique(img.reshape(-1, img.shape[-1]), axis=0)))
"""


def test_offscreen_render_coloured_by_displacement(bend_out, tmp_path):
    png = tmp_path / "frame.png"
    p = subprocess.run([sys.executable, "-c", RENDER_SCRIPT, str(bend_out.with_suffix(".xdmf")), str(png)],
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr
    assert png.stat().st_size > 1000 and int(p.stdout.split()[-1]) > 50     # a coloured picture, not a blank


def test_own_output_as_mesh(bend_out, tmp_path):
    r = read_h5(bend_out)
    for src, frame, want in ((bend_out, None, -1), (bend_out.with_suffix(".xdmf"), None, -1), (bend_out, 1, 1)):
        out = tmp_path / "again.h5"
        extra = [] if frame is None else ["-mesh_frame", frame]
        run_ok(["run", "bend", "-mesh", src, *extra, "-traction_face", "left", "-final_time", 0.01, "-dt", 0.01,
                "-quiet", "-output", out])        # (the bent bar's end is no longer a box face; its clamped end is)
        again = read_h5(out)
        assert np.array_equal(again["points"], r["x"][want]) and np.array_equal(again["tetra"], r["tetra"])
        assert np.all(json_sets(again)["bar"]["count"] == len(r["tetra"]))
    p = hyperelastic(["run", "bend", "-mesh", bend_out, "-mesh_frame", 7, "-output", tmp_path / "n.h5"])
    assert p.returncode == 2 and "no frame 7" in p.stderr and len(p.stderr.strip().splitlines()) == 1


def json_sets(r):
    import json
    return {s["name"]: s for s in json.loads(r["attrs"]["sets"])}


def test_fields_same_on_two_ranks(bend_out, tmp_path):
    import h5py
    from hyperelastic.core.files import input_order
    out = tmp_path / "two.h5"
    run_ok([*RUN, "-output", out], nprocs=2)
    a, b = read_h5(bend_out, frames=True), read_h5(out, frames=True)      # (the input order: any layout)
    for name in ("displacement", "velocity", "J", "energy_density", "von_mises"):
        u, w = a["frames"][2][name], b["frames"][2][name]
        assert np.abs(u - w).max() <= 1e-8 * max(1.0, np.abs(u).max()), name
    with h5py.File(bend_out) as f, h5py.File(out) as g:
        assert np.array_equal(f["mesh/region"][:], g["mesh/region"][:][input_order(g)[1]])


def test_writes_end_together_on_two_ranks(tmp_path):
    """A frame or checkpoint write returns on every rank after rank 0's HDF5 writes (slowed down here), so
    that the wait is the output's and not the next residual's in -log_view (tests/mpi_output_check.py)."""
    from conftest import run_mpi_script
    p = run_mpi_script("mpi_output_check.py", [tmp_path / "o.h5"])
    assert p.returncode == 0 and p.stdout.split() == ["ok"], p.stdout + p.stderr


def test_a_write_that_fails_on_rank_0_ends_every_rank(tmp_path):
    """An error in rank 0's HDF5 writes of a frame (the per-rank layout's metadata) is raised on every rank: the job
    ends with an error status and the error's line, where the other rank waited for ever in the frame's end
    (tests/mpi_output_check.py fail; the run before the fix hung to this test's timeout)."""
    from conftest import run_mpi_script
    p = run_mpi_script("mpi_output_check.py", [tmp_path / "o.h5", "fail"], timeout=120)
    assert p.returncode != 0 and "a write of rank 0 failed" in p.stderr, p.stdout + p.stderr
