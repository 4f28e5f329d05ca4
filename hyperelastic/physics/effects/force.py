"""A total force on surfaces: the uniform dead traction F / A over their reference area A (users know
forces, not pressures). Its resultant is F exactly, whatever the mesh."""
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI

from ...core.options import Row, facet_sets, needs, time_function
from .base import LoadKind, Spec
from ...element import faces
from .traction import TRACTION_WORK, Traction, surfaces


class Force(Traction):
    """The dead traction F/A on triangles whose reference area, summed over the ranks, is A."""
    name = "force"

    def __init__(self, X, tris, force, scale=None, nlv=0, mpi=None):
        local = float(faces.areas(X, tris).sum())
        area = local if mpi is None else mpi.allreduce(local, op=MPI.SUM)
        if not area > 0:
            raise ValueError("a total force on surfaces of zero area")
        self.area = area
        super().__init__(X, tris, np.asarray(force, float) / area, scale, nlv)


@dataclass(frozen=True)
class TotalForce:
    value: tuple      # [N]
    faces: tuple      # ((set name, components), ...)
    scale: object     # time function (base.load_factor)


def _read(opts, where):
    f = opts.vector("force")
    if f is None or not opts.has("force_faces"):
        raise needs(where, "force", "-force Fx,Fy,Fz and -force_faces surfaces")
    return TotalForce(tuple(f), tuple(facet_sets(opts, "force_faces")), time_function(opts, "force"))


def build_force(p, ctx):
    tris = ctx.space.set_triangles([n for n, _ in p.faces])
    return [Force(ctx.space.X, tris, p.value, p.scale, ctx.space.nlv, ctx.space.mpi)]


SPEC = Spec(
    "force", "a total dead force on surfaces (the traction F/area)", implied_by=("force",), read=_read,
    sets=surfaces("force_faces"), build=build_force, energies=(TRACTION_WORK,),
    load=LoadKind("vector", TotalForce, "`-L1_force Fx,Fy,Fz` (total, dead)"),
    rows=(Row(("force", "force_faces", "force_ramp", "force_time"), "-force Fx,Fy,Fz -force_faces S1,S2,…",
              "a total dead force [N] on the surfaces: the uniform traction F / (their reference area); "
              "`-force_ramp A` or `-force_time EXPR`"),))
