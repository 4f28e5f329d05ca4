"""The effects a scene can call for, one module each (see base.py for the residual they add to), and
`build`, which constructs exactly the ones a scene names: an effect not named is never built."""
from collections import Counter

import numpy as np

from ..errors import UserError


def held(space, specs):
    """(local vertices, (n, 3) held components) of [(set name, components)] (a vertex in several sets
    holds the union of their components)."""
    comps = np.zeros((space.nlv, 3), bool)
    for name, cs in specs:
        comps[np.ix_(space.set_vertices(name), ["xyz".index(c) for c in cs])] = True
    vertices = np.flatnonzero(comps.any(axis=1))
    return vertices, comps[vertices]


def build(scene, space, kernels, density=None):
    """(effects, constraints) of the scene on the space, in the scene's order; `kernels` are the
    cell kernels of its material(s) on the space's cells, `density` the scene's (default) or one per
    local cell (-regions)."""
    from .damping import RayleighDamping, ViscousDamping
    from .dirichlet import Fixed, Prescribed
    from .elasticity import Elasticity
    from .gravity import Gravity
    from .inertia import Inertia
    from .traction import FollowerTwist, Pressure, Traction
    s, p, nlv, k = scene, scene.params, space.nlv, kernels
    rho = s.rho if density is None else density
    effects, constraints = [], []
    for name in s.effects:
        if name == "elasticity":
            effects.append(Elasticity(k, s.hessian_projection))
        elif name == "inertia":
            effects.append(Inertia(k, rho, s.lumped, nlv))
        elif name == "damping":
            effects.append(ViscousDamping(k, p["damping"], s.lumped, nlv))
        elif name == "rayleigh":
            effects.append(RayleighDamping(k, rho, p["rayleigh_alpha"], p["rayleigh_beta"], s.lumped, nlv))
        elif name == "gravity":
            effects.append(Gravity(k, rho, p["gravity"], nlv))
        elif name in ("traction", "follower_traction"):
            tris = space.set_triangles([n for n, _ in p["traction_face"]])
            if name == "traction":
                effects.append(Traction(space.X, tris, p["traction"], p["traction_ramp"], nlv))
            else:
                effects.append(FollowerTwist(space.X, tris, p["traction_twist"], p["traction_ramp"], nlv))
        elif name == "pressure":
            tris = space.set_triangles([n for n, _ in p["pressure_faces"]])
            effects.append(Pressure(space.X, tris, p["pressure"], p["pressure_ramp"]))
        elif name == "loads":
            for load in p["loads"]:
                tris = space.set_triangles([n for n, _ in load["faces"]])
                if load["kind"] == "traction":
                    effects.append(Traction(space.X, tris, load["value"], load["scale"], nlv))
                else:
                    effects.append(Pressure(space.X, tris, load["value"], load["scale"]))
        elif name == "fixed":
            constraints.append(Fixed(space.X, *held(space, p["fix"])))
        elif name == "prescribed":
            vertices, comps = held(space, p["prescribe_faces"])
            constraints.append(Prescribed(space.X, vertices, p["prescribe"], p["prescribe_amount"], comps))
    if len(constraints) == 2:         # -fix and -prescribe_faces: no component may be held by both
        both = space.mpi.allreduce(len(np.intersect1d(constraints[0].dofs, constraints[1].dofs)))
        if both:
            raise UserError("options -fix and -prescribe_faces hold the same components of some vertices (a "
                            "shared surface or edge): give each component of a vertex one condition (e.g. "
                            "-fix S:xz with -prescribe_faces S:y)")
    return effects, constraints


def built(effects, constraints):
    """{effect name: instances built} of one run (stored in the output as JSON)."""
    return dict(Counter(e.name for e in list(effects) + list(constraints)))
