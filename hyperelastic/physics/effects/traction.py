from dataclasses import dataclass

import numpy as np

from ...element import faces
from ...core.options import Row, facet_sets, needs, time_function
from .base import DeadLoad, Energy, LoadKind, Spec


class Traction(DeadLoad):
    """Dead-load surface traction t [Pa] per unit reference area on a face, scaled by its time function
    (base.load_factor: a ramp A min(t,1) or -NAME_time): f_a = int t N_a dA (t A/3 per vertex of a 3-node
    triangle; faces.shares)."""
    name = "traction"
    work_column = "traction_work"

    def __init__(self, X, tris, traction, scale=None, nlv=0):
        share = np.zeros(nlv)
        np.add.at(share, tris.ravel(), faces.shares(X, tris).ravel())
        super().__init__((share[:, None] * np.asarray(traction, float)[None, :]).ravel(), scale)


@dataclass(frozen=True)
class DeadTraction:
    value: tuple      # [Pa per reference area]
    faces: tuple      # ((set name, components), ...)
    scale: object     # time function: None, a ramp A (A min(t,1)) or an expressions.TimeFunction


def read_faces(opts):
    """-traction_face (default: the right end of the bar) and its time function: shared with the follower
    twist."""
    return tuple(facet_sets(opts, "traction_face", "right")), time_function(opts, "traction")


def _read(opts, where):
    faces, scale = read_faces(opts)
    t = opts.vector("traction")
    if t is None:
        raise needs(where, "traction", "-traction tx,ty,tz")
    return DeadTraction(tuple(t), faces, scale)


def surfaces(option):
    """A spec's `sets`: the facet sets of a parameter set's `faces`, named by `option`."""
    return lambda p: [(option, n, "facets") for n, _ in p.faces]


def build_traction(p, ctx):
    return [Traction(ctx.space.X, ctx.space.set_triangles([n for n, _ in p.faces]), p.value, p.scale, ctx.space.nlv)]


TRACTION_WORK = Energy("traction_work", -1, "work potential f.x of the dead loads (tractions, forces) [J]",
                       work=True)

SPEC = Spec(
    "traction", "a dead traction per reference area on surfaces", implied_by=("traction",), read=_read,
    sets=surfaces("traction_face"), build=build_traction, energies=(TRACTION_WORK,),
    load=LoadKind("vector", DeadTraction, "`-L1_traction tx,ty,tz` (dead, per reference area)"),
    rows=(Row(("traction", "traction_face", "traction_ramp", "traction_time"), "-traction tx,ty,tz",
              "dead-load traction [Pa per reference area] on the surfaces `-traction_face S1,S2,…`, scaled by "
              "`-traction_ramp A` (A·min(t,1)) or by a time function `-traction_time EXPR`", "right"),))
