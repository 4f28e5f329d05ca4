"""What a scene calls for: mesh, material(s), effects with their parameters, time settings.
Everything is read and validated here, from the declarations of the materials (materials/) and the effects
(effects.REGISTRY), before any mesh is loaded or file written. Which options exist at all is the catalog's
(catalog.py, which reads these declarations and calls read_scene)."""
from dataclasses import dataclass, field

from .. import formulations
from ..physics import effects as effects_pkg
from ..physics import materials
from ..element.reference import ORDERS, TET_RULES
from ..core.errors import UserError
from ..output.fields import DEFAULT_FIELDS, output_fields
from ..mesh.generate import MAX_LEVEL
from ..discretization import partition
from ..core.options import Options, prefixed_names

OUTPUT_LAYOUTS = ("auto", "gather", "ranks")     # -output_layout (output/writer.py, output/ranks.py)

DEFAULT_MATERIAL = "stvk"
DEFAULT_EFFECTS = effects_pkg.DEFAULT
EFFECTS = effects_pkg.NAMES
# How effects switch on (stated in -help and the options reference, catalog.py):
EFFECTS_RULE = ("an effect is on when `-effects` lists it or one of its main options is given (`-gravity` adds "
                "gravity; elasticity is always on); a `-effects` on the command line replaces the scene file's "
                "effects: the scene file's options for effects that are not on otherwise are then ignored, and "
                "a note names them")


@dataclass
class Scene:
    """A scene's settings, with the application's defaults (the only place they are written)."""
    name: str
    mesh: str = None            # path, or None for the cached bar at `level`
    mesh_frame: int = -1        # the frame of an output file given as -mesh (default: the last)
    level: int = 1
    refine: int = 0             # uniform refinements of the mesh, made on the ranks after distributing it coarse
    partitioner: str = partition.DEFAULT    # how the cells are split among the ranks (discretization/partition.py)
    order: int = 0              # element order as given: 1 (4-node) or 2 (10-node) tetrahedra; 0: the mesh's own
    quadrature: int = 0         # degree of the stiffness rule as given (element.reference.TET_RULES); 0: the default
                                # (the run's element is decided once from both and the mesh: Element.decide)
    formulation: str = "auto"           # a formulations.REGISTRY name, or auto (formulations.choose)
    incompressible: bool = False        # the mixed formulation's incompressible limit (kappa -> inf)
    solid: materials.Solid = field(default_factory=lambda: materials.default_solid(DEFAULT_MATERIAL))
    lumped: bool = False
    quasistatic: bool = False
    step_forces: bool = None      # the forces of every accepted step in the statistics (default: quasistatic)
    effects: dict = field(default_factory=dict)   # {effect name: its parameters (None: it has none)}, in order
    notes: list = field(default_factory=list)     # what the user should know (options ignored), one line each
    ignored: list = field(default_factory=list)   # the scene file's options a command-line -effects overrode
    dt: float = 1e-2
    final_time: float = 1.0
    fps: float = 30.0
    jacobian: str = "assembled"
    matrix_free: str = ""         # "mf" (-snes_mf: PETSc's MFFD, no preconditioner), "mf_operator" or ""
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
    output_fields: tuple = DEFAULT_FIELDS   # what each frame holds (fields.OUTPUT_FIELDS)
    output_layout: str = "auto"             # gather (one file, rank 0) | ranks (a file per rank + FILE.h5's VDS)
    reuse_preconditioner: str = "auto"  # auto: keep a GAMG set-up until the Krylov iterations grow (solver.py)
    diverging_newton: int = 3           # full Newton steps: stop an attempt after this many diverging ones (solver.py)
    integrator: str = "beuler"    # beuler: backward Euler (thesis); ts: PETSc TS (-ts_type alpha2)
    energy_momentum: bool = False  # -integrator ts at rho_inf = 1: the discrete-gradient elastic force
    regions: list = field(default_factory=list)  # [Region]: a material per physical volume (-regions)

    def materials(self):
        """The material classes the scene uses (its own and its regions')."""
        return [self.solid.material] + [r.solid.material for r in self.regions]

    def set_uses(self):
        """(option, set name, "facets" | "tets") of every set the scene's effects use, in order."""
        return [u for name, params in self.effects.items() for u in effects_pkg.SPECS[name].set_uses(params)]

    def prefixes(self):
        """The names that prefix options: (regions, loads)."""
        ld = self.effects.get("loads")
        return [r.name for r in self.regions], (ld.names if ld is not None else [])


@dataclass
class Region:
    """A physical volume with its own material, read from options with the region's name as prefix
    (-NAME_material, -NAME_preset, -NAME_E, -NAME_nu, -NAME_rho and the material's own constants;
    defaults: the scene's own)."""
    name: str
    solid: materials.Solid

    def describe(self):
        return self.solid.describe()


MAX_REFINE = 8                     # 8^8 = 1.7e7 tetrahedra from each coarse one
MAX_STEPS, MAX_FRAMES = 1e9, 1e6   # a run beyond these is a typo, not a simulation on this machine
JACOBIANS = ("assembled", "shell", "seed_fd", "seed_fd2")
INTEGRATORS = ("beuler", "ts")
ASSEMBLIES = ("setvalues", "coo")
STORAGES = ("auto", "aij", "sbaij", "shell")   # the matrix the Krylov method multiplies by (solver.resolve_storage)


def read_scene(name, opts=None, from_scene=()):
    """The Scene from the options database: every value validated, defaults from the dataclass.
    from_scene: the options whose values came from the scene file (not the command line), for the rule
    by which effects switch on (EFFECTS_RULE)."""
    opts = opts or Options()
    s = Scene(name=name)
    _read_material(s, opts)
    s.regions = _read_regions(s, opts)
    _check_material_options(s, opts)
    _read_time(s, opts)
    _read_solver(s, opts)
    s.effects = read_effects(s, opts, set(from_scene))
    return s


def _read_material(s, opts):
    s.mesh = opts.string("mesh", s.mesh)
    s.mesh_frame = opts.integer("mesh_frame", s.mesh_frame)
    s.level = opts.integer("level", s.level, minimum=1)
    if s.level > MAX_LEVEL:
        raise UserError(f"option -level: {s.level}: levels go up to {MAX_LEVEL} (~2x the tets per level; for a finer "
                        "mesh give -mesh FILE)")
    if s.mesh is not None and opts.has("level"):
        raise UserError(f"options -mesh and -level: -level picks the built-in bar, -mesh {s.mesh} replaces it; give "
                        "one")
    s.refine = opts.integer("refine", s.refine, minimum=0)
    if s.refine > MAX_REFINE:
        raise UserError(f"option -refine: {s.refine}: at most {MAX_REFINE} (each level makes 8x the tetrahedra)")
    if opts.has("partitioner"):
        s.partitioner = opts.string("partitioner")
        why = partition.refusal(s.partitioner)
        if why:
            raise UserError(f"option -partitioner: {why}")
    if s.refine and s.partitioner == "metis":
        raise UserError("options -refine and -partitioner metis: -refine splits the coarse mesh into contiguous ranges "
                        "of its Morton order and refines them where they lie; METIS partitions a whole mesh on one "
                        "rank (give -partitioner morton, or a PETSc graph partitioner where this PETSc has one)")
    s.order = opts.integer("order", s.order) if opts.has("order") else s.order
    if opts.has("order") and s.order not in ORDERS:
        raise UserError(f"option -order: {s.order}: give 1 (linear, 4-node) or 2 (quadratic, 10-node tetrahedra)")
    s.quadrature = opts.integer("quadrature_degree", s.quadrature) if opts.has("quadrature_degree") else s.quadrature
    if opts.has("quadrature_degree") and s.quadrature not in TET_RULES:
        raise UserError(f"option -quadrature_degree: {s.quadrature}: the rules are of degree "
                        f"{', '.join(map(str, TET_RULES))}")
    s.solid = materials.read_solid(opts, "", s.solid, f"scene '{s.name}'")
    s.formulation = opts.choice("formulation", formulations.NAMES, s.formulation)
    for spec in formulations.REGISTRY:
        spec.read(opts, s)
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
    out = [Region(name, materials.read_solid(opts, f"{name}_", s.solid, f"region '{name}'"))
           for name in prefixed_names(opts, "regions")]
    if opts.has("regions") and not out:
        raise UserError("option -regions: needs a list of physical volumes (names or tags)")
    return out


def _check_material_options(s, opts):
    """A material constant given for a material that does not have it is a mistake, not a default."""
    solids = [("", s.solid)] + [(f"{r.name}_", r.solid) for r in s.regions]
    used = {p.name for _, sol in solids for p in sol.material.parameters}
    owners = {n: m for m in materials.MATERIALS.values() for n in m.list_options}     # (-ogden_mu: ogden's)
    for name, owner in owners.items():
        if opts.has(name) and all(sol.material is not owner for _, sol in solids):
            mats = ", ".join(dict.fromkeys(m.name for m in s.materials()))
            raise UserError(f"option -{name}: a list of {owner.name}'s constants, not of this scene's {mats}")
        for prefix, sol in solids[1:]:
            if opts.has(prefix + name) and sol.material is not owner:
                raise UserError(f"option -{prefix}{name}: a list of {owner.name}'s constants, not of region "
                                f"'{prefix[:-1]}''s {sol.material.name}")
    for name, param in materials.own_parameters().items():
        if opts.has(name) and name not in used:
            mats = ", ".join(dict.fromkeys(m.name for m in s.materials()))
            raise UserError(f"option -{name}: a constant of {_declaring(name)}, not of this scene's {mats}")
        for prefix, sol in solids[1:]:
            if opts.has(prefix + name) and param not in sol.material.parameters:
                raise UserError(f"option -{prefix}{name}: a constant of {_declaring(name)}, not of region "
                                f"'{prefix[:-1]}''s {sol.material.name}")


def _declaring(name):
    return " and ".join(m.name for m in materials.MATERIALS.values() if any(p.name == name for p in m.parameters))


def _read_time(s, opts):
    s.quasistatic = opts.flag("quasistatic", s.quasistatic)
    s.step_forces = opts.flag("step_forces", s.quasistatic if s.step_forces is None else s.step_forces)
    s.dt = opts.real("dt", s.dt, minimum=0)
    s.final_time = opts.real("final_time", s.final_time, minimum=0, exclusive=False)
    s.fps = opts.real("frames_per_second", s.fps, minimum=0)
    s.step_control = opts.flag("step_control", s.step_control)
    s.dt_min = opts.real("dt_min", s.dt / 1024, minimum=0)
    if s.dt_min > s.dt:
        raise UserError(f"option -dt_min: {s.dt_min:g} must be <= -dt {s.dt:g}")
    s.dt_grow_after = opts.integer("dt_grow_after", s.dt_grow_after, minimum=1)
    s.checkpoint_every = opts.integer("checkpoint_every", s.checkpoint_every, minimum=0)
    s.output_fields = output_fields(opts.names("output_fields", ""))
    s.output_layout = opts.choice("output_layout", OUTPUT_LAYOUTS, s.output_layout)
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
    if s.integrator == "ts" and s.step_forces:
        raise UserError("option -step_forces: each step's reactions and loads are backward Euler's (its residual at "
                        "the step's end); -integrator ts records none (-integrator beuler)")


def _read_solver(s, opts):
    s.jacobian = opts.choice("jacobian", JACOBIANS, s.jacobian)
    mf, mf_op = opts.flag("snes_mf"), opts.flag("snes_mf_operator")
    if mf and mf_op:
        raise UserError("options -snes_mf and -snes_mf_operator: choose one (-snes_mf_operator preconditions MFFD "
                        "with -jacobian's matrix, -snes_mf uses none)")
    s.matrix_free = "mf" if mf else "mf_operator" if mf_op else ""
    if mf and s.jacobian != "assembled":
        raise UserError(f"options -snes_mf and -jacobian {s.jacobian}: -snes_mf uses no Jacobian of ours (MFFD "
                        "replaces it); -snes_mf_operator preconditions with it")
    s.assembly = opts.choice("assembly", ASSEMBLIES, s.assembly)
    s.operator_storage = opts.choice("operator_storage", STORAGES, s.operator_storage)
    s.hessian_projection = opts.flag("hessian_projection", s.hessian_projection)
    s.reuse_preconditioner = opts.choice("reuse_preconditioner", ("auto", "never"), s.reuse_preconditioner)
    s.diverging_newton = opts.integer("diverging_newton", s.diverging_newton, minimum=0)
    s.objective = opts.flag("objective", s.objective)
    s.inversion_guard = opts.flag("inversion_guard",
                                  not all(m.defined_when_inverted for m in s.materials()))


def read_effects(s, opts, from_scene=frozenset()):
    """{name: parameters} of the effects the scene calls for, by EFFECTS_RULE: those -effects lists (or
    the defaults), and those an option switches on; each effect's parameters read by its spec. With a
    command-line -effects, the scene file's own options switch nothing on (they are ignored, with a note)."""
    where = f"scene '{s.name}'"
    listed = opts.names("effects", ",".join(DEFAULT_EFFECTS))
    for e in listed:
        if e not in EFFECTS:
            raise UserError(f"{where}: unknown effect '{e}' (known: {', '.join(EFFECTS)})")
    names = list(dict.fromkeys(listed))
    override = opts.has("effects") and "effects" not in from_scene     # the command line's list
    for spec in effects_pkg.REGISTRY:
        given = [k for k in spec.implied_by if opts.has(k) and not (override and k in from_scene)]
        if spec.name not in names and given:
            names.append(spec.name)
    if "elasticity" not in names:
        names.insert(0, "elasticity")
    out = {}
    for name in names:
        spec = effects_pkg.SPECS[name]
        if s.quasistatic and spec.dynamic:
            continue
        params = spec.parameters(opts, where)
        if spec.is_active(params):     # a parameter may switch the effect off (e.g. -damping 0)
            out[name] = params
    _unused_effect_options(s, opts, names, from_scene if override else ())
    return out


def _unused_effect_options(s, opts, names, overridden):
    """Options of effects the scene does not call for: the scene file's under a command-line -effects
    (`overridden`) are ignored, and a note names them; any other is an error (e.g. -traction_face
    without -traction)."""
    on = {k for n in names for r in effects_pkg.SPECS[n].rows for k in r.names} | _shared_with(names)
    for spec in effects_pkg.REGISTRY:
        for key in (k for r in spec.rows for k in r.names):
            if spec.name in names or key in on or key.startswith(("LOAD_", "REGION_")) or not opts.has(key):
                continue
            if key in overridden:
                s.ignored.append(key)
                continue
            raise UserError(f"option -{key}: an option of effect '{spec.name}', which scene '{s.name}' does not "
                            f"switch on (give its main option, or list it in -effects)")
    if s.ignored:
        s.notes.append(f"-effects {opts.string('effects')} on the command line replaces the scene file's effects: "
                       "ignored its " + " ".join(f"-{k}" for k in s.ignored))


def _shared_with(names):
    """Options an active effect reads from another effect's rows (the follower twist's surfaces)."""
    return {k for n in names for k in effects_pkg.SPECS[n].shares}
