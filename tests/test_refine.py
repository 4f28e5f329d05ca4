"""-refine K (issue 44 item 3): the mesh distributed coarse, every rank refining its own part. The split is a valid
conforming mesh of the same body (the whole mesh's checks), the sets follow exactly (4 facets per facet, 8 cells per
cell, the same areas and volumes), the numbering and the answer are the same on 1, 2 and 4 ranks and from a .msh or
its prepared file, a restart on another rank count continues it, and a homogeneous stretch stays exact on it."""
import itertools
import os

import numpy as np
import pytest

from conftest import ROOT, read_h5, run_ok

OPTS = os.path.join(ROOT, "examples", "bimaterial.opts")


def _volumes(X):
    a, b, c, d = (X[..., i, :] for i in range(4))
    return np.einsum("...i,...i->...", np.cross(b - a, c - a), d - a) / 6


def test_the_eight_children_tile_their_parent():
    """For each choice of the inner octahedron's diagonal: eight positively oriented children of 1/8 the volume
    (an affine image of the reference split), each parent face covered by exactly four child faces, the other child
    faces met twice inside."""
    from hyperelastic.discretization.refine import CHILD_FACE, CHILDREN
    from hyperelastic.element.reference import EDGES
    rng = np.random.default_rng(0)
    X = rng.normal(size=(4, 3))
    if _volumes(X) < 0:
        X = X[[1, 0, 2, 3]]
    nodes = np.concatenate([X, [0.5 * (X[i] + X[j]) for i, j in EDGES]])
    for d in range(3):
        V = _volumes(nodes[CHILDREN[d]])
        assert (V > 0).all() and np.allclose(V, _volumes(X) / 8), d
        on = CHILD_FACE[d]
        assert [(on == k).sum() for k in range(4)] == [4, 4, 4, 4], d
        inner = [frozenset(np.delete(CHILDREN[d, j], m)) for j, m in zip(*np.nonzero(on < 0))]
        assert all(inner.count(f) == 2 for f in inner) and len(inner) == 16, d


def test_a_refined_mesh_is_a_checked_mesh_of_the_same_body(l1_mesh):
    """Two levels of the bar (refine_whole, what rank 0 writes for a gathered output): the whole mesh's checks
    (conforming faces, no overlap, one piece, no unused vertex) pass, the volume and the boundary's area are the
    coarse mesh's, 16x the boundary facets; the shapes do not degrade (the worst cell's quality stays the coarse
    mesh's worst: the shortest diagonal)."""
    from hyperelastic.discretization.refine import refine_whole
    from hyperelastic.mesh.read import check, read_mesh
    from hyperelastic.mesh.sets import Mesh
    coarse = read_mesh(l1_mesh)
    points, tets = refine_whole(coarse, 2)
    assert len(tets) == 64 * len(coarse.tets) and np.array_equal(points[:len(coarse.points)], coarse.points)
    boundary = check(points, tets, "refined")
    fine = Mesh.from_meshio("refined", points, tets, boundary)
    assert len(fine.facet_cell) == 16 * len(coarse.facet_cell)
    assert np.isclose(fine.area(slice(None)), coarse.area(slice(None)), rtol=1e-12)
    assert np.isclose(_volumes(points[tets]).sum(), _volumes(coarse.points[coarse.tets]).sum(), rtol=1e-12)

    def quality(p, t):
        L = np.sqrt(sum(((p[t[:, i]] - p[t[:, j]]) ** 2).sum(1) for i, j in itertools.combinations(range(4), 2)) / 6)
        return 6 * np.sqrt(2) * _volumes(p[t]) / L ** 3
    assert quality(points, tets).min() >= quality(coarse.points, coarse.tets).min() * (1 - 1e-12)


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    """The two-material bar (physical surfaces and volumes) coarse, as .msh and prepared."""
    d = tmp_path_factory.mktemp("refine")
    run_ok(["mesh", os.path.join(ROOT, "examples", "bimaterial.geo"), "--size", "0.25", "-o", d / "bi.msh"])
    run_ok(["mesh", d / "bi.msh", "--prepare", "-o", d / "bi.h5"])
    return d


def _run(d, mesh, out, nprocs, *extra):
    p = run_ok(["run", OPTS, "-mesh", d / mesh, "-output", d / out, "-final_time", 0.25, *extra], nprocs=nprocs)
    return p, read_h5(d / out)


def test_sets_and_answers_follow_the_refinement_on_any_rank_count(meshes):
    """-refine 1 of the .msh on 1, 2 and 4 ranks and of its prepared file: the set lines give 4x the facets and 8x
    the tetrahedra with the coarse areas and volumes, the regions keep their materials; the refined mesh is the same
    (numbering and positions) everywhere and the answer the same to 1e-10 (bitwise on one rank from either file);
    the stretch is homogeneous (nu = 0: each half's closed-form stretch) on the fine mesh as on the coarse one."""
    p0, coarse = _run(meshes, "bi.msh", "c.h5", 1)
    sets0 = {ln.split(":")[0]: ln for ln in p0.stderr.splitlines() if ln.startswith("set ")}
    p1, ref = _run(meshes, "bi.msh", "r1.h5", 1, "-refine", 1)
    sets1 = {ln.split(":")[0]: ln for ln in p1.stderr.splitlines() if ln.startswith("set ")}
    assert set(sets1) == set(sets0) and len(sets0) >= 6
    for name, line in sets0.items():
        n0, n1 = int(line.split(": ")[1].split()[0]), int(sets1[name].split(": ")[1].split()[0])
        assert n1 == (4 if "facets" in line else 8) * n0, (line, sets1[name])
        assert line.split(",")[1:] == sets1[name].split(",")[1:], (line, sets1[name])       # area / volume
    assert "note: -refine 1: " in p1.stderr and len(ref["tetra"]) == 8 * len(coarse["tetra"])
    for mesh, n in (("bi.msh", 2), ("bi.msh", 4), ("bi.h5", 1)):
        p, got = _run(meshes, mesh, f"r{mesh}{n}.h5", n, "-refine", 1)
        assert np.array_equal(got["tetra"], ref["tetra"]) and np.array_equal(got["points"], ref["points"]), (mesh, n)
        err = np.abs(got["x"] - ref["x"]).max() / np.abs(ref["x"]).max()
        assert (err == 0) if n == 1 else (err < 1e-10), (mesh, n, err)
    # the bar is stretched homogeneously in each half: the end's displacement is the coarse run's (both exact)
    end0 = coarse["x"][-1][:, 0].max() - coarse["points"][:, 0].max()
    end1 = ref["x"][-1][:, 0].max() - ref["points"][:, 0].max()
    assert end0 > 1e-3 and abs(end1 - end0) < 1e-6 * end0, (end0, end1)


def test_a_refined_run_restarts_on_another_rank_count(meshes):
    """A 2-rank -refine 1 run checkpointed half way, restarted on one rank (which refines again from the recorded
    options), ends where the uninterrupted one-rank run ends; a P2 run on the refined mesh agrees on 1 and 2 ranks."""
    run_ok(["run", OPTS, "-mesh", meshes / "bi.msh", "-refine", 1, "-output", meshes / "k.h5", "-final_time", 0.5,
            "-checkpoint_every", 1], nprocs=2)
    run_ok(["run", "--restart", meshes / "k.h5", "-final_time", 1])
    _, whole = _run(meshes, "bi.msh", "w.h5", 1, "-refine", 1, "-final_time", 1)
    got = read_h5(meshes / "k.h5")
    assert np.abs(got["x"][-1] - whole["x"][-1]).max() < 1e-10 * np.abs(whole["x"]).max()
    _, q1 = _run(meshes, "bi.msh", "q1.h5", 1, "-refine", 1, "-order", 2)
    _, q2 = _run(meshes, "bi.msh", "q2.h5", 2, "-refine", 1, "-order", 2)
    assert q1["tetra"].shape[1] == 10 and np.array_equal(q1["tetra"], q2["tetra"])
    assert np.abs(q1["x"] - q2["x"]).max() < 1e-10 * np.abs(q1["x"]).max()


def test_a_quadratic_meshs_edge_nodes_are_the_first_levels_vertices(tmp_path):
    """A quadratic rod (curved surface): -refine 1 puts the new vertices at its edge nodes, on the cylinder, so the
    refined linear mesh's volume is closer to pi r^2 L than the coarse corners' (straight midpoints would keep the
    coarse faceting); its numbering: the quadratic mesh's own nodes."""
    from hyperelastic.discretization.refine import refine_whole
    from hyperelastic.mesh.read import corners, read_mesh
    run_ok(["mesh", os.path.join(ROOT, "examples", "rod.geo"), "--size", "0.006", "--order", "2", "-o",
            tmp_path / "rod.msh"])
    q = read_mesh(str(tmp_path / "rod.msh"))
    points, tets = refine_whole(q, 1)
    assert len(points) == len(q.points) and np.array_equal(points, q.points)
    lin = corners(q)
    V0, V1 = _volumes(lin.points[lin.tets]).sum(), _volumes(points[tets]).sum()
    mid, mid_tets = refine_whole(lin, 1)
    assert np.isclose(_volumes(mid[mid_tets]).sum(), V0, rtol=1e-12)
    lo, hi = q.points.min(axis=0), q.points.max(axis=0)
    r, L = (hi[0] - lo[0]) / 2, hi[2] - lo[2]
    exact = np.pi * r * r * L
    assert abs(V1 - exact) < 0.5 * abs(V0 - exact), (V0, V1, exact)
