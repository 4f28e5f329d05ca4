"""What a scene calls for: mesh, material, effects with their parameters, time settings.
Everything is read and validated here, before any mesh is loaded or file written."""
import os
import re
from dataclasses import dataclass, field

from . import materials
from .errors import UserError
from .options import Options, insert_defaults, parse_options_file, resolve_scene

DEFAULT_MATERIAL = "stvk"
DEFAULT_EFFECTS = ("elasticity", "inertia")
EFFECTS = ("elasticity", "inertia", "damping", "rayleigh", "gravity", "traction", "follower_traction",
           "pressure", "loads", "fixed", "prescribed")
# an effect is implied by the option that carries its parameter (e.g. -gravity adds gravity)
IMPLIED_BY = {"damping": "damping", "rayleigh": ("rayleigh_alpha", "rayleigh_beta"), "gravity": "gravity",
              "traction": "traction", "follower_traction": "traction_twist", "pressure": "pressure", "loads": "loads",
              "fixed": "fix", "prescribed": ("prescribe_motion", "prescribe_x", "prescribe_y", "prescribe_z",
                                             "prescribe_ux", "prescribe_uy", "prescribe_uz")}


@dataclass
class Scene:
    """A scene's settings, with the application's defaults (the only place they are written)."""
    name: str
    mesh: str = None            # path, or None for the cached bar at `level`
    mesh_frame: int = -1        # the frame of an output file given as -mesh (default: the last)
    level: int = 1
    material: object = None     # a materials class (default: DEFAULT_MATERIAL)
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
    operator_storage: str = "auto"  # sbaij: Krylov MatMults on an SBAIJ copy of the symmetric tangent
    hessian_projection: bool = False
    objective: bool = True        # register the incremental potential with SNES (energy line search merit)
    initial_scale: tuple = None   # x(0) = c + diag(s) (X - c), c the centroid (e.g. -1,1,1: mirrored)
    initial_spin: tuple = None    # v(0) = w x (X - c): angular velocity about the centroid [rad/s]
    initial_rotation: tuple = None  # x(0) = c + R(r) (X - c), r a rotation vector [rad] (after the scale)
    step_control: bool = True     # reject a failed step and retry with h/2, down to dt_min
    dt_min: float = 0.0           # default: dt / 1024
    dt_grow_after: int = 2        # successful steps before h is doubled back toward dt
    inversion_guard: bool = False # shorten Newton updates that would invert an element (default: on for
                                  # materials undefined when inverted)
    checkpoint_every: int = 0     # write the full state every N steps (0: only on SIGINT/SIGTERM)
    reuse_preconditioner: str = "auto"  # auto: keep a GAMG set-up until the Krylov iterations grow (solver.py)
    integrator: str = "beuler"    # beuler: backward Euler (thesis); ts: PETSc TS (-ts_type alpha2)
    energy_momentum: bool = False  # -integrator ts at rho_inf = 1: the discrete-gradient elastic force
    regions: list = field(default_factory=list)  # [Region]: a material per physical volume (-regions)


@dataclass
class Region:
    """A physical volume with its own material, read from options with the region's name as prefix
    (-NAME_material, -NAME_preset, -NAME_E, -NAME_nu, -NAME_rho; defaults: the scene's own)."""
    name: str
    material: object
    E: float
    nu: float
    rho: float
    lam: float
    mu: float

    def describe(self):
        return describe_material(self.material, self.E, self.nu, self.rho)


def describe_material(material, E, nu, rho):
    """One line of a material and its parameters, as the set report prints it."""
    return f"{material.name}, E {E:g}, nu {nu:g}, rho {rho:g}"


PREFIX = re.compile(r"[A-Za-z0-9_]+")     # what a region's or load's name must be to prefix options
MAX_STEPS, MAX_FRAMES = 1e9, 1e6   # a run beyond these is a typo, not a simulation on this machine
JACOBIANS = ("assembled", "shell", "seed_fd", "seed_fd2")
INTEGRATORS = ("beuler", "ts")
ASSEMBLIES = ("setvalues", "coo")
STORAGES = ("auto", "aij", "sbaij")   # the matrix the Krylov method multiplies by (solver.resolve_storage)


def facet_sets(opts, name, default=None, components=False):
    """The facet sets an option names: a comma list of physical surface names or tags, or bounding-box
    faces (left, right, front, back, bottom, top); resolved against the mesh when it is read. With
    `components`, each may end in :x, :yz, ... (the components it holds; default all three). Returns
    [(name, components)]."""
    items = opts.names(name, default or "")
    if not items:
        raise UserError(f"option -{name}: needs a list of surfaces (physical names or tags, or left, right, "
                        "front, back, bottom, top)")
    out = []
    for it in items:
        set_name, sep, comps = it.partition(":")
        if not set_name:
            raise UserError(f"option -{name}: '{it}' names no surface")
        if sep and not components:
            raise UserError(f"option -{name}: '{it}': components (:{comps}) are not taken here")
        if sep and (not comps or set(comps) - set("xyz") or len(set(comps)) != len(comps)):
            raise UserError(f"option -{name}: '{it}': components must be some of x, y, z once each (e.g. "
                            f"{set_name}:x or {set_name}:xz)")
        out.append((set_name, comps if sep else "xyz"))
    return out


def facet_set_uses(s):
    """(option, set name) of every facet set the scene's effects use, in order."""
    p, out = s.params, []
    if "fixed" in s.effects:
        out += [("fix", n) for n, _ in p["fix"]]
    if "traction" in s.effects or "follower_traction" in s.effects:
        out += [("traction_face", n) for n, _ in p["traction_face"]]
    if "pressure" in s.effects:
        out += [("pressure_faces", n) for n, _ in p["pressure_faces"]]
    if "prescribed" in s.effects:
        out += [("prescribe_faces", n) for n, _ in p["prescribe_faces"]]
    if "loads" in s.effects:
        out += [(f"{load['name']}_faces", n) for load in p["loads"] for n, _ in load["faces"]]
    return out


def load_scene(scene_arg):
    """(Scene, path of its options file) for a built-in scene name or an options file: the file's
    options become defaults under the command line's, then everything is read and validated."""
    from .catalog import check_application_options, check_petsc_values
    path = resolve_scene(scene_arg)
    pairs = parse_options_file(path)
    insert_defaults(pairs)
    opts = Options()
    check_application_options(sorted(opts.o.getAll()), _prefixes(opts, "regions"), _prefixes(opts, "loads"),
                              {k for k, _ in pairs})
    check_petsc_values(opts.o)
    name = os.path.splitext(os.path.basename(path))[0]
    return read_scene(name), path


def _prefixes(opts, option):
    """The names -regions / -loads list that can be option prefixes (the others are refused when the
    scene is read)."""
    return [w for w in opts.names(option) if PREFIX.fullmatch(w)]


def read_scene(name, opts=None):
    """The Scene from the options database: every value validated, defaults from the dataclass."""
    opts = opts or Options()
    s = Scene(name=name)
    _read_material(s, opts)
    s.regions = _read_regions(s, opts)
    _read_time(s, opts)
    _read_solver(s, opts)
    s.effects = _read_effects(s, opts)
    return s


def _material_parameters(opts, prefix, default, where):
    """(material class, E, nu, rho) from -PREFIXmaterial, -PREFIXpreset, -PREFIXE, -PREFIXnu, -PREFIXrho,
    over `default` (material, E, nu, rho); validated."""
    mat = opts.string(f"{prefix}material", None)
    try:
        mat = default[0] if mat is None else materials.get(mat)
    except UserError as e:
        raise UserError(f"option -{prefix}material: {e}") from None
    preset = opts.string(f"{prefix}preset", None)
    E, nu, rho = default[1:]
    if preset is not None:
        if preset not in materials.PRESETS:
            raise UserError(f"option -{prefix}preset: unknown preset '{preset}' (choose from "
                            f"{', '.join(sorted(materials.PRESETS))})")
        E, nu, rho = materials.PRESETS[preset]
    E, nu, rho = opts.real(f"{prefix}E", E), opts.real(f"{prefix}nu", nu), opts.real(f"{prefix}rho", rho)
    materials.check_parameters(E, nu, rho, where=where)
    return mat, E, nu, rho


def _read_material(s, opts):
    s.mesh = opts.string("mesh", s.mesh)
    s.mesh_frame = opts.integer("mesh_frame", s.mesh_frame)
    from .mesh import MAX_LEVEL
    s.level = opts.integer("level", s.level, minimum=1)
    if s.level > MAX_LEVEL:
        raise UserError(f"option -level: {s.level}: levels go up to {MAX_LEVEL} (~2x the tets per level; for a finer "
                        "mesh give -mesh FILE)")
    if s.mesh is not None and opts.has("level"):
        raise UserError(f"options -mesh and -level: -level picks the built-in bar, -mesh {s.mesh} replaces it; give "
                        "one")
    s.material, s.E, s.nu, s.rho = _material_parameters(
        opts, "", (materials.get(DEFAULT_MATERIAL), s.E, s.nu, s.rho), f"scene '{s.name}'")
    s.lam, s.mu = materials.lame(s.E, s.nu)
    s.lumped = opts.choice("mass", ("consistent", "lumped"), "lumped" if s.lumped else "consistent") == "lumped"
    s.initial_scale = opts.vector("initial_scale")
    if s.initial_scale is not None and 0.0 in s.initial_scale:
        raise UserError(f"option -initial_scale: {opts.string('initial_scale')} has a zero scale (every element "
                        "would be flat)")
    s.initial_spin = opts.vector("initial_spin")
    s.initial_rotation = opts.vector("initial_rotation")


def _read_regions(s, opts):
    """-regions A,B,...: physical volumes (names or tags) each with its own material, read with the
    region's name as option prefix; cells in none of them keep the scene's material."""
    out = []
    for name in opts.names("regions"):
        _option_prefix(name, "regions")
        if any(r.name == name for r in out):
            raise UserError(f"option -regions: '{name}' is listed twice")
        mat, E, nu, rho = _material_parameters(opts, f"{name}_", (s.material, s.E, s.nu, s.rho),
                                               f"region '{name}'")
        lam, mu = materials.lame(E, nu)
        out.append(Region(name, mat, E, nu, rho, lam, mu))
    if opts.has("regions") and not out:
        raise UserError("option -regions: needs a list of physical volumes (names or tags)")
    return out


def materials_of(s):
    """The material classes a scene uses (its own and its regions')."""
    return [s.material] + [r.material for r in s.regions]


def _read_time(s, opts):
    s.quasistatic = opts.flag("quasistatic", s.quasistatic)
    s.dt = opts.real("dt", s.dt, minimum=0)
    s.final_time = opts.real("final_time", s.final_time, minimum=0, exclusive=False)
    s.fps = opts.real("frames_per_second", s.fps, minimum=0)
    s.step_control = opts.flag("step_control", s.step_control)
    s.dt_min = opts.real("dt_min", s.dt / 1024, minimum=0)
    if s.dt_min > s.dt:
        raise UserError(f"option -dt_min: {s.dt_min:g} must be <= -dt {s.dt:g}")
    s.dt_grow_after = opts.integer("dt_grow_after", s.dt_grow_after, minimum=1)
    s.checkpoint_every = opts.integer("checkpoint_every", s.checkpoint_every, minimum=0)
    s.integrator = opts.choice("integrator", INTEGRATORS, s.integrator)
    s.energy_momentum = opts.flag("energy_momentum", s.energy_momentum)
    if s.energy_momentum and s.integrator != "ts":
        raise UserError("option -energy_momentum: modifies the midpoint step of -integrator ts "
                        "(-ts_alpha_radius 1); backward Euler has none")
    if s.final_time > 0 and s.dt > s.final_time:
        raise UserError(f"option -dt: {s.dt:g} is longer than -final_time {s.final_time:g}")
    if s.final_time / s.dt > MAX_STEPS:
        raise UserError(f"options -final_time {s.final_time:g} and -dt {s.dt:g}: more than {MAX_STEPS:.0e} steps")
    if s.final_time * s.fps > MAX_FRAMES:
        raise UserError(f"options -final_time {s.final_time:g} and -frames_per_second {s.fps:g}: more than "
                        f"{MAX_FRAMES:.0e} frames")
    if s.quasistatic and s.initial_spin is not None and any(s.initial_spin):
        raise UserError("options -quasistatic and -initial_spin: a quasi-static run has no velocity to start with")
    if s.integrator == "ts" and s.quasistatic:
        raise UserError("option -integrator ts: integrates dynamics; -quasistatic steps use -integrator beuler")


def _read_solver(s, opts):
    s.jacobian = opts.choice("jacobian", JACOBIANS, s.jacobian)
    mf, mf_op = opts.flag("snes_mf"), opts.flag("snes_mf_operator")
    if mf and mf_op:
        raise UserError("options -snes_mf and -snes_mf_operator: choose one (-snes_mf_operator preconditions MFFD "
                        "with -jacobian's matrix, -snes_mf uses none)")
    if mf and s.jacobian != "assembled":
        raise UserError(f"options -snes_mf and -jacobian {s.jacobian}: -snes_mf uses no Jacobian of ours (MFFD "
                        "replaces it); -snes_mf_operator preconditions with it")
    s.assembly = opts.choice("assembly", ASSEMBLIES, s.assembly)
    s.operator_storage = opts.choice("operator_storage", STORAGES, s.operator_storage)
    s.hessian_projection = opts.flag("hessian_projection", s.hessian_projection)
    s.reuse_preconditioner = opts.choice("reuse_preconditioner", ("auto", "never"), s.reuse_preconditioner)
    s.objective = opts.flag("objective", s.objective)
    s.inversion_guard = opts.flag("inversion_guard",
                                  not all(m.defined_when_inverted for m in materials_of(s)))


def _read_effects(s, opts):
    """The effects the scene names (-effects), plus those implied by an option carrying their
    parameter; each effect's parameters into s.params."""
    named = opts.names("effects", ",".join(DEFAULT_EFFECTS))
    for e in named:
        if e not in EFFECTS:
            raise UserError(f"scene '{s.name}': unknown effect '{e}' (known: {', '.join(EFFECTS)})")
    effects = list(dict.fromkeys(named))
    for e, keys in IMPLIED_BY.items():
        keys = (keys,) if isinstance(keys, str) else keys
        if e not in effects and any(opts.has(k) for k in keys):
            effects.append(e)
    if "elasticity" not in effects:
        effects.insert(0, "elasticity")
    for e in list(effects):
        if e in PARAMETERS and not PARAMETERS[e](s, opts, s.params):
            effects.remove(e)          # a parameter that switches the effect off (e.g. -damping 0)
    if s.quasistatic:
        effects = [e for e in effects if e not in ("inertia", "damping", "rayleigh")]
    return effects


def _needs(s, effect, what):
    raise UserError(f"scene '{s.name}': effect '{effect}' needs {what}")


def _damping(s, opts, p):
    c = opts.real("damping", None, minimum=0, exclusive=False)
    if c is None:
        _needs(s, "damping", "-damping c")
    p["damping"] = c
    return c != 0


def _rayleigh(s, opts, p):
    p["rayleigh_alpha"] = opts.real("rayleigh_alpha", 0.0, minimum=0, exclusive=False)
    p["rayleigh_beta"] = opts.real("rayleigh_beta", 0.0, minimum=0, exclusive=False)
    return p["rayleigh_alpha"] != 0 or p["rayleigh_beta"] != 0


def _gravity(s, opts, p):
    p["gravity"] = opts.vector("gravity")
    if p["gravity"] is None:
        _needs(s, "gravity", "-gravity gx,gy,gz")
    return True


def time_function(opts, prefix):
    """A load's time function: -PREFIX_time EXPR (an expression of t), or -PREFIX_ramp A (A min(t,1));
    None (factor 1) without either."""
    from .expressions import TimeFunction
    if opts.has(f"{prefix}_time") and opts.has(f"{prefix}_ramp"):
        raise UserError(f"options -{prefix}_time and -{prefix}_ramp: give one time function, not both")
    if opts.has(f"{prefix}_time"):
        return TimeFunction(opts.string(f"{prefix}_time"), f"option -{prefix}_time")
    return opts.real(f"{prefix}_ramp", None)


def _option_prefix(name, option):
    if not PREFIX.fullmatch(name):
        raise UserError(f"option -{option}: '{name}' cannot be an option prefix (letters, digits and _ only; a "
                        "physical group can also be named by its tag)")


def _traction_face(opts, p):
    p["traction_face"] = facet_sets(opts, "traction_face", "right")
    p["traction_ramp"] = time_function(opts, "traction")


def _traction(s, opts, p):
    _traction_face(opts, p)
    p["traction"] = opts.vector("traction")
    if p["traction"] is None:
        _needs(s, "traction", "-traction tx,ty,tz")
    return True


def _follower_traction(s, opts, p):
    _traction_face(opts, p)
    p["traction_twist"] = opts.real("traction_twist", None)
    if p["traction_twist"] is None:
        _needs(s, "follower_traction", "-traction_twist k")
    return True


def _pressure(s, opts, p):
    p["pressure"] = opts.real("pressure", None)
    if p["pressure"] is None or not opts.has("pressure_faces"):
        _needs(s, "pressure", "-pressure p and -pressure_faces surfaces")
    p["pressure_faces"] = facet_sets(opts, "pressure_faces")
    p["pressure_ramp"] = time_function(opts, "pressure")
    return True


def _loads(s, opts, p):
    """-loads A,B,...: loads each with its own surfaces and time function, read with the load's name as
    prefix: -A_traction tx,ty,tz (dead, per reference area) or -A_pressure p (follower), -A_faces S1,...,
    -A_time EXPR or -A_ramp R."""
    out = []
    for name in opts.names("loads"):
        _option_prefix(name, "loads")
        if any(d["name"] == name for d in out):
            raise UserError(f"option -loads: '{name}' is listed twice")
        tr, pr = opts.has(f"{name}_traction"), opts.has(f"{name}_pressure")
        if tr == pr:
            raise UserError(f"load '{name}': give one of -{name}_traction tx,ty,tz or -{name}_pressure p")
        if not opts.has(f"{name}_faces"):
            raise UserError(f"load '{name}': needs -{name}_faces (physical surface names or tags, or box faces)")
        out.append({"name": name, "kind": "traction" if tr else "pressure",
                    "value": opts.vector(f"{name}_traction") if tr else opts.real(f"{name}_pressure"),
                    "faces": facet_sets(opts, f"{name}_faces"), "scale": time_function(opts, name)})
    if not out:
        _needs(s, "loads", "-loads NAME,... with -NAME_traction or -NAME_pressure and -NAME_faces")
    p["loads"] = out
    return True


def _fixed(s, opts, p):
    if not opts.has("fix"):
        _needs(s, "fixed", "-fix faces (e.g. left)")
    p["fix"] = facet_sets(opts, "fix", components=True)
    return True


def _prescribed(s, opts, p):
    """-prescribe_faces S[:xyz],... moved by a preset (-prescribe_motion M, amount -prescribe_amount A)
    and/or per component by expressions of t, X, Y, Z, A: positions -prescribe_x/_y/_z or displacements
    -prescribe_ux/_uy/_uz (an expression replaces the preset's for its component); components
    with neither stay at their reference positions."""
    from .effects.dirichlet import PRESETS
    from .expressions import Expression
    given = [k for k in ("x", "y", "z") if opts.has(f"prescribe_{k}") or opts.has(f"prescribe_u{k}")]
    if not opts.has("prescribe_faces") or not (opts.has("prescribe_motion") or given):
        _needs(s, "prescribed", "-prescribe_faces and -prescribe_motion or expressions -prescribe_x/_ux ...")
    p["prescribe_faces"] = facet_sets(opts, "prescribe_faces", components=True)
    p["prescribe_amount"] = opts.real("prescribe_amount", 1.0)
    motion = opts.choice("prescribe_motion", tuple(PRESETS), None) if opts.has("prescribe_motion") else None
    p["prescribe_motion"] = motion
    where = f"preset {motion}"
    exprs = {k: (text, kind, where) for k, (text, kind) in PRESETS[motion].items()} if motion else {}
    held = set("".join(c for _, c in p["prescribe_faces"]))
    for k in "xyz":
        if opts.has(f"prescribe_{k}") and opts.has(f"prescribe_u{k}"):
            raise UserError(f"options -prescribe_{k} and -prescribe_u{k}: give the position or the displacement "
                            f"of component {k}, not both")
        for kind, key in (("position", f"prescribe_{k}"), ("displacement", f"prescribe_u{k}")):
            if opts.has(key):
                if k not in held:
                    raise UserError(f"option -{key}: component {k} is not held on any of -prescribe_faces "
                                    f"({','.join(n + ':' + c for n, c in p['prescribe_faces'])})")
                exprs[k] = (opts.string(key), kind, f"option -{key}")
    p["prescribe"] = {k: (Expression(text, ("t", "X", "Y", "Z", "A"), where), kind)
                      for k, (text, kind, where) in exprs.items()}
    return True


# effect -> reader of its parameters (returns False when they switch the effect off)
PARAMETERS = {"damping": _damping, "rayleigh": _rayleigh, "gravity": _gravity, "traction": _traction,
              "follower_traction": _follower_traction, "pressure": _pressure, "loads": _loads, "fixed": _fixed,
              "prescribed": _prescribed}
