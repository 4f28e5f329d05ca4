"""Every bad input ends in exactly one error line and a non-zero exit, never a traceback, and
never touches an existing output file."""
import os

import numpy as np
import pytest

from bad_input_suite import cube
from conftest import hyperelastic, read_h5, run_ok


def one_line_error(p, *words):
    assert p.returncode != 0, p.stdout + p.stderr
    lines = [l for l in p.stderr.splitlines() if l.strip()]
    assert len(lines) == 1, p.stderr
    assert "Traceback" not in p.stderr
    for w in words:
        assert w in lines[0], (w, lines[0])
    return lines[0]


def write_msh(path, points, tets):
    import meshio
    meshio.write(path, meshio.Mesh(np.asarray(points, float), [("tetra", np.asarray(tets))]), file_format="gmsh22",
                 binary=False)


def bad_meshes(tmp):
    P, T = cube(3)
    cases = {}
    def add(name, pts, tets, *words):
        path = os.path.join(tmp, f"{name}.msh")
        write_msh(path, pts, tets)
        cases[name] = (path, words)
    p = P.copy(); p[5, 1] = np.nan
    add("nan", p, T, "vertex 5", "non-finite")
    p = P.copy(); p[9, 2] = np.inf
    add("inf", p, T, "vertex 9", "non-finite")
    p = np.vstack([P, [[9, 9, 9]]])
    add("unused", p, T, "not used")
    p = P.copy(); p[7] = p[6]
    add("duplicate", p, T, "duplicates")
    t = T.copy(); t[4] = t[4][[0, 2, 1, 3]]
    add("inverted", P, t, "tetrahedron 4", "inverted")
    p = P.copy()
    t = T.copy(); t[2] = [0, 1, 2, 3]
    add("flat", p, t, "tetrahedron 2", "zero volume")
    path = os.path.join(tmp, "garbage.msh")
    with open(path, "wb") as fh:
        fh.write(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n\x00\xff garbage")
    cases["garbage"] = (path, ("cannot be read",))
    import meshio
    path = os.path.join(tmp, "triangles.vtu")
    meshio.write(path, meshio.Mesh(P, [("triangle", np.array([[0, 1, 2]]))]))
    cases["triangles"] = (path, ("no tetrahedra", "triangle"))
    path = os.path.join(tmp, "missing.msh")
    cases["missing"] = (path, ("no such file",))
    t = T.copy(); t[3, 2] = len(P) + 5
    path = os.path.join(tmp, "range.vtu")
    meshio.write(path, meshio.Mesh(P, [("tetra", t)]))
    cases["range"] = (path, ("tetrahedron 3", "out of range"))
    path = os.path.join(tmp, "empty.vtu")
    meshio.write(path, meshio.Mesh(P, [("tetra", np.zeros((0, 4), int))]))
    cases["empty"] = (path, ("cannot be read",))     # meshio cannot read its own empty .vtu
    good = os.path.join(tmp, "good.msh")
    write_msh(good, P, T)
    text = open(good, "rb").read()
    path = os.path.join(tmp, "truncated.msh")
    with open(path, "wb") as fh:
        fh.write(text[: len(text) // 2])
    cases["truncated"] = (path, ("cannot be read",))
    path = os.path.join(tmp, "garbage.vtu")
    with open(path, "wb") as fh:
        fh.write(b'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid"><Piece NumberOfPoints="4"')
    cases["garbage_vtu"] = (path, ("cannot be read",))
    return cases


def test_bad_meshes(tmp_path):
    out = tmp_path / "keep.h5"
    run_ok(["run", "bend", "-final_time", "0.01", "-quiet", "-output", out])     # an earlier result
    precious = out.read_bytes()
    import time
    for name, (path, words) in bad_meshes(str(tmp_path)).items():
        t0 = time.time()
        p = hyperelastic(["run", "bend", "-mesh", path, "-output", out, "-quiet"], timeout=20)
        assert time.time() - t0 < 20, name
        line = one_line_error(p, *words)
        assert path in line, line
        assert p.returncode == 2
    assert out.read_bytes() == precious


def test_good_custom_mesh_runs(tmp_path):
    """A mesh from another source (meshio-written .vtu) runs; end faces are found from its bbox."""
    import meshio
    P, T = cube(3)
    path = str(tmp_path / "cube.vtu")
    meshio.write(path, meshio.Mesh(P * [10, 4, 4] - [5, 2, 2], [("tetra", T)]))
    p = hyperelastic(["run", "bend", "-mesh", path, "-final_time", "0.02", "-quiet", "-output", tmp_path / "c.h5"])
    assert p.returncode == 0, p.stderr


OPTION_CASES = [
    (["-E", "-5"], ["Young", "-E"]),
    (["-E", "abc"], ["-E", "not a number"]),
    (["-nu", "0.5"], ["Poisson", "-nu"]),
    (["-nu", "-1"], ["Poisson"]),
    (["-rho", "0"], ["density"]),
    (["-dt", "0"], ["-dt"]),
    (["-dt", "-1"], ["-dt"]),
    (["-final_time", "-1"], ["-final_time"]),
    (["-material", "jelly"], ["unknown material", "jelly"]),
    (["-jacobian", "magic"], ["-jacobian", "magic"]),
    (["-mass", "heavy"], ["-mass"]),
    (["-preset", "unobtainium"], ["preset"]),
    (["-gravity", "0,1"], ["-gravity"]),
    (["-level", "0"], ["-level"]),
    (["-fix", "middle"], ["-fix", "no surface 'middle'", "box faces: left"]),
    (["-fix", "left:w"], ["-fix", "components"]),
    (["-fix", "left:xx"], ["-fix", "components"]),
    (["-fix", ":x"], ["-fix", "names no surface"]),
    (["-traction_face", "right:y"], ["-traction_face", "components"]),
    (["-traction_face", "7"], ["-traction_face", "no surface '7'", "physical surfaces: none"]),
    (["-ksp_type", "nonsense"], ["PETSc", "KSP type nonsense"]),
    (["-snes_rtol", "abc"], ["-snes_rtol", "abc", "not a number"]),
    (["-checkpoint_every", "-1"], ["-checkpoint_every"]),
    (["-checkpoint_every", "x"], ["-checkpoint_every", "not an integer"]),
    (["-dt_min", "1"], ["-dt_min", "-dt"]),
    (["-step_control", "maybe"], ["-step_control", "not a boolean"]),
    (["-initial_spin", "1,2"], ["-initial_spin"]),
    (["-material", "snh", "-nu", "0.5"], ["Poisson"]),
]


@pytest.mark.parametrize("args,words", OPTION_CASES)
def test_bad_options(tmp_path, args, words):
    p = hyperelastic(["run", "bend", "-quiet", "-output", tmp_path / "o.h5", *args], timeout=20)
    one_line_error(p, *words)
    assert p.returncode == 2
    assert not (tmp_path / "o.h5").exists()


def test_unknown_scene_and_bad_scene_files(tmp_path):
    one_line_error(hyperelastic(["run", "nosuchscene"]), "unknown scene", "nosuchscene")
    f = tmp_path / "s.opts"
    f.write_text("-effects elasticity,inertia,telekinesis\n")
    one_line_error(hyperelastic(["run", str(f), "-output", tmp_path / "o.h5"]), "unknown effect", "telekinesis")
    f.write_text("-effects elasticity,gravity\n")
    one_line_error(hyperelastic(["run", str(f), "-output", tmp_path / "o.h5"]), "gravity", "needs")
    f.write_text("effects elasticity\n")
    one_line_error(hyperelastic(["run", str(f), "-output", tmp_path / "o.h5"]), "line 1")


def test_bad_output_paths(tmp_path):
    one_line_error(hyperelastic(["run", "bend", "-output", tmp_path]), "is a directory")
    f = tmp_path / "file"
    f.write_text("x")
    one_line_error(hyperelastic(["run", "bend", "-output", f / "o.h5"]), "cannot create directory")
    assert f.read_text() == "x"
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if os.access(ro, os.W_OK):
            pytest.skip("running as a user that can write anywhere")
        one_line_error(hyperelastic(["run", "bend", "-output", ro / "o.h5"]), "not writable")
    finally:
        ro.chmod(0o700)


def test_bad_input_under_mpi(tmp_path):
    """Both ranks exit with one line from rank 0, no deadlock."""
    p = hyperelastic(["run", "bend", "-mesh", tmp_path / "missing.msh", "-quiet"], nprocs=2, timeout=60)
    one_line_error(p, "no such file")
    p = hyperelastic(["run", "bend", "-E", "-1", "-quiet"], nprocs=2, timeout=60)
    one_line_error(p, "Young")
    cases = bad_meshes(str(tmp_path))
    for name in ("garbage_vtu", "inverted", "range"):
        path, words = cases[name]
        one_line_error(hyperelastic(["run", "bend", "-mesh", path, "-quiet"], nprocs=2, timeout=60), *words)
    for args, words in (OPTION_CASES[1], OPTION_CASES[8], OPTION_CASES[-3]):
        one_line_error(hyperelastic(["run", "bend", "-quiet", *args], nprocs=2, timeout=60), *words)
    one_line_error(hyperelastic(["run", "--restart", tmp_path / "missing.h5"], nprocs=2, timeout=60), "--restart")


def test_mesh_command(tmp_path):
    out = tmp_path / "m.msh"
    p = hyperelastic(["mesh", "bar", "--level", "1", "-o", out])
    assert p.returncode == 0, p.stderr
    assert "vertices" in p.stdout and "tets" in p.stdout and "min edge" in p.stdout
    one_line_error(hyperelastic(["mesh", "nothing", "--level", "1", "-o", out]), "unknown mesh geometry")
    one_line_error(hyperelastic(["mesh", "bar", "--level", "0", "-o", out]), "level")


def test_mesh_without_a_volume_leaves_nothing_and_help_writes_nothing(tmp_path):
    """A 2-D geometry: one line, exit 2, no .msh (issue 34); `run SCENE -help` on a scene without a mesh
    prints the options and creates no output directory."""
    (tmp_path / "flat.geo").write_text('SetFactory("OpenCASCADE");\nRectangle(1) = {0, 0, 0, 1, 1};\n')
    one_line_error(hyperelastic(["mesh", "flat.geo", "--size", "0.3", "-o", "flat.msh"], cwd=tmp_path),
                   "no tetrahedra")
    (tmp_path / "s.opts").write_text("-material neohookean\n-quasistatic\n")
    p = hyperelastic(["run", "s.opts", "-help"], cwd=tmp_path)
    assert p.returncode == 0 and "-material" in p.stdout, p.stderr
    # a scene naming surfaces of a mesh it does not name: the help still, and why PETSc's part is missing
    (tmp_path / "t.opts").write_text("-fix clamp\n-loads L\n-L_faces top\n-L_traction 0,0,-1\n")
    p = hyperelastic(["run", "t.opts", "-help"], cwd=tmp_path)
    assert p.returncode == 0 and "-material" in p.stdout and "no surface 'clamp'" in p.stdout, p.stderr
    (tmp_path / "t.opts").unlink()
    assert sorted(os.listdir(tmp_path)) == ["flat.geo", "s.opts"]


def options_files(d):
    """{case: (path given to -options_file, words of the error)}: files PETSc would choke on."""
    os.makedirs(d, exist_ok=True)
    j = lambda n: os.path.join(d, n)  # noqa: E731
    with open(j("self.opts"), "w") as fh:
        fh.write(f"-dt 0.01\n-options_file {j('self.opts')}\n")
    with open(j("a.opts"), "w") as fh:
        fh.write(f"-options_file {j('b.opts')}\n")
    with open(j("b.opts"), "w") as fh:
        fh.write(f"# b includes a\n-options_file {j('a.opts')}\n")
    with open(j("utf16.opts"), "wb") as fh:
        fh.write("-dt 0.01\n".encode("utf-16"))
    os.mkfifo(j("fifo.opts"))
    return {"missing": (j("missing.opts"), ("does not exist",)), "self": (j("self.opts"), ("includes itself",)),
            "mutual": (j("a.opts"), ("a.opts -> b.opts -> a.opts",)), "directory": (d, ("not a regular file",)),
            "fifo": (j("fifo.opts"), ("not a regular file",)), "utf16": (j("utf16.opts"), ("not UTF-8",))}


@pytest.mark.parametrize("case", ["missing", "self", "mutual", "directory", "fifo", "utf16"])
def test_bad_options_file(tmp_path, case):
    """-options_file that is missing, includes itself (directly or through another), is a directory, a
    FIFO or not UTF-8: one line, exit 2, within 20 s (no traceback, hang or SIGSEGV), files untouched."""
    cases = options_files(str(tmp_path / "o"))
    path, words = cases[case]
    before = {f: open(f, "rb").read() for f in (str(tmp_path / "o" / n) for n in ("self.opts", "a.opts", "b.opts"))}
    p = hyperelastic(["run", "bend", "-options_file", path, "-quiet", "-output", tmp_path / "o.h5"], timeout=20)
    assert p.returncode == 2
    one_line_error(p, *words)
    assert {f: open(f, "rb").read() for f in before} == before
    assert not (tmp_path / "o.h5").exists()


def test_bad_options_file_under_mpi(tmp_path):
    path, words = options_files(str(tmp_path / "o"))["mutual"]
    p = hyperelastic(["run", "bend", "-options_file", path, "-quiet"], nprocs=2, timeout=60)
    assert p.returncode == 2
    one_line_error(p, *words)


def _digest(*paths):
    import hashlib
    return [hashlib.sha256(open(p, "rb").read()).hexdigest() for p in paths]


def test_failed_run_keeps_the_previous_result(tmp_path):
    """A run (or a restart) that fails before completing a step leaves the earlier FILE.h5 and its XDMF
    byte-identical and no partial file; a successful one replaces them (issue 15: no result lost)."""
    out, xdmf = tmp_path / "out.h5", tmp_path / "out.xdmf"
    base = ["run", "bend", "-final_time", 0.05, "-checkpoint_every", 2, "-quiet", "-output", out]
    assert hyperelastic(base).returncode == 0
    before = _digest(out, xdmf)
    for args in (base + ["-pc_type", "lu", "-jacobian", "shell"],
                 ["run", "--restart", out, "-final_time", 0.1, "-pc_type", "lu", "-jacobian", "shell"]):
        one_line_error(hyperelastic(args), "PETSc")
        assert _digest(out, xdmf) == before, args
        assert sorted(os.listdir(tmp_path)) == ["out.h5", "out.xdmf"]
    assert hyperelastic(["run", "--restart", out, "-final_time", 0.1, "-quiet"]).returncode == 0
    assert _digest(out, xdmf) != before


LATE_FAILURE = ["-traction_time", "1+1e4*max(t-0.035,0)", "-snes_max_it", 3, "-dt_min", 0.01]   # fails at step 4


def test_a_run_failing_after_its_first_step_puts_the_earlier_output_back(tmp_path):
    """Issue 73 item 10: a run (or a restart) that fails after completing steps leaves the earlier FILE.h5 and its
    XDMF byte-identical; its own frames are in FILE.failed.h5 with an XDMF of that name (readable, saying it failed),
    and the error line says so. A run that ends replaces the earlier output, with nothing left aside."""
    import meshio
    out, xdmf = tmp_path / "out.h5", tmp_path / "out.xdmf"
    base = ["run", "bend", "-final_time", 0.05, "-checkpoint_every", 2, "-quiet", "-output", out]
    run_ok(base)
    before = _digest(out, xdmf)
    for args, frames in ((base + LATE_FAILURE, "frames 0..1"),
                         (["run", "--restart", out, "-final_time", 0.08] + LATE_FAILURE[:1] + ["1+1e4*max(t-0.065,0)"]
                          + LATE_FAILURE[2:], "frames 0..2")):
        p = hyperelastic(args)
        line = one_line_error(p, "'out.h5' is kept as it was", f"this run's {frames} are in", "out.failed.h5")
        assert p.returncode == 3 and "did not converge" in line
        assert _digest(out, xdmf) == before, args
        assert sorted(os.listdir(tmp_path)) == ["out.failed.h5", "out.failed.xdmf", "out.h5", "out.xdmf"]
        failed = read_h5(tmp_path / "out.failed.h5")
        assert "did not converge" in failed["attrs"]["failure"] and len(failed["time"]) == int(frames[-1]) + 1
        r = meshio.xdmf.TimeSeriesReader(str(tmp_path / "out.failed.xdmf"))
        points, _ = r.read_points_cells()
        assert r.num_steps == len(failed["time"]) and np.array_equal(points, failed["points"])
        assert "failed:" in hyperelastic(["report", tmp_path / "out.failed.h5"]).stdout
    run_ok(base)                       # one that ends replaces the earlier output; nothing is left aside
    assert _digest(out, xdmf) != before
    assert sorted(os.listdir(tmp_path)) == ["out.failed.h5", "out.failed.xdmf", "out.h5", "out.xdmf"]


def test_a_reader_that_leaves_ends_the_command_as_a_pipeline_expects(tmp_path):
    """`hyperelastic report FILE | head -1`: the reader gone, the command exits 141 (128 + SIGPIPE) with nothing on
    stderr (PETSc's signal handler had printed its crash banner and aborted, exit 15)."""
    import subprocess
    import sys
    out = tmp_path / "o.h5"
    run_ok(["run", "bend", "-final_time", 0.02, "-quiet", "-output", out])
    r, w = os.pipe()
    os.close(r)
    try:
        p = subprocess.run([os.path.join(os.path.dirname(sys.executable), "hyperelastic"), "report", str(out)],
                           stdout=w, stderr=subprocess.PIPE, text=True, timeout=60)
    finally:
        os.close(w)
    assert p.returncode == 141 and p.stderr == ""


def test_output_never_overwrites_an_input(tmp_path):
    mesh = tmp_path / "m.msh"
    assert hyperelastic(["mesh", "bar", "--level", 1, "-o", mesh]).returncode == 0
    assert hyperelastic(["run", "bend", "-final_time", 0.02, "-quiet", "-output", tmp_path / "r.h5"]).returncode == 0
    opts = tmp_path / "o.opts"
    opts.write_text("-final_time 0.02\n")
    keep = [mesh, tmp_path / "r.h5", tmp_path / "r.xdmf", opts]
    before = _digest(*keep)
    one_line_error(hyperelastic(["run", "bend", "-output", tmp_path / "o.xdmf"]), "must end in .h5")
    one_line_error(hyperelastic(["run", "bend", "-mesh", mesh, "-output", mesh]), "must end in .h5")
    one_line_error(hyperelastic(["run", "bend", "-mesh", tmp_path / "r.xdmf", "-output", tmp_path / "r.h5"]),
                   "would overwrite the input")
    one_line_error(hyperelastic(["run", "bend", "-mesh", tmp_path / "r.h5", "-output", tmp_path / "r.hdf5"]),
                   "would overwrite the input")     # its XDMF would be r.xdmf, the input's
    one_line_error(hyperelastic(["run", opts, "-output", tmp_path / "o.h5", "-options_file", tmp_path / "o.h5"]),
                   "options file")
    assert _digest(*keep) == before


def test_full_disk_keeps_every_frame_written_before(tmp_path):
    """A run onto a disk that fills up (a 1 MB tmpfs, where the process may mount one; the generated
    suite covers the file size limit everywhere) stops with one line, exit 2, and leaves a readable
    file holding the frames written before (HDF5 and XDMF)."""
    import subprocess
    d = tmp_path / "small"
    d.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(d)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        out = d / "full.h5"
        p = hyperelastic(["run", "bend", "-final_time", "5", "-frames_per_second", "60", "-quiet", "-output", out],
                         timeout=120)
        line = one_line_error(p, "full.h5", "no room for frame", "MB free on the disk")
        assert p.returncode == 2
        import h5py
        import meshio
        with h5py.File(out, "r") as f:
            n = f["x"].shape[0]
            assert n >= 2 and np.isfinite(f["x"][:]).all() and f["time"].shape[0] == n
        assert f"frames 0..{n - 1}" in line
        r = meshio.xdmf.TimeSeriesReader(str(d / "full.xdmf"))
        r.read_points_cells()
        assert r.num_steps == n
    finally:   # lazily: meshio's reader may still hold full.h5 open, and a busy mount would outlive the test
        subprocess.run(["umount", "-l", str(d)], capture_output=True)


def test_the_index_range_is_checked_before_petsc_overflows(petsc):
    """A mesh whose unknowns exceed PETSc's 32-bit indices is one line naming the count and the way out (64-bit
    indices), before any distribution (issue 44, item 6): shown on a stand-in mesh with 2^31/3 nodes' worth of rows
    and with this PETSc's own bits, and checked with 8-bit indices on a small one."""
    import numpy as np
    from hyperelastic.app.model import check_index_range
    from hyperelastic.core.errors import UserError
    check_index_range(1000, "small")                                                    # fine
    with pytest.raises(UserError, match=r"3,000 unknowns \(3 per node\) exceed the 8-bit indices .*64-bit"):
        check_index_range(1000, "small", index_bits=8)
    big = 2 ** 31 // 3 + 1
    if np.dtype(petsc.IntType).itemsize == 4:
        with pytest.raises(UserError, match="32-bit indices"):
            check_index_range(big, "big")
