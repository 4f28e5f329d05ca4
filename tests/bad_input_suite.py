"""The bad-input suite (issue 15): at least 600 distinct bad inputs generated from a seed, each checked
against the README's promise — exit 2 (bad input) or 3 (solver failure), exactly one line on stderr
starting `hyperelastic: error:` and no traceback, within 20 s, and every file that existed before
byte-identical afterwards (no new or removed files either).

    .venv/bin/python tests/bad_input_suite.py [--seed S] [--jobs N] [--only CATEGORY] [--list] [--every K]

runs the whole suite (or every K-th case) and prints the counts by category and outcome;
tests/test_bad_input_suite.py runs the quick subset (every QUICK_EVERY-th case) in `make test`.

Every case runs in a directory of its own holding a previous result (prev.h5 with a checkpoint, and
prev.xdmf), a good mesh, a good scene and an options file; most runs write to prev.h5, so a run that
lost or touched the previous result would fail the check. Progress lines are off (-quiet) so that
the one line is the error.
"""
import argparse
import hashlib
import os
import random
import shutil
import stat
import subprocess
import sys
import tempfile
import time
from collections import Counter
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

import warmrun

HERE = os.path.dirname(os.path.abspath(__file__))
BIN = os.path.dirname(sys.executable)
SEED = 15
TIME_LIMIT = 20.0
QUICK_EVERY = 9


@dataclass
class Case:
    name: str                  # unique
    category: str
    args: list                 # after `hyperelastic`
    setup: object = None       # fn(dir) writing the case's own inputs
    nprocs: int = 1
    words: tuple = ()          # each must appear in the error line
    rcs: tuple = (2, 3)
    fsize: int = 0             # RLIMIT_FSIZE in bytes (a full disk), 0: none
    after: object = None       # fn(dir) -> error text or None: a further check


# ---------------------------------------------------------------------------------------- world
def cube(n=2):
    """A structured tetrahedral mesh of the unit cube, positively oriented."""
    g = np.linspace(0, 1, n + 1)
    P = np.array([[x, y, z] for z in g for y in g for x in g])
    idx = lambda i, j, k: i + (n + 1) * (j + (n + 1) * k)  # noqa: E731
    T = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                v = [idx(i + a, j + b, k + c) for c in (0, 1) for b in (0, 1) for a in (0, 1)]
                for t in ((0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)):
                    T.append([v[q] for q in t])
    T = np.array(T)
    D = np.stack([P[T[:, a]] - P[T[:, 0]] for a in (1, 2, 3)], axis=-1)
    neg = np.linalg.det(D) < 0
    T[neg] = T[neg][:, [0, 2, 1, 3]]
    return P, T


def write_msh(path, points, tets, binary=False):
    import meshio
    meshio.write(path, meshio.Mesh(np.asarray(points, float), [("tetra", np.asarray(tets))]), file_format="gmsh22",
                 binary=binary)


SCENE = """# a good scene: the cube clamped on the left, pulled on the right
-mesh good.msh
-material neohookean
-fix left
-traction 1e4,0,0
-traction_face right
-final_time 0.02
-dt 0.01
"""


# a full disk: the file size limit (ulimit -f) set after MPI is up (MPICH's shared memory needs larger files)
FSIZE_WRAPPER = """import resource, signal, sys
from mpi4py import MPI
lim = int(sys.argv[1])
sys.argv[0] = "hyperelastic"
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
resource.setrlimit(resource.RLIMIT_FSIZE, (lim, lim))
from hyperelastic.cli.main import main
sys.exit(main(sys.argv[2:]))
"""


def hyperelastic_cmd(args, nprocs=1, fsize=0):
    if fsize:
        return [sys.executable, "-c", FSIZE_WRAPPER, str(fsize)] + [str(a) for a in args]
    exe = os.path.join(BIN, "hyperelastic")
    cmd = [exe] + [str(a) for a in args]
    if nprocs > 1:
        mpiexec = shutil.which("mpiexec", path=BIN) or shutil.which("mpiexec")
        cmd = [mpiexec, "-n", str(nprocs)] + cmd
    return cmd


def make_world(d):
    """The inputs every case starts from (copied into its directory)."""
    os.makedirs(d, exist_ok=True)
    P, T = cube()
    write_msh(os.path.join(d, "good.msh"), P, T)
    with open(os.path.join(d, "scene.opts"), "w") as fh:
        fh.write(SCENE)
    with open(os.path.join(d, "solver.opts"), "w") as fh:
        fh.write("-ksp_type cg\n-pc_type jacobi\n")
    p = subprocess.run(hyperelastic_cmd(["run", "scene.opts", "-checkpoint_every", "1", "-output", "prev.h5",
                                         "-quiet"]), cwd=d, capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        raise RuntimeError(f"the previous result could not be made: {p.stderr}")
    p = subprocess.run(hyperelastic_cmd(["run", "scene.opts", "-checkpoint_every", "1", "-output", "ranks.h5", "-quiet"],
                                        nprocs=2), cwd=d, capture_output=True, text=True, timeout=120)
    if p.returncode != 0:
        raise RuntimeError(f"the per-rank result could not be made: {p.stderr}")
    return d


# ---------------------------------------------------------------------------------------- cases
BEND = ["run", "scene.opts", "-quiet", "-output", "prev.h5"]


def typo(rng, word):
    """A misspelling of word: two neighbours swapped, a letter dropped or doubled."""
    for _ in range(20):
        i = rng.randrange(len(word) - 1)
        kind = rng.choice("sdr")
        if kind == "s":
            w = word[:i] + word[i + 1] + word[i] + word[i + 2:]
        elif kind == "d":
            w = word[:i] + word[i + 1:]
        else:
            w = word[:i] + word[i] + word[i:]
        if w != word and "_" not in (w[0], w[-1]) and "__" not in w:
            return w
    return word + "x"


def option_value_cases(rng):
    out = []
    real_bad = ["nan", "inf", "-inf", "1e308", "", "abc", "1,2"]
    kinds = {
        "positive": (["E", "rho", "dt", "frames_per_second", "dt_min", "spring", "kappa", "mu"],
                     real_bad + ["0", "-1", "1e-320"]),
        "final_time": (["final_time"], real_bad + ["-1"]),
        "nu": (["nu"], real_bad + ["0.5", "-1", "2"]),
        "nonnegative": (["damping", "rayleigh_alpha", "rayleigh_beta", "C01"], real_bad + ["-1"]),
        "order": (["order"], ["0", "3", "1.5", "abc", ""]),
        "quadrature": (["quadrature_degree"], ["0", "3", "4", "1.5", "abc", ""]),
        "real": (["traction_twist", "prescribe_amount", "pressure"], real_bad),
        "level": (["level"], ["0", "-1", "1.5", "abc", "", "99", "1e308"]),
        "int": (["checkpoint_every", "dt_grow_after", "mesh_frame"], ["1.5", "abc", "", "-5"]),
        "vector": (["gravity", "traction", "initial_scale", "initial_spin", "initial_rotation", "force",
                    "body_force"],
                   ["1,2", "1,2,3,4", "a,b,c", "nan,0,0", "inf,0,0", "1e308,0,0", "", ",,", "1e-320,0,0"]),
        "choice": (["material", "preset", "jacobian", "assembly", "operator_storage", "integrator", "mass",
                    "prescribe_motion", "formulation", "output_layout"],
                   ["bogus", "", "STVK", "1"]),
        "flag": (["quasistatic", "step_control", "objective", "hessian_projection", "inversion_guard", "incompressible"],
                 ["maybe", "2", "-1", "yes please"]),
        "faces": (["fix", "traction_face", "pressure_faces", "prescribe_faces", "spring_faces", "force_faces"],
                  ["", "nonexistent", "left:w", ":x", "left:xx", "7", "left,", ",left", "left,,right", ","]),
        "names": (["regions", "loads", "effects", "body_force_regions"], ["", "nonexistent", "a b", "x,x", ",",
                                                                        "elasticity,", ",elasticity", "a,,b"]),
        # the rubbers' constants (issue 71): an extensibility, a locking stretch, an Ogden term's modulus and exponent
        "rubber": (["Jm", "lambda_m", "mu1", "alpha1"], real_bad + ["0", "-1", "1", "1e3"]),
        # HGO's (issue 71): its fibres' dispersion and stiffening, a family's direction
        "tissue": (["dispersion", "k2"], real_bad + ["-1", "0.5"]),
        "fibre": (["fibre1", "fibre2"], ["0,0,0", "1,2", "a,b,c", "nan,0,0", "1e308,0,0", ""]),
        # the viscoelastic effect's Prony series (issue 71)
        "prony": (["prony_beta", "prony_tau"], ["", "abc", "nan", "inf", "-1", "1,2", "1,2,3,4,5", "0.1,,0.2"]),
    }
    context = {"pressure_faces": ["-pressure", "1e3"], "prescribe_faces": ["-prescribe_motion", "stretch_x"],
               "prescribe_motion": ["-prescribe_faces", "right"], "pressure": ["-pressure_faces", "right"],
               "prescribe_amount": ["-prescribe_faces", "right", "-prescribe_motion", "stretch_x"],
               "mesh_frame": ["-mesh", "prev.h5"], "regions": [], "loads": [],
               "spring": ["-spring_faces", "right"], "spring_faces": ["-spring", "1e5"], "kappa": ["-material",
               "neohookean_split"], "mu": ["-material", "neohookean_split"], "C01": ["-material", "mooney_rivlin"],
               "Jm": ["-material", "gent"], "lambda_m": ["-material", "arruda_boyce"], "mu1": ["-material", "ogden"],
               "alpha1": ["-material", "ogden"], "dispersion": ["-material", "hgo"], "k2": ["-material", "hgo"],
               "fibre1": ["-material", "hgo", "-k1", "1e5"], "fibre2": ["-material", "hgo", "-fibre1", "1,0,0"],
               "prony_beta": ["-material", "neohookean_split", "-prony_tau", "0.1"],
               "prony_tau": ["-material", "neohookean_split", "-prony_beta", "0.3"],
               "quadrature_degree": ["-order", "2"], "force": ["-force_faces", "right"],
               "force_faces": ["-force", "1,0,0"], "body_force_regions": ["-body_force", "0,0,1"]}
    skip = {("mesh_frame", "-5"), ("initial_spin", "1e-320,0,0"), ("initial_rotation", "1e-320,0,0"),
            ("gravity", "1e-320,0,0"), ("traction", "1e-320,0,0"), ("force", "1e-320,0,0"),
            ("body_force", "1e-320,0,0"),   # valid values (a tiny vector is a vector)
            ("Jm", "1"), ("Jm", "1e3"), ("lambda_m", "1e3"), ("mu1", "1"), ("mu1", "1e3"), ("alpha1", "1"),
            ("alpha1", "-1"), ("mu1", "1e-320"), ("k2", "0.5")}
    for kind, (names, values) in kinds.items():
        for name in names:
            for v in values:
                if (name, v) in skip:
                    continue
                if kind == "vector" and name == "initial_scale" and v == "1e-320,0,0":
                    v = "0,1,1"
                out.append(Case(f"value:{name}={v!r}", "option values", BEND + [f"-{name}", v] + context.get(name, [])))
    petsc_real = ["snes_rtol", "snes_atol", "snes_stol", "ksp_rtol", "ksp_atol", "ts_rtol", "ts_atol", "mat_mffd_err"]
    for name in petsc_real:
        for v in ("-1", "nan", "inf", "abc", ""):
            out.append(Case(f"petsc:{name}={v!r}", "PETSc values", BEND + [f"-{name}", v]))
    for name, bad in (("snes_max_it", "-3"), ("ksp_max_it", "-3"), ("snes_max_funcs", "-5"),
                      ("ksp_gmres_restart", "0"), ("ts_max_snes_failures", "-5"), ("snes_lag_jacobian", "-7")):
        for v in (bad, "1.5", "abc", ""):
            out.append(Case(f"petsc:{name}={v!r}", "PETSc values", BEND + [f"-{name}", v]))
    for name in ("snes_max_it", "ksp_max_it"):        # a limit no solve can converge within
        for v in ("0", str(-rng.randrange(1, 100))):
            out.append(Case(f"petsc:{name}={v}", "PETSc values", BEND + [f"-{name}", v]))
    for v in ("2", "-1"):
        out.append(Case(f"petsc:ts_alpha_radius={v}", "PETSc values",
                        BEND + ["-integrator", "ts", "-ts_alpha_radius", v]))
    types = [("ksp_type", []), ("pc_type", []), ("snes_type", []), ("snes_linesearch_type", []),
             ("ts_type", ["-integrator", "ts"]), ("ts_adapt_type", ["-integrator", "ts"]),
             ("mat_mffd_type", ["-snes_mf"]), ("pc_factor_mat_solver_type", ["-pc_type", "lu"])]
    for name, ctx in types:
        for v in ("nonsense", "mumps" if name == "pc_factor_mat_solver_type" else "NONE!"):
            out.append(Case(f"petsc:{name}={v}", "PETSc values", BEND + ctx + [f"-{name}", v]))
    return out


def unknown_option_cases(rng):
    from hyperelastic.app.catalog import COMMON_PETSC, option_names
    out = []
    for name in dict.fromkeys(option_names()):     # (a name several materials declare is one option)
        if len(name) < 4:
            continue
        w = typo(rng, name)
        out.append(Case(f"typo:{name}->{w}", "unknown options", BEND + [f"-{w}", "1"], words=(f"-{w}",)))
    for name in [n for n in COMMON_PETSC if n.startswith(("snes_", "ksp_", "pc_", "ts_"))][:30]:
        w = typo(rng, name)
        if w.split("_", 1)[0] not in ("snes", "ksp", "pc", "ts"):
            w = name + "x"
        out.append(Case(f"typo:{name}->{w}", "unknown options", BEND + [f"-{w}", "1"], words=(f"-{w}",)))
    for args in (["-materail", "neohookean"], ["-foo"], ["-Material", "snh"], ["-x", "1"], ["-E_", "1e6"],
                 ["-soft_E", "1e6"], ["-pull_faces", "right"], ["-ts_type", "alpha2"], ["-ts_adapt_type", "basic"]):
        out.append(Case(f"unknown:{' '.join(args)}", "unknown options", BEND + args))
    return out


def conflict_cases(rng):
    C = [
        (["-quasistatic", "-initial_spin", "0,0,1"], "-quasistatic"),
        (["-snes_mf", "-jacobian", "shell"], "-snes_mf"),
        (["-snes_mf", "-snes_mf_operator"], "-snes_mf"),
        (["-prescribe_faces", "left", "-prescribe_motion", "stretch_x"], "-fix"),
        (["-prescribe_faces", "bottom:x", "-prescribe_ux", "0.1*t"], "-fix"),
        (["-initial_scale", "0,1,1"], "-initial_scale"),
        (["-dt", "1e308"], "-dt"),
        (["-final_time", "1e308"], "-final_time"),
        (["-final_time", "1e7", "-dt", "1e-3"], "steps"),
        (["-frames_per_second", "1e9"], "frames"),
        (["-dt_min", "0.5"], "-dt_min"),
        (["-integrator", "ts", "-quasistatic"], "-integrator"),
        (["-integrator", "ts", "-ts_type", "euler"], "-ts_type"),
        (["-traction_time", "t", "-traction_ramp", "1"], "-traction_time"),
        (["-prescribe_faces", "right", "-prescribe_x", "X", "-prescribe_ux", "0"], "-prescribe_x"),
        (["-prescribe_faces", "right:y", "-prescribe_x", "X"], "-prescribe_x"),
        (["-regions", "a,a"], "-regions"),
        (["-loads", "p,p", "-p_pressure", "1", "-p_faces", "right"], "-loads"),
        (["-loads", "p", "-p_pressure", "1", "-p_traction", "1,0,0", "-p_faces", "right"], "load 'p'"),
        (["-loads", "p", "-p_pressure", "1"], "-p_faces"),
        (["-pressure", "1e3"], "-pressure_faces"),
        (["-effects", "damping"], "-damping"),
        (["-effects", "gravity"], "-gravity"),
        (["-prescribe_x", "X"], "-prescribe_faces"),
        (["-operator_storage", "sbaij", "-jacobian", "shell"], "-operator_storage"),
        (["-operator_storage", "sbaij", "-assembly", "coo"], "-operator_storage"),
        (["-operator_storage", "sbaij", "-snes_mf_operator"], "-operator_storage"),
        (["-operator_storage", "sbaij", "-pressure", "1e3", "-pressure_faces", "right"], "-operator_storage"),
        (["-prescribe_faces", "right", "-prescribe_x", "1/(t-0.01)"], "t="),
        (["-prescribe_faces", "right", "-prescribe_x", "__import__('os')"], "-prescribe_x"),
        (["-traction_time", "log(t)"], "t="),
        (["-prescribe_faces", "right", "-prescribe_x", "X +"], "-prescribe_x"),
    ]
    return [Case(f"conflict:{' '.join(a)}", "conflicting combinations", BEND + a, words=(w,)) for a, w in C]


def _write(d, name, data):
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(os.path.join(d, name), mode) as fh:
        fh.write(data)


def file_cases(rng):
    out = []
    scenes = {
        "empty": b"", "comments": b"# nothing but a comment\n\n", "binary": bytes(rng.randrange(256) for _ in range(400)),
        "utf16": "-dt 0.01\n".encode("utf-16"), "latin1": "# Gr\xfc\xdfe\n-dt 0.01\n".encode("latin-1"),
        "nul": b"-dt 0.01\x00\n", "three_tokens": b"-dt 0.01 0.02\n", "no_dash": b"dt 0.01\n",
        "quote": b"-mesh 'good.msh\n", "unknown": b"-mesh good.msh\n-materail snh\n",
        "include": b"-mesh good.msh\n-options_file solver.opts\n", "bad_value": b"-mesh good.msh\n-E -3\n",
        "huge_line": b"-E " + b"9" * 100000 + b"\n", "lone_dash": b"-\n", "crlf_bad": b"-dt 0.01\r\n-E\r\nabc\r\n",
    }
    for name, data in scenes.items():
        out.append(Case(f"scene:{name}", "scene and options files", ["run", f"{name}.opts", "-quiet", "-output",
                        "prev.h5"], setup=lambda d, n=name, b=data: _write(d, f"{n}.opts", b)))
    out.append(Case("scene:directory", "scene and options files", ["run", "sub", "-quiet"],
                    setup=lambda d: os.mkdir(os.path.join(d, "sub"))))
    out.append(Case("scene:directory.opts", "scene and options files", ["run", "sub.opts", "-quiet"],
                    setup=lambda d: os.mkdir(os.path.join(d, "sub.opts"))))
    out.append(Case("scene:fifo", "scene and options files", ["run", "fifo.opts", "-quiet"],
                    setup=lambda d: os.mkfifo(os.path.join(d, "fifo.opts"))))
    out.append(Case("scene:missing", "scene and options files", ["run", "missing.opts", "-quiet"]))
    out.append(Case("scene:none", "scene and options files", ["run", "-quiet"]))
    out.append(Case("scene:non-utf8-name", "scene and options files", ["run", os.fsdecode(b"sc\xe8ne.opts"), "-quiet"],
                    setup=lambda d: _write(d, os.fsdecode(b"sc\xe8ne.opts"), b"-dt\n")))
    opts = {"empty": b"", "binary": bytes(rng.randrange(256) for _ in range(300)), "utf16": "-dt 0.01\n".encode("utf-16"),
            "latin1": "# \xe9\n-dt 0.01\n".encode("latin-1"), "self": b"-options_file self.opts\n",
            "mutual": b"-options_file b.opts\n", "unknown": b"-snes_rtoll 1e-3\n", "bad": b"-snes_rtol -1\n"}
    for name, data in opts.items():
        def setup(d, n=name, b=data):
            _write(d, f"{n}.opts", b)
            _write(d, "b.opts", b"-options_file mutual.opts\n")
        out.append(Case(f"options_file:{name}", "scene and options files", BEND + ["-options_file", f"{name}.opts"],
                        setup=setup))
    for name, setup in (("missing", None), ("directory", lambda d: os.mkdir(os.path.join(d, "o.opts"))),
                        ("fifo", lambda d: os.mkfifo(os.path.join(d, "o.opts")))):
        out.append(Case(f"options_file:{name}", "scene and options files", BEND + ["-options_file", "o.opts"],
                        setup=setup))
    out.append(Case("options_file:no value", "scene and options files", BEND + ["-options_file"]))
    return out


def mesh_cases(rng):
    P, T = cube()
    out = []

    def add(name, pts, tets, words=(), fmt="msh"):
        def setup(d):
            path = os.path.join(d, f"m.{fmt}")
            if fmt == "msh":
                write_msh(path, pts, tets)
            else:
                import meshio
                meshio.write(path, meshio.Mesh(np.asarray(pts, float), [("tetra", np.asarray(tets))]))
        out.append(Case(f"mesh:{name}", "meshes", BEND + ["-mesh", f"m.{fmt}"], setup=setup, words=words))

    for v in rng.sample(range(len(P)), 5):
        for kind, val in (("nan", np.nan), ("inf", np.inf), ("huge", 1e300), ("-inf", -np.inf)):
            p = P.copy()
            p[v, rng.randrange(3)] = val
            add(f"{kind}@{v}", p, T, (f"vertex {v}",))
    for a in rng.sample(range(len(P)), 5):
        b = rng.choice([v for v in range(len(P)) if v != a])
        p = P.copy()
        p[b] = p[a]
        add(f"duplicate_vertex@{a},{b}", p, T)
    for c in rng.sample(range(len(T)), 5):
        t = np.vstack([T, T[c][[1, 0, 3, 2]]])
        add(f"duplicate_tet@{c}", P, t, ("tetrahedra",))
    for c in rng.sample(range(len(T)), 5):   # a tet sharing a face with tet c, its fourth vertex on the same side
        a, b, cc, dd = P[T[c]]
        n = np.cross(b - a, cc - a)
        side = (P - a) @ n
        cand = [v for v in range(len(P)) if v not in T[c] and side[v] * ((dd - a) @ n) > 1e-9]
        if not cand:
            continue
        t = np.vstack([T, [[T[c][0], T[c][1], T[c][2], rng.choice(cand)]]])
        D = np.stack([P[t[-1, k]] - P[t[-1, 0]] for k in (1, 2, 3)], axis=-1)
        if np.linalg.det(D) < 0:
            t[-1] = t[-1][[0, 2, 1, 3]]
        add(f"overlapping_tet@{c}", P, t, ("overlap",))
    for c in rng.sample(range(len(T)), 5):
        t = T.copy()
        t[c] = t[c][[0, 2, 1, 3]]
        add(f"inverted@{c}", P, t, (f"tetrahedron {c}", "inverted"))
    for c in rng.sample(range(len(T)), 4):
        p = P.copy()
        t = T.copy()
        t[c] = [T[c][0], T[c][1], T[c][2], T[c][0]]
        add(f"repeated_vertex@{c}", p, t, (f"tetrahedron {c}",))
    for c in rng.sample(range(len(T)), 4):
        t = T.copy()
        t[c, rng.randrange(4)] = rng.choice([len(P), len(P) + 7, 10 ** 6])
        add(f"index_out_of_range@{c}", P, t, (f"tetrahedron {c}",), fmt="vtu")
    add("unused_vertex", np.vstack([P, [[5, 5, 5]]]), T, ("not used",))
    add("flat", np.c_[P[:, :2], np.zeros(len(P))], T, fmt="vtu")
    inverted = T.copy()
    inverted[3] = inverted[3][[0, 2, 1, 3]]
    out.append(Case("mesh:inverted_refined@3", "meshes", BEND + ["-mesh", "m.msh", "-refine", "1"],
                    setup=lambda d: write_msh(os.path.join(d, "m.msh"), P, inverted),
                    words=("tetrahedron 3", "inverted")))

    def text_mesh(name, mutate, words=()):
        def setup(d):
            path = os.path.join(d, "m.msh")
            write_msh(path, P, T)
            with open(path, "rb") as fh:
                data = fh.read()
            with open(path, "wb") as fh:
                fh.write(mutate(data))
        out.append(Case(f"mesh:{name}", "meshes", BEND + ["-mesh", "m.msh"], setup=setup, words=words))

    with tempfile.TemporaryDirectory() as d:       # where the data sections of the mesh file lie
        write_msh(os.path.join(d, "probe.msh"), P, T)
        with open(os.path.join(d, "probe.msh"), "rb") as fh:
            probe = fh.read()
    lo, hi = probe.index(b"$Nodes"), probe.index(b"$EndElements")
    for cut in rng.sample(range(lo + 7, hi), 8):
        text_mesh(f"truncated@{cut}", lambda b, c=cut: b[:c])
    for at in rng.sample(range(lo + 7, hi), 6):    # at the start of the line: inside a number it can be benign
        text_mesh(f"garbage@{at}", lambda b, a=at: b[:b.rindex(b"\n", 0, a) + 1] + b"@#garbage!% "
                  + b[b.rindex(b"\n", 0, a) + 1:])
    text_mesh("elements_missing", lambda b: b[:b.index(b"$Elements")])
    text_mesh("wrong_count", lambda b: b.replace(b"$Elements\n", b"$Elements\n9999999\n", 1)[:len(b)])

    for k in range(4):          # a second, separate copy of the cube shifted into the first: overlapping pieces
        shift = np.array([rng.uniform(0.05, 0.8), rng.uniform(-0.5, 0.5), rng.uniform(-0.5, 0.5)])
        add(f"overlapping_pieces@{k}", np.vstack([P, P + shift]), np.vstack([T, T + len(P)]), ("overlap",))
    one = (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]]), np.array([[0, 1, 2, 3]]))
    out.append(Case("mesh:fewer_cells_than_ranks", "meshes", BEND + ["-mesh", "one.msh"], nprocs=2,
                    setup=lambda d: write_msh(os.path.join(d, "one.msh"), *one), words=("MPI ranks",)))
    out.append(Case("mesh:empty_file", "meshes", BEND + ["-mesh", "e.msh"], setup=lambda d: _write(d, "e.msh", b"")))
    out.append(Case("mesh:binary_junk", "meshes", BEND + ["-mesh", "j.msh"],
                    setup=lambda d: _write(d, "j.msh", bytes(rng.randrange(256) for _ in range(2000)))))
    out.append(Case("mesh:directory", "meshes", BEND + ["-mesh", "dir.msh"],
                    setup=lambda d: os.mkdir(os.path.join(d, "dir.msh"))))
    out.append(Case("mesh:fifo", "meshes", BEND + ["-mesh", "fifo.msh"],
                    setup=lambda d: os.mkfifo(os.path.join(d, "fifo.msh"))))
    out.append(Case("mesh:missing", "meshes", BEND + ["-mesh", "nothere.msh"]))
    out.append(Case("mesh:unknown_extension", "meshes", BEND + ["-mesh", "m.xyz"],
                    setup=lambda d: _write(d, "m.xyz", b"1 2 3\n")))
    out.append(Case("mesh:text_file", "meshes", BEND + ["-mesh", "scene.opts"]))
    out.append(Case("mesh:empty_name", "meshes", BEND + ["-mesh", ""]))

    def cells(kind, cells_):
        def setup(d):
            import meshio
            meshio.write(os.path.join(d, "c.vtu"), meshio.Mesh(P, [(kind, np.asarray(cells_))]))
        out.append(Case(f"mesh:only_{kind}", "meshes", BEND + ["-mesh", "c.vtu"], setup=setup))
    cells("triangle", [[0, 1, 2], [1, 2, 3]])
    cells("line", [[0, 1]])
    cells("hexahedron", [[0, 1, 4, 3, 9, 10, 13, 12]])
    cells("tetra10", [list(range(10))])
    out.append(Case("mesh:output_without_frames", "meshes", BEND + ["-mesh", "prev.h5", "-mesh_frame", "99"]))
    out.append(Case("mesh:h5_not_ours", "meshes", BEND + ["-mesh", "x.h5"], setup=_foreign_h5))
    return out


def _foreign_h5(d):
    import h5py
    with h5py.File(os.path.join(d, "x.h5"), "w") as f:
        f["data"] = np.arange(10.0)


def output_cases(rng):
    base = ["run", "scene.opts", "-quiet"]
    C = [
        ("directory", ["-output", "."], None),
        ("subdirectory", ["-output", "sub"], lambda d: os.mkdir(os.path.join(d, "sub"))),
        ("dev_null", ["-output", "/dev/null"], None),
        ("dev_full", ["-output", "/dev/full"], None),
        ("xdmf", ["-output", "prev.xdmf"], None),
        ("txt", ["-output", "o.txt"], None),
        ("empty", ["-output", ""], None),
        ("too_long", ["-output", "x" * 300 + ".h5"], None),
        ("too_long_path", ["-output", "/".join(["d" * 200] * 30) + "/o.h5"], None),
        ("parent_is_file", ["-output", "good.msh/o.h5"], None),
        ("equals_mesh", ["-mesh", "prev.h5", "-output", "prev.h5"], None),
        ("equals_mesh_xdmf", ["-mesh", "prev.xdmf", "-output", "prev.h5"], None),
        ("equals_scene", ["-output", "scene.opts"], None),
        ("equals_scene_h5", ["-output", "scene.h5"], lambda d: shutil.copy(os.path.join(d, "scene.opts"),
                                                                           os.path.join(d, "scene.h5"))),
        ("equals_options_file", ["-options_file", "solver.opts", "-output", "solver.opts"], None),
        ("xdmf_is_directory", ["-output", "q.h5"], lambda d: os.mkdir(os.path.join(d, "q.xdmf"))),
        ("partial_is_directory", ["-output", "q.h5"], lambda d: os.mkdir(os.path.join(d, "q.h5.partial"))),
        ("h5_is_fifo", ["-output", "f.h5"], lambda d: os.mkfifo(os.path.join(d, "f.h5"))),
        ("non_utf8_dir", ["-output", os.fsdecode(b"\xff\xfe/o.h5")], lambda d: _write(d, os.fsdecode(b"\xff\xfe"), "x")),
        ("failed_solve", ["-output", "prev.h5", "-pc_type", "lu", "-jacobian", "shell"], None),
        ("failed_solve_mumps", ["-output", "prev.h5", "-pc_type", "lu", "-pc_factor_mat_solver_type", "mumps"], None),
    ]
    out = [Case(f"output:{n}", "output paths", base + a, setup=s) for n, a, s in C]
    out.append(Case("output:disk_full", "output paths", ["run", "scene.opts", "-quiet", "-output", "full.h5",
                    "-final_time", "2", "-checkpoint_every", "5"], fsize=600_000, rcs=(2,), after=_frames_kept,
                    words=("full.h5",)))
    out.append(Case("output:disk_full_at_start", "output paths", ["run", "scene.opts", "-quiet", "-output", "full.h5"],
                    fsize=2_000, rcs=(2,), words=("full.h5",)))
    return out


def _frames_kept(d):
    """After a full disk: full.h5 is a readable output holding the frames flushed before."""
    import h5py
    path = os.path.join(d, "full.h5")
    if not os.path.exists(path):
        return "full.h5 was not kept"
    try:
        with h5py.File(path, "r") as f:
            n = f["x"].shape[0]
            t = f["time"][:]
        if n < 2 or len(t) != n or not np.all(np.diff(t) > 0):
            return f"full.h5 holds {n} frames"
    except Exception as e:
        return f"full.h5 unreadable: {e}"
    return None


def restart_cases(rng):
    out = []
    base = lambda f: ["run", "--restart", f, "-quiet"]  # noqa: E731
    out.append(Case("restart:missing", "restart files", base("none.h5")))
    for other in ("other.h5", "sub/other.h5", "scene.h5"):     # -output naming another file than the restarted one
        out.append(Case(f"restart:output={other}", "restart files", base("prev.h5") + ["-output", other]))
    out.append(Case("restart:no_file", "restart files", ["run", "--restart"]))
    out.append(Case("restart:directory", "restart files", base("sub"), setup=lambda d: os.mkdir(os.path.join(d, "sub"))))
    out.append(Case("restart:fifo", "restart files", base("f.h5"), setup=lambda d: os.mkfifo(os.path.join(d, "f.h5"))))
    out.append(Case("restart:text", "restart files", base("scene.opts")))
    out.append(Case("restart:foreign_h5", "restart files", base("x.h5"), setup=_foreign_h5))

    def copy_and(fn):
        def setup(d):
            shutil.copy(os.path.join(d, "prev.h5"), os.path.join(d, "r.h5"))
            fn(os.path.join(d, "r.h5"))
        return setup

    def truncate(frac):
        def fn(p):
            n = os.path.getsize(p)
            with open(p, "r+b") as fh:
                fh.truncate(int(n * frac))
        return fn
    for frac in sorted(x / 100 for x in rng.sample(range(5, 96), 6)):
        out.append(Case(f"restart:truncated@{frac:.2f}", "restart files", base("r.h5"), setup=copy_and(truncate(frac))))

    def smash(at, n=64):
        def fn(p):
            with open(p, "r+b") as fh:
                fh.seek(at)
                fh.write(b"\xff" * n)
        return fn
    for at in (0, 8, 24, 40, 96):
        out.append(Case(f"restart:corrupt_metadata@{at}", "restart files", base("r.h5"), setup=copy_and(smash(at))))

    def h5edit(fn):
        def edit(p):
            import h5py
            with h5py.File(p, "r+") as f:
                fn(f)
        return copy_and(edit)

    def slot(f):
        return f[f"checkpoint/{int(f.attrs['checkpoint_slot'])}"]

    def set_attr(key, val):
        return lambda f: slot(f).attrs.__setitem__(key, val)

    def replace(name, data):
        def fn(f):
            g = slot(f)
            del g[name]
            g[name] = data
        return fn
    edits = {
        "no_checkpoint": lambda f: f.attrs.__setitem__("checkpoint_slot", -1),
        "slot_missing": lambda f: f.attrs.__setitem__("checkpoint_slot", 7),
        "x_missing": lambda f: slot(f).__delitem__("x"),
        "v_missing": lambda f: slot(f).__delitem__("v"),
        "x_wrong_shape": replace("x", np.zeros((5, 3))),
        "x_flat": replace("x", np.zeros(27 * 3)),
        "x_nan": lambda f: slot(f)["x"].__setitem__((0, 0), np.nan),
        "v_inf": lambda f: slot(f)["v"].__setitem__((1, 2), np.inf),
        "x_strings": replace("x", np.array([b"a", b"b"])),
        "h_nan": set_attr("h_try", np.nan),
        "h_zero": set_attr("h_try", 0.0),
        "h_negative": set_attr("h_try", -0.01),
        "t_nan": set_attr("t", np.nan),
        "t_beyond_end": set_attr("t", 1e9),
        "step_negative": set_attr("step", -3),
        "nframes_too_many": set_attr("nframes", 10 ** 6),
        "nstats_negative": set_attr("nstats", -1),
        "attr_missing": lambda f: slot(f).attrs.__delitem__("h_try"),
        "options_missing": lambda f: f.attrs.__delitem__("options"),
        "scene_missing": lambda f: f.attrs.__setitem__("scene_file", "gone.opts"),
        "mesh_missing": lambda f: f.__delitem__("mesh"),
        "time_missing": lambda f: f.__delitem__("time"),
        "stats_missing": lambda f: f.__delitem__("stats"),
        "options_garbage": lambda f: f.attrs.__setitem__("options", "-E -3\n-materail x"),
    }
    for name, fn in edits.items():
        out.append(Case(f"restart:{name}", "restart files", base("r.h5"), setup=h5edit(fn)))

    def other_mesh(d):
        P, T = cube(3)
        write_msh(os.path.join(d, "other.msh"), P, T)
        shutil.copy(os.path.join(d, "prev.h5"), os.path.join(d, "r.h5"))
    out.append(Case("restart:other_mesh", "restart files", base("r.h5") + ["-mesh", "other.msh"], setup=other_mesh))
    out.append(Case("restart:other_level", "restart files", base("r.h5") + ["-mesh", "", "-level", "2"],
                    setup=copy_and(lambda p: None)))
    out.append(Case("restart:bad_option", "restart files", base("prev.h5") + ["-E", "-1"]))
    out.append(Case("restart:typo", "restart files", base("prev.h5") + ["-materail", "snh"]))
    out.append(Case("restart:failing_solve", "restart files", base("prev.h5") + ["-pc_type", "lu", "-jacobian", "shell"]))
    return out


def plot_cases(rng):
    base = ["plot"]
    return [
        Case("plot:missing", "plot", base + ["none.h5"]),
        Case("plot:foreign_h5", "plot", base + ["x.h5", "-o", "x.png"], setup=_foreign_h5),
        Case("plot:text", "plot", base + ["scene.opts", "-o", "x.png"]),
        Case("plot:no_mesh", "plot", base + ["r.h5", "-o", "x.png"], setup=lambda d: _no_mesh(d)),
        Case("plot:bad_frame", "plot", base + ["prev.h5", "--frame", "99", "-o", "x.png"]),
        Case("plot:png_is_input", "plot", base + ["prev.h5", "-o", "prev.h5"]),
        Case("plot:directory", "plot", base + ["prev.h5", "-o", "."]),
        Case("plot:fifo", "plot", base + ["prev.h5", "-o", "f.png"], setup=lambda d: os.mkfifo(os.path.join(d, "f.png"))),
        Case("plot:empty_name", "plot", base + ["prev.h5", "-o", ""]),
        Case("plot:parent_is_file", "plot", base + ["prev.h5", "-o", "good.msh/x.png"]),
    ] + [Case(f"plot:nonfinite:{v}@{frame}", "plot", base + ["r.h5", "--frame", str(frame), "-o", "x.png"],
              setup=lambda d, v=v: _nonfinite(d, v)) for v in ("nan", "inf") for frame in (-1, 0)]


def _nonfinite(d, value):
    """r.h5: prev.h5 with a non-finite coordinate in every frame."""
    import h5py
    shutil.copy(os.path.join(d, "prev.h5"), os.path.join(d, "r.h5"))
    with h5py.File(os.path.join(d, "r.h5"), "r+") as f:
        x = f["x"][:]
        x[:, 0, 0] = float(value)
        f["x"][...] = x


def _no_mesh(d):
    import h5py
    shutil.copy(os.path.join(d, "prev.h5"), os.path.join(d, "r.h5"))
    with h5py.File(os.path.join(d, "r.h5"), "r+") as f:
        del f["mesh"]


def command_line_cases(rng):
    """Words PETSc would skip (a word after an option's value) or keep as options nothing reads (`--name`,
    a bare `-`), at each place between the pairs of a good command line."""
    good = ["-dt", "0.01", "-final_time", "0.02", "-E", "2e6"]
    words = ["stray", "extra.h5", "scene.opts", "0.5", "-", "--", "--dt", "---quiet", "--final_time=1"]
    out = []
    for w in words:
        for pos in range(0, len(good) + 1, 2):
            out.append(Case(f"cmdline:{w}@{pos}", "command line", ["run", "scene.opts"] + good[:pos] + [w] + good[pos:]
                            + ["-quiet", "-output", "prev.h5"]))
    for args in (["mesh", "bar", "--level", "1", "-o", "m.msh", "stray"], ["plot", "prev.h5", "stray", "-o", "x.png"],
                 ["scenes", "--bogus"], ["scenes", "stray"], ["study", "bogus"]):
        out.append(Case(f"cmdline:{' '.join(args)}", "command line", args))
    return out


LINES = {"double_dash": "--dt 0.01", "two_options": "-dt 0.01 -E 2e6", "no_dash": "dt 0.01", "lone_dash": "- 0.01",
         "open_quote": "-mesh 'good.msh", "triple_dash": "---dt 0.01", "three_words": "-dt 0.01 0.02",
         "dash_after_comment": "-dt 0.01 # fine\n--E 2e6"}


def options_line_cases(rng):
    """Malformed lines, each in an -options_file (PETSc would print a multi-line report for some, keep
    others as options nothing reads) and in a scene file, among good lines at a random place."""
    out = []
    for name, line in LINES.items():
        good = ["-final_time 0.02", "-E 2e6", "# a comment"]
        at = rng.randrange(len(good) + 1)
        text = "\n".join(good[:at] + [line] + good[at:]) + "\n"
        out.append(Case(f"optline:file:{name}", "scene and options files", BEND + ["-options_file", "l.opts"],
                        setup=lambda d, t=text: _write(d, "l.opts", t.encode())))
        scene = "-mesh good.msh\n-material neohookean\n" + text
        out.append(Case(f"optline:scene:{name}", "scene and options files", ["run", "l.opts", "-quiet", "-output",
                        "prev.h5"], setup=lambda d, t=scene: _write(d, "l.opts", t.encode())))
    return out


def viewer_cases(rng):
    """PETSc viewers writing into a directory that does not exist, or over a file of the run (PETSc would
    fail at its finalization, after the run, or overwrite it)."""
    out = []
    for key in ("log_view", "ksp_monitor", "snes_view", "ksp_converged_reason", "snes_monitor_short"):
        for value in (":nodir/f.txt", "ascii:nodir/sub/f.txt", ":prev.xdmf", ":scene.opts", ":good.msh",
                      ":prev.h5", ":."):
            out.append(Case(f"viewer:{key}={value}", "PETSc values", BEND + [f"-{key}", value]))
    return out


def mesh_command_cases(rng):
    """`hyperelastic mesh` with wrong values and outputs."""
    base = ["mesh", "bar"]
    out = []
    for size in ("inf", "nan", "-1", "0", "abc", "", "1e-320"):
        out.append(Case(f"meshcmd:size={size!r}", "mesh command", base + ["--size", size, "-o", "m.msh"]))
    for level in ("0", "-1", "99", "1.5", "x"):
        out.append(Case(f"meshcmd:level={level!r}", "mesh command", base + ["--level", level, "-o", "m.msh"]))
    for extra in (["--order", "3"], ["--order", "0"], ["--refine", "-1"], ["--size", "1", "--level", "1"], []):
        args = extra if "--level" in extra else extra + ["--level", "1"]
        out.append(Case(f"meshcmd:{' '.join(extra) or 'no output'}", "mesh command",
                        base + args + (["-o", "m.msh"] if extra else [])))
    outputs = {"empty": ("", None), "fifo": ("f.msh", lambda d: os.mkfifo(os.path.join(d, "f.msh"))),
               "directory": ("sub", lambda d: os.mkdir(os.path.join(d, "sub"))), "dev_null": ("/dev/null", None),
               "parent_is_file": ("good.msh/m.msh", None), "equals_input": ("scene.opts", None)}
    for name, (o, setup) in outputs.items():
        out.append(Case(f"meshcmd:output:{name}", "mesh command", base + ["--level", "1", "-o", o], setup=setup))
    for name, (g, setup) in {"missing": ("none.geo", None), "text": ("scene.opts", None),
                             "directory": ("g.geo", lambda d: os.mkdir(os.path.join(d, "g.geo"))),
                             "junk": ("j.geo", lambda d: _write(d, "j.geo", b"Point(1) = {0, 0;\n")),
                             "flat": ("f.geo", lambda d: _write(d, "f.geo", b'SetFactory("OpenCASCADE");\n'
                                                                         b"Rectangle(1) = {0, 0, 0, 1, 1};\n"))}.items():
        out.append(Case(f"meshcmd:geometry:{name}", "mesh command", ["mesh", g, "--size", "0.5", "-o", "m.msh"],
                        setup=setup))
    return out


def study_cases(rng):
    """`hyperelastic study` with wrong values (each refused before any run)."""
    part = ["study", "refinement", "--part", "part.geo", "--scene", "scene.opts", "-output_dir", "st"]

    def geo(d):
        _write(d, "part.geo", b'SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1};\n')
    C = {"budget": ["study", "refinement", "--budget", str(rng.choice([-5, 0, "nan", "inf"]))],
         "jobs": ["study", "accuracy", "--jobs", "0"], "kind": ["study", "bogus"],
         "output_dir": ["study", "accuracy", "-output_dir", "good.msh"],
         "part_missing": part[:3] + ["none.geo"] + part[4:] + ["--size", "0.5"],
         "part_without_size": part, "size": part + ["--size", rng.choice(["inf", "-1", "0", "nan"])],
         "order": part + ["--size", "0.5", "--order", rng.choice(["3", "1,,2", "0", "x"])],
         "refine": part + ["--size", "0.5", "--refine", rng.choice(["-1", "0", "1"])],
         "watch": part + ["--size", "0.5", "--watch", rng.choice(["bogus", "point:1,2", "point:a,b,c"])],
         "order_without_part": ["study", "refinement", "--order", "2"]}
    return [Case(f"study:{n}", "study command", a, setup=geo) for n, a in C.items()]


def contract_cases(rng):
    """The contracts of the newer features (issues 48, 44, 49): each refused with one line where it once ran into garbage,
    an internal error or a misleading line."""
    part = ["study", "price", "--part", "part.geo", "--scene", "scene.opts", "--size", "0.5", "--target", "0.01",
            "-output_dir", "st"]

    def geo(d):
        _write(d, "part.geo", b'SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1};\n')
    C = [
        ("mixed_snes_mf", BEND + ["-formulation", "mixed", "-order", "2", "-material", "neohookean_split", "-snes_mf"],
         ("-snes_mf",), None),
        ("mixed_augment_value", BEND + ["-formulation", "mixed", "-order", "2", "-material", "neohookean_split",
                                        "-mixed_augment", "much"], ("-mixed_augment much", ">= 0"), None),
        ("mixed_augment_gamg", BEND + ["-formulation", "mixed", "-order", "2", "-material", "neohookean_split",
                                       "-mixed_augment", "3", "-fieldsplit_u_pc_type", "gamg"],
         ("-mixed_augment 3", "p-multigrid"), None),
        ("mixed_augment_sor", BEND + ["-formulation", "mixed", "-order", "2", "-material", "neohookean_split",
                                      "-mixed_augment", "3", "-fieldsplit_u_mg_levels_pc_type", "sor"],
         ("-mixed_augment 3", "smoother"), None),
        ("p2_one_point", BEND + ["-order", "2", "-quadrature_degree", "1"], ("zero-energy",), None),
        ("p1_mesh_rule", BEND + ["-quadrature_degree", "5"], ("linear tetrahedra",), None),
        ("p1_rule", BEND + ["-order", "1", "-quadrature_degree", "2"], ("linear tetrahedra",), None),
        ("report_frame", ["report", "prev.h5", "--frame", "999"], ("--frame 999",), None),
        ("report_frame_negative", ["report", "prev.h5", "--frame", "-99"], ("--frame -99",), None),
        ("report_forces_dynamic", ["report", "prev.h5", "--forces"], ("-step_forces",), None),
        ("price_bogus_option", part + ["--run-args", "-bogus 1"], ("-bogus",), geo),
        ("price_bad_value", part + ["--run-args", "-E -5"], ("-E",), geo),
        ("price_without_part", ["study", "price", "--scene", "scene.opts"], ("--part", "price"), None),
        ("price_max_runs", part + ["--max-runs", "0"], ("--max-runs 0",), geo),
        ("price_max_level", part + ["--max-level", "-1"], ("--max-level -1",), geo),
        ("mesh_empty_step", ["mesh", "e.step", "--size", "0.5", "-o", "m.msh"], ("no geometry",),
         lambda d: _write(d, "e.step", b"")),
        ("mesh_huge_size_geo", ["mesh", "part.geo", "--size", "1e300", "-o", "m.msh"], ("extent",), geo),
        ("mesh_huge_size_bar", ["mesh", "bar", "--size", "1e300", "-o", "m.msh"], ("extent",), None),
        ("restart_other_order", ["run", "--restart", "prev.h5", "-order", "2", "-quiet"], ("order",), None),
        ("expression_leading_minus", BEND + ["-effects", "elasticity,fixed,prescribed", "-prescribe_faces", "right",
                                             "-prescribe_uz", "-t*Z"], ("read as an option", "(-t*Z)"), None),
        ("partitioner_unknown", BEND + ["-partitioner", "scotch"], ("-partitioner", "morton, metis"), None),
        ("partitioner_not_built", BEND + ["-partitioner", "parmetis"], ("-partitioner", "built without it"), None),
        ("obstacle_inside", BEND + ["-obstacle", "plane:0,0,1,0"], ("-obstacle", "at the start"), None),
        ("obstacle_kind", BEND + ["-obstacle", "cone:0,0,1,0"], ("-obstacle", "plane:"), None),
        ("obstacle_dhat", BEND + ["-obstacle", "plane:0,0,1,-3", "-contact_dhat", "-1"], ("-contact_dhat",), None),
        ("obstacle_motion_count", BEND + ["-obstacle", "plane:0,0,1,-3", "-obstacle_motion", "0,0,t;0,0,0"],
         ("-obstacle_motion", "2 translations"), None),
        ("obstacle_file_unreadable", BEND + ["-obstacle", "mesh:plate.vtu"], ("-obstacle", "cannot be read"),
         lambda d: _write(d, "plate.vtu", b"<VTKFile garbage\n")),
        ("obstacle_friction_negative", BEND + ["-obstacle", "plane:0,0,1,-3", "-contact_friction", "-0.2"],
         ("-contact_friction",), None),
        ("obstacle_file_no_triangles", BEND + ["-obstacle", "mesh:plate.obj"], ("-obstacle", "no triangles"),
         lambda d: _write(d, "plate.obj", b"v 0 0 0\nv 1 0 0\n")),
        ("obstacle_mesh_through", BEND + ["-obstacle", "mesh:plate.obj"], ("-obstacle", "intersects", "crosses"),
         lambda d: _write(d, "plate.obj", b"v 0 -5 -5\nv 0 5 -5\nv 0 5 5\nv 0 -5 5\nf 1 2 3\nf 1 3 4\n")),
        ("refine_negative", BEND + ["-refine", "-1"], ("-refine", ">= 0"), None),
        ("refine_too_deep", BEND + ["-refine", "9"], ("-refine", "at most 8"), None),
        ("refine_metis", BEND + ["-refine", "1", "-partitioner", "metis"], ("-refine", "metis"), None),
        ("refine_not_integer", BEND + ["-refine", "two"], ("-refine", "not an integer"), None),
        ("pmg_on_p1", BEND + ["-pc_type", "mg"], ("-pc_type mg", "-order 2"), None),
        ("pmg_levels", BEND + ["-order", "2", "-pc_type", "mg", "-pc_mg_levels", "3"], ("-pc_mg_levels 3",), None),
        ("pmg_galerkin", BEND + ["-order", "2", "-pc_type", "mg", "-pc_mg_galerkin", "both"], ("-pc_mg_galerkin",),
         None),
    ]
    return [Case(f"contract:{n}", "contracts", a, setup=setup, words=w) for n, a, w, setup in C]


def _damaged_prepared(key, i, j):
    """A setup: good.msh prepared as p.h5 (in-process), then row i of dataset `key` set to row j's value."""
    def setup(d):
        import h5py
        from hyperelastic.mesh.prepared import prepare
        from hyperelastic.mesh.read import read_mesh
        prepare(read_mesh(os.path.join(d, "good.msh")), os.path.join(d, "p.h5"))
        with h5py.File(os.path.join(d, "p.h5"), "r+") as f:
            v = f[key][:]
            v[i] = v[j]
            f[key][:] = v
    return setup


def _truncated_piece(d):
    """Rank 1's file of the per-rank output ranks.h5 cut to half its size."""
    folder = os.path.join(d, "ranks.h5.d")
    piece = os.path.join(folder, sorted(os.listdir(folder))[1])
    os.truncate(piece, os.path.getsize(piece) // 2)


def _renamed_output(d):
    """ranks.h5 and its folder renamed to moved.h5 and moved.h5.d."""
    os.rename(os.path.join(d, "ranks.h5"), os.path.join(d, "moved.h5"))
    os.rename(os.path.join(d, "ranks.h5.d"), os.path.join(d, "moved.h5.d"))


def error_contract_cases(rng):
    """Issue 73: the error contract for what runs past one machine and for contact. Each case is one of its causes,
    on 2 ranks where ranks are involved (a hang fails at TIME_LIMIT)."""
    def big(d):
        with open(os.path.join(d, "big.opts"), "w") as fh:
            fh.write(SCENE + "-E " + "1" * 1_000_000 + "\n")
    C = [  # name, args, words, setup, ranks
        ("obstacle_inside_one_rank", BEND + ["-obstacle", "sphere:1,1,1,0.3"], ("-obstacle", "at the start"), None, 2),
        ("obstacle_inside_other_rank", BEND + ["-obstacle", "sphere:0,0,0,0.3"], ("-obstacle", "at the start"), None,
         2),
        ("prepare_into_directory", ["mesh", "good.msh", "--prepare", "-o", "d.h5"], ("--prepare", "directory"),
         lambda d: os.mkdir(os.path.join(d, "d.h5")), 1),
        ("prepare_over_xdmf_data", ["mesh", "prev.xdmf", "--prepare", "-o", "prev.h5"], ("--prepare", "data"), None,
         1),
        ("dhat_beyond_the_part", BEND + ["-obstacle", "plane:0,0,1,-3", "-contact_dhat", "1e20"],
         ("-contact_dhat", "size"), None, 1),
        ("megabyte_value", ["run", "big.opts", "-quiet", "-output", "prev.h5"], ("line 9", "1,000,003 characters"),
         big, 1),
        ("ignored_option", BEND + ["-mixed_augment", "5"], ("-mixed_augment", "does not read"), None, 1),
        ("ignored_option_two_ranks", BEND + ["-mixed_augment", "5"], ("-mixed_augment", "does not read"), None, 2),
        ("box_face_without_facets", BEND + ["-mesh", "tet.msh"], ("-traction_face", "'right'", "no boundary facet"),
         lambda d: write_msh(os.path.join(d, "tet.msh"), np.eye(4, 3, -1), [[0, 1, 2, 3]]), 1),
        ("box_face_without_facets_two_ranks", BEND + ["-mesh", "tets.msh"], ("-traction_face", "no boundary facet"),
         lambda d: write_msh(os.path.join(d, "tets.msh"), np.vstack([np.eye(4, 3, -1), [0, 0, -1]]),
                             [[0, 1, 2, 3], [0, 2, 1, 4]]), 2),
        ("sphere_inside_the_part", BEND + ["-obstacle", "sphere:0.5,0.5,0.5,0.2"], ("-obstacle", "inside the part"),
         None, 2),
        ("box_inside_the_part", BEND + ["-obstacle", "box:0.3,0.3,0.3,0.6,0.6,0.6"], ("-obstacle", "inside the part"),
         None, 1),
        ("prepared_repeated_vertex_two_ranks", BEND + ["-mesh", "p.h5"], ("node indices", "not a numbering"),
         _damaged_prepared("input_index", 1, 0), 2),
        ("prepared_repeated_cell_two_ranks", BEND + ["-mesh", "p.h5"], ("cell indices", "not a numbering"),
         _damaged_prepared("cell_input_index", 5, 30), 2),
        ("prepared_repeated_vertex_gather", BEND + ["-mesh", "p.h5", "-output_layout", "gather"],
         ("node indices", "not a numbering"), _damaged_prepared("input_index", 20, 3), 2),
        ("truncated_piece_report", ["report", "ranks.h5"], ("ranks.h5.d/", "truncated"), _truncated_piece, 1),
        ("truncated_piece_plot", ["plot", "ranks.h5", "-o", "r.png"], ("ranks.h5.d/", "truncated"), _truncated_piece,
         1),
        ("truncated_piece_restart", ["run", "--restart", "ranks.h5", "-quiet"], ("ranks.h5.d/", "truncated"),
         _truncated_piece, 1),
        ("truncated_piece_restart_two_ranks", ["run", "--restart", "ranks.h5", "-quiet"], ("ranks.h5.d/", "truncated"),
         _truncated_piece, 2),
        ("truncated_piece_as_mesh_two_ranks", ["run", "scene.opts", "-mesh", "ranks.h5", "-quiet", "-output", "n.h5"],
         ("ranks.h5.d/", "truncated"), _truncated_piece, 2),
        ("renamed_output_report", ["report", "moved.h5"], ("keep ranks.h5.d/", "written as 'ranks.h5'"),
         _renamed_output, 1),
        ("refine_beyond_memory", BEND + ["-refine", "8"], ("-refine 8", "805,306,368", "GB a rank"), None, 1),
        ("refine_beyond_memory_two_ranks", BEND + ["-refine", "8"], ("-refine 8", "GB a rank on 2"), None, 2),
        ("motion_not_finite_later", BEND + ["-obstacle", "plane:0,0,1,-3", "-obstacle_motion", "0,0,log(0.015-t)"],
         ("-obstacle_motion", "t=0.02"), None, 1),
        ("rigid_not_finite_later_two_ranks", BEND + ["-effects", "elasticity,fixed,rigid", "-rigid", "right",
                                                     "-rigid_uy", "1/(t-0.02)"], ("-rigid_uy", "t=0.02"), None, 2),
        ("graded_geometry_asks_a_billion", ["mesh", "fine.geo", "--graded", "--size", "0.5", "-o", "f.msh"],
         ("fine.geo", "--graded", "tetrahedra"), lambda d: _write(
             d, "fine.geo", b'SetFactory("OpenCASCADE");\nBox(1) = {0, 0, 0, 1, 1, 1};\nField[1] = MathEval;\n'
                            b'Field[1].F = "0.002";\nBackground Field = 1;\n'), 1),
        ("triangles_inside_the_part", BEND + ["-obstacle", "mesh:inner.obj"], ("-obstacle", "inside the part"),
         lambda d: _write(d, "inner.obj", b"v 0.4 0.4 0.5\nv 0.6 0.4 0.5\nv 0.5 0.6 0.5\nf 1 2 3\n"), 1),
    ]
    out = [Case(f"contract73:{n}", "contracts", a, setup=setup, nprocs=r, words=w) for n, a, w, setup, r in C]
    # item 10: a run that fails after its first step (a load that jumps past what 3 Newton iterations solve, no
    # halving) puts the earlier output back as it was and leaves its own frames beside it, FILE.failed.h5
    late = ["-final_time", "0.05", "-traction_time", "1+1e4*max(t-0.015,0)", "-snes_max_it", "3", "-dt_min", "0.01"]
    out += [Case("contract73:solve_fails_after_first_step", "contracts", BEND + late, rcs=(3,), after=_failed_beside,
                 words=("step 2", "'prev.h5' is kept as it was", "'prev.failed.h5'")),
            Case("contract73:solve_fails_after_first_step_two_ranks", "contracts",
                 ["run", "scene.opts", "-quiet", "-output", "ranks.h5"] + late, nprocs=2, rcs=(3,),
                 after=_failed_beside, words=("step 2", "'ranks.h5' is kept as it was", "'ranks.failed.h5'"))]
    return out


def _failed_beside(d):
    """After a run that failed past its first step: its output FILE.failed.h5 (and .xdmf) beside the earlier one,
    holding its frames and the failure; nothing else new but its per-rank files."""
    import h5py
    new = sorted(n for n in os.listdir(d) if ".failed." in n)
    if len(new) != 2 or not new[0].endswith(".failed.h5") or not new[1].endswith(".failed.xdmf"):
        return f"expected FILE.failed.h5 and FILE.failed.xdmf, found {new}"
    try:
        with h5py.File(os.path.join(d, new[0]), "r") as f:
            n, failure = f["x"].shape[0], f.attrs.get("failure", "")
            x = f["x"][:]
    except Exception as e:
        return f"{new[0]} unreadable: {e}"
    if n < 1 or "step 2" not in failure or not np.isfinite(x).all():
        return f"{new[0]}: {n} frames, failure {failure!r}"
    with open(os.path.join(d, new[1])) as fh:
        if new[0] not in fh.read():
            return f"{new[1]} does not name {new[0]}"
    return None


MPI_CATEGORIES = ("option values", "unknown options", "conflicting combinations", "scene and options files",
                  "meshes", "output paths", "restart files")


def all_cases(seed=SEED):
    """The suite: every generator's cases, then about 60 of them again under mpiexec -n 2."""
    rng = random.Random(seed)
    cases = []
    for gen in (option_value_cases, unknown_option_cases, conflict_cases, file_cases, mesh_cases, output_cases,
                restart_cases, plot_cases, command_line_cases, options_line_cases, viewer_cases, mesh_command_cases,
                study_cases, contract_cases, error_contract_cases):
        cases += gen(rng)
    pool = [c for c in cases if c.category in MPI_CATEGORIES and not c.fsize]
    mpi = []
    for c in random.Random(seed + 1).sample(pool, 60):
        mpi.append(Case("mpi2:" + c.name, c.category + " (2 ranks)", c.args, c.setup, 2, c.words, c.rcs))
    cases += mpi
    names = [c.name for c in cases]
    dup = [n for n, k in Counter(names).items() if k > 1]
    assert not dup, dup
    return cases


# ---------------------------------------------------------------------------------------- checks
def _snapshot(d):
    """{relative path: sha256 | 'dir' | 'fifo'} of everything under d."""
    out = {}
    for root, dirs, files in os.walk(d):
        for n in dirs:
            out[os.path.relpath(os.path.join(root, n), d)] = "dir"
        for n in files:
            p = os.path.join(root, n)
            st = os.lstat(p)
            if stat.S_ISREG(st.st_mode):
                with open(p, "rb") as fh:
                    out[os.path.relpath(p, d)] = hashlib.sha256(fh.read()).hexdigest()
            else:
                out[os.path.relpath(p, d)] = "special"
    return out


def run_case(case, world, workdir):
    """(outcome, detail): outcome 'pass' or what broke the promise."""
    d = os.path.join(workdir, "".join(ch if ch.isalnum() else "_" for ch in case.name)[:80] + f"_{abs(hash(case.name))}")
    shutil.copytree(world, d)
    if case.setup is not None:
        case.setup(d)
    before = _snapshot(d)
    t0 = time.time()
    try:
        if case.nprocs == 1 and not case.fsize:
            p = warmrun.run(case.args, cwd=d, timeout=TIME_LIMIT, text=False)
        else:
            p = subprocess.run(hyperelastic_cmd(case.args, case.nprocs, case.fsize), cwd=d, capture_output=True,
                               timeout=TIME_LIMIT)
    except subprocess.TimeoutExpired:
        return "hang", f"no exit within {TIME_LIMIT:g} s"
    dt = time.time() - t0
    err = p.stderr.decode(errors="replace")
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith("note: ")]   # (one error line; notes
    if p.returncode < 0:                                                                      # are kept by -quiet)
        return "crash", f"signal {-p.returncode}: {err[-300:]}"
    if p.returncode == 0:
        return "accepted", "exit 0"
    if "Traceback" in err:
        return "traceback", err[-400:]
    if p.returncode not in case.rcs:
        return "exit status", f"exit {p.returncode}: {lines[-1] if lines else ''}"
    if len(lines) != 1:
        return "lines", f"{len(lines)} lines: {' | '.join(lines)[:400]}"
    if not lines[0].startswith("hyperelastic: error:") or "internal error" in lines[0]:
        return "message", lines[0]
    missing = [w for w in case.words if w not in lines[0]]
    if missing:
        return "message", f"{lines[0]} (expected {missing})"
    after = _snapshot(d)
    changed = sorted(k for k, v in before.items() if after.get(k) != v)
    if changed:
        return "data touched", f"{changed}: {lines[0]}"
    new = sorted(k for k, v in after.items() if k not in before and v != "dir")
    if new and not case.after:
        return "files left", f"{new}: {lines[0]}"
    if case.after is not None:
        why = case.after(d)
        if why:
            return "data lost", why
    shutil.rmtree(d, ignore_errors=True)
    return "pass", f"{dt:.1f} s: {lines[0]}"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=SEED)
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--every", type=int, default=1, help="run every K-th case (the quick subset: %d)" % QUICK_EVERY)
    ap.add_argument("--only", help="a category, or a substring of case names")
    ap.add_argument("--list", action="store_true")
    ap.add_argument("-v", "--verbose", action="store_true")
    a = ap.parse_args(argv)
    cases = all_cases(a.seed)[::a.every]
    if a.only:
        cases = [c for c in cases if a.only == c.category or a.only in c.name]
    if a.list:
        for c in cases:
            print(f"{c.category:28s} {c.name}")
        print(len(cases), "cases")
        return 0
    with tempfile.TemporaryDirectory(prefix="badinput_") as tmp:
        world = make_world(os.path.join(tmp, "world"))
        t0 = time.time()
        with ThreadPoolExecutor(a.jobs) as ex:
            results = list(ex.map(lambda c: (c, *run_case(c, world, tmp)), cases))
        wall = time.time() - t0
    by = Counter((c.category, o) for c, o, _ in results)
    cats = list(dict.fromkeys(c.category for c in cases))
    print(f"{len(cases)} cases, seed {a.seed}, {wall:.0f} s wall on {a.jobs} jobs")
    for cat in cats:
        counts = {o: n for (c, o), n in by.items() if c == cat}
        print(f"  {cat:36s} " + ", ".join(f"{o} {n}" for o, n in sorted(counts.items())))
    outcomes = Counter(o for _, o, _ in results)
    print("total: " + ", ".join(f"{o} {n}" for o, n in sorted(outcomes.items())))
    for c, o, why in results:
        if o != "pass" or a.verbose:
            print(f"{o:13s} {c.name}: {why}")
    return 0 if outcomes.get("pass", 0) == len(cases) else 1


if __name__ == "__main__":
    sys.exit(main())
