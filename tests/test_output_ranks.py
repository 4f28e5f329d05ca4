"""The per-rank output layout (issue 45): every rank writes its own part of each frame to FILE.h5.d/, FILE.h5 holds
metadata and HDF5 virtual datasets; the same answers as the gathered layout through mesh/input_index; real readers
read it; a restart continues it on any rank count; a kill -9 at any write leaves it readable."""
import json
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok
from test_output_readers import VTK_SCRIPT

RUN = ["run", "bend", "-level", 1, "-dt", 0.03, "-final_time", 0.06, "-checkpoint_every", 1, "-quiet",
       "-output_fields", "default,stress,J_nodal,von_mises_nodal"]


@pytest.fixture(scope="module")
def outs(tmp_path_factory):
    d = tmp_path_factory.mktemp("ranks")
    run_ok([*RUN, "-output", d / "one.h5"])
    run_ok([*RUN, "-output", d / "two.h5"], nprocs=2)
    return d


def test_two_ranks_write_their_own_files_and_the_same_answer(outs):
    one, two = read_h5(outs / "one.h5", frames=True), read_h5(outs / "two.h5", frames=True)
    assert two["attrs"]["output_layout"] == "ranks" and one["attrs"]["output_layout"] == "gather"
    assert sorted(os.listdir(outs / "two.h5.d"))[0].endswith("_r00000.h5") and len(os.listdir(outs / "two.h5.d")) == 2
    assert np.array_equal(one["points"], two["points"]) and np.array_equal(np.sort(one["tetra"], axis=1),
                                                                          np.sort(two["tetra"], axis=1))
    assert np.abs(one["x"] - two["x"]).max() < 1e-12
    for a, b in zip(one["frames"], two["frames"]):
        assert set(a) == set(b) >= {"J_nodal", "von_mises_nodal", "stress", "displacement"}
        for k in a:
            scale = max(1.0, np.nanmax(np.abs(a[k])))
            assert np.nanmax(np.abs(a[k] - b[k])) <= 1e-9 * scale, k     # (nodal sums in another order)


def test_rank_0_writes_only_metadata(outs):
    """Every mesh-sized dataset of FILE.h5 is virtual (the ranks' data); what FILE.h5 holds itself is small."""
    with h5py.File(outs / "two.h5") as f:
        nv = f["mesh/points"].shape[0]
        real = []
        f.visititems(lambda name, d: real.append(name) if isinstance(d, h5py.Dataset) and not d.is_virtual
                     and d.size >= nv else None)
        assert real == [] and f["x"].is_virtual and f["frames/1/J"].is_virtual and f["series/J"].is_virtual
        assert [(s.file_name, s.dset_name) for s in f["frames/1/J"].virtual_sources()] == [(".", "series/J")]
        sources = {s.file_name for s in f["series/J"].virtual_sources()}
        assert len(sources) == 2 and all(s.startswith("two.h5.d/") for s in sources)


def test_readers_read_a_four_rank_output(outs, tmp_path):
    """meshio (through the XDMF), VTK's XDMF reader and the application (as a mesh) read a 4-rank output
    (oversubscribed); a frame's virtual dataset is one mapping whatever the rank count (row i of FILE.h5's series,
    which maps each rank's file once, every frame with it: issue 74, rank 0's metadata flat in the ranks)."""
    import meshio
    four = tmp_path / "four.h5"
    run_ok([*RUN, "-output", four], nprocs=4)
    r, one = read_h5(four, frames=True), read_h5(outs / "one.h5", frames=True)
    assert np.abs(r["x"] - one["x"]).max() < 1e-12 and len(os.listdir(tmp_path / "four.h5.d")) == 4
    with h5py.File(four) as f:
        X, T = f["mesh/points"][:], f["mesh/tetra"][:]
        for i in range(3):
            (m,) = f[f"frames/{i}/von_mises"].virtual_sources()
            assert (m.file_name, m.dset_name) == (".", "series/von_mises")
            assert m.src_space.get_select_bounds() == ((i, 0), (i, len(T) - 1))
        maps = f["series/von_mises"].virtual_sources()
        assert {(s.file_name, s.dset_name) for s in maps} == {
            (f"four.h5.d/{n}", "series/von_mises") for n in os.listdir(tmp_path / "four.h5.d")}
        assert len(maps) == 4 and f["series/von_mises"].shape == (3, len(T))
    with meshio.xdmf.TimeSeriesReader(str(tmp_path / "four.xdmf")) as reader:
        points, cells = reader.read_points_cells()
        assert np.array_equal(points, X) and np.array_equal(cells[0].data, T) and reader.num_steps == 3
        _, pd, cd = reader.read_data(2)
        assert set(pd) >= {"displacement", "J_nodal"} and np.all(np.abs(cd["J"][0] - 1) < 0.05)
    p = subprocess.run([sys.executable, "-c", VTK_SCRIPT, str(tmp_path / "four.xdmf")], capture_output=True,
                       text=True, timeout=120)
    assert p.returncode == 0 and "rror" not in p.stderr, p.stderr
    rows = [line.split() for line in p.stdout.strip().splitlines()]
    assert len(rows) == 3 and all(row[1:3] == [str(len(X)), str(len(T))] for row in rows)
    again = tmp_path / "again.h5"
    run_ok(["run", "bend", "-mesh", four, "-traction_face", "left", "-final_time", 0.01, "-dt", 0.01, "-quiet",
            "-output", again])        # (the bent bar's end is no longer a box face; its clamped end is)
    assert np.array_equal(read_h5(again)["points"][np.lexsort(read_h5(again)["points"].T)],
                          r["x"][-1][np.lexsort(r["x"][-1].T)])


@pytest.mark.parametrize("ranks", [1, 2, 4])
def test_restart_on_any_rank_count(outs, tmp_path, ranks):
    """Written on 2 ranks, stopped at a checkpoint, restarted on 1, 2 and 4 (oversubscribed) ranks: the same
    trajectory as the run that was not stopped (bitwise on 2), the file still in its first part's order."""
    full = tmp_path / "full.h5"
    run_ok([*RUN[:7], 0.12, *RUN[8:], "-output", full], nprocs=2)
    cut = tmp_path / "cut.h5"
    run_ok([*RUN, "-output", cut], nprocs=2)
    before = sorted(os.listdir(tmp_path / "cut.h5.d"))
    run_ok(["run", "--restart", cut, "-final_time", 0.12, "-quiet"], nprocs=ranks)
    a, b = read_h5(full, frames=True), read_h5(cut, frames=True)
    assert np.array_equal(a["time"], b["time"]) and len(b["time"]) == 5
    tol = 0 if ranks == 2 else 1e-12
    assert np.abs(a["x"] - b["x"]).max() <= tol
    assert np.nanmax(np.abs(a["frames"][4]["von_mises"] - b["frames"][4]["von_mises"])) <= 1e-6 * (tol > 0)
    with h5py.File(cut) as f:
        parts = __import__("json").loads(f.attrs["parts"])
        assert [len(p["files"]) for p in parts] == [2, ranks] and f.attrs["restarts"] == 1
        # the file's rank count, partition and memory are the restart's; the first part's are kept beside them
        a = f.attrs
        assert a["mpi_ranks"] == ranks == len(a["cells_per_rank"]) == len(a["peak_rss_mb_per_rank"])
        assert json.loads(a["partition"]).get("cut_faces", 0) >= 0 and sum(a["cells_per_rank"]) == len(b["tetra"])
        earlier = json.loads(a["earlier_parts"])
        assert [e["mpi_ranks"] for e in earlier] == [2] and len(earlier[0]["peak_rss_mb_per_rank"]) == 2
    after = sorted(os.listdir(tmp_path / "cut.h5.d"))
    assert set(before) < set(after) and len(after) == 2 + ranks      # the first part's files kept as they were


def test_a_new_run_replaces_the_files_only_when_it_commits(tmp_path):
    """A run over an earlier per-rank output that fails before its first step leaves that output (its rank files
    too) byte-identical; one that completes a step removes the earlier run's rank files (a gathered one, the
    directory)."""
    out = tmp_path / "o.h5"
    run_ok([*RUN, "-output", out], nprocs=2)
    files = {p: (tmp_path / "o.h5.d" / p).read_bytes() for p in os.listdir(tmp_path / "o.h5.d")}
    main = out.read_bytes()
    p = hyperelastic([*RUN, "-output", out, "-dt_min", 0.03, "-snes_max_it", 1], nprocs=2)
    assert p.returncode != 0
    assert out.read_bytes() == main
    assert {q: (tmp_path / "o.h5.d" / q).read_bytes() for q in os.listdir(tmp_path / "o.h5.d")} == files
    # failing after its first step (issue 73 item 10): the earlier output and its rank files as they were, the run's
    # own output o.failed.h5 beside it, its rank files in o.h5.d/ too; the next run that ends keeps those
    p = hyperelastic([*RUN, "-output", out, "-traction_time", "1+1e4*max(t-0.015,0)", "-snes_max_it", 3,
                      "-dt_min", 0.01], nprocs=2)
    assert p.returncode == 3 and "o.failed.h5'" in p.stderr
    assert out.read_bytes() == main
    assert {q: (tmp_path / "o.h5.d" / q).read_bytes() for q in files} == files
    failed = set(os.listdir(tmp_path / "o.h5.d")) - set(files)
    assert len(failed) == 2 and read_h5(tmp_path / "o.failed.h5")["x"].shape[0] == 1
    run_ok([*RUN, "-output", out], nprocs=2)
    now = set(os.listdir(tmp_path / "o.h5.d")) - failed
    assert len(now) == 2 and not now & set(files) and failed < set(os.listdir(tmp_path / "o.h5.d"))
    assert np.isfinite(read_h5(tmp_path / "o.failed.h5")["x"]).all()
    (tmp_path / "o.failed.h5").unlink()
    run_ok([*RUN, "-output", out])                          # one rank, gathered: the ranks' directory goes too
    assert not (tmp_path / "o.h5.d").exists() and read_h5(out)["attrs"]["output_layout"] == "gather"


def test_one_rank_can_write_the_per_rank_layout(outs, tmp_path):
    r = tmp_path / "r.h5"
    run_ok([*RUN, "-output", r, "-output_layout", "ranks"])
    a, b = read_h5(outs / "one.h5", frames=True), read_h5(r, frames=True)
    assert np.array_equal(a["x"], b["x"]) and all(np.array_equal(a["frames"][2][k], b["frames"][2][k], equal_nan=True)
                                                  for k in a["frames"][2] if not k.endswith("_nodal"))


def test_kill_at_writes_of_a_two_rank_run():
    """kill -9 at writes of a 2-rank run (scripts/crash_writes.py --ranks 2): every file left opens, holds only the
    reference's frames, and restarts to the reference. Six kills over the ~680 writes each rank makes (frames,
    checkpoints, the close), two of them restarted; the script's sweep of every 7th: 0 of 195 bad (BENCHMARKS.md)."""
    script = os.path.join(ROOT, "scripts", "crash_writes.py")
    p = subprocess.run([sys.executable, script, "--ranks", "2", "--first", "45", "--last", "700", "--every", "130",
                        "--restart-every", "3", "--jobs", "1"], capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stdout + p.stderr


def test_a_file_where_the_ranks_directory_goes_is_one_line(tmp_path):
    (tmp_path / "o.h5.d").write_text("mine")
    p = hyperelastic([*RUN, "-output", tmp_path / "o.h5"], nprocs=2, timeout=120)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "o.h5.d' exists and is not a directory" in lines[0], p.stderr
    assert (tmp_path / "o.h5.d").read_text() == "mine" and not (tmp_path / "o.h5").exists()


def test_report_and_plot_read_a_block_at_a_time(outs, tmp_path, monkeypatch):
    """`report --at` and `plot` go through the cells a block at a time (one rank's part at most) and read only the
    rows they need: the same line and the same surface with blocks of 100 rows as with one block, on both layouts,
    and the 2-rank output reports what the 1-rank one does."""
    from hyperelastic.core import files
    from hyperelastic.output import plot, report
    lines = {}
    for name in ("one.h5", "two.h5"):
        with h5py.File(outs / name) as f:
            got = []
            for block in (files.BLOCK, 100):
                monkeypatch.setattr(files, "BLOCK", block)
                X = f["mesh/points"][:]
                tri = plot.boundary_surface(f)
                got.append((report._at(f, 2, np.array([1.0, 0.5, 0.3])),
                            sorted(map(tuple, np.sort(X[tri].round(12), axis=1).reshape(len(tri), -1).tolist()))))
            assert got[0] == got[1] and len(files.cell_blocks(f)) > 2
            lines[name] = got[0]
    assert lines["one.h5"][1] == lines["two.h5"][1]            # the same boundary surface
    a, b = (np.array([float(v) for v in __import__("re").findall(r"[-+]?\d\.\d+e?[-+]?\d*", lines[n][0])])
            for n in ("one.h5", "two.h5"))
    assert np.allclose(a, b, rtol=1e-5)
    run_ok(["plot", outs / "two.h5", "-o", tmp_path / "two.png"])
    assert (tmp_path / "two.png").stat().st_size > 10000


def test_a_one_rank_output_restarts_on_two_ranks(outs, tmp_path):
    """A gathered (1-rank) output restarted on 2 ranks: the state read in slices, the file written on in its own
    layout and order, the uninterrupted 1-rank trajectory to the solver tolerance."""
    full = tmp_path / "full.h5"
    run_ok([*RUN[:7], 0.12, *RUN[8:], "-output", full])
    cut = tmp_path / "cut.h5"
    run_ok([*RUN, "-output", cut])
    run_ok(["run", "--restart", cut, "-final_time", 0.12, "-quiet"], nprocs=2)
    a, b = read_h5(full), read_h5(cut)
    assert b["attrs"]["output_layout"] == "gather" and not (tmp_path / "cut.h5.d").exists()
    assert np.array_equal(a["time"], b["time"]) and np.abs(a["x"] - b["x"]).max() <= 1e-12


def test_a_per_rank_output_without_its_files_is_one_line(tmp_path):
    """FILE.h5 copied without FILE.h5.d/: restart, report, plot and -mesh each say which file is missing."""
    out = tmp_path / "o.h5"
    run_ok([*RUN, "-output", out], nprocs=2)
    os.rename(tmp_path / "o.h5.d", tmp_path / "away")
    for args, who in ((["run", "--restart", out, "-final_time", 0.1], "--restart"), (["report", out], "report:"),
                      (["plot", out, "-o", tmp_path / "p.png"], "plot:"),
                      (["run", "bend", "-mesh", out, "-output", tmp_path / "b.h5"], "mesh")):
        p = hyperelastic(args, timeout=120)
        lines = p.stderr.strip().splitlines()
        assert p.returncode == 2 and len(lines) == 1 and who in lines[0] and "is missing" in lines[0], p.stderr
