"""The effects a scene can call for, one module each (see base.py for the residual they add to and for
`Spec`, what an effect declares), listed in REGISTRY; `build` constructs exactly the ones a scene names:
an effect not named is never built."""
from collections import Counter
from dataclasses import dataclass

import numpy as np

from ...core.errors import UserError
from . import (body_force, contact, damping, dirichlet, elasticity, follower, force, gravity, inertia, loads, pressure,
               rigid, spring, traction, viscoelastic)

# Every effect, in the order their options are listed and implied effects are added to a scene; -loads takes as its
# kinds the effects before it that declare a LoadKind (traction, pressure, force, spring).
_EFFECTS = (
    elasticity.SPEC,
    viscoelastic.SPEC,
    inertia.SPEC,
    damping.SPEC,
    damping.RAYLEIGH,
    gravity.SPEC,
    body_force.SPEC,
    traction.SPEC,
    follower.SPEC,
    pressure.SPEC,
    force.SPEC,
    spring.SPEC,
)
REGISTRY = _EFFECTS + (
    loads.spec([s for s in _EFFECTS if s.load is not None]),
    dirichlet.FIXED,
    dirichlet.PRESCRIBED,
    rigid.SPEC,
    contact.SPEC,
)
SPECS = {s.name: s for s in REGISTRY}
NAMES = tuple(SPECS)
DEFAULT = ("elasticity", "inertia")


def energies():
    """{column: base.Energy} of every effect, in registry order (an energy two effects report, once)."""
    out = {}
    for s in REGISTRY:
        for e in s.energies:
            out.setdefault(e.column, e)
    return out


@dataclass
class Context:
    """What an effect is built from: the distributed space, the elastic cell kernels of the material(s),
    the cells' geometry (kernels.Cells, for mass matrices and body forces), the density (a scalar, or one
    per local cell with -regions), the mass matrix kind, -hessian_projection and the largest Young's modulus of the
    solids in use (a stiffness scale: the contact barrier's default), and whether the run is quasi-static (time a load
    parameter: contact's friction smooths by a slip per step, not a speed)."""
    space: object
    kernels: object
    cells: object
    density: object
    lumped: bool = False
    projection: bool = False
    modulus: float = 1.0
    quasistatic: bool = False
    part_solids: tuple = ()     # [(local cell indices, or None: all; Solid)] of the kernels' parts (model.cell_kernels)


def build(scene, ctx):
    """(effects, constraints) of the scene (its effects: {name: parameters}, in order) in the Context."""
    effects, constraints = [], []
    for name, params in scene.effects.items():
        for item in SPECS[name].build(params, ctx):
            (constraints if isinstance(item, dirichlet.Constraint) else effects).append(item)
    for i, a in enumerate(constraints):       # no component may be held by two conditions
        for b in constraints[i + 1:]:
            both = ctx.space.mpi.allreduce(len(np.intersect1d(a.dofs, b.dofs)))
            if both:
                raise UserError(f"options {a.option} and {b.option} hold the same components of some vertices (a "
                                "shared surface or edge): give each component of a vertex one condition (e.g. "
                                "-fix S:xz with -prescribe_faces S:y)")
    return effects, constraints


def built(effects, constraints):
    """{effect name: instances built} of one run (stored in the output as JSON)."""
    return dict(Counter(e.name for e in list(effects) + list(constraints)))
