"""Contact (issue 46): IPC's barrier as the IPC authors' toolkit computes it, a residual that is the barrier energy's
gradient and a tangent that is the residual's derivative, an update stopped short of the first impact, a frictionless
plate pressing the bar equal to prescribing its end at the same place, a dropped bar that never passes through the
floor (checked from the output alone, at every frame), boxes and triangulated obstacles, self-contact between pieces
and within one body (checked by the toolkit's intersection test on the output), Hertz's contact radius, Coulomb
friction sliding and sticking, the same answer on 1 and 2 ranks, and bad input refused in one line."""
import math
import os
import shutil

import numpy as np
import pytest

from conftest import ROOT, hyperelastic, read_h5, run_ok

from hyperelastic.physics.effects.contact import Contact, barrier
from hyperelastic.physics.effects.obstacles import KINDS, Obstacle


def test_the_barrier_is_the_ipc_toolkits():
    """b, b', b'' against ipctk's (Li et al. 2020's barrier, the IPC authors' code) over (0, dhat], 0 beyond; +inf at
    d <= 0."""
    ipctk = pytest.importorskip("ipctk")
    dhat = 0.3
    d = np.concatenate([np.geomspace(1e-6, dhat, 40), [0.31, 1.0]])
    b, b1, b2 = barrier(d, dhat)
    for i, di in enumerate(d):
        want = (ipctk.barrier(di, dhat), ipctk.barrier_first_derivative(di, dhat),
                ipctk.barrier_second_derivative(di, dhat))
        assert np.allclose((b[i], b1[i], b2[i]), want, rtol=1e-12, atol=1e-300), (di, (b[i], b1[i], b2[i]), want)
    assert barrier(np.array([0.0, -1.0]), dhat)[0].tolist() == [np.inf, np.inf]


def _effect():
    """A contact effect on 40 random nodes near a plane and a sphere (a fixed and a moving one)."""
    rng = np.random.default_rng(3)
    X = rng.uniform([-1, -1, 0.01], [1, 1, 0.2], (40, 3))
    sphere_c = np.array([0.0, 0.0, 0.9])
    plane = Obstacle("plane", (0.0, 0.0, 1.0, 0.0), text="plane:0,0,1,0")
    sphere = Obstacle("sphere", (*sphere_c, 0.6), (lambda t: 0.0, lambda t: 0.0, lambda t: -0.05 * t),
                      "sphere:0,0,0.9,0.6")
    X = X[(np.linalg.norm(X - sphere_c, axis=1) > 0.62) & (np.linalg.norm(X - sphere_c + [0, 0, 0.05], axis=1) > 0.62)]
    c = Contact(np.arange(len(X)), rng.uniform(0.5, 1.5, len(X)), X, np.arange(len(X)), (plane, sphere), 0.15, 1e3)
    c.begin_step(1.0, 0.1, None, None)
    return c, X.ravel()


def _is_the_potentials_gradient(c, x, rng, tol=1e-6, n=12):
    """c's residual at x against central differences of its potential in n random components."""
    r = np.zeros_like(x)
    c.residual(x, r)
    h = 1e-7
    for i in rng.choice(len(x), n, replace=False):
        e = np.zeros_like(x)
        e[i] = h
        fd = (c.potential(x + e) - c.potential(x - e)) / (2 * h)
        assert abs(fd - r[i]) <= tol * max(1.0, abs(r[i])), (i, fd, r[i])
    return r


def _is_the_residuals_derivative(c, x, rng, rtol=1e-5):
    """c's tangent (linearized at x) applied to a random v against the central difference of its residual along v;
    its blocks positive semi-definite."""
    c.linearize(x)
    v = rng.normal(size=x.shape)
    y = np.zeros_like(x)
    c.apply(v, y)
    rp, rm = np.zeros_like(x), np.zeros_like(x)
    c.residual(x + 1e-7 * v, rp)
    c.residual(x - 1e-7 * v, rm)
    assert np.allclose((rp - rm) / 2e-7, y, rtol=rtol, atol=0.1 * rtol * np.abs(y).max())
    assert np.linalg.eigvalsh(c.blocks).min() >= -1e-9 * np.abs(c.blocks).max()


def test_residual_and_tangent_are_the_energys_derivatives():
    """Central differences: the residual is the potential's gradient (plane and sphere terms), and for the plane terms
    (an exact Hessian) the tangent is the residual's derivative; the sphere's curvature term is dropped, so there
    the tangent is the positive semi-definite part (every block's eigenvalues >= 0)."""
    c, x = _effect()
    rng = np.random.default_rng(1)
    r = _is_the_potentials_gradient(c, x, rng)
    assert np.abs(r).max() > 0 and c.undefined == 0
    _is_the_residuals_derivative(Contact(c.nodes, c.area, x, c.nodes, c.obstacles[:1], c.dhat, c.kappa), x, rng)
    c.linearize(x)
    assert np.linalg.eigvalsh(c.blocks).min() >= -1e-9 * np.abs(c.blocks).max()


def test_friction_is_the_gradient_of_its_lagged_potential_and_its_tangent_psd():
    """IPC's smoothed, lagged Coulomb friction on the obstacles: the mollifier equals the IPC Toolkit's f0 and f1; at
    slips below and beyond eps_v h the residual is the potential's gradient and the tangent the residual's derivative
    (central differences), every 3x3 block positive semi-definite."""
    ipctk = pytest.importorskip("ipctk")
    from hyperelastic.physics.effects.contact import mollifier
    for y in (0.0, 1e-3, 0.1, 0.29, 0.31, 2.0):
        f0, f1y, _ = mollifier(np.array([y]), 0.3)
        assert np.isclose(f0[0], ipctk.smooth_friction_f0(y, 0.3)) and np.isclose(f1y[0] * y, ipctk.smooth_friction_f1(y, 0.3))
    c0, x0 = _effect()
    rng = np.random.default_rng(5)
    for scale in (1e-3, 0.05):                      # slips below and beyond eps_v h = 0.01
        c = Contact(c0.nodes, c0.area, x0, c0.nodes, c0.obstacles, c0.dhat, c0.kappa, mu=0.4, eps_v=0.1)
        c.begin_step(1.0, 0.1, x0, None)
        slip = rng.normal(size=x0.shape) * scale
        slip.reshape(-1, 3)[:, 2] = 0.0
        x = x0 + slip
        _is_the_potentials_gradient(c, x, rng, tol=1e-5)
        only_plane = Contact(c0.nodes, c0.area, x0, c0.nodes, c0.obstacles[:1], c0.dhat, c0.kappa, mu=0.4, eps_v=0.1)
        only_plane.begin_step(1.0, 0.1, x0, None)
        _is_the_residuals_derivative(only_plane, x, rng, rtol=1e-4)


def test_an_update_stops_short_of_the_first_impact():
    """max_step: a node moving straight through the plane or into the sphere stops CCD_MARGIN short of the exact time
    of impact; moving away, the whole update; the time of impact of a ray and a sphere is the quadratic's root."""
    c, x = _effect()
    down = np.zeros_like(x).reshape(-1, 3)
    down[:, 2] = -1.0
    s = c.max_step(x, down.ravel())
    z = x.reshape(-1, 3)[:, 2]
    assert np.isclose(s, 0.9 * z.min()) and c.max_step(x, -down.ravel()) <= 1.0
    toi = KINDS["sphere"].time_of_impact(np.array([0, 0, 0, 1.0]), np.array([[3.0, 0, 0]]), np.array([[-4.0, 0, 0]]))
    assert np.isclose(toi[0], 0.5)


def test_a_box_is_met_at_its_faces_edges_and_corners():
    """box:X0,...: the distance is the Euclidean distance to the box outside (to a face, an edge, a corner), negative
    inside; its gradient is the distance's (central differences); a ray's time of impact is where it enters the box
    (the slabs), inf where it misses or moves away; the tangent is the PSD part (blocks' eigenvalues >= 0)."""
    distances = KINDS["box"].distances
    v = np.array([0.0, 0.0, 0.0, 1.0, 2.0, 3.0])
    x = np.array([[0.5, 1.0, 3.5], [1.3, 2.4, 1.0], [1.3, 2.4, 3.5], [0.5, 1.0, 1.0], [-2.0, 1.0, 1.0]])
    d, g = distances(v, x)
    assert np.allclose(d, [0.5, 0.5, np.sqrt(0.09 + 0.16 + 0.25), -0.5, 2.0])
    h = 1e-7
    for i in (0, 1, 2, 4):
        fd = [(distances(v, x[i:i + 1] + h * e)[0][0] - distances(v, x[i:i + 1] - h * e)[0][0]) / (2 * h)
              for e in np.eye(3)]
        assert np.allclose(fd, g[i], atol=1e-6), (i, fd, g[i])
    toi = KINDS["box"].time_of_impact(v, np.array([[-1.0, 1, 1], [-1.0, 1, 1], [-1.0, 5, 1], [2.0, 1, 1]]),
                         np.array([[2.0, 0, 0], [-2.0, 0, 0], [2.0, 0, 0], [1.0, 0, 0]]))
    assert np.isclose(toi[0], 0.5) and np.isinf(toi[1:]).all()
    rng = np.random.default_rng(2)
    X = rng.uniform([-0.2, -0.2, 3.01], [1.2, 2.2, 3.1], (30, 3))
    box = Obstacle("box", tuple(v), text="box:0,0,0,1,2,3")
    c = Contact(np.arange(len(X)), np.ones(len(X)), X, np.arange(len(X)), (box,), 0.15, 1e3)
    c.begin_step(1.0, 0.1, None, None)
    _is_the_potentials_gradient(c, X.ravel(), rng, n=10)
    c.linearize(X.ravel())
    assert np.linalg.eigvalsh(c.blocks).min() >= -1e-9 * np.abs(c.blocks).max()


def test_every_kind_draws_the_surface_it_measures():
    """Each kind's drawing (for the pictures) lies on the obstacle: its vertices at distance 0 (a sphere's within its
    tessellation, exactly at the vertices); a sphere's and a box's triangles close a surface (every edge in two
    triangles) facing outward (the distance's gradient at a triangle's centroid along its normal); a plane's covers
    the body's box seen along the normal."""
    lo, hi = np.array([0.0, 0, 0]), np.array([2.0, 1, 1])
    for text in ("plane:0,0,1,-0.5", "plane:1,1,0,0.3", "sphere:0.5,0.5,2,0.7", "box:0,0,1.5,1,2,3"):
        kind, body = text.split(":")
        ob = Obstacle(kind, KINDS[kind].parse(body, text)[0], text=text)
        v = ob.at(0.0)
        P, T = ob.drawing(0.0, lo, hi)
        d, _ = ob.form.distances(v, P)
        assert np.abs(d).max() < 1e-12, (text, d)
        n = np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]])
        g = ob.form.distances(v, P[T].mean(axis=1))[1]
        assert ((n * g).sum(axis=1) > 0).all(), text                         # outward: into the free side
        if kind != "plane":
            e = np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]), axis=1)
            assert (np.unique(e, axis=0, return_counts=True)[1] == 2).all(), text
            continue
        c, a, b = P.mean(axis=0), (P[1] - P[0]) / 2, (P[3] - P[0]) / 2        # (the square's centre and half sides)
        corners = lo + np.array([[i & 1, (i >> 1) & 1, (i >> 2) & 1] for i in range(8)]) * (hi - lo)
        q = corners - np.outer(corners @ v[:3] - v[3], v[:3]) - c               # (projected onto the plane)
        assert (np.abs(q @ a) <= a @ a).all() and (np.abs(q @ b) <= b @ b).all(), text


GROUND = '''

class Wall(ObstacleKind):
    name = "wall"
    values = "X: the half-space x < X is free (a wall facing -x)"
    count = 1

    @staticmethod
    def moved(v, u):
        return v + u[0]

    @staticmethod
    def distances(v, x):
        return v[0] - x[:, 0], np.broadcast_to([-1.0, 0.0, 0.0], x.shape)

    @staticmethod
    def time_of_impact(v, x, dx):
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.where(dx[:, 0] > 0, (v[0] - x[:, 0]) / dx[:, 0], np.inf)

    @classmethod
    def impact_moving(cls, old, new, a, b):
        return cls.time_of_impact(old, a, b - a - np.array([new[0] - old[0], 0.0, 0.0]))

    @staticmethod
    def drawing(v, lo, hi):
        return np.array([[v[0], lo[1], lo[2]], [v[0], hi[1], lo[2]], [v[0], hi[1], hi[2]]]), np.array([[0, 2, 1]])
'''


def test_an_obstacle_kind_added_by_its_recipe_presses_as_the_plane_does(tmp_path):
    """Issue 69 item 2: a throw-away kind (`wall:X`, the half-space x < X free) added to a copy of the package by one
    class and its registry line reaches the option, -help and the contact effect: `press` with `-obstacle wall:5.005`
    gives the trajectory and the contact force of `-obstacle plane:-1,0,0,-5.005`."""
    import difflib
    import shutil
    import subprocess
    import sys
    from conftest import ROOT
    copy = tmp_path / "copy"
    shutil.copytree(os.path.join(ROOT, "hyperelastic"), copy / "hyperelastic",
                    ignore=shutil.ignore_patterns("__pycache__"))
    path = copy / "hyperelastic" / "physics" / "effects" / "obstacles.py"
    before = path.read_text()
    line = "KINDS = {k.name: k for k in (Plane, Sphere, Box, TriangleMesh)}"
    after = before.replace(line, GROUND.strip("\n") + "\n\n\n" + line.replace("TriangleMesh)", "TriangleMesh, Wall)"))
    path.write_text(after)
    changed = [ln for ln in difflib.unified_diff(before.splitlines(), after.splitlines(), n=0)
               if ln[:1] in "+-" and not ln.startswith(("+++", "---")) and ln[1:].strip()]
    assert sum(ln.startswith("-") for ln in changed) == 1, changed          # the registry line; the rest is the class
    env = dict(os.environ, PYTHONPATH=str(copy))
    common = ["run", "press", "-final_time", "0.3"]
    p = subprocess.run([sys.executable, "-m", "hyperelastic"] + common + ["-obstacle", "wall:5.005", "-output",
                       str(tmp_path / "w.h5")], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    h = subprocess.run([sys.executable, "-m", "hyperelastic", "run", "-help"], cwd=tmp_path, env=env,
                       capture_output=True, text=True, timeout=300)
    assert "wall:X" in h.stdout + h.stderr
    q = run_ok(common + ["-output", tmp_path / "p.h5"])
    w, pl = read_h5(tmp_path / "w.h5"), read_h5(tmp_path / "p.h5")
    assert len(w["x"]) == len(pl["x"]) > 1
    assert np.abs(w["x"] - pl["x"]).max() <= 1e-12 * np.abs(pl["x"]).max()
    fw, fp = _forces(p.stderr, "load contact"), _forces(q.stderr, "load contact")
    assert abs(fw[0] - fp[0]) <= 1e-9 * abs(fp[0]) and fp[0] != 0


SPHERE = """-quasistatic
-effects elasticity,fixed,contact
-material linear
-E 1e6
-nu 0.3
-fix zmin
-obstacle sphere:0.5,0.5,1.501,0.5
-obstacle_motion 0,0,-0.03*t
-contact_faces zmax
-contact_dhat 1e-5
-dt 0.2
"""


@pytest.mark.parametrize("order,extra", [(1, ["-options_file", "gamg"]), (2, [])])
def test_a_sphere_pressed_into_a_block_balances_at_every_step(tmp_path, order, extra):
    """Issue 72 item 1: a rigid sphere pressed into a clamped unit cube with a barrier reach 1e-5 of the part (its
    stiffness makes Newton's updates tiny at contact). Before, SNES stopped on the step norm with the contact force
    unbalanced, and the step was accepted: on P1 with GAMG every step (a contact force of 500-3,200 N against a clamp
    reaction of 0), on P2 4e-4 of the force off. Now every accepted step balances: the clamp's reaction equals the
    contact force to 1e-4 (Solver.SNORM_EQUILIBRIUM; measured: 2e-9 on P1, 1.8e-5 on P2)."""
    (tmp_path / "sphere.opts").write_text(SPHERE)
    mesh = tmp_path / "cube.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "cube.geo"), "--size", 0.2, "-o", mesh])
    run_ok(["run", tmp_path / "sphere.opts", "-mesh", mesh, "-order", order, *extra, "-quiet", "-output",
            tmp_path / "s.h5"])
    st = read_h5(tmp_path / "s.h5")["stats"]
    ok = st["rejected"] == 0
    reaction, contact = st["reaction_zmin_Fz"][ok], st["load_contact_Fz"][ok]
    assert ok.sum() == 5 and (np.abs(contact) > 100).all(), contact
    assert (np.abs(reaction + contact) <= 1e-4 * np.abs(contact)).all(), (reaction, contact)


def test_a_refused_start_names_what_crosses(tmp_path):
    """Issue 72 item 2 (its message): `press`'s plate moves 1 m into a 5 mm gap in its first step of 0.5 s, further than
    a start may push the end's nodes (a cell would invert under 1.25 times the push; 0.4 m in 0.2 s is pushed since the
    eighteenth session): the rejected attempt says which obstacle reaches which node, and no longer that held nodes
    were moved (none is)."""
    p = run_ok(["run", "press", "-dt", 0.5, "-final_time", 0.5, "-output", tmp_path / "p.h5"])
    line = next(ln for ln in p.stderr.splitlines() if "rejected" in ln)
    assert "no start of the step is free of contact" in line and "held nodes" not in line, line
    assert "-obstacle plane:-1,0,0,-5.005 reaches contact node " in line and "inside it" in line, line


FRICTION_STATIC = """-quasistatic
-effects elasticity,prescribed,contact
-material linear
-E 1e6
-nu 0.3
-obstacle plane:0,0,1,-0.001
-contact_faces zmin
-contact_friction 0.3
-prescribe_faces zmax
-prescribe_uz -0.05*min(2*t,1)
-prescribe_ux 0.2*max(2*t-1,0)
-dt 0.05
-final_time 1
"""


def test_quasi_static_friction_by_slip_distance(tmp_path):
    """Issue 72 item 3: a unit cube (E = 1 MPa) pressed onto a floor through its top face (5% in the first half of the
    load), then its top pulled sideways by 0.2 m, mu = 0.3, quasi-static: the smoothing is a slip a step (the default
    0.1 dhat), not a speed in pseudo-time. While the pull is small the bottom sticks (it moves 2% of the top's 0.02 m,
    the smoothed law's creep; the tangential reaction 0.1 of the normal one); once it slides the tangential reaction is
    mu N to 1% (measured 0.01% at the end). A speed (-contact_friction_eps) in a quasi-static run is refused."""
    (tmp_path / "f.opts").write_text(FRICTION_STATIC)
    mesh = tmp_path / "cube.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "cube.geo"), "--size", 0.25, "-o", mesh])
    run_ok(["run", tmp_path / "f.opts", "-mesh", mesh, "-quiet", "-output", tmp_path / "f.h5"])
    got = read_h5(tmp_path / "f.h5")
    st, X, x, t = got["stats"], got["points"], got["x"], got["time"]
    ok = st["rejected"] == 0
    ratio = -st["reaction_zmax_Fx"][ok] / st["reaction_zmax_Fz"][ok]
    ts = st["time"][ok]
    assert np.abs(ratio[ts >= 0.75] / 0.3 - 1).max() < 1e-2, ratio
    first_pull = int(np.argmin(abs(t - 0.55)))
    bottom, top = np.isclose(X[:, 2], 0), np.isclose(X[:, 2], 1)
    moved = (x[first_pull] - X)[:, 0]
    assert ratio[np.argmin(abs(ts - 0.55))] < 0.5 * 0.3 and moved[bottom].mean() < 0.05 * moved[top].mean()
    p = hyperelastic(["run", tmp_path / "f.opts", "-mesh", mesh, "-contact_friction_eps", 1e-3, "-output",
                      tmp_path / "g.h5"])
    lines = [ln for ln in p.stderr.strip().splitlines() if not ln.startswith("note: ")]
    assert p.returncode == 2 and len(lines) == 1 and "-contact_friction_slip" in lines[0], p.stderr


def test_the_bent_bar_rests_on_a_box(tmp_path):
    """The quasi-static bend's tip (it sags ~1.3 m) comes down on a box below it: no node inside the box in any frame,
    a contact force that carries part of the load."""
    p = run_ok(["run", "bend", "-quasistatic", "-obstacle", "box:3,-9,-3,7,-2.6,3", "-output", tmp_path / "b.h5"])
    got = read_h5(tmp_path / "b.h5")
    for xf in got["x"]:
        inside = (xf[:, 0] > 3) & (xf[:, 0] < 7) & (xf[:, 1] > -9) & (xf[:, 1] < -2.6) & (np.abs(xf[:, 2]) < 3)
        assert not inside.any()
    f = _forces(p.stderr, "load contact")
    assert f[1] > 1e3 and got["stats"]["contact_nodes"][-1] > 0


OPTS = """-quasistatic
-effects elasticity,fixed,{end}
-fix left:x,front:y,bottom:z
-dt 0.25
{extra}
"""


def _forces(stderr, row):
    line = next(ln for ln in stderr.splitlines() if ln.strip().startswith(row))
    return np.array([float(v) for v in line.split("F = (")[1].split(")")[0].split(",")])


def test_a_plate_pressing_the_bar_is_the_end_prescribed_there(tmp_path):
    """`press` (a frictionless plate moving in against the end on rollers) against prescribing the end's x at the
    place the plate left it: the contact force equals the reaction and the positions agree (a homogeneous
    compression either way); the contact force balances the rollers' reaction; no node ever crossed the plate."""
    p = run_ok(["run", "press", "-output", tmp_path / "c.h5"])
    got = read_h5(tmp_path / "c.h5", frames=True)
    x, X = got["x"], got["points"]
    end = x[-1][np.isclose(X[:, 0], X[:, 0].max()), 0]
    assert end.max() - end.min() < 1e-9 and 2.99 < end.mean() < 3.0          # a flat end, a gap below dhat
    for t, xf in zip(got["time"], x):                                        # the plate: x < 5.005 - 2 min(t, 1)
        assert xf[:, 0].max() < 5.005 - 2 * min(t, 1)
    f_contact = _forces(p.stderr, "load contact")
    (tmp_path / "pp.opts").write_text(OPTS.format(end="prescribed", extra=f"-prescribe_faces right:x\n"
                                                  f"-prescribe_ux ({float(end.mean() - 5)!r})*min(t,1)"))
    q = run_ok(["run", tmp_path / "pp.opts", "-output", tmp_path / "p.h5"])
    ref = read_h5(tmp_path / "p.h5")
    f_reaction = _forces(q.stderr, "reaction right")
    assert abs(f_contact[0] - f_reaction[0]) < 1e-5 * abs(f_reaction[0]), (f_contact, f_reaction)   # (6 digits)
    assert np.abs(ref["x"][-1] - x[-1]).max() < 1e-8
    assert abs(_forces(p.stderr, "reaction left")[0] + f_contact[0]) < 1e-5 * abs(f_contact[0])
    st = got["stats"]
    ok = st["rejected"] == 0                     # (a rejected attempt's row has no energies)
    assert (~ok).sum() <= 2, st["rejected"]      # (0.2 m a step into a 5 mm gap: the start pushed; 6 without it)
    assert st["contact_dmin"][ok].min() > 0 and st["contact_nodes"][ok][-1] > 0 and st["contact_energy"][ok][-1] > 0
    # contact results (issue 70 item 2): the plate's force in every accepted step is the forces table's contact load,
    # its translation the scene's motion, its area at the end the whole end face (4 x 4), and the frame's pressure
    # field the homogeneous compression's F / A at every node of the end; report --contact prints them
    F = np.stack([st[f"obstacle1_F{c}"][ok] for c in "xyz"], axis=1)
    assert np.allclose(F[:, 0], st["load_contact_Fx"][ok], rtol=1e-12, atol=0) and np.abs(F[:, 1:]).max() == 0
    assert np.allclose(st["obstacle1_ux"][ok], -2 * np.minimum(st["time"][ok], 1), rtol=0, atol=1e-15)
    assert st["obstacle1_area"][ok][-1] == pytest.approx(16.0, rel=1e-12)
    last = got["frames"][-1]
    pressed = last["contact_status"] == 1
    assert pressed.sum() > 0 and np.allclose(last["contact_pressure"][pressed], -F[-1, 0] / 16.0, rtol=1e-6)
    assert np.array_equal(pressed, np.isclose(X[:, 0], X[:, 0].max()))
    line = run_ok(["report", tmp_path / "c.h5", "--contact"]).stdout.splitlines()[-1]
    assert line.startswith(f"  obstacle1 plane:-1,0,0,-5.005: F = ({F[-1, 0]:.6g}, ") and "area 16," in line, line
    assert f"peak pressure {-F[-1, 0] / 16:.6g}," in line and f"{int(pressed.sum())} nodes in contact" in line, line
    assert "patch extent (0, 4.2" in line and "moved by (-2, 0, 0)" in line, line
    # the force-squeeze curve (issue 70 item 3): report --curve X,Y writes the CSV and the PNG of two statistics
    # columns, a point per accepted step; a watched quantity gives a point per frame; --list names the columns
    (tmp_path / "curves").mkdir()
    q = run_ok(["report", tmp_path / "c.h5", "--list", "--curve", "obstacle1_ux,obstacle1_Fx",
                "--curve", "time,u_x:5,0,0", "--out", tmp_path / "curves"])
    assert "  obstacle1_Fx" in q.stdout.splitlines() and f"({ok.sum()} points, one per step)" in q.stdout, q.stdout
    rows = np.loadtxt(tmp_path / "curves" / "c_obstacle1_ux_obstacle1_Fx.csv", delimiter=",", skiprows=1)
    assert np.array_equal(rows[:, 0], st["obstacle1_ux"][ok]) and np.array_equal(rows[:, 1], F[:, 0])
    assert (tmp_path / "curves" / "c_obstacle1_ux_obstacle1_Fx.png").stat().st_size > 10000
    frames = np.loadtxt(tmp_path / "curves" / "c_time_u_x-5-0-0.csv", delimiter=",", skiprows=1)
    assert np.array_equal(frames[:, 0], got["time"]) and np.allclose(frames[-1, 1], end.mean() - 5, atol=1e-6)
    bad = hyperelastic(["report", tmp_path / "c.h5", "--curve", "time,obstacle9_Fx", "--out", tmp_path / "curves"])
    assert bad.returncode == 2 and "obstacle9_Fx" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1
    assert not list((tmp_path / "curves").glob("*obstacle9*"))
    # a picture worth looking at (issue 70 item 5): the contact pressure, seen along y, with the plate drawn
    import matplotlib.image
    pic = run_ok(["plot", tmp_path / "c.h5", "-o", tmp_path / "p.png", "--field", "contact_pressure", "--view", "y"])
    assert f"field contact_pressure from 0 to {-F[-1, 0] / 16:.6g}, displacement scale 1" in pic.stdout, pic.stdout
    img = matplotlib.image.imread(tmp_path / "p.png")
    assert img.shape[:2] == (700, 1000) and img[..., :3].std() > 0.05           # (not blank)
    # inside the part (issue 70 item 5): the field on a plane (--slice), the part below a plane (--clip)
    for cut in (["--slice", "x=0"], ["--clip", "y=0", "--view", "z"]):
        q = run_ok(["plot", tmp_path / "c.h5", "-o", tmp_path / "cut.png", "--field", "von_mises", *cut])
        img = matplotlib.image.imread(tmp_path / "cut.png")
        assert img.shape[:2] == (700, 1000) and img[..., :3].std() > 0.05 and "field von_mises" in q.stdout, cut
    # frames as an animated GIF: one camera and colour range, each frame its own picture
    from PIL import Image
    q = run_ok(["plot", tmp_path / "c.h5", "--frames", "9:10", "-o", tmp_path / "a.gif", "--field", "contact_pressure"])
    assert "2 frames 9..10, field contact_pressure from 0 to " in q.stdout, q.stdout
    with Image.open(tmp_path / "a.gif") as gif:
        shots = []
        for k in range(gif.n_frames):
            gif.seek(k)
            shots.append(np.asarray(gif.convert("RGB"), float))
    assert len(shots) == 2 and shots[0].shape[:2] == (700, 1000)
    assert np.abs(shots[1] - shots[0]).mean() > 0.1                                 # the plate moves, frame by frame
    # and as an MP4 video (H.264), read back by ffmpeg's own decoder: the same frames, not blank, moving
    import imageio_ffmpeg
    run_ok(["plot", tmp_path / "c.h5", "--frames", "8:10", "-o", tmp_path / "a.mp4", "--field", "contact_pressure"])
    reader = imageio_ffmpeg.read_frames(str(tmp_path / "a.mp4"))
    meta = next(reader)
    video = [np.frombuffer(f, np.uint8).reshape(700, 1000, 3).astype(float) for f in reader]
    assert meta["codec"] == "h264" and meta["size"] == (1000, 700) and len(video) == 3
    assert video[0].std() > 5 and np.abs(video[2] - video[0]).mean() > 0.1
    q = hyperelastic(["plot", tmp_path / "c.h5", "--frames", "8:10", "-o", tmp_path / "a.avi"])
    assert q.returncode == 2 and "must be a .gif or .mp4 file" in q.stderr and not (tmp_path / "a.avi").exists()
    for bad in (["--field", "nothing"], ["--field", "von_mises:x"], ["--view", "w"], ["--range", "2,1"],
                ["--slice", "x=99"], ["--clip", "q=1"], ["--clip", "x=0", "--slice", "y=0"], ["--frames", "2:99"],
                ["--frames", "3:1"]):
        q = hyperelastic(["plot", tmp_path / "c.h5", "-o", tmp_path / "q.png", *bad])
        assert q.returncode == 2 and len(q.stderr.strip().splitlines()) == 1, (bad, q.stderr)
    assert not (tmp_path / "q.png").exists()


def test_contact_results_refused_where_there_are_none(tmp_path):
    run_ok(["run", "bend", "-level", 1, "-final_time", 0.02, "-quiet", "-output", tmp_path / "b.h5"])
    p = hyperelastic(["report", tmp_path / "b.h5", "--contact"])
    assert p.returncode == 2 and len(p.stderr.strip().splitlines()) == 1 and "--contact" in p.stderr, p.stderr


def test_a_dropped_bar_never_passes_through_the_floor_on_1_and_2_ranks(tmp_path):
    """`drop_floor` to after the bounce: no node below the floor in any frame (from the output alone); backward Euler
    never gains energy through the bounce (the barrier's energy counted); the same answer on 2 ranks."""
    args = ["run", "drop_floor", "-final_time", 0.5, "-frames_per_second", 40]
    run_ok(args + ["-output", tmp_path / "d1.h5"])
    run_ok(args + ["-output", tmp_path / "d2.h5"], nprocs=2)
    one, two = read_h5(tmp_path / "d1.h5"), read_h5(tmp_path / "d2.h5")
    z = one["x"][:, :, 2]
    assert z.min() > -2.5 and z.min() < -2.5 + 0.02 and one["stats"]["contact_nodes"].max() > 0
    st = one["stats"]
    energy = st["energy_total"][st["rejected"] == 0]          # (kinetic + elastic + barrier + gravity's potential)
    assert st["contact_energy"].max() > 0 and (np.diff(energy) <= 1e-9 * np.abs(energy).max()).all()
    assert np.abs(one["x"] - two["x"]).max() < 1e-8 * np.abs(one["x"]).max()


def test_an_adaptive_barrier_stiffens_at_the_impact_and_relaxes_after(tmp_path):
    """-contact_kappa adaptive on `drop_floor`: kappa is its minimum (the default 0.1 E / dhat) until the bar nears
    the floor, is raised by the balance against the bar's inertia and weight while it presses (measured: up to 2.4x at
    the first bounce), never above 100x, and is back at its minimum once the bar has left the floor; the stiffer barrier
    holds the bar farther from the floor than the fixed one at the same step; no node below the floor; the barrier's
    energy is in energy_total; the same answer on 2 ranks."""
    args = ["run", "drop_floor", "-final_time", 0.75, "-frames_per_second", 40]
    run_ok(args + ["-output", tmp_path / "fixed.h5"])
    run_ok(args + ["-contact_kappa", "adaptive", "-output", tmp_path / "a1.h5"])
    run_ok(args + ["-contact_kappa", "adaptive", "-output", tmp_path / "a2.h5"], nprocs=2)
    fixed, one, two = (read_h5(tmp_path / n) for n in ("fixed.h5", "a1.h5", "a2.h5"))
    k, kf = one["stats"]["contact_kappa"], fixed["stats"]["contact_kappa"]
    lo = kf[np.isfinite(kf)].max()
    assert np.allclose(kf[np.isfinite(kf)], lo)                      # (fixed: one kappa throughout)
    ratio = k / lo
    touching = one["stats"]["contact_nodes"] > 0
    assert ratio[np.isfinite(ratio)].min() == pytest.approx(1.0) and 1.5 < np.nanmax(ratio) <= 100.0
    assert ratio[~touching & (one["stats"]["time"] < 0.3)] == pytest.approx(1.0)
    assert ratio[-1] == pytest.approx(1.0) and not touching[-1]    # (off the floor again at t = 0.75)
    i = int(np.nanargmax(ratio))
    assert one["stats"]["contact_dmin"][i] > fixed["stats"]["contact_dmin"][i]
    assert one["x"][:, :, 2].min() > -2.5
    assert np.abs(one["x"] - two["x"]).max() < 1e-8 * np.abs(one["x"]).max()
    assert np.allclose(two["stats"]["contact_kappa"], k, rtol=1e-8, equal_nan=True)


def test_generalized_alpha_keeps_the_floor_and_energy_momentum_conserves_through_the_bounce(tmp_path):
    """-integrator ts: contact acts at the step's end state X1 (the SNES unknown the pre-check keeps off the floor),
    the predictor is replaced by the step's start where it lies through the floor. drop_floor through the bounce:
    no node below the floor in any frame with generalized-alpha (its energy may rise between steps by at most 1e-3 of
    the impact's kinetic energy: the scheme is not monotone) nor with -energy_momentum (the barrier by a discrete
    gradient from x^n to x1), which without damping keeps energy_total to 1e-5 of that kinetic energy over the run;
    generalized-alpha gives the same answer on 2 ranks."""
    args = ["run", "drop_floor", "-integrator", "ts", "-final_time", 0.5, "-frames_per_second", 40]
    run_ok(args + ["-output", tmp_path / "a.h5"])
    run_ok(args + ["-output", tmp_path / "a2.h5"], nprocs=2)
    run_ok(args + ["-energy_momentum", "-ts_alpha_radius", 1, "-damping", 0, "-output", tmp_path / "m.h5"])
    one, two, em = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "a2.h5"), read_h5(tmp_path / "m.h5")
    assert np.abs(one["x"] - two["x"]).max() < 1e-8 * np.abs(one["x"]).max()
    for got, tol in ((one, 1e-3), (em, 1e-5)):
        z = got["x"][:, :, 2]
        assert z.min() > -2.5 and z.min() < -2.5 + 0.02
        st = got["stats"]
        ok = st["rejected"] == 0
        energy, scale = st["energy_total"][ok], st["kinetic"][ok].max()
        assert st["contact_energy"][ok].max() > 0 and scale > 1e5
        if got is one:
            assert np.diff(energy).max() <= tol * scale, np.diff(energy).max() / scale
        else:
            assert np.abs(energy - energy[0]).max() <= tol * scale, np.abs(energy - energy[0]).max() / scale


@pytest.mark.parametrize("extra,words", [
    (["-obstacle", "plane:0,0,1,0"], ("inside", "start")),
    (["-obstacle", "cone:0,0,1,0"], ("-obstacle", "plane:")),
    (["-obstacle", "sphere:0,0,9,-1"], ("radius",)),
    (["-obstacle", "plane:0,0,0,1"], ("normal",)),
    (["-obstacle", "plane:0,0,1,-3", "-obstacle_motion", "0,0"], ("-obstacle_motion",)),
    (["-obstacle", "plane:0,0,1,-3", "-contact_dhat", "0"], ("-contact_dhat",)),
    (["-obstacle", "mesh:/nonexistent/plate.stl"], ("-obstacle", "no such file")),
    (["-obstacle", "box:1,1,1,0,2,2"], ("-obstacle", "corner")),
    (["-obstacle", "box:0,0,0,1,1"], ("-obstacle", "six numbers")),
    (["-obstacle", "plane:0,0,1,-3", "-contact_friction", "-0.1"], ("-contact_friction",)),
])
def test_bad_contact_input_is_one_line(tmp_path, extra, words):
    p = hyperelastic(["run", "bend", "-output", tmp_path / "o.h5", "-final_time", 0.01] + extra)
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode != 0 and len(lines) == 1 and lines[0].startswith("hyperelastic: error:"), p.stderr
    assert all(w in lines[0] for w in words), lines[0]
    assert not os.path.exists(tmp_path / "o.h5")


# --- self-contact (-contact_self): two blocks of one mesh pressed together ------------------------------------------
EXAMPLES = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples")


@pytest.fixture(scope="module")
def stack(tmp_path_factory):
    """examples/stack.geo meshed at size 0.25 (two unit cubes 0.05 apart, ~820 tets)."""
    path = tmp_path_factory.mktemp("stack") / "stack.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "stack.geo"), "--size", 0.25, "-o", path])
    return path


def _boundary_triangles(tetra):
    """The faces of the tets that belong to one tet only (the output's own surface, found without the app)."""
    faces = np.concatenate([tetra[:, [1, 2, 3]], tetra[:, [0, 3, 2]], tetra[:, [0, 1, 3]], tetra[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def test_blocks_pressed_together_carry_one_blocks_homogeneous_compression(tmp_path, stack):
    """examples/stack.opts: the lid pushes the upper block 0.25 down onto the lower one across a gap of 0.05 (self-
    contact between two pieces of one mesh, frictionless, quasi-static). Both blocks then carry the homogeneous uniaxial
    compression of one unit block shortened by (0.2 + the barrier's final gap)/2: its reaction equals the stack's to
    0.3% (measured 0.06%). Independently of the contact code, at every frame: the upper block stays above the lower
    one, and the output's surface does not intersect itself (ipctk.has_intersections). The contact forces are internal
    (they sum to 0); the matrix-free tangent (-jacobian shell, the pairs' blocks in its apply) gives the same frames
(to t = 0.5)."""
    ipctk = pytest.importorskip("ipctk")
    p = run_ok(["run", os.path.join(EXAMPLES, "stack.opts"), "-mesh", stack, "-output", tmp_path / "s.h5"])
    got = read_h5(tmp_path / "s.h5")
    X, tets, st = got["points"], got["tetra"], got["stats"]
    upper = X[:, 2] > 1.02
    surface = _boundary_triangles(tets)
    edges = ipctk.edges(surface)
    for xf in got["x"]:
        assert xf[upper, 2].min() > xf[~upper, 2].max()
        assert not ipctk.has_intersections(ipctk.CollisionMesh(X, edges, surface), xf)
    ok = st["rejected"] == 0
    gap = float(st["contact_dmin"][ok][-1])
    assert 0 < gap < 0.0025 and st["contact_pairs"][ok][-1] > 0 and st["contact_energy"][ok][-1] > 0
    f_lid = _forces(p.stderr, "reaction lid")
    assert np.abs(_forces(p.stderr, "load contact")).max() < 1e-9 * abs(f_lid[2])
    # self-contact's results (issue 70): the pairs carry the lid's force across the unit face (measured 0.03%: the
    # pairs' forces are not all along z), their forces balance, and the output's pressure field integrates to it
    # over the nodes of status -1 with areas computed here from the output's own surface (its facing faces, z = 1, 1.05)
    last = np.flatnonzero(ok)[-1]
    assert abs(st["self_carried"][last] - abs(f_lid[2])) < 1e-3 * abs(f_lid[2])
    assert st["self_area"][last] == pytest.approx(1.0, abs=1e-12)
    assert np.abs([st[f"self_F{c}"][last] for c in "xyz"]).max() < 1e-12 * abs(f_lid[2])
    fields = read_h5(tmp_path / "s.h5", frames=True)["frames"][-1]
    pressed = fields["contact_status"] == -1
    facing = surface[np.ptp(X[surface][:, :, 2], axis=1) < 1e-12]
    facing = facing[np.isclose(X[facing[:, 0], 2], 1.0) | np.isclose(X[facing[:, 0], 2], 1.05)]
    corners = X[facing]
    node_area = np.zeros(len(X))
    np.add.at(node_area, facing, np.repeat(0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2]
                                                                          - corners[:, 0]), axis=1)[:, None] / 3, 3, 1))
    assert pressed.sum() == 62 and np.isclose(0.5 * node_area[pressed].sum(), 1.0, rtol=1e-12)
    carried = 0.5 * (fields["contact_pressure"][pressed] * node_area[pressed]).sum()
    assert carried == pytest.approx(st["self_carried"][last], rel=1e-10)
    text = hyperelastic(["report", tmp_path / "s.h5", "--contact"]).stdout
    assert f"self-contact (the surface against itself): carries {st['self_carried'][last]:.6g}, area 1, " in text, text
    assert "62 nodes in contact" in text
    cube = tmp_path / "cube.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "cube.geo"), "--size", 0.25, "-o", cube])
    q = run_ok(["run", "bend", "-mesh", cube, "-quasistatic", "-effects", "elasticity,fixed,prescribed",
                "-fix", "zmin:z,xmin:x,ymin:y", "-prescribe_faces", "zmax:z",
                "-prescribe_uz", f"-{(0.2 + gap) / 2!r}*t", "-dt", 0.1, "-output", tmp_path / "c.h5"])
    f_one = _forces(q.stderr, "reaction zmax")
    assert abs(f_lid[2] - f_one[2]) < 3e-3 * abs(f_one[2]), (f_lid, f_one)
    run_ok(["run", os.path.join(EXAMPLES, "stack.opts"), "-mesh", stack, "-jacobian", "shell", "-final_time", 0.5,
            "-output", tmp_path / "sh.h5"])
    shell = read_h5(tmp_path / "sh.h5")["x"]                   # (pressed from t = 0.2 on)
    assert np.abs(shell - got["x"][:len(shell)]).max() < 1e-6 * np.abs(got["x"][-1] - X).max()


def test_the_assembled_operator_couples_pairs_as_the_matrix_free_one_does(petsc, stack):
    """The pairs' blocks between surface nodes, applied beside the assembled tangent (jacobians.Coupled: an AIJ of the
    couplings alone, in global numbering), multiply as the matrix-free tangent's apply does, at a state where the
    blocks are 1e-3 apart (thousands of coupling entries) and surface nodes on the symmetry planes are held in one
    direction (their rows and columns left out; each of the two omissions alone changes the product by ~1e-3)."""
    pytest.importorskip("ipctk")
    from conftest import make_model
    from test_operators import apply
    from hyperelastic.solving import jacobians
    system = make_model(petsc, os.path.join(EXAMPLES, "stack.opts"), [("mesh", str(stack))]).system
    X0 = system.space.X
    x = X0.copy()
    x[X0[:, 2] > 1.02, 2] -= 0.049                                      # (the upper block down to a gap of 1e-3)
    x += 1e-4 * np.random.default_rng(1).standard_normal(x.shape)
    system.begin_step(0.1, 0.1, x.ravel().copy(), np.zeros(x.size))
    X = system.global_state(x.ravel())
    system.linearize(X)
    effect = next(e for e in system.effects if hasattr(e, "coupling_entries"))
    assert effect.coupling is not None and effect.coupling.nnz > 1000
    assert system.cmask.reshape(-1, 3)[effect.nodes].any()            # (held dofs among the surface's)
    a = jacobians.make(system, "assembled")
    a.update()
    V = X.duplicate()
    V.setRandom()
    ya, ys = apply(a.operator, V), apply(jacobians.make(system, "shell").mat, V)
    assert np.abs(ya - ys).max() <= 1e-12 * np.abs(ys).max()


def test_self_contact_in_dynamics_on_two_ranks_and_with_generalized_alpha(tmp_path, stack):
    """The stack with inertia (the lid's motion now drives the upper block dynamically): backward Euler gives the same
    frames on 1 and 2 ranks (the gathered surface and its pairs' couplings); -integrator ts (contact at the step's end
    state) meets the lower block without its surface intersecting in any frame (ipctk.has_intersections)."""
    ipctk = pytest.importorskip("ipctk")
    args = ["run", os.path.join(EXAMPLES, "stack.opts"), "-mesh", stack, "-quasistatic", 0, "-effects",
            "elasticity,inertia,fixed,prescribed,contact", "-final_time", 0.3]
    run_ok(args + ["-output", tmp_path / "a.h5"])
    run_ok(args + ["-output", tmp_path / "b.h5"], nprocs=2)
    run_ok(args + ["-integrator", "ts", "-output", tmp_path / "t.h5"])
    one, two, ts = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5"), read_h5(tmp_path / "t.h5")
    assert one["stats"]["contact_pairs"][-1] > 0 and ts["stats"]["contact_pairs"][-1] > 0
    assert np.abs(one["x"] - two["x"]).max() < 1e-9
    surface = _boundary_triangles(ts["tetra"])
    mesh = ipctk.CollisionMesh(ts["points"], ipctk.edges(surface), surface)
    assert not any(ipctk.has_intersections(mesh, xf) for xf in ts["x"])


def test_a_triangulated_plate_presses_as_the_plane_does(tmp_path):
    """`press` with its plate given as two triangles in an .obj file (-obstacle mesh:FILE, moving by the scene's
    -obstacle_motion; IPC's point-triangle and edge-edge pairs through ipctk): no node of the end ever passes the
    plate (every frame, from the output alone), the end stops within dhat of it, and the contact force is the plane's
    within 0.1% (measured 0.02%; the two triangles' shared edge makes the pressure less even than the plane's). Newton
    converges as on the plane (a median of 3 iterations a step: the plate's pairs' tangent is exact in the body's
    unknowns; projected pair by pair with the plate's vertices it took 38-55), and it takes the plane's steps."""
    plate = tmp_path / "plate.obj"
    plate.write_text("v 5.005 -3 -3\nv 5.005 3 -3\nv 5.005 3 3\nv 5.005 -3 3\nf 1 2 3\nf 1 3 4\n")
    p = run_ok(["run", "press", "-obstacle", f"mesh:{plate}", "-output", tmp_path / "m.h5"])
    got = read_h5(tmp_path / "m.h5")
    end = np.isclose(got["points"][:, 0], got["points"][:, 0].max())
    for t, xf in zip(got["time"], got["x"]):
        assert xf[end, 0].max() < 5.005 - 2 * min(t, 1)
    assert got["x"][-1][end, 0].min() > 3.005 - 0.02
    q = run_ok(["run", "press", "-output", tmp_path / "p.h5"])
    f_mesh, f_plane = _forces(p.stderr, "load contact"), _forces(q.stderr, "load contact")
    assert abs(f_mesh[0] - f_plane[0]) < 1e-3 * abs(f_plane[0]), (f_mesh, f_plane)
    stats = [read_h5(tmp_path / f)["stats"] for f in ("m.h5", "p.h5")]
    its = [np.median(st["newton_its"][st["rejected"] == 0]) for st in stats]
    assert its[0] <= its[1], its
    # and takes the plane's steps: its first step's start carries the end's nodes the plate reaches along with it
    # (SelfContact.pushed; it rejected 6 steps, down to h/64, pushing nothing), and neither rejects any (one each
    # before the eighteenth session: a push was refused beyond 0.3 of a surface edge, now where a cell would invert)
    assert [int(st["rejected"].sum()) for st in stats] == [0, 0] and len(stats[0]["step"]) == len(stats[1]["step"])
    # the plate's results (issue 70 item 2, for triangulated obstacles): its force each accepted step is the forces
    # table's `load contact` (the gradient over the plate's vertices: minus the body's share of its pairs), its contact
    # area the plane's, and `report --contact` reads them with the contact pressure and status fields
    m, ok = stats[0], stats[0]["rejected"] == 0
    for c in "xyz":
        assert np.allclose(m[f"obstacle1_F{c}"][ok], m[f"load_contact_F{c}"][ok], rtol=1e-9, atol=1e-9 * abs(f_plane[0]))
    assert abs(m["obstacle1_area"][-1] - stats[1]["obstacle1_area"][-1]) <= 1e-12 * stats[1]["obstacle1_area"][-1]
    lines = [next(ln for ln in run_ok(["report", tmp_path / f, "--contact"]).stdout.splitlines() if "obstacle1" in ln)
             for f in ("m.h5", "p.h5")]
    assert "obstacle1 mesh:" in lines[0] and lines[0].split("nodes in contact")[0].split()[-1] == \
        lines[1].split("nodes in contact")[0].split()[-1], lines
    # on 2 ranks the same (the results gather the positions on every rank: rank 0 alone had left the other waiting)
    run_ok(["run", "press", "-obstacle", f"mesh:{plate}", "-final_time", 0.4, "-output", tmp_path / "two.h5"], nprocs=2)
    two = read_h5(tmp_path / "two.h5")["stats"]
    n = len(two["step"])
    assert n > 3 and np.nanmax(np.abs(m["obstacle1_Fx"][:n])) > 0
    for col in ("obstacle1_Fx", "obstacle1_area", "self_carried"):
        assert np.allclose(two[col], m[col][:n], rtol=1e-8, atol=1e-12 * abs(f_plane[0]), equal_nan=True), col


def test_obstacles_are_numbered_in_the_order_given(tmp_path):
    """-obstacle lists a triangulated plate far from the bar before the press's plane: the statistics name the plate
    obstacle1 (no force: it touches nothing) and the plane obstacle2 (the press's force), whichever effect computes
    each (the analytic obstacles' and the triangles' were each numbered from 1)."""
    plate = tmp_path / "far.obj"
    plate.write_text("v -20 -3 -3\nv -20 3 -3\nv -20 3 3\nv -20 -3 3\nf 1 2 3\nf 1 3 4\n")
    run_ok(["run", "press", "-obstacle", f"mesh:{plate};plane:-1,0,0,-5.005", "-obstacle_motion", "0,0,0;-2*t,0,0",
            "-final_time", 0.3, "-output", tmp_path / "o.h5", "-quiet"])
    st = read_h5(tmp_path / "o.h5")["stats"]
    ok = st["rejected"] == 0
    assert (st["obstacle1_Fx"][ok] == 0).all() and (st["obstacle2_Fx"][ok][-1] < 0)
    assert np.allclose(st["obstacle2_Fx"][ok], st["load_contact_Fx"][ok], rtol=1e-9)


def test_hertz_contact_radius_and_peak_pressure(tmp_path):
    """examples/hertz.opts: a quarter of a linear-elastic half ball (R = 1, E = 1e6, nu = 0.3) pressed onto a rigid
    plane (3,062 tets graded to 0.02 at the pole). From the output alone: each contact node's force is kappa A_i
    |b'(d_i)| (A_i its share of the ball's reference area; b' by the IPC Toolkit), F the full ball's total; for
    Hertz's pressure p0 sqrt(1 - r^2/a^2), <r^2> weighted by the pressure is (2/5) a^2, so a = sqrt(5/2 <r^2>_f).
    Against a = (3 F R / (4 E*))^(1/3): within 2% (measured 0.4%; 1.1% and 1.3% at edges 0.01 and 0.005, where the
    barrier's reach dhat = 1.7e-3 blurs the edge of the contact); the pole's pressure against p0 = 3F/(2 pi a^2)
    within 8% (5.3%, then 2.5% and 1.8% on those meshes)."""
    ipctk = pytest.importorskip("ipctk")
    msh = tmp_path / "hertz.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "hertz.geo"), "--size", 0.2, "--graded", "-o", msh])
    run_ok(["run", os.path.join(EXAMPLES, "hertz.opts"), "-mesh", msh, "-output", tmp_path / "h.h5"])
    got = read_h5(tmp_path / "h.h5")
    X, x = got["points"], got["x"][-1]
    tri = _boundary_triangles(got["tetra"])
    c = X[tri].mean(axis=1)
    ball = tri[(c[:, 0] > 1e-9) & (c[:, 1] > 1e-9) & (c[:, 2] < 1 - 1e-9)]
    area = 0.5 * np.linalg.norm(np.cross(X[ball[:, 1]] - X[ball[:, 0]], X[ball[:, 2]] - X[ball[:, 0]]), axis=1)
    A = np.zeros(len(X))
    np.add.at(A, ball, np.repeat(area[:, None] / 3, 3, axis=1))
    E, nu, R = 1e6, 0.3, 1.0
    dhat = 1e-3 * np.linalg.norm(X.max(0) - X.min(0))            # (the defaults: README)
    kappa = 0.1 * E / dhat
    on = A > 0
    d = x[on, 2] + 0.001                                         # (the plane z = -0.001)
    p = np.array([-kappa * ipctk.barrier_first_derivative(di, dhat) if di < dhat else 0.0 for di in d])
    f, r2 = A[on] * p, X[on, 0] ** 2 + X[on, 1] ** 2
    F = 4 * f.sum()
    a = (3 * F * R / (4 * E / (1 - nu ** 2))) ** (1 / 3)
    assert 0.1 < a < 0.2, a
    assert abs(np.sqrt(2.5 * (f * r2).sum() / f.sum()) / a - 1) < 0.02
    assert abs(p[np.argmin(r2)] / (3 * F / (2 * np.pi * a * a)) - 1) < 0.08


SLIDE = ["run", "bend", "-effects", "elasticity,inertia,gravity,body_force,contact", "-gravity", "0,0,-9.81",
         "-obstacle", "plane:0,0,1,-2.02", "-contact_friction", 0.5, "-E", 1e8, "-final_time", 0.6, "-dt", 0.01,
         "-frames_per_second", 100, "-step_forces"]


def _centre(got):
    """Centre of mass (x, z) per frame: the vertices weighted by a quarter of their tets' volumes (exact for P1)."""
    P, T = got["points"], got["tetra"]
    vol = np.abs(np.einsum("ij,ij->i", np.cross(P[T[:, 1]] - P[T[:, 0]], P[T[:, 2]] - P[T[:, 0]]),
                           P[T[:, 3]] - P[T[:, 0]])) / 6
    w = np.zeros(len(P))
    np.add.at(w, T, np.repeat(vol[:, None] / 4, 4, axis=1))
    return got["x"][:, :, 0] @ (w / w.sum()), got["x"][:, :, 2] @ (w / w.sum())


def _coulomb_slide(got, push, mu=0.5, g=9.81, m=160000.0, h=0.01):
    """(each late step's friction over mu x its starting normal force, the lag-corrected acceleration of
    test_coulomb_friction_slides_and_sticks) of a sliding run."""
    st = got["stats"]
    ok = st["rejected"] == 0
    fx, fz, ts = st["load_contact_Fx"][ok], st["load_contact_Fz"][ok], st["time"][ok]
    late = ts > 0.2
    ratio = -fx[1:][late[1:]] / (mu * fz[:-1][late[1:]])
    xc, zc = _centre(got)
    t = got["time"]
    i, j = np.argmin(abs(t - 0.2)), np.argmin(abs(t - 0.55))
    v = lambda a, k: (a[k] - a[k - 1]) / (t[k] - t[k - 1])           # noqa: E731
    lam = lambda k: fz[np.argmin(abs(ts - t[k]))]                     # noqa: E731
    acc = ((v(xc, j) - v(xc, i)) + mu * (v(zc, j) - v(zc, i))) / (t[j] - t[i]) \
        - mu * h * (lam(j) - lam(i)) / (m * (t[j] - t[i]))
    return ratio, acc


def test_friction_on_a_triangulated_floor_is_the_planes(tmp_path):
    """The sliding case of test_coulomb_friction_slides_and_sticks on a floor of two triangles (-obstacle mesh:,
    friction through the IPC Toolkit's TangentialCollisions and FrictionPotential, lagged the same way): the same
    Coulomb law (to 1e-3) and the same acceleration (to 1e-3 of g)."""
    floor = tmp_path / "floor.obj"
    floor.write_text("v -30 -30 -2.02\nv 30 -30 -2.02\nv 30 30 -2.02\nv -30 30 -2.02\nf 1 2 3\nf 1 3 4\n")
    args = [a if a != "plane:0,0,1,-2.02" else f"mesh:{floor}" for a in SLIDE]
    run_ok(args + ["-body_force", f"{0.8 * 1000 * 9.81!r},0,0", "-output", tmp_path / "m.h5"])
    ratio, acc = _coulomb_slide(read_h5(tmp_path / "m.h5"), 0.8)
    assert np.abs(ratio - 1).max() < 1e-3, ratio
    assert abs(acc - 0.3 * 9.81) < 1e-3 * 9.81, acc


def test_coulomb_friction_slides_and_sticks(tmp_path):
    """The bar (10 x 4 x 4 m, rho 1000, E 1e8) dropped 0.02 m onto a floor with friction mu = 0.5, pushed along x by a
    body force. Pushed with 0.8 rho g it slides: every step's friction is mu times the normal force the step started
    with (the lag; forces table, to 1e-3), and the centre of mass obeys m (dv_x + mu dv_z) = (F - mu m g) dt, corrected
    for that lag, to 1e-3 (backward Euler's momentum: the velocities are the frames' backward differences). Pushed with
    0.3 rho g it sticks: the friction equals the push (0.6 mu N, to 1e-3 once the landing has rung out) and the bar
    creeps at the smoothed friction's speed, f1(v/eps_v) = 0.6, v = (1 - sqrt(0.4)) eps_v (IPC's static friction is a
    steep viscous law below eps_v). 1 and 2 ranks agree."""
    g, mu = 9.81, 0.5
    for push, name in ((0.8, "slide"), (0.3, "stick")):
        run_ok(SLIDE + ["-body_force", f"{push * 1000 * g!r},0,0", "-output", tmp_path / f"{name}.h5"])
        got = read_h5(tmp_path / f"{name}.h5")
        st = got["stats"]
        ok = st["rejected"] == 0
        fx, fz, ts = st["load_contact_Fx"][ok], st["load_contact_Fz"][ok], st["time"][ok]
        late = ts > (0.2 if name == "slide" else 0.45)           # (sticking settles after the landing's ring)
        ratio = -fx[1:][late[1:]] / (mu * fz[:-1][late[1:]])
        xc, zc = _centre(got)
        t = got["time"]
        if name == "slide":
            ratio, acc = _coulomb_slide(got, push)
            assert np.abs(ratio - 1).max() < 1e-3, ratio
            assert abs(acc - (push - mu) * g) < 1e-3 * g, acc
            assert st["contact_sliding"][ok][-1] > 0
        else:
            assert np.abs(ratio - push / mu).max() < 1e-3 * push / mu, ratio
            creep = (xc[-1] - xc[np.argmin(abs(t - 0.3))]) / (t[-1] - 0.3)
            assert abs(creep / ((1 - np.sqrt(0.4)) * 1e-3) - 1) < 0.15, creep
            assert st["contact_sliding"][ok][-1] == 0
            run_ok(SLIDE + ["-body_force", f"{push * 1000 * g!r},0,0", "-output", tmp_path / "two.h5"], nprocs=2)
            assert np.abs(read_h5(tmp_path / "two.h5")["x"] - got["x"]).max() < 1e-8     # (the same on 2 ranks)


def test_a_slot_pressed_shut_never_passes_through_itself(tmp_path):
    """examples/slot.opts: one body (a block with a slot) pressed until the slot's faces touch and press (self-contact
    within one connected body, 1,873 tets). Checked from the output alone: in no frame does its surface intersect
    itself (ipctk.has_intersections); the slot's faces met (pairs within dhat from t = 0.5 on, never at distance 0),
    their forces are internal (sum 0); 2 ranks give 1 rank's frames."""
    ipctk = pytest.importorskip("ipctk")
    msh = tmp_path / "slot.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "slot.geo"), "--size", 0.3, "-o", msh])
    args = ["run", os.path.join(EXAMPLES, "slot.opts"), "-mesh", msh]
    p = run_ok(args + ["-output", tmp_path / "a.h5"])
    got = read_h5(tmp_path / "a.h5")
    surface = _boundary_triangles(got["tetra"])
    edges = ipctk.edges(surface)
    for xf in got["x"]:
        assert not ipctk.has_intersections(ipctk.CollisionMesh(got["points"], edges, surface), xf)
    st = got["stats"]
    late = st["time"] >= 0.5 - 1e-9
    assert (st["contact_pairs"][late] > 0).all() and (st["contact_dmin"][late] > 0).all()
    assert (st["contact_pairs"][st["time"] < 0.35] == 0).all()
    assert np.abs(_forces(p.stderr, "load contact")).max() < 1e-6 * np.abs(_forces(p.stderr, "reaction top")).max()
    run_ok(args + ["-final_time", 0.6, "-output", tmp_path / "b.h5"], nprocs=2)
    two = read_h5(tmp_path / "b.h5")
    n = len(two["x"])
    assert np.abs(two["x"] - got["x"][:n]).max() < 1e-8


def test_a_flattened_rubber_tube_closes_on_itself_with_the_mixed_formulation(tmp_path):
    """Issue 72 item 4: examples/tube.opts, nearly incompressible rubber (nu = 0.499, quadratic tetrahedra: the mixed
    P2-P1 formulation, its pressure untouched by the barrier) squeezed between two plates until the tube's inner walls
    press on each other (self-contact's pairs couple distant displacement dofs beside K_uu: jacobians.Coupled). From
    the output alone: no frame's surface intersects itself (ipctk.has_intersections); the walls press (pairs, a carried
    force) and their forces sum to zero; the plates' forces are equal and opposite. Continued from a checkpoint before
    the walls meet, 2 ranks with the tangent by blocks (the field split, the pairs beside K_uu) give the frames of 1
    rank with it as one AIJ of displacements and pressures under LU (the pairs beside it in the unknowns' numbering:
    MixedSystem.unknown_numbers), to 1e-8."""
    ipctk = pytest.importorskip("ipctk")
    msh = tmp_path / "tube.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "tube.geo"), "--size", 0.1, "--order", 2, "-o", msh])
    a, b = tmp_path / "a.h5", tmp_path / "b.h5"
    run_ok(["run", os.path.join(EXAMPLES, "tube.opts"), "-mesh", msh, "-final_time", 1.1, "-checkpoint_every", 1,
            "-pc_type", "lu", "-quiet", "-output", a])
    shutil.copy(a, b)
    run_ok(["run", "--restart", a, "-final_time", 1.13, "-quiet"])
    run_ok(["run", "--restart", b, "-final_time", 1.13, "-pc_type", "fieldsplit", "-quiet"], nprocs=2)
    got, two = read_h5(a), read_h5(b)
    assert got["attrs"]["formulation"] == "mixed"
    surface = _boundary_triangles(got["tetra"])
    collision = ipctk.CollisionMesh(got["points"], ipctk.edges(surface), surface)
    assert not any(ipctk.has_intersections(collision, xf) for xf in got["x"])
    st = got["stats"]
    last = np.flatnonzero(st["rejected"] == 0)[-1]
    assert st["contact_pairs"][last] > 0 and st["self_carried"][last] > 10, st["self_carried"][last]
    assert np.abs([st[f"self_F{c}"][last] for c in "xyz"]).max() < 1e-10 * st["self_carried"][last]
    assert st["obstacle1_Fy"][last] == pytest.approx(-st["obstacle2_Fy"][last], rel=1e-6)
    assert np.allclose(two["time"], got["time"]) and np.abs(two["x"] - got["x"]).max() < 1e-8


# --- held nodes and contact: the old squeeze and invert scenes with -contact_self ---------------------------------
def test_squeeze_with_self_contact_never_passes_through_itself(tmp_path):
    """squeeze (St.VK, both ends prescribed to half the length) folds its sides near the ends: without contact its
    surface crosses itself from t = 0.66 on (measured: every frame from there); with -contact_self no frame's surface
    does (ipctk.has_intersections on the output alone), the folds press (pairs within dhat), and the held end faces
    never carry the surface through itself: a step whose every start would (x^n with the held nodes at their targets)
    is retried shorter. To t = 0.8."""
    ipctk = pytest.importorskip("ipctk")
    run_ok(["run", "squeeze", "-contact_self", "-final_time", 0.8, "-output", tmp_path / "s.h5", "-quiet"])
    got = read_h5(tmp_path / "s.h5")
    surface = _boundary_triangles(got["tetra"])
    mesh = ipctk.CollisionMesh(got["points"], ipctk.edges(surface), surface)
    assert not any(ipctk.has_intersections(mesh, xf) for xf in got["x"])
    assert got["time"][-1] == pytest.approx(0.8)
    assert np.nanmax(got["stats"]["contact_pairs"]) > 0


@pytest.mark.parametrize("extra,words,when", [
    # invert prescribes both end faces through each other (they meet at t = 0.5): one step to t = 0.6 is refused at
    # once, at the time the held triangles meet (a path straight in t: no smaller step helps)
    (["invert", "-contact_self", "-dt", 0.6, "-final_time", 0.6], ("held triangles", "no smaller step"), 0.5),
    # a plane moving into the bar's clamped end (it reaches x = -5 at t = 2.5e-4)
    (["bend", "-obstacle", "plane:1,0,0,-5.005", "-obstacle_motion", "20*t,0,0"],
     ("-obstacle plane:1,0,0,-5.005", "held node"), 2.5e-4),
])
def test_held_nodes_driven_into_contact_stop_the_run_at_once(tmp_path, extra, words, when):
    import re
    p = hyperelastic(["run"] + extra + ["-output", tmp_path / "o.h5", "-quiet"])
    assert p.returncode == 3, p.stderr
    line = p.stderr.strip().splitlines()[-1]
    assert all(w in line for w in words), line
    assert float(re.search(r"into contact at about t=(\S+):", line).group(1)) == pytest.approx(when, rel=1e-4)
    got = read_h5(tmp_path / "o.h5")                    # (the start's frame kept, no attempt solved)
    assert len(got["x"]) == 1 and len(got["stats"].get("step", ())) == 0


def test_an_obstacle_through_the_body_at_the_start_names_the_first_crossing(tmp_path):
    plate = tmp_path / "plate.obj"
    plate.write_text("v 0 -5 -5\nv 0 5 -5\nv 0 5 5\nv 0 -5 5\nf 1 2 3\nf 1 3 4\n")
    p = hyperelastic(["run", "bend", "-obstacle", f"mesh:{plate}", "-output", tmp_path / "o.h5"])
    lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
    assert p.returncode == 2 and len(lines) == 1, p.stderr
    assert "intersects" in lines[0] and "the edge of nodes" in lines[0] and "crosses the triangle of obstacle" in lines[0]


def test_a_twisted_rod_coils_onto_itself_and_never_through(tmp_path):
    """examples/coil.opts (twist3 continued: a rod of aspect 20 turned four times while its ends approach) on a coarse
    mesh (1,310 tets, dt 0.01, to t = 0.95): the rod buckles into a loop that meets itself (pairs within dhat from
    t ~ 0.88, measured), and no frame's surface intersects itself (ipctk.has_intersections on the output alone).
    Without -contact_self the same rod passes through itself (measured: at t = 0.945 on 3,007 tets, at t = 1.2 here)."""
    ipctk = pytest.importorskip("ipctk")
    mesh = tmp_path / "coil.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "coil.geo"), "--size", 0.04, "-o", mesh])
    run_ok(["run", os.path.join(EXAMPLES, "coil.opts"), "-mesh", mesh, "-final_time", 0.95, "-dt", 0.01,
            "-output", tmp_path / "c.h5", "-quiet"])
    got = read_h5(tmp_path / "c.h5")
    st = got["stats"]
    surface = _boundary_triangles(got["tetra"])
    collision = ipctk.CollisionMesh(got["points"], ipctk.edges(surface), surface)
    assert not any(ipctk.has_intersections(collision, xf) for xf in got["x"])
    assert st["contact_pairs"][-1] > 0 and 0 < st["contact_dmin"][-1] < 0.002 and st["rejected"].sum() == 0
    assert np.ptp(got["x"][-1][:, 2]) > 0.2            # (out of its axis: a loop, not a straight twisted rod)


@pytest.mark.parametrize("tan_theta", [0.5, 0.2])
def test_a_block_on_a_tilted_floor_slides_at_its_closed_form_or_sticks(tmp_path, tan_theta):
    """Issue 72 item 3's dynamic closed form: a stiff unit block (E = 1e8, rho = 1000, 100 tets) on a floor with
    Coulomb friction mu = 0.3, gravity tilted by theta (the floor tilted the other way), 0.5 s of backward Euler.
    tan(theta) = 0.5 > mu: it slides with a = g (sin(theta) - mu cos(theta)) (the centroid's motion fitted after
    0.2 s: within 1%, measured 3e-7) and the floor's force on it is mu N (obstacle1_F: friction's with the barrier's;
    the forces table's load contact). tan(theta) = 0.2 < mu: it sticks — the floor's tangential force is tan(theta)
    N (1%) and the block creeps below IPC's smoothing speed eps_v = 1 mm/s (0.43 mm/s) where it would be sliding at
    ~1 m/s without friction."""
    msh = tmp_path / "cube.msh"
    run_ok(["mesh", os.path.join(EXAMPLES, "cube.geo"), "--size", 0.5, "-o", msh])
    g, th, mu = 9.81, math.atan(tan_theta), 0.3
    out = tmp_path / "b.h5"
    run_ok(["run", "bend", "-mesh", msh, "-material", "neohookean", "-E", 1e8, "-nu", 0.3, "-rho", 1000,
            "-effects", "elasticity,inertia,gravity,contact", "-gravity", f"{g * math.sin(th)!r},0,{-g * math.cos(th)!r}",
            "-obstacle", "plane:0,0,1,-0.0005", "-contact_faces", "zmin", "-contact_friction", mu, "-final_time", 0.5,
            "-dt", 0.005, "-frames_per_second", 100, "-quiet", "-output", out])
    r = read_h5(out)
    t, ux = r["time"], (r["x"][:, :, 0] - r["points"][:, 0]).mean(axis=1)
    ratio = r["stats"]["obstacle1_Fx"][-1] / r["stats"]["obstacle1_Fz"][-1]
    assert int(r["stats"]["rejected"].sum()) == 0
    if tan_theta > mu:
        late = t >= 0.2
        a = 2 * np.polyfit(t[late], ux[late], 2)[0]
        want = g * (math.sin(th) - mu * math.cos(th))
        assert abs(a - want) <= 0.01 * want, (a, want)
        assert abs(ratio + mu) <= 1e-3 * mu, ratio
    else:
        assert abs(ratio + tan_theta) <= 0.01 * tan_theta, ratio
        early = np.searchsorted(t, 0.1)
        assert (ux[-1] - ux[early]) / (t[-1] - t[early]) < 1e-3


def test_the_oring_takes_the_steps_it_asks_for(tmp_path):
    """Issue 72 item 2: the quadratic O-ring (examples/oring.opts, 2,904 P2 tets at size 0.1 mm, mixed, nu 0.4995)
    squeezed by a plate that moves 17.65 um a step (-dt 1/30) into a 5 um gap: its first touch and the steps after it
    start from the nodes the plate reaches pushed ahead of it (only those, to dhat; the push carried half-way into the
    cells beside them where one layer would near inversion) and from the last step's rate with the nodes it leaves in
    reach pushed: no step is rejected (8 of 38 attempts were, over the whole squeeze, before the eighteenth session;
    12,028 tets: none now)."""
    msh = tmp_path / "oring.msh"
    run_ok(["mesh", f"{ROOT}/examples/oring.geo", "--size", 0.0001, "--order", 2, "-o", msh])
    run_ok(["run", f"{ROOT}/examples/oring.opts", "-mesh", msh, "-dt", 1 / 30, "-final_time", 0.2,
            "-output", tmp_path / "o.h5", "-quiet"])
    st = read_h5(tmp_path / "o.h5")["stats"]
    assert int(st["rejected"].sum()) == 0 and len(st["time"]) == 6, st["rejected"]
    assert st["obstacle1_Fy"][-1] < 0                  # (it touched: the plate carries a force)
