"""Every option of the application, with its default and a line of help: the one list that
`hyperelastic run --help` / `-help` prints, that the unknown-option check reads, and that the options reference's
table is generated from (`python -m hyperelastic.app.catalog --reference`: docs/reference/options.md; a test
keeps them equal).

Options named after a region or a load (`-soft_E`, `-pull_faces`) are written with the placeholder
REGION or LOAD and expanded with the names the scene lists in -regions / -loads.

Options that are not the application's are PETSc's: they pass the first check when they belong to a
PETSc family (snes_, ksp_, pc_, ts_, mat_, dm_, log_ ...); once SNES (and TS) have read the options
database, an option of the solver families (snes_, ksp_, pc_, ts_) that PETSc did not use is an
error too, except the families PETSc reads only later (sub-solvers, multigrid levels, viewers)."""
import difflib
import math
import os
import re
import sys
import textwrap

from .. import formulations
from ..physics import effects, materials
from ..element.reference import DEFAULT_DEGREE, TET_RULES
from ..discretization import partition
from ..core.errors import UserError
from ..core.files import VIEWERS
from ..core.options import PREFIX, Options, Row, all_options, insert_defaults, parse_options_file, resolve_scene
from .scene import (ASSEMBLIES, DEFAULT_EFFECTS, DEFAULT_MATERIAL, EFFECTS, EFFECTS_RULE, INTEGRATORS, JACOBIANS,
                    STORAGES, Scene, read_scene)

_S = Scene(name="SCENE")
_OWN = tuple(materials.own_parameters()) + tuple(dict.fromkeys(      # the materials' own constants (-C10, -kappa,
    n for m in materials.MATERIALS.values() for n in m.list_options))   # ...) and lists of them (-ogden_mu)


def _material_list():
    return ", ".join(f"`{m.name}`" + (f" ({m.summary})" if m.summary else "") for m in materials.MATERIALS.values())


HEAD = (
    Row(("mesh", "mesh_frame"), "-mesh FILE", "any tetrahedral mesh meshio reads (.msh with physical groups, .vtu, "
        ".mesh …), an output of this application (.h5 or its .xdmf: the configuration of frame `-mesh_frame N`, "
        "default the last, becomes the reference; regions kept), or a prepared mesh (`hyperelastic mesh MESH --prepare "
        "-o FILE.h5`), which every rank reads its own slice of", "cached bar at `-level`"),
    Row(("level",), "-level N", "bar mesh level: 1..8 = thesis L1..L8 (edge 0.80 … 0.30), 9.. finer (≈2× tets each)",
        f"{_S.level}"),
    Row(("refine",), "-refine K", "refine the mesh K times uniformly after distributing it coarse: every rank splits "
        "each of its tetrahedra into 8 (new vertices at edge midpoints; at the first level of a quadratic mesh its "
        "edge nodes), so no rank holds the whole fine mesh and set-up scales with the ranks; physical surfaces, "
        "volumes and regions follow exactly (4 facets per facet, 8 cells per cell a level); the same numbering on "
        "any rank count. Curved surfaces stay as faceted as the coarse mesh (a quadratic coarse mesh: as its edge "
        "nodes place them). Not with `-partitioner metis`", f"{_S.refine}"),
    Row(("partitioner",), "-partitioner NAME", "how the cells are split among the MPI ranks: `morton` (equal "
        "contiguous ranges along a Z-curve through the cells: PETSc's `simple` partitioner on the spatially ordered "
        "mesh), `metis` (METIS on the cells' face graph, through PETSc's `shell` partitioner; seeded); PETSc's "
        "`parmetis`, `ptscotch`, `chaco` where the PETSc in use has them. The start-up report gives the faces cut "
        "and the largest part against the mean", partition.DEFAULT),
    Row(("order",), "-order 1|2", "element order: 1, linear tetrahedra (4 nodes); 2, quadratic (10 nodes: a "
        "linear mesh gets straight edges with a node at each midpoint, a quadratic mesh (`hyperelastic mesh "
        "--order 2`, or an output of an order-2 run) keeps its curved ones); `-order 1` on a quadratic mesh "
        "uses its corners", "the mesh's (1 for the bar)"),
    Row(("quadrature_degree",), "-quadrature_degree N", "the degree of the rule that integrates quadratic "
        "tetrahedra's stiffness: " + ", ".join(f"{d} ({len(TET_RULES[d][1])} points)" for d in TET_RULES if d > 1)
        + "; the mass matrix and the loads are integrated exactly on straight cells", str(DEFAULT_DEGREE[2])),
    Row(("formulation",), "-formulation " + "|".join(formulations.NAMES), "; ".join(
        f"`{f.name}`: {f.summary}" for f in formulations.REGISTRY) + ". `auto`: the first formulation that claims the "
        "scene, else displacement (a start-up note says which; the output's `formulation` attribute records it)",
        _S.formulation),
) + formulations.rows() + (
    Row(("material",), "-material NAME", _material_list(), DEFAULT_MATERIAL),
    Row(("hessian_projection",), "-hessian_projection", "element tangents projected to positive semi-definite "
        "(eigenvalues clamped at 0), and the contact barrier's pairs with triangulated obstacles pair by pair as "
        "those within the contact surface are (else exact in the body's unknowns); the residual is unchanged", "off"),
    Row(("objective",), "-objective", "register the incremental potential E(x) (backward Euler as energy "
        "minimization) with SNES, so the line search uses the energy as merit; a scene with an effect that has none "
        "(follower traction) falls back to the residual norm and says so. `-objective 0`: residual-norm merit", "on"),
    Row(("inversion_guard",), "-inversion_guard", "shorten any Newton update that would invert an element (a "
        "line-search pre-check)", "on for " + ", ".join(m.name for m in materials.MATERIALS.values()
                                                 if not m.defined_when_inverted)),
    Row(("step_control", "dt_grow_after"), "-step_control", "reject a step whose solve fails (or gives NaN/Inf), "
        "retry with h/2; regrow ×2 after `-dt_grow_after N` accepted steps", f"on, N = {_S.dt_grow_after}"),
    Row(("dt_min",), "-dt_min", "below this step size the run stops with one line naming step, time and reason",
        "dt/1024"),
    Row(("initial_scale", "initial_rotation", "initial_spin"),
        "-initial_scale sx,sy,sz / -initial_rotation rx,ry,rz / -initial_spin wx,wy,wz",
        "initial state about the centroid c: x = c + diag(s)(X − c), then rotated by the rotation vector r; "
        "v = w × (x − c) (no scale may be 0; no spin with `-quasistatic`)", "rest"),
    Row(("E", "nu", "rho"), "-E -nu -rho", "Young's modulus [Pa], Poisson's ratio, density [kg/m³]",
        f"{_S.solid.values['E']:g}, {_S.solid.values['nu']:g}, {_S.solid.rho:g}"),
) + tuple(materials.rows()) + (
    Row(("regions", "REGION_material", "REGION_preset", "REGION_E", "REGION_nu", "REGION_rho")
        + tuple(f"REGION_{n}" for n in _OWN), "-regions R1,R2,…",
        "a material per physical volume (name or tag): `-R1_material`, `-R1_preset`, `-R1_E`, `-R1_nu`, `-R1_rho` "
        "and its material's constants (PETSc-style prefixes; defaults: the un-prefixed ones, which also hold for "
        "cells in no listed region); each region's parameters checked like the scene's", "one material"),
    Row(("preset",), "-preset NAME", ", ".join(materials.PRESETS)),
    Row(("mass",), "-mass", "`consistent` or `lumped` (also used for damping matrices)",
        "lumped" if _S.lumped else "consistent"),
    Row(("effects",), "-effects LIST", f"effects: {', '.join(EFFECTS)}. Rule: {EFFECTS_RULE}",
        ",".join(DEFAULT_EFFECTS)),
)

TAIL = (
    Row(("quasistatic",), "-quasistatic", "no inertia or damping: solve k(x) = f(t) per step", "off"),
    Row(("step_forces",), "-step_forces [0|1]", "the reactions and load resultants of every accepted step in the "
        "statistics (`reaction_NAME_Fx` ... `_Mz`, `load_NAME_...`; `report --forces --frame N`); a dynamic run "
        "pays ~10% for them (one residual evaluation per effect and step)", "on for -quasistatic, else off"),
    Row(("dt", "final_time", "frames_per_second"), "-dt -final_time -frames_per_second",
        "time step, end time, output frames per second (at most 1e9 steps and 1e6 frames)",
        f"{_S.dt:g}, {_S.final_time:g}, {_S.fps:g}"),
    Row(("jacobian",), "-jacobian MODE", "`assembled` (AIJ, block size 3), `shell` (exact, matrix-free), "
        "`seed_fd`, `seed_fd2` (the thesis' formulas); not with `-snes_mf`, which uses none", _S.jacobian),
    Row(("assembly",), "-assembly setvalues|coo", "how the assembled tangent is filled: `setvalues` preallocates the "
        "AIJ with its exact pattern (from the cell adjacency, on any number of ranks) and adds the cell blocks a chunk at a "
        "time (8,192 linear cells, 16 MB of blocks at most), straight into its values through a per-cell map of positions (~1.0 KB/tet in all at 660k tets; "
        "cells at a partition boundary at positions found once, the rows another rank owns sent to it in one "
        "Alltoallv); `coo` uses PETSc's COO path (as fast, ~5.7 KB/tet)", _S.assembly),
    Row(("operator_storage",), "-operator_storage auto|aij|sbaij|shell", "`sbaij`: the Krylov method and the multigrid "
        "smoothers multiply by an SBAIJ copy of the assembled tangent (its upper block triangle, gathered from "
        "the AIJ after every fill: about 60% of the bytes per MatMult, ~120 B/tet more memory); the "
        "preconditioner is still built from the AIJ. Only for a symmetric tangent (`-jacobian assembled`, "
        "`-assembly setvalues`, no follower loads, no `-snes_mf_operator`). `shell`: the Krylov method "
        "multiplies by the exact tangent applied cell by cell (as `-jacobian shell`), the preconditioner is built "
        "from the assembled AIJ. With `-formulation mixed`, `sbaij` is a MatNest whose displacement block is "
        "SBAIJ (the field split's GAMG smooths with it), under the field split only. `auto`: sbaij where it applies, else aij (the output's `operator_storage` attribute says which)", _S.operator_storage),
    Row(("reuse_preconditioner",), "-reuse_preconditioner auto|never", "`auto`: a GAMG set-up is kept across "
        "Newton iterations and time steps (SNESSetLagPreconditioner, persisting) until a Krylov solve needs more "
        "than 1.5× the iterations of the first solve after it, or fails; then it is rebuilt at the next Jacobian "
        "(and at every checkpoint). With `-formulation mixed` the same holds for the field split's displacement "
        "GAMG (PCSetReusePreconditioner on that split). `never`: a set-up per Jacobian. An explicit "
        "`-snes_lag_preconditioner` wins",
        _S.reuse_preconditioner),
    Row(("diverging_newton",), "-diverging_newton K", "with a line search that may raise the residual norm (full "
        "steps, `-snes_linesearch_type basic`, or the critical point's, `cp`: the mixed formulation's default): an "
        "attempt whose residual norm stays above 10× the smallest it has had for K Newton iterations in a row is "
        "stopped as diverged (step control halves it) instead of running to `-snes_max_it`; 0: never",
        str(_S.diverging_newton)),
    Row(("output",), "-output FILE.h5", "output file (an `.xdmf` is written beside it); it may not be an input",
        "output/SCENE.h5"),
    Row(("output_fields",), "-output_fields LIST", "what each frame holds besides `x`: `displacement`, "
        "`velocity` (point); `J`, `energy_density`, `von_mises` (cell); on request `stress` (Cauchy, Tensor6: xx, "
        "xy, xz, yy, yz, zz), `principal_stress` (its eigenvalues, largest first), `strain` (Green–Lagrange, "
        "Tensor6), `fibre1_stretch`, `fibre2_stretch` (`hgo`'s fibre stretches |F a|; NaN in cells without the "
        "family), `NAME_nodal` of any cell field (averaged at the nodes, weighted by the cells' volumes), "
        "`stress_recovered` (point, Tensor6: each cell's stress at its quadrature points fitted linearly, taken to "
        "its nodes and averaged there: h^2 accurate on quadratic tetrahedra, where cell values are h) and "
        "`von_mises_recovered`; `default`, `all`. With the mixed formulation the stress's mean is the pressure field's",
        "default (displacement, velocity, J, energy_density, von_mises)"),
    Row(("output_layout",), "-output_layout auto|gather|ranks", "`gather`: rank 0 gathers every frame and writes "
        "FILE.h5 alone, in the input mesh's node and cell order; `ranks`: every rank writes its own part of each frame "
        "to FILE.h5.d/TAG_rNNNNN.h5 and FILE.h5 presents them as the same datasets (HDF5 virtual datasets), in the "
        "partition's order with `mesh/input_index` and `mesh/cell_input_index` giving each row's input index. "
        "`auto`: gather on one rank, ranks on several. A restart writes on in the layout of its file",
        "auto"),
    Row(("checkpoint_every",), "-checkpoint_every N", "write the full state (x, v, t, step-control state) into "
        "FILE.h5 every N steps", "0 (only on a signal)"),
    Row(("integrator",), "-integrator beuler|ts", "`beuler`: backward Euler (the thesis' integrator, one SNES solve "
        "per step); `ts`: PETSc TS on the second-order form M a + C v + k(x) = f(t) with `-ts_type alpha2` "
        "(generalized-α; `-ts_alpha_radius ρ∞`, `-ts_alpha_alpha_m/_alpha_f/_gamma/_beta`), `-ts_adapt_type "
        "none|basic|dsp` with `-ts_rtol -ts_atol`, `-ts_adapt_monitor`, `-ts_max_snes_failures`, "
        "`-ts_max_step_rejections`", _S.integrator),
    Row(("energy_momentum",), "-energy_momentum", "with `-integrator ts` and `-ts_alpha_radius 1` (the midpoint "
        "rule): the elastic force of each step is the discrete gradient of the strain energy between its ends "
        "(Simo & Tarnow 1992; Gonzalez 2000), so total energy and angular momentum are conserved to the solver's "
        "tolerance; the Jacobian stays the midpoint tangent (Newton converges linearly; `-snes_mf_operator` "
        "gives the exact one)", "off"),
    Row(("quiet",), "-quiet", "no progress lines, start-up report or forces table (notes and warnings are still printed)"),
    Row(("debug",), "-debug", "a Python traceback instead of the one-line error"),
    Row(("help",), "-help", "this list (with the scene's values), then PETSc's own options as its solvers read "
        "them; nothing is run or written"),
)

ROWS = HEAD + tuple(row for spec in effects.REGISTRY for row in spec.rows) + TAIL

# the choices a row's values come from, checked against the scene reader's own lists by the tests
CHOICES = {"material": materials.REGISTRY, "jacobian": JACOBIANS, "formulation": formulations.NAMES, "assembly": ASSEMBLIES,
           "operator_storage": STORAGES, "integrator": INTEGRATORS, "effects": EFFECTS}

# The PETSc families an option may belong to (its first word): passed on to PETSc.
PETSC_FAMILIES = frozenset(
    "snes ksp pc ts tao mat vec dm dmplex petscpartitioner petscsection sf is ao log options malloc memory info "
    "help version viewer draw sub mg fieldsplit fp on start stop debugger no check objects history use device "
    "matptap petsc skip error display nox saws python bv characteristic pf random".split())
# the solver families whose options PETSc has read once SNES/TS read the database (checked then) ...
SOLVER_FAMILIES = ("snes_", "ksp_", "pc_", "ts_")
# ... except those read only later: viewers at the end of a solve, MFFD and matrix options at set-up
READ_LATER = re.compile(r"(^|_)view($|_)")

# PETSc options a user is likely to mistype, for the suggestion (facts from the PETSc manual pages)
COMMON_PETSC = (
    "snes_type snes_rtol snes_atol snes_stol snes_max_it snes_max_funcs snes_monitor snes_converged_reason "
    "snes_view snes_linesearch_type snes_linesearch_monitor snes_mf snes_mf_operator snes_lag_jacobian "
    "snes_lag_preconditioner snes_lag_preconditioner_persists snes_ksp_ew snes_max_linear_solve_fail "
    "snes_divergence_tolerance snes_test_jacobian snes_tr_delta0 ksp_type ksp_rtol ksp_atol ksp_divtol "
    "ksp_max_it ksp_monitor ksp_converged_reason ksp_view ksp_gmres_restart ksp_norm_type ksp_initial_guess_nonzero "
    "pc_type pc_factor_mat_solver_type pc_factor_levels pc_gamg_threshold pc_gamg_agg_nsmooths "
    "pc_gamg_reuse_interpolation pc_gamg_square_graph pc_mg_levels pc_jacobi_type ts_type ts_alpha_radius "
    "ts_alpha_alpha_m ts_alpha_alpha_f ts_alpha_gamma ts_alpha_beta ts_adapt_type ts_rtol ts_atol ts_monitor "
    "ts_adapt_monitor ts_max_snes_failures ts_max_step_rejections ts_adapt_dt_min ts_adapt_dt_max "
    "mat_mffd_type mat_mffd_err mat_view log_view options_file options_left dm_view help malloc_debug "
    "sub_pc_type sub_ksp_type mg_levels_ksp_type mg_levels_pc_type mg_coarse_pc_type").split()


# PETSc's numeric options whose wrong values it would take silently or reject only later: name ->
# (integer?, smallest value, largest value) (-1 is "unlimited" where PETSc has it; an iteration limit of 0
# would make every solve fail, or stop before it starts)
PETSC_VALUES = {
    "snes_rtol": (False, 0, None), "snes_atol": (False, 0, None), "snes_stol": (False, 0, None),
    "ksp_rtol": (False, 0, 1), "ksp_atol": (False, 0, None), "ts_rtol": (False, 0, None),
    "ts_atol": (False, 0, None), "mat_mffd_err": (False, 0, None), "ts_alpha_radius": (False, 0, 1),
    "snes_max_it": (True, 1, None), "snes_max_funcs": (True, -1, None), "ksp_max_it": (True, 1, None),
    "ksp_gmres_restart": (True, 1, None), "snes_max_linear_solve_fail": (True, 0, None),
    "ts_max_snes_failures": (True, -1, None), "ts_max_step_rejections": (True, -1, None),
    "snes_lag_jacobian": (True, -2, None), "snes_lag_preconditioner": (True, -2, None),
}
PETSC_WORDS = ("default", "petsc_default", "decide", "petsc_decide", "determine", "petsc_determine",
               "current", "petsc_current")


def check_petsc_values(opts):
    """Values of PETSC_VALUES' options: numbers in range (PETSc's symbolic DEFAULT/DECIDE/... pass)."""
    for key, (integer, lo, hi) in PETSC_VALUES.items():
        if not opts.hasName(key):
            continue
        text = (opts.getString(key, "") or "").strip()
        if text.lower() in PETSC_WORDS:
            continue
        try:
            v = int(text) if integer else float(text)
        except ValueError:
            kind = "an integer" if integer else "a number"
            raise UserError(f"option -{key}: '{text}' is not {kind}") from None
        if not math.isfinite(v):
            raise UserError(f"option -{key}: {text} is not a finite number")
        if v < lo or (hi is not None and v > hi):
            rng = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
            raise UserError(f"option -{key}: {text} must be {rng}")


def option_names(regions=(), loads=()):
    """Every application option name, the placeholders expanded with the scene's region and load names."""
    out = []
    for row in ROWS:
        for n in row.names:
            if n.startswith("REGION_"):
                out += [r + n[6:] for r in regions]
            elif n.startswith("LOAD_"):
                out += [ld + n[4:] for ld in loads]
            else:
                out.append(n)
    return out


def suggestion(key, candidates):
    """' (did you mean -X?)' for the closest candidate, or ''."""
    close = difflib.get_close_matches(key, list(candidates), n=1, cutoff=0.7)
    return f" (did you mean -{close[0]}?)" if close else ""


def _prefixed_template(key):
    """Whether key is NAME_x for a REGION_x or LOAD_x of the catalog (with any NAME)."""
    for row in ROWS:
        for n in row.names:
            if n.startswith(("REGION_", "LOAD_")):
                suffix = n[n.index("_"):]
                if key.endswith(suffix) and len(key) > len(suffix):
                    return True
    return False


def check_application_options(keys, regions=(), loads=(), scene_keys=()):
    """Every option in `keys` (the options database: command line, scene and options files) is the
    application's or belongs to a PETSc family; else one line naming the closest known option. A
    region's or load's option that the scene file sets (`scene_keys`) passes when the command line's
    -regions/-loads no longer lists its name (the scene's own region, dropped by an override)."""
    known = set(option_names(regions, loads))
    for key in keys:
        if key in known or key.split("_", 1)[0] in PETSC_FAMILIES:
            continue
        if key in scene_keys and _prefixed_template(key):
            continue
        if not re.fullmatch(r"[A-Za-z0-9_]+", key):      # an expression's leading minus: PETSc took it for an option
            raise UserError(f"'-{key}' was read as an option, not as the value before it: PETSc takes a word that "
                            f"starts with '-' (and not with a digit) for an option; write the expression as (-{key}) "
                            f"or 0 - {key}")
        raise UserError(f"unknown option -{key}{suggestion(key, sorted(known) + COMMON_PETSC)}")


def check_solver_options(opts):
    """After SNES (and TS) have read the options database: an option of the solver families that PETSc
    did not use is unknown (a misspelling), or meaningless for this run (`-ts_type` under backward Euler,
    `-ksp_gmres_restart` under CG): one line, before any output is written."""
    used = []
    for key, _ in all_options():
        if not key.startswith(SOLVER_FAMILIES) or READ_LATER.search(key):
            continue
        if opts.used(key):
            used.append(key)
            continue
        if key.startswith("ts_") and not opts.used("ts_type"):
            raise UserError(f"option -{key}: PETSc TS options need -integrator ts")
        hint = suggestion(key, [c for c in COMMON_PETSC + used if c != key])
        raise UserError(f"option -{key}: not used by PETSc for this run (unknown, or not for the solver types "
                        f"chosen){hint}")


# PETSc's families whose options PETSc itself reads as it finalizes (or at any time): never reported unused
READ_AT_EXIT = frozenset("log options malloc memory objects on viewer info help version check fp no skip error display "
                         "debugger start stop history saws petsc".split())


def unused_petsc_options(opts):
    """At the end of a run: ['-key value'] of the PETSc options (not the application's: check_application_used) that
    nothing read, and PETSc's own report of them (four lines on stdout as it finalizes) turned off: the run says
    them in one note (issue 73: -dm_bogus 1 was reported only there)."""
    names = set(option_names())
    left = [f"-{k} {v}".rstrip() for k, v in all_options() if not opts.used(k) and k not in names
            and not _prefixed_template(k) and k.split("_", 1)[0] not in READ_AT_EXIT]
    if opts.hasName("options_left"):       # (asked for: PETSc's own report stands)
        return []
    opts.setValue("options_left", "0")
    return left


def check_application_used(opts):
    """After the model and its solvers are set up (before any output is written): an option of the application that
    nothing read is one this run ignores (-mixed_augment on a displacement run, -contact_dhat without contact, ...):
    one line, rather than PETSc's four-line warning after the run (issue 73)."""
    names = set(option_names())
    for key, _ in all_options():
        if (key in names or _prefixed_template(key)) and key.split("_", 1)[0] not in PETSC_FAMILIES \
                and not opts.used(key):
            raise UserError(f"option -{key}: this run does not read it (it is for another formulation, effect, "
                            "integrator or kind of run: see `hyperelastic run --help`)")




def check_viewer_files(opts, taken=()):
    """A PETSc viewer's FILE in a directory that does not exist, or over an input or output file (`taken`):
    PETSc reports it only when it writes, at the end (after the run). One line, before any work is done."""
    taken = {os.path.realpath(t): t for t in taken if t}
    for key, value in all_options():
        if VIEWERS.search(key) and ":" in value:
            why = _viewer_file_problem(value.split(":")[1], taken)
            if why:
                opts.delValue(key)        # (PETSc would still try to open it at its finalization)
                raise UserError(f"option -{key}: {why}")


def _viewer_file_problem(path, taken):
    if not path:
        return None
    d = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(d):
        return f"'{path}': directory '{os.path.dirname(path)}' does not exist"
    if not os.access(d, os.W_OK) or os.path.isdir(path):
        return f"'{path}' cannot be written"
    if os.path.realpath(path) in taken:
        return f"'{path}' is a file of this run (its input or output '{taken[os.path.realpath(path)]}')"
    return None


def _plain(text):
    return text.replace("`", "")


def help_text(values=None, width=100):
    """The options in PETSc's -help style: '  -name <value>: help'. `values`: the scene's values by option
    name (shown instead of the defaults)."""
    values = values or {}
    lines = ["Options of hyperelastic (defaults in <>; PETSc's own follow with -help on a scene):"]
    for row in ROWS:
        shown = [f"{n}={values[n]}" for n in row.names if n in values]
        now = ", ".join(shown) if shown else _plain(row.default)
        lines.append(textwrap.fill(f"  {row.synopsis} <{now}>: {_plain(row.help)}", width=width,
                                   subsequent_indent="      ", break_on_hyphens=False))
    return "\n".join(lines)


def markdown_table():
    """The option table of the options reference (docs/reference/options.md)."""
    def cell(s):
        return s.replace("|", "\\|")
    out = ["| option | meaning | default |", "|---|---|---|"]
    for row in ROWS:
        out.append(f"| `{cell(row.synopsis)}` | {cell(row.help)} | {cell(row.default)} |")
    return "\n".join(out)


REFERENCE_HEAD = """# Options reference

Every option of the application, as `hyperelastic run --help` prints it (`hyperelastic run SCENE -help`: with the
scene's values, then PETSc's own options as its solvers read them). This page is generated from the application's
catalog (`python -m hyperelastic.app.catalog --reference`, which `make docs` runs; tests/test_catalog.py keeps the two
equal). PETSc's own options (`-snes_*`, `-ksp_*`, `-pc_*`, `-ts_*`, `-log_view`, ...) work as PETSc documents them; an
option that is neither the application's nor PETSc's, or a solver option the run did not use, is refused before
anything runs, naming the closest one.
"""


def reference_page():
    """docs/reference/options.md: the option table with its heading."""
    return REFERENCE_HEAD + "\n" + markdown_table() + "\n"


def load_scene(scene_arg):
    """(Scene, path of its options file) for a built-in scene name or an options file: the file's
    options become defaults under the command line's, every option is checked to be the application's or
    PETSc's, then the scene is read and validated (scene.read_scene)."""
    path = resolve_scene(scene_arg)
    pairs = parse_options_file(path)
    opts = Options()
    from_scene = {k for k, _ in pairs if not opts.has(k)}
    insert_defaults(pairs)
    check_application_options([k for k, _ in all_options()], _prefixes(opts, "regions"), _prefixes(opts, "loads"),
                              {k for k, _ in pairs})
    check_petsc_values(opts.o)
    name = os.path.splitext(os.path.basename(path))[0]
    return read_scene(name, opts, from_scene), path


def _prefixes(opts, option):
    """The names -regions / -loads list that can be option prefixes (the others are refused when the
    scene is read)."""
    return [w for w in opts.names(option) if PREFIX.fullmatch(w)]


def scene_option_names(scene):
    """Every option name of the application for this scene (its regions' and loads' prefixes expanded)."""
    return option_names(*scene.prefixes())


if __name__ == "__main__":
    flags = sys.argv[1:]
    print(markdown_table() if "--markdown" in flags else reference_page() if "--reference" in flags else help_text(),
          end="\n" if "--reference" not in flags else "")
