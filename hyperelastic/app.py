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

    def initial_state(self):
        """Local positions and velocities at t = 0 (rest), with the constraint scale set."""
        import numpy as np
        sp, sysm = self.space, self.system
        x = sp.X.ravel().copy()
        v = np.zeros_like(x)
        sysm.begin_step(0.0, self.scene.dt, x, v)
        X = sp.global_vec()
        X.getArray()[:] = sp.owned_array(x)
        sysm.impose_global(X)
        sysm.linearize(X)
        sysm.set_scale(sp.global_vec())
        return x, v
