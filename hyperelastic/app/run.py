"""`hyperelastic run`: Scene -> Model (mesh, space, effects, system) -> Solver -> Writer -> integrator.
Imported by the command line only after PETSc has been initialized with the run's arguments (cli.py)."""
import json
import os
import resource
import signal
import sys

import numpy as np

from mpi4py import MPI
from petsc4py import PETSc

from .catalog import (check_application_used, check_solver_options, check_viewer_files, help_text, load_scene,
                      scene_option_names, unused_petsc_options)
from ..core.errors import Interrupted, SolveError, UserError
from ..core.expressions import TIME_EXPRESSIONS, check_times
from ..core.files import CHECKPOINT_CELLS, StateRows, check_output_path, output_names
from ..physics import materials
from ..physics.effects.seams import Results, declaring
from ..solving.forces import held_components, record, surface_forces, table
from ..solving.integrators import BackwardEuler, step_count
from ..solving.rigid import line as rigid_line
from .model import build_model, collective
from ..core.options import Options
from ..output.ranks import RankWriter
from ..output.writer import Writer, run_attributes
from ..mesh.sets import REGION_LABEL
from ..solving.solver import Solver
from ..solving.ts_integrator import GeneralizedAlpha, check_energy_momentum, make_ts


def run_scene(scene_arg, options_files, restart=None, restart_path=None, signals=None):
    """Set up and run a scene (a built-in name or an options file) with the options database as it is;
    restart: the checkpoint state of `restart_path` to continue from (files.read_checkpoint); signals: a list the
    SIGINT/SIGTERM of the set-up are recorded in (honoured by the integrator before its first step)."""
    comm = PETSc.COMM_WORLD
    TIME_EXPRESSIONS.clear()          # (this run's, made from here on: check_times)
    stage = PETSc.Log.Stage("Setup")
    stage.push()
    scene, scene_file = load_scene(scene_arg)
    opts = Options()
    helping = opts.has("help")
    if helping and comm.getRank() == 0:
        print(help_text(_help_values(scene, opts)), flush=True)
    out = opts.string("output", os.path.join("output", f"{scene.name}.h5"))
    quiet = opts.flag("quiet")
    inputs = [scene_file, scene.mesh] + list(options_files)
    if restart is not None:
        inputs = [i for i in inputs if i and os.path.realpath(i) != os.path.realpath(out)]
    if not helping:               # (-help writes nothing: not even the output's directory)
        collective(comm, lambda: check_output_path(out, inputs))      # before any expensive work
    collective(comm, lambda: check_viewer_files(PETSc.Options(), inputs + output_names(out)))
    try:
        model = build_model(scene, comm)
    except UserError as e:
        if not helping:
            raise
        if comm.getRank() == 0:        # (the help above is what was asked for; PETSc's part needs a model)
            print(f"(PETSc's solver options are listed once the scene runs on a mesh: {e})", flush=True)
        return 0
    if restart is not None:
        collective(comm, lambda: _check_restart(restart, model, scene, restart_path))
    solver, ts = _solver(scene, model, comm)
    check_solver_options(PETSc.Options())
    if helping:                  # PETSc printed its own options as its solvers read them
        return 0
    _check_before_writing(scene)
    if comm.getRank() == 0:
        _start_lines(scene, model, solver, quiet)
    if restart is not None:      # the state read (collective) before anything is written: a bad row is one line
        restart = dict(restart, **{k: model.space.read_cell_state(v) if k in CHECKPOINT_CELLS else
                                   model.space.read_state(v) for k, v in restart.items() if isinstance(v, StateRows)})
    attrs = run_attributes(model, scene_file, solver)
    stage.pop()
    writer = open_writer(_layout(scene, comm, restart, out), out, model, attrs, restart, scene.output_fields)
    writer.point_scalars = point_values(model)
    integ = _integrator(scene, model, solver, writer, ts, restart, quiet)
    integ.run_notes = [n for n in attrs["notes"].splitlines() if n]     # the start-up's; the run's own follow
    forces, rigid_lines = _integrate(integ, writer, comm, scene, signals)
    advice = solver.advice()
    if comm.getRank() == 0 and not quiet:
        if forces:
            print("\n".join(table(forces, integ.t, held_components(scene)) + rigid_lines), file=sys.stderr)
        print(f"wrote {out} ({integ.step} steps, {writer.nframes} frames)", file=sys.stderr)
    if comm.getRank() == 0 and advice:          # (a note: -quiet silences progress, never a note)
        print(f"note: {advice}", file=sys.stderr)
    unused = unused_petsc_options(PETSc.Options())
    if comm.getRank() == 0 and unused:
        print(f"note: PETSc options this run did not use: {', '.join(unused)}", file=sys.stderr)
    return 0


def _check_before_writing(scene):
    """What can still be refused once the model and its solvers are set up: an application option nothing read, an
    expression of t not finite at a step end."""
    check_application_used(PETSc.Options())
    check_times(np.minimum(np.arange(step_count(scene.final_time, scene.dt) + 1) * scene.dt, scene.final_time))


def _integrator(scene, model, solver, writer, ts, restart, quiet):
    """The run's integrator: generalized-alpha through PETSc's TS (ts given), else backward Euler."""
    if ts is not None:
        return GeneralizedAlpha(scene, model.system, solver, writer, model.x0, model.v0, ts, checkpoint=restart,
                                quiet=quiet)
    return BackwardEuler(scene, model.system, solver, writer, model.x0, model.v0, checkpoint=restart, quiet=quiet)


def point_values(model):
    """(local positions x) -> {name: local array per node} of every frame's scalar point fields: the formulation's
    (the mixed pressure) and the effects' Results (contact pressure and status; the same name from several effects
    added); None where there are none."""
    own = model.formulation.point_values(model.system)
    effects = declaring(model.system.effects, Results)
    if own is None and not effects:
        return None

    def values(x):
        out = dict(own(x)) if own is not None else {}
        for e in effects:
            for k, a in e.point_values(x).items():
                out[k] = out[k] + a if k in out else a
        return out
    return values


def _help_values(scene, opts):
    """The scene's values of its options for `-help`: those given, and the material's E, nu, rho and own constants
    as the scene resolved them (a -preset's, or a constant's default from E and nu), where not given."""
    values = {n: opts.o.getString(n, "") for n in scene_option_names(scene) if opts.has(n)}
    solid = scene.solid
    preset = opts.string("preset", None)
    why = f" (-preset {preset})" if preset else " (from E and nu)"
    for name, v in list(solid.values.items()) + [("rho", solid.rho)]:
        if name not in values:
            values[name] = materials.shown(v) + (why if preset or name not in ("E", "nu", "rho") else "")
    return values


def _start_lines(scene, model, solver, quiet=False):
    """The run's start-up lines on stderr: the part, its sets, the partition, the notes (with -quiet the notes only:
    -quiet silences what a run reports, never what it warns of)."""
    lines = part_lines(model, scene) + [f"set {line}" for line in model.set_lines()]
    lines += [model.space.partition_line] if model.space.partition_line else []
    notes = scene.notes + model.notes + ([solver.merit_note] if solver.merit_note else []) + solver.notes
    lines += [f"note: {n}" for n in notes]
    if quiet:
        lines = [ln for ln in lines if ln.startswith("note: ")]
    if lines:
        print("\n".join(lines), file=sys.stderr)


MM_LIKE = (20.0, 1e8)      # a part longer than this in mesh units with a modulus above this (Pa) looks like mm


def part_lines(model, scene):
    """The start-up line with the part's size (the mesh's units are read as metres), and a note when the
    size and the stiffest modulus look like mixed units: a part tens of metres long with a metal's or a
    plastic's modulus in pascals is, far more often, a part drawn in millimetres."""
    lo, hi = model.space.bbox
    ext = hi - lo
    line = f"part: {ext[0]:.3g} x {ext[1]:.3g} x {ext[2]:.3g} (bounding box; the mesh's units are read as metres)"
    E = max([scene.solid.values["E"]] + [r.solid.values["E"] for r in scene.regions])
    if ext.max() > MM_LIKE[0] and E > MM_LIKE[1]:
        return [line, f"note: a part {ext.max():.3g} m long with E = {E:g} Pa: if it is drawn in millimetres, "
                      "scale the mesh to metres (or give E, pressures and tractions in MPa and forces in N: then "
                      "stresses come out in MPa and densities must be in t/mm^3)"]
    return [line]


def _solver(scene, model, comm):
    """(Solver, PETSc TS or None) of the scene: under -integrator ts the TS's own SNES."""
    ts = make_ts(comm) if scene.integrator == "ts" else None
    solver = Solver(model.system, scene.jacobian, scene.assembly, guard=scene.inversion_guard,
                    objective=scene.objective and ts is None, snes=ts.getSNES() if ts else None,
                    reuse_pc=scene.reuse_preconditioner, storage=scene.operator_storage,
                    diverging=scene.diverging_newton,
                    plan=model.formulation.solver_plan(model.system))
    if ts is not None and any(rb.free.any() for rb in model.system.rigid):
        raise UserError("option -integrator ts: a rigid face with loads (-rigid_fx ... -rigid_mz) is balanced around "
                        "each step's solve by backward Euler or quasi-static steps; under TS give it motions only")
    if ts is not None:
        ts.setFromOptions()      # (again when the integrator is set up) so that its options count as used
        check_energy_momentum(ts, scene)
    return solver, ts


def _integrate(integ, writer, comm, scene, signals=None):
    """Run the integrator with SIGINT/SIGTERM honoured at the next frame; the file is closed whatever
    happens, kept when the run ended or stopped on request with a checkpoint. Returns the forces on the
    body at the end (forces.py; backward Euler and quasi-static runs) and the rigid face's line (solving/rigid.py),
    also recorded in the file."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: integ.request_stop(signum))
    if signals:                  # (one that came while the run was set up: before its first step)
        integ.request_stop(signals[0])
    ended, failed = False, None
    forces, lines = None, []
    try:
        integ.run()
        ended = True
        if isinstance(integ, BackwardEuler):
            forces = surface_forces(scene, integ.system, integ.x)
            writer.set_attr("forces", json.dumps({"t": integ.t, "forces": record(forces, held_components(scene))}))
            if integ.rigid is not None:          # the rigid face's reference point and its reaction about it
                text, rec = rigid_line(integ.system, integ.rigid, integ.x)
                lines.append(text)
                writer.set_attr("rigid", json.dumps(dict(rec, t=integ.t)))
        return forces, lines
    except Interrupted:
        ended = True          # stopped on request with a checkpoint: keep it, even before a first step
        raise
    except UserError as e:    # (an input that fails only now, inside a step: the file says so, not "finished")
        writer.set_attr("failure", str(e))
        failed = e
        raise
    except SolveError as e:   # (the integrator has recorded it in the file)
        failed = e
        raise
    finally:
        writer.set_attr("steps_completed", integ.step)
        writer.set_attr("peak_rss_mb", peak_rss_mb(comm))
        writer.set_attr("peak_rss_mb_per_rank", peak_rss_mb(comm, every=True))
        writer.close(keep=ended)
        if failed is not None and writer.moved:     # (the earlier output put back: the line says where this run's is)
            failed.args = (f"{failed}; {writer.moved}",)


def _layout(scene, comm, restart, out):
    """The output's layout: a restart's file's own, else -output_layout (auto: gather on one rank, ranks on more)."""
    if restart is not None:
        return restart.get("layout", "gather")
    if scene.output_layout != "auto":
        return scene.output_layout
    return "ranks" if comm.getSize() > 1 else "gather"


def open_writer(layout, out, model, attrs, restart, fields):
    """The output's writer of `layout` (output/writer.py: gather, output/ranks.py: ranks)."""
    region = model.space.cell_values(REGION_LABEL)
    if layout == "ranks":
        return RankWriter(out, model.space, attrs, resume=restart, kernels=model.kernels, region=region, fields=fields)
    points, tets = model.whole_mesh()
    return Writer(out, model.space, points, tets, attrs, resume=restart, kernels=model.kernels,
                  region=region, fields=fields)


def _check_restart(state, model, scene, path):
    """The checkpoint fits the run it continues: the same element order and mesh, and time left before
    -final_time."""
    for e in model.system.effects:
        e.check_resume(state, path)
    nodes = 4 if model.element.order == 1 else 10
    if state.get("cell_nodes") in (4, 10) and state["cell_nodes"] != nodes:
        kind = {4: "linear (order 1)", 10: "quadratic (order 2)"}
        raise UserError(f"--restart '{path}': the checkpoint was written with {kind[state['cell_nodes']]} tetrahedra, "
                        f"this run has {kind[nodes]} ones (a restart continues with the element order it was "
                        "written with: drop -order)")
    if len(state["x"]) != model.space.nv_total:
        raise UserError(f"--restart '{path}': the checkpoint has {len(state['x'])} vertices, the mesh of this run "
                        f"{model.space.nv_total} (a restart continues on the mesh it was written with)")
    if state["t"] >= scene.final_time * (1 - 1e-12):
        raise UserError(f"--restart '{path}': the checkpoint is at t = {state['t']:g}, the end of the run "
                        f"(-final_time {scene.final_time:g}); give a later -final_time to continue")


def peak_rss_kib():
    """This process's peak resident memory [KiB]: Linux's VmHWM (/proc/self/status), the high-water mark of this
    process image's own memory. Not getrusage's ru_maxrss there: Linux keeps that across fork and exec, so a run
    started by a large process (a benchmark script, a test runner) reported its parent's size as its own (a run of
    100 MB started from a 1 GiB Python process read 1,062 MB). getrusage elsewhere."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return float(line.split()[1])
    except OSError:
        pass
    return float(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)


def peak_rss_mb(comm, every=False):
    """Peak resident memory [MB] of the most loaded rank so far (peak_rss_kib); every: each rank's."""
    kib = peak_rss_kib()
    if every:
        return np.array(comm.tompi4py().allgather(kib)) / 1024.0
    return comm.tompi4py().allreduce(kib, op=MPI.MAX) / 1024.0
