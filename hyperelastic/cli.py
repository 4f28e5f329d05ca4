"""hyperelastic: implicit FEM for stiff hyperelastic solids on PETSc.

  hyperelastic run SCENE [PETSc options]         simulate a scene (built-in name or options file)
  hyperelastic run --restart FILE.h5 [options]   continue a run from the last checkpoint in FILE.h5
  hyperelastic mesh bar --level N -o FILE.msh    generate a gmsh mesh of the thesis' bar
  hyperelastic plot FILE.h5 [-o FILE.png]        picture of a frame (default: the last)
  hyperelastic scenes                            list the built-in scenes
  hyperelastic study accuracy|refinement [-output_dir DIR] [--full] [--jobs N]
                                                 what accuracy costs in time: CSV, PNGs, markdown
"""
import argparse
import os
import sys

from .errors import Interrupted, SolveError, UserError

EXIT_USER, EXIT_SOLVE, EXIT_INTERNAL = 2, 3, 1


def _petsc(argv):
    import petsc4py
    petsc4py.init([sys.argv[0]] + list(argv))
    from petsc4py import PETSc
    return PETSc


def _restart_args(argv):
    """(scene file, PETSc arguments, checkpoint state) for `run --restart FILE [options]`: the options
    recorded in FILE, then the command line's (which win), writing on into FILE."""
    from mpi4py import MPI
    if len(argv) < 2 or argv[1].startswith("-"):
        raise UserError("run --restart: needs the FILE.h5 of an earlier run")
    path = argv[1]
    res = err = None
    if MPI.COMM_WORLD.rank == 0:
        try:
            from .output import read_checkpoint
            state, attrs = read_checkpoint(path)
            args = []
            for line in str(attrs.get("options", "")).splitlines():
                key, _, val = line.partition(" ")
                if key.lstrip("-") != "output":
                    args += [key] + ([val] if val else [])
            res = (attrs["scene_file"], args + ["-output", path] + list(argv[2:]), state)
        except UserError as e:
            err = str(e)
        except Exception as e:     # any other defect must not leave the other ranks waiting
            err = f"--restart '{path}': not a hyperelastic output file with a checkpoint ({type(e).__name__}: {e})"
    err = MPI.COMM_WORLD.bcast(err, root=0)
    if err:
        raise UserError(err)
    scene, args, state = MPI.COMM_WORLD.bcast(res, root=0)
    return scene, args, state


def run(argv):
    restart = None
    if argv and argv[0] == "--restart":
        scene_arg, petsc_args, restart = _restart_args(argv)
    elif not argv or argv[0].startswith("-"):
        raise UserError("run: needs a SCENE (a built-in name or an options file); see `hyperelastic scenes`")
    else:
        scene_arg, petsc_args = argv[0], argv[1:]
    PETSc = _petsc(petsc_args)
    import signal
    from . import __version__
    from .app import Problem, collective
    from .effects.inertia import Inertia
    from .integrators import BackwardEuler
    from .options import all_options
    from .output import Writer, check_output_path
    from .solver import Solver
    import numpy as np

    comm = PETSc.COMM_WORLD
    stage = PETSc.Log.Stage("Setup")
    stage.push()
    out = None

    def check_output(prob):
        nonlocal out
        out = prob.opts.string("output", os.path.join("output", f"{prob.name}.h5"))
        collective(comm, lambda: check_output_path(out))
    prob = Problem(scene_arg, comm, before_mesh=check_output)
    scene, space, system, name, path = prob.scene, prob.space, prob.system, prob.name, prob.scene_file
    quiet = prob.opts.flag("quiet")
    mesh_file, points, tets = scene.mesh, prob.points, prob.tets
    integ = BackwardEuler(scene, system, None, None, quiet)
    integ.x, integ.v = prob.initial_state()
    solver = Solver(system, scene.jacobian)
    integ.solver = solver
    attrs = {"options": "\n".join(f"-{k} {v}".rstrip() for k, v in all_options()),
             "scene": name, "scene_file": os.path.abspath(path), "effects": ",".join(e for e in scene.effects),
             "effects_built": repr(system.built()), "hyperelastic_version": __version__,
             "petsc_version": ".".join(map(str, PETSc.Sys.getVersion())), "mpi_ranks": comm.getSize(),
             "jacobian": scene.jacobian + (f" ({solver.mf})" if solver.mf else ""),
             "material": scene.material.name, "E": scene.E, "nu": scene.nu, "rho": scene.rho,
             "mesh": os.path.abspath(mesh_file) if mesh_file else f"bar level {scene.level}",
             "vertices_per_rank": np.array(space.mpi.allgather(space.nlv)),
             "cells_per_rank": np.array(space.mpi.allgather(space.nc)),
             "mass_matrix_builds": Inertia.MASS_BUILDS}
    stage.pop()
    writer = Writer(out, space, points, tets, attrs, resume=restart)
    integ.writer = writer
    if restart is not None:
        integ.resume(restart)

    def on_signal(signum, frame):
        integ.signal = signum     # honoured at the next frame, on every rank
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    try:
        integ.run()
    finally:
        writer.set_attr("steps_completed", integ.step)
        writer.set_attr("peak_rss_mb", peak_rss_mb(comm))
        writer.close()
    if not quiet and comm.getRank() == 0:
        print(f"wrote {out} ({integ.step} steps, {writer.nframes} frames)", file=sys.stderr)
    return 0


def peak_rss_mb(comm):
    """Peak resident memory [MB] of the most loaded rank so far (getrusage: KiB on Linux)."""
    import resource
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    from mpi4py import MPI
    return comm.tompi4py().allreduce(kib, op=MPI.MAX) / 1024.0


def mesh_cmd(argv):
    ap = _ArgParser(prog="hyperelastic mesh", description="Generate a tetrahedral mesh with gmsh.")
    ap.add_argument("geometry", help="name of a .geo file under meshes/ (e.g. bar)")
    ap.add_argument("--level", type=int, help="refinement level: 1..8 = thesis L1..L8, 9.. finer (~2x tets each)")
    ap.add_argument("--size", type=float, help="target edge length instead of a level")
    ap.add_argument("-o", "--output", required=True, help="output .msh file")
    a = _parse(ap, argv)
    if (a.level is None) == (a.size is None):
        raise UserError("hyperelastic mesh: give exactly one of --level N or --size H")
    from .mesh import generate
    st = generate(a.geometry, a.level, a.output, a.size)
    print(f"{a.output}: level {a.level or '-'} target edge {st['target_size']:.4g}: {st['vertices']} vertices, "
          f"{st['tets']} tets, min edge {st['min_edge']:.4g}")
    return 0


def _parse(ap, argv):
    return ap.parse_args(argv)


class _ArgParser(argparse.ArgumentParser):
    """argparse that reports a bad argument as one UserError line instead of usage + exit."""

    def error(self, message):
        raise UserError(f"{self.prog}: {message}")


def plot_cmd(argv):
    ap = _ArgParser(prog="hyperelastic plot", description="Render a frame of an output file to PNG.")
    ap.add_argument("file")
    ap.add_argument("-o", "--output", default=None)
    ap.add_argument("--frame", type=int, default=-1)
    a = _parse(ap, argv)
    from .plot import render
    out = a.output or os.path.splitext(a.file)[0] + ".png"
    render(a.file, out, a.frame)
    print(out)
    return 0


def scenes_cmd(argv):
    from .options import SCENES_DIR, builtin_scenes
    for s in builtin_scenes():
        with open(os.path.join(SCENES_DIR, s + ".opts")) as fh:
            first = fh.readline().lstrip("# ").strip()
        print(f"{s:10s} {first}")
    return 0


def study_cmd(argv):
    from .study import main as study_main
    return study_main(argv)


COMMANDS = {"run": run, "mesh": mesh_cmd, "plot": plot_cmd, "scenes": scenes_cmd, "study": study_cmd}


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "-debug" in argv
    if debug:
        argv.remove("-debug")
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(__doc__)
        return 0
    cmd = COMMANDS.get(argv[0])
    if cmd is None:
        _error(f"unknown command '{argv[0]}' (choose from {', '.join(COMMANDS)})")
        return EXIT_USER
    try:
        return cmd(argv[1:])
    except UserError as e:
        _error(str(e))
        return EXIT_USER
    except SolveError as e:
        _error(str(e))
        return EXIT_SOLVE
    except Interrupted as e:
        _error(str(e))
        return 128 + int(e.signum)
    except KeyboardInterrupt:
        _error("interrupted")
        return 130
    except Exception as e:
        if type(e).__name__ == "Error" and hasattr(e, "ierr"):   # petsc4py.PETSc.Error
            from .libpetsc import error_message
            _error(f"PETSc: {error_message(e.ierr)}")
            return EXIT_USER
        if debug:
            import traceback
            traceback.print_exc()
        else:
            msg = " ".join(str(e).split())[:300] or type(e).__name__
            _error(f"internal error: {type(e).__name__}: {msg} (rerun with -debug for a traceback)", every_rank=True)
        _abort_if_parallel(EXIT_INTERNAL)
        return EXIT_INTERNAL


def _comm():
    if "petsc4py.PETSc" in sys.modules:
        from petsc4py import PETSc
        return PETSc.COMM_WORLD
    return None


def _abort_if_parallel(code):
    """An error raised on some ranks only would leave the others waiting in a collective call."""
    comm = _comm()
    if comm is not None and comm.getSize() > 1:
        sys.stderr.flush()
        comm.tompi4py().Abort(code)


def _error(msg, every_rank=False):
    comm = _comm()
    if comm is not None:   # no 'unused options' report after an error: the one line says what is wrong
        from petsc4py import PETSc
        PETSc.Options().setValue("options_left", "0")
    if comm is not None:
        rank = comm.getRank()
    elif "mpi4py.MPI" in sys.modules:      # MPI is up but PETSc is not yet (e.g. run --restart)
        rank = sys.modules["mpi4py.MPI"].COMM_WORLD.rank
    else:
        rank = 0
    if every_rank or rank == 0:
        print(f"hyperelastic: error: {msg}", file=sys.stderr, flush=True)


if __name__ == "__main__":
    sys.exit(main())
