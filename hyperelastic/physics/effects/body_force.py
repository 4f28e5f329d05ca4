"""A body force per reference volume on chosen regions (physical volumes), or on the whole body: gravity
acts on every cell with its density; this one acts where it is told, with a value of its own [N/m^3]
and a time function. f_a = int b N_a dV = b V/4 per cell vertex (P1)."""
from dataclasses import dataclass

import numpy as np

from ...core.options import Row, needs, time_function, volume_sets
from .base import DeadLoad, Energy, Spec


class BodyForce(DeadLoad):
    name = "body_force"
    work_column = "body_force_work"

    def __init__(self, cells, which, b, scale, nlv):
        """cells: a kernels.Cells of the local cells; which: the local cells it acts on."""
        share = np.zeros(nlv)
        np.add.at(share, cells.cells[which].ravel(), cells.load_shares(1.0, which).ravel())
        super().__init__((share[:, None] * np.asarray(b, float)[None, :]).ravel(), scale)


@dataclass(frozen=True)
class VolumeLoad:
    value: tuple      # [N/m^3]
    regions: tuple    # physical volumes (names or tags); () for the whole body
    scale: object     # time function (base.load_factor)


def _read(opts, where):
    b = opts.vector("body_force")
    if b is None:
        raise needs(where, "body_force", "-body_force bx,by,bz")
    return VolumeLoad(tuple(b), tuple(volume_sets(opts, "body_force_regions")), time_function(opts, "body_force"))


def _build(p, ctx):
    sp = ctx.space
    which = np.arange(sp.nc) if not p.regions else np.unique(np.concatenate([sp.set_cells(r) for r in p.regions]))
    return [BodyForce(ctx.cells, which, p.value, p.scale, sp.nlv)]


SPEC = Spec(
    "body_force", "a body force per reference volume on regions or the whole body", implied_by=("body_force",),
    read=_read, sets=lambda p: [("body_force_regions", r, "tets") for r in p.regions], build=_build,
    energies=(Energy("body_force_work", -1, "work potential f.x of the body forces (-body_force) [J]", work=True),),
    rows=(Row(("body_force", "body_force_regions", "body_force_ramp", "body_force_time"),
              "-body_force bx,by,bz -body_force_regions R1,…",
              "a body force [N/m³ of reference volume] on the physical volumes listed (default: the whole body); "
              "`-body_force_ramp A` or `-body_force_time EXPR`"),))
