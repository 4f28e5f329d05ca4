"""What a scene calls for: mesh, material, effects with their parameters, time settings.
Everything is read and validated here, before any mesh is loaded or file written."""
from dataclasses import dataclass, field

from . import materials
from .errors import UserError
from .options import Options

EFFECTS = ("elasticity", "inertia", "damping", "rayleigh", "gravity", "traction", "follower_traction",
           "fixed", "prescribed")
FACES = {"left": (0, "min"), "right": (0, "max"), "front": (1, "min"), "back": (1, "max"),
         "bottom": (2, "min"), "top": (2, "max")}
# an effect is implied by the option that carries its parameter (e.g. -gravity adds gravity)
IMPLIED_BY = {"damping": "damping", "rayleigh": ("rayleigh_alpha", "rayleigh_beta"), "gravity": "gravity",
              "traction": "traction", "follower_traction": "traction_twist", "fixed": "fix",
              "prescribed": "prescribe_motion"}


@dataclass
class Scene:
    name: str
    mesh: str = None            # path, or None for the cached bar at `level`
    level: int = 1
    material: object = None
    E: float = 1e6
    nu: float = 0.3
    rho: float = 1000.0
    mu: float = 0.0
    lam: float = 0.0
    lumped: bool = False
    quasistatic: bool = False
    effects: list = field(default_factory=list)
    params: dict = field(default_factory=dict)
    dt: float = 1e-2
    final_time: float = 1.0
    fps: float = 30.0
    jacobian: str = "assembled"
    assembly: str = "setvalues"   # how the assembled tangent is filled (jacobians.AssembledChunked / Assembled)
    hessian_projection: bool = False
    initial_scale: tuple = None   # x(0) = c + diag(s) (X - c), c the centroid (e.g. -1,1,1: mirrored)
    initial_spin: tuple = None    # v(0) = w x (X - c): angular velocity about the centroid [rad/s]
    initial_rotation: tuple = None  # x(0) = c + R(r) (X - c), r a rotation vector [rad] (after the scale)
    step_control: bool = True     # reject a failed step and retry with h/2, down to dt_min
    dt_min: float = 0.0
    dt_grow_after: int = 2        # successful steps before h is doubled back toward dt
    inversion_guard: bool = False # shorten Newton updates that would invert an element
    checkpoint_every: int = 0     # write the full state every N steps (0: only on SIGINT/SIGTERM)


JACOBIANS = ("assembled", "shell", "seed_fd", "seed_fd2")


def faces(opts, name):
    fs = opts.names(name)
    if not fs:
        raise UserError(f"option -{name}: needs a face list (e.g. left,right)")
    for f in fs:
        if f not in FACES:
            raise UserError(f"option -{name}: unknown face '{f}' (choose from {', '.join(FACES)})")
    return fs


def read_scene(name, opts=None):
    opts = opts or Options()
    s = Scene(name=name)
    s.mesh = opts.string("mesh", None)
    s.level = opts.integer("level", 1, minimum=1)
    s.material = materials.get(opts.string("material", "stvk"))
    preset = opts.string("preset", None)
    E, nu, rho = 1e6, 0.3, 1000.0
    if preset is not None:
        if preset not in materials.PRESETS:
            raise UserError(f"option -preset: unknown preset '{preset}' (choose from "
                            f"{', '.join(sorted(materials.PRESETS))})")
        E, nu, rho = materials.PRESETS[preset]
    s.E = opts.real("E", E)
    s.nu = opts.real("nu", nu)
    s.rho = opts.real("rho", rho)
    materials.check_parameters(s.E, s.nu, s.rho, where=f"scene '{name}'")
    s.lam, s.mu = materials.lame(s.E, s.nu)
    s.lumped = opts.choice("mass", ("consistent", "lumped"), "consistent") == "lumped"
    s.quasistatic = opts.flag("quasistatic")
    s.dt = opts.real("dt", 1e-2, minimum=0)
    s.final_time = opts.real("final_time", 1.0, minimum=0, exclusive=False)
    s.fps = opts.real("frames_per_second", 30.0, minimum=0)  # the thesis framework default
    s.jacobian = opts.choice("jacobian", JACOBIANS, "assembled")
    s.assembly = opts.choice("assembly", ("setvalues", "coo"), "setvalues")
    s.hessian_projection = opts.flag("hessian_projection")
    s.initial_scale = opts.vector("initial_scale")
    s.initial_spin = opts.vector("initial_spin")
    s.initial_rotation = opts.vector("initial_rotation")
    s.step_control = opts.flag("step_control", True)
    s.dt_min = opts.real("dt_min", s.dt / 1024, minimum=0)
    if s.dt_min > s.dt:
        raise UserError(f"option -dt_min: {s.dt_min:g} must be <= -dt {s.dt:g}")
    s.dt_grow_after = opts.integer("dt_grow_after", 2, minimum=1)
    s.inversion_guard = opts.flag("inversion_guard", not s.material.defined_when_inverted)
    s.checkpoint_every = opts.integer("checkpoint_every", 0, minimum=0)

    named = opts.names("effects", "elasticity,inertia")
    for e in named:
        if e not in EFFECTS:
            raise UserError(f"scene '{name}': unknown effect '{e}' (known: {', '.join(EFFECTS)})")
    effects = list(dict.fromkeys(named))
    for e, keys in IMPLIED_BY.items():
        keys = (keys,) if isinstance(keys, str) else keys
        if e not in effects and any(opts.has(k) for k in keys):
            effects.append(e)
    if "elasticity" not in effects:
        effects.insert(0, "elasticity")
    p = s.params
    if "damping" in effects:
        c = opts.real("damping", None, minimum=0, exclusive=False)
        if c is None:
            raise UserError(f"scene '{name}': effect 'damping' needs -damping c")
        if c == 0:
            effects.remove("damping")
        p["damping"] = c
    if "rayleigh" in effects:
        p["rayleigh_alpha"] = opts.real("rayleigh_alpha", 0.0, minimum=0, exclusive=False)
        p["rayleigh_beta"] = opts.real("rayleigh_beta", 0.0, minimum=0, exclusive=False)
        if p["rayleigh_alpha"] == 0 and p["rayleigh_beta"] == 0:
            effects.remove("rayleigh")
    if "gravity" in effects:
        p["gravity"] = opts.vector("gravity")
        if p["gravity"] is None:
            raise UserError(f"scene '{name}': effect 'gravity' needs -gravity gx,gy,gz")
    if "traction" in effects or "follower_traction" in effects:
        p["traction_face"] = opts.choice("traction_face", tuple(FACES), "right")
        p["traction_ramp"] = opts.real("traction_ramp", None)
    if "traction" in effects:
        p["traction"] = opts.vector("traction")
        if p["traction"] is None:
            raise UserError(f"scene '{name}': effect 'traction' needs -traction tx,ty,tz")
    if "follower_traction" in effects:
        p["traction_twist"] = opts.real("traction_twist", None)
        if p["traction_twist"] is None:
            raise UserError(f"scene '{name}': effect 'follower_traction' needs -traction_twist k")
    if "fixed" in effects:
        if not opts.has("fix"):
            raise UserError(f"scene '{name}': effect 'fixed' needs -fix faces (e.g. left)")
        p["fix"] = faces(opts, "fix")
    if "prescribed" in effects:
        from .effects.dirichlet import Prescribed
        if not opts.has("prescribe_motion") or not opts.has("prescribe_faces"):
            raise UserError(f"scene '{name}': effect 'prescribed' needs -prescribe_faces and -prescribe_motion")
        p["prescribe_faces"] = faces(opts, "prescribe_faces")
        p["prescribe_motion"] = opts.choice("prescribe_motion", Prescribed.MOTIONS, None)
        p["prescribe_amount"] = opts.real("prescribe_amount", 1.0)
    if s.quasistatic:
        for e in ("inertia", "damping", "rayleigh"):
            if e in effects:
                effects.remove(e)
    s.effects = effects
    return s


def face_set(space, names):
    import numpy as np
    return np.unique(np.concatenate([space.face_vertices(*FACES[f]) for f in names]))


def build(scene, space):
    """Construct exactly the effects the scene names (an effect not named is never built).
    Returns (effects, constraints, kernels)."""
    from .effects.damping import RayleighDamping, ViscousDamping
    from .effects.dirichlet import Fixed, Prescribed
    from .effects.elasticity import Elasticity
    from .effects.gravity import Gravity
    from .effects.inertia import Inertia
    from .effects.traction import FollowerTwist, Traction
    from .kernels import CellKernels
    s, p, nlv = scene, scene.params, space.nlv
    k = CellKernels(space.cells, space.Dminv, space.vol, s.material.kernel_id, s.mu, s.lam)
    effects, constraints = [], []
    for name in s.effects:
        if name == "elasticity":
            effects.append(Elasticity(k, s.material, s.hessian_projection))
        elif name == "inertia":
            effects.append(Inertia(k, s.rho, s.lumped, nlv))
        elif name == "damping":
            effects.append(ViscousDamping(k, p["damping"], s.lumped, nlv))
        elif name == "rayleigh":
            effects.append(RayleighDamping(k, s.rho, p["rayleigh_alpha"], p["rayleigh_beta"], s.lumped, nlv))
        elif name == "gravity":
            effects.append(Gravity(k, s.rho, p["gravity"], nlv))
        elif name in ("traction", "follower_traction"):
            tris = space.boundary_triangles(face_set(space, [p["traction_face"]]))
            if name == "traction":
                effects.append(Traction(space.X, tris, p["traction"], p["traction_ramp"], nlv))
            else:
                effects.append(FollowerTwist(space.X, tris, p["traction_twist"], p["traction_ramp"], nlv))
        elif name == "fixed":
            constraints.append(Fixed(space.X, face_set(space, p["fix"])))
        elif name == "prescribed":
            constraints.append(Prescribed(space.X, face_set(space, p["prescribe_faces"]), p["prescribe_motion"],
                                          p["prescribe_amount"]))
    return effects, constraints, k
