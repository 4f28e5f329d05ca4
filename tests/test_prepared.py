"""Prepared meshes read in slices (issue 44 item 4): `hyperelastic mesh MESH --prepare -o F.h5` writes a checked,
Z-ordered mesh that every rank of a run reads its own slice of; the run is the one on the source mesh (bitwise on
one rank, to round-off on 2 and 4), its sets and regions the same, a damaged file one line."""
import os

import h5py
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok

OPTS = os.path.join(ROOT, "examples", "bimaterial.opts")


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """The two-material bar (physical surfaces and volumes) as .msh, and prepared."""
    d = tmp_path_factory.mktemp("prepared")
    run_ok(["mesh", os.path.join(ROOT, "examples", "bimaterial.geo"), "--size", "0.1", "-o", d / "bi.msh"])
    p = run_ok(["mesh", d / "bi.msh", "--prepare", "-o", d / "bi.h5"])
    assert "end_soft: " in p.stdout and "soft: " in p.stdout
    return d


def test_the_prepared_file_is_the_source_mesh(meshes):
    """Read whole, a prepared mesh gives the source's checked arrays and named sets exactly; its own rows are the
    Z-order (cells ascending along the curve, vertices by first use)."""
    from hyperelastic.mesh.read import read_mesh
    a, b = read_mesh(str(meshes / "bi.msh")), read_mesh(str(meshes / "bi.h5"))
    for k in ("points", "tets", "facet_cell", "facet_k"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    assert set(a.groups) == set(b.groups) == {"soft", "stiff", "end_soft", "end_stiff"}
    for name, g in a.groups.items():
        h = b.groups[name]
        assert (g.kind, g.tag, g.ignored) == (h.kind, h.tag, h.ignored) and np.array_equal(g.items, h.items), name
    with h5py.File(meshes / "bi.h5") as f:
        cells = f["cells"][:]
        first = np.unique(cells.ravel(), return_index=True)[1]
        assert (np.diff(first) > 0).all()                     # vertex k is first used before vertex k + 1


def _run(meshes, mesh, out, nprocs, *extra):
    p = run_ok(["run", OPTS, "-mesh", meshes / mesh, "-output", meshes / out, "-final_time", 0.25, *extra],
               nprocs=nprocs)
    return p, read_h5(meshes / out, frames=True)


def test_runs_read_in_slices_give_the_source_meshs_answer(meshes):
    """-mesh F.h5 on 1 and 2 ranks against -mesh F.msh: bitwise on one rank (the same order, the same DM), to
    round-off on 2 (3 ranks: the output test below; 4: tests/test_partition.py's memory test); the same set and
    region lines (counts and measures summed over the ranks)."""
    p_ref, ref = _run(meshes, "bi.msh", "ref.h5", 1)
    sets = [ln for ln in p_ref.stderr.splitlines() if ln.startswith("set ")]
    assert len(sets) == 6 and any("front" in s for s in sets)
    for n in (1, 2):
        p, got = _run(meshes, "bi.h5", f"sl{n}.h5", n)
        assert [ln for ln in p.stderr.splitlines() if ln.startswith("set ")] == sets, n
        assert got["attrs"]["mesh_read"] == "slices" and ref["attrs"]["mesh_read"] == "rank 0"
        assert np.array_equal(got["tetra"], ref["tetra"]) and np.array_equal(got["points"], ref["points"])
        err = np.abs(got["x"] - ref["x"]).max() / np.abs(ref["x"]).max()
        assert err == 0 if n == 1 else err < 1e-12, (n, err)
        for a, b in zip(got["frames"], ref["frames"]):
            for k in b:
                assert np.abs(a[k] - b[k]).max() <= 1e-9 * max(1.0, np.abs(b[k]).max()), (n, k)


def test_selectors_and_unknown_sets_on_slices(meshes):
    """A geometric selector picks the same facets from the ranks' parts (the bounding box is the whole mesh's), and
    an unknown surface or an empty selector is the same one line as on the source mesh, once, on 2 ranks."""
    p, got = _run(meshes, "bi.h5", "x0.h5", 2, "-fix", "x=0")
    q, ref = _run(meshes, "bi.msh", "x0ref.h5", 1, "-fix", "x=0")
    line = [ln for ln in q.stderr.splitlines() if ln.startswith("set x=0")]
    assert line and line == [ln for ln in p.stderr.splitlines() if ln.startswith("set x=0")]
    assert np.abs(got["x"] - ref["x"]).max() < 1e-12 * np.abs(ref["x"]).max()
    for spec, want in (("nosuch", "has no surface 'nosuch'"), ("x=5", "'x=5' selects no boundary facet")):
        a = hyperelastic(["run", OPTS, "-mesh", meshes / "bi.h5", "-fix", spec, "-output", meshes / "e.h5"], 2)
        b = hyperelastic(["run", OPTS, "-mesh", meshes / "bi.msh", "-fix", spec, "-output", meshes / "e.h5"], 1)
        assert a.returncode == b.returncode == 2
        assert a.stderr.count("error:") == 1 and want in a.stderr
        assert a.stderr.replace("bi.h5", "bi.msh") == b.stderr


def _damaged(meshes, name, edit):
    path = meshes / name
    path.write_bytes((meshes / "bi.h5").read_bytes())
    with h5py.File(path, "r+") as f:
        edit(f)
    return path


@pytest.mark.parametrize("edit, want", [
    (lambda f: f.__delitem__("boundary"), "prepared dataset 'boundary' is missing"),
    (lambda f: f["cells"].__setitem__((7, 0), 10 ** 6), r"has a vertex index out of range"),
    (lambda f: f["cells"].__setitem__(-3, f["cells"][-3][[1, 0, 2, 3]]), "is inverted"),
    (lambda f: f["points"].__setitem__(5, [np.nan, 0, 0]), "non-finite"),
    (lambda f: f.attrs.__setitem__("version", 99), "prepared mesh version 99"),
])
def test_a_damaged_prepared_file_is_one_line(meshes, edit, want):
    """A prepared file edited by hand or cut short: one error line (from whichever rank holds the bad rows), exit
    2, on 2 ranks; the inverted cell is named by its index in the source mesh."""
    path = _damaged(meshes, "bad.h5", edit)
    p = hyperelastic(["run", OPTS, "-mesh", path, "-output", meshes / "e.h5"], 2)
    assert p.returncode == 2 and p.stderr.count("error:") == 1 and want in p.stderr, p.stderr
    if want == "is inverted":
        with h5py.File(meshes / "bi.h5") as f:
            assert f"tetrahedron {f['cell_input_index'][-3]} is inverted" in p.stderr
    # read whole by rank 0 (METIS' path): checked as any mesh, one line too
    q = hyperelastic(["run", OPTS, "-mesh", path, "-partitioner", "metis", "-output", meshes / "e.h5"], 2)
    assert q.returncode == 2 and q.stderr.count("error:") == 1 and "internal" not in q.stderr, q.stderr


def test_prepare_refuses_what_it_cannot_write(meshes, tmp_path):
    """--prepare takes a mesh file and an .h5 output; a refusal writes nothing and leaves an earlier file whole."""
    keep = tmp_path / "keep.h5"
    keep.write_bytes((meshes / "bi.h5").read_bytes())
    for args, want in (([meshes / "bi.msh", "--prepare", "-o", tmp_path / "x.msh"], "must end in .h5"),
                       ([meshes / "bi.msh", "--prepare", "--size", "1", "-o", keep], "takes a mesh file"),
                       ([tmp_path / "none.msh", "--prepare", "-o", keep], "none.msh")):
        p = hyperelastic(["mesh", *args])
        assert p.returncode == 2 and want in p.stderr, p.stderr
    assert keep.read_bytes() == (meshes / "bi.h5").read_bytes() and not (tmp_path / "x.msh").exists()


def test_a_quadratic_mesh_prepared_and_read_in_slices(meshes):
    """A 10-node mesh keeps its own edge nodes (on the curved geometry where gmsh put them): read whole it is the
    source's arrays; read in slices (each rank its cells' edge nodes, exchanged from slices of the edge rows) the
    run is the .msh run's, bitwise on one rank; -order 1 of it reads it whole on rank 0 (its corners)."""
    from hyperelastic.mesh.read import read_mesh
    run_ok(["mesh", os.path.join(ROOT, "examples", "bimaterial.geo"), "--size", "0.15", "--order", "2",
            "-o", meshes / "q.msh"])
    run_ok(["mesh", meshes / "q.msh", "--prepare", "-o", meshes / "q.h5"])
    a, b = read_mesh(str(meshes / "q.msh")), read_mesh(str(meshes / "q.h5"))
    for k in ("points", "tets", "nodes", "facet_cell", "facet_k"):
        assert np.array_equal(getattr(a, k), getattr(b, k)), k
    for n in (1, 2):
        _, ref = _run(meshes, "q.msh", f"qref{n}.h5", n)
        _, got = _run(meshes, "q.h5", f"q{n}.h5", n)
        assert got["attrs"]["mesh_read"] == "slices" and got["attrs"]["element_order"] == 2
        assert np.array_equal(got["tetra"], ref["tetra"]) and np.array_equal(got["points"], ref["points"])
        err = np.abs(got["x"] - ref["x"]).max() / np.abs(ref["x"]).max()
        assert err == 0 if n == 1 else err < 1e-12, (n, err)
    _, got = _run(meshes, "q.h5", "q_p1.h5", 2, "-order", "1")
    assert got["attrs"]["mesh_read"] == "rank 0" and got["attrs"]["element_order"] == 1


def test_order_2_in_slices_and_metis_whole(meshes):
    """-order 2 elevates the slices (each edge's node at its midpoint, numbered as rank 0 numbers an elevated mesh:
    the same mesh/tetra and nodes through input_index) with the .msh run's answer, bitwise on one rank; METIS'
    serial graph reads the prepared mesh whole on rank 0, with the same answer."""
    for n in (1, 2):
        _, ref = _run(meshes, "bi.msh", f"p2ref{n}.h5", n, "-order", "2")
        _, got = _run(meshes, "bi.h5", f"p2_{n}.h5", n, "-order", "2")
        assert got["attrs"]["mesh_read"] == "slices" and got["tetra"].shape[1] == 10
        assert np.array_equal(got["tetra"], ref["tetra"]) and np.array_equal(got["points"], ref["points"])
        err = np.abs(got["x"] - ref["x"]).max() / np.abs(ref["x"]).max()
        assert err == 0 if n == 1 else err < 1e-12, (n, err)
    p_ref, ref = _run(meshes, "bi.msh", "mref.h5", 2, "-partitioner", "metis")
    p, got = _run(meshes, "bi.h5", "m.h5", 2, "-partitioner", "metis")
    assert got["attrs"]["mesh_read"] == "rank 0" and np.array_equal(got["x"], ref["x"])
    # and says so (issue 73: it did so quietly); a .msh is read whole anyway: no note
    assert "note: -partitioner metis: mesh" in p.stderr and "read whole on rank 0" in p.stderr, p.stderr
    assert "note: -partitioner metis" not in p_ref.stderr


def test_a_per_rank_output_is_read_in_slices(meshes):
    """-mesh of a per-rank output (issue 45 item 4): every rank reads its slice of the output's rows (its boundary
    found by counting faces over the ranks), on 2 and 3 ranks; the same sets, regions and answer as rank 0 reading
    it whole (-partitioner metis), to the solver tolerance (other partitions)."""
    run_ok(["run", OPTS, "-mesh", meshes / "bi.msh", "-output", meshes / "o2.h5", "-final_time", 0.25], nprocs=2)
    opts = ["-fix", "x=0", "-traction_face", "right", "-mesh_frame", 0, "-final_time", 0.25]
    whole, got = {}, {}
    p = run_ok(["run", OPTS, "-mesh", meshes / "o2.h5", "-output", meshes / "w.h5", "-partitioner", "metis", *opts],
               nprocs=2)
    whole = read_h5(meshes / "w.h5")
    sets = [ln for ln in p.stderr.splitlines() if ln.startswith("set ")]
    assert len(sets) == 4 and whole["attrs"]["mesh_read"] == "rank 0"
    for n in (2, 3):
        q = run_ok(["run", OPTS, "-mesh", meshes / "o2.h5", "-output", meshes / f"s{n}.h5", *opts], nprocs=n)
        got = read_h5(meshes / f"s{n}.h5")
        assert got["attrs"]["mesh_read"] == "slices"
        assert [ln for ln in q.stderr.splitlines() if ln.startswith("set ")] == sets
        assert np.array_equal(got["points"], whole["points"]) and np.array_equal(got["tetra"], whole["tetra"])
        assert np.abs(got["x"] - whole["x"]).max() < 1e-9 * np.abs(whole["x"]).max()


def test_the_ranks_face_count_finds_boundaries_and_overlaps(petsc):
    """discretization.slices.boundary_masks (the checks of faces made where the faces meet, not on rank 0): two tets
    on opposite sides of a shared face have 3 boundary facets each; with the second's apex moved to the first's side
    (both still positive) they overlap; a third tet on the shared face is a face of three cells."""
    from mpi4py import MPI
    from hyperelastic.core.errors import UserError
    from hyperelastic.discretization.slices import boundary_masks
    P = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0, 0, -1], [0.1, 0.1, 0.5]], float)
    cells = np.array([[0, 1, 2, 3], [0, 2, 1, 4]])
    ids = cells.copy()
    masks, nb = boundary_masks(MPI.COMM_WORLD, "m", cells, P[cells], ids, np.arange(2), len(P))
    assert nb == 6 and [bin(m).count("1") for m in masks] == [3, 3]
    assert all(m & (1 << 3) == 0 for m in masks)           # the shared face 0-1-2 omits each cell's largest id
    same = np.array([[0, 1, 2, 3], [0, 1, 2, 5]])           # both positive, both above the face 0-1-2
    with pytest.raises(UserError, match="same side"):
        boundary_masks(MPI.COMM_WORLD, "m", same, P[same], same, np.arange(2), len(P))
    three = np.array([[0, 1, 2, 3], [0, 2, 1, 4], [0, 1, 2, 5]])
    with pytest.raises(UserError, match="shares a face with two others"):
        boundary_masks(MPI.COMM_WORLD, "m", three, P[three], three, np.arange(3), len(P))


def test_a_run_on_a_prepared_mesh_restarts_on_another_rank_count(meshes):
    """A run read in slices on 2 ranks, restarted on 1 and 3: the restart reads the prepared mesh in slices again
    (its recorded -mesh) and continues to the uninterrupted run's answer."""
    full = ["run", OPTS, "-mesh", meshes / "bi.h5", "-checkpoint_every", 1, "-final_time", 0.75]
    run_ok([*full, "-output", meshes / "full.h5"], nprocs=2)
    ref = read_h5(meshes / "full.h5")
    for n in (1, 3):
        cut = meshes / f"cut{n}.h5"
        run_ok([*full[:-2], "-final_time", 0.5, "-output", cut], nprocs=2)
        run_ok(["run", "--restart", cut, "-final_time", 0.75], nprocs=n)
        got = read_h5(cut)
        assert got["attrs"]["mesh_read"] == "slices" and len(got["x"]) == len(ref["x"])
        assert np.abs(got["x"] - ref["x"]).max() < 1e-12 * np.abs(ref["x"]).max(), n
