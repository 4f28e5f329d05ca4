"""Setting up a run: scene options -> mesh -> distributed space -> effects -> system. Shared by the
command line, the tests and the scripts (PETSc must already be initialized)."""
import os

from petsc4py import PETSc

from .errors import UserError
from .mesh import cached_bar, read
from .options import Options, insert_defaults, parse_options_file, resolve_scene
from .scene import build, read_scene
from .space import Space
from .system import System


def collective(comm, fn):
    """Run fn on rank 0 and broadcast its result, or its UserError to every rank."""
    mpi = comm.tompi4py()
    res = err = None
    if mpi.rank == 0:
        try:
            res = fn()
        except UserError as e:
            err = str(e)
    err = mpi.bcast(err, root=0)
    if err is not None:
        raise UserError(err)
    return res


def rotation_matrix(r):
    """Rodrigues' formula: the rotation by |r| radians about r."""
    import numpy as np
    r = np.asarray(r, float)
    th = np.linalg.norm(r)
    if th == 0:
        return np.eye(3)
    k = r / th
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K


class Problem:
    """Everything of a run except the solver and the output."""

    def __init__(self, scene_arg, comm=None, before_mesh=None):
        self.comm = comm or PETSc.COMM_WORLD
        self.scene_file = resolve_scene(scene_arg)
        insert_defaults(parse_options_file(self.scene_file))
        self.opts = Options()
        self.name = os.path.splitext(os.path.basename(self.scene_file))[0]
        self.scene = read_scene(self.name, self.opts)
        if before_mesh:
            before_mesh(self)        # e.g. check the output path before any expensive work
        sc = self.scene
        mesh = collective(self.comm, lambda: read(sc.mesh if sc.mesh else cached_bar(sc.level)))
        self.points, self.tets = mesh if mesh is not None else (None, None)
        self.space = Space(self.comm, self.points, self.tets)
        self.effects, self.constraints, self.kernels = build(sc, self.space)
        self.system = System(self.space, self.effects, self.constraints)
        self.system.inversion_guard = sc.inversion_guard
        self.system.assembly = sc.assembly

    def centroid(self):
        """Mean of the mesh vertices (the same on every rank)."""
        import numpy as np
        from mpi4py import MPI
        sp = self.space
        own = sp.X[sp.lvid_of_owned]
        tot = sp.mpi.allreduce(np.append(own.sum(axis=0), len(own)), op=MPI.SUM)
        return tot[:3] / tot[3]

    def initial_state(self):
        """Local positions and velocities at t = 0, with the constraint scale set: the reference
        configuration at rest, unless -initial_scale (x = c + diag(s)(X - c)), -initial_rotation
        (x = c + R (x - c), R = exp([r]x)) or -initial_spin (v = w x (x - c)) ask otherwise; c is the
        centroid."""
        import numpy as np
        sp, sysm, sc = self.space, self.system, self.scene
        X = sp.X
        x, v = X.copy(), np.zeros_like(X)
        if any(a is not None for a in (sc.initial_scale, sc.initial_rotation, sc.initial_spin)):
            c = self.centroid()
            if sc.initial_scale is not None:
                x = c + (x - c) * np.asarray(sc.initial_scale)
            if sc.initial_rotation is not None:
                x = c + (x - c) @ rotation_matrix(sc.initial_rotation).T
            if sc.initial_spin is not None:
                v = np.cross(np.asarray(sc.initial_spin), x - c)
        x, v = x.ravel().copy(), v.ravel().copy()
        sysm.begin_step(0.0, self.scene.dt, x, v)
        X = sp.global_vec()
        X.getArray()[:] = sp.owned_array(x)
        sysm.impose_global(X)
        sysm.linearize(X)
        sysm.set_scale(sp.global_vec())
        return x, v
