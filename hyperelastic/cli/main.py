"""hyperelastic: implicit FEM for stiff hyperelastic solids on PETSc.

  hyperelastic run SCENE [PETSc options]         simulate a scene (built-in name or options file)
  hyperelastic run --restart FILE.h5 [options]   continue a run from the last checkpoint in FILE.h5
  hyperelastic mesh bar --level N -o FILE.msh    generate a gmsh mesh of the thesis' bar
  hyperelastic mesh PART.geo --size H -o F.msh   mesh your own .geo/.step (physical groups kept; --refine N;
                                                 --graded keeps its own size fields, H the largest edge)
  hyperelastic mesh F.msh --prepare -o F.h5      check and order a mesh once; runs with -mesh F.h5 read it in
                                                 slices, every MPI rank its own
  hyperelastic plot FILE.h5 [-o FILE.png]        picture of a frame (default: the last)
  hyperelastic report FILE.h5 [--at X,Y,Z] [--frame N] [--watch Q]
                                                 the run, its forces, values at material points, again
  hyperelastic scenes                            list the built-in scenes
  hyperelastic --version                         this version and the libraries it runs on
  hyperelastic study accuracy|refinement [-output_dir DIR] [--full] [--jobs N]
                                                 what accuracy costs in time: CSV, PNGs, markdown
  hyperelastic study price --part P --scene S --size H --watch Q --target ERR
                                                 the cheapest setting for a target error on your part
  hyperelastic fit DATA.csv --model NAME [-o F.opts] [--plot F.png]
                                                 a rubber model fitted to uniaxial, equibiaxial and planar
                                                 tests, with Drucker's stability; F.opts for -options_file
"""
import math
import os
import re
import signal
import sys
import tempfile
import time
import traceback

from ..core.data import recipe_path, recipes
from ..core.errors import ArgParser, Interrupted, SolveError, UserError
from ..core.files import option_lines, read_checkpoint, replayed
from ..mesh.generate import empty_group_lines, format_normal, generate

# petsc4py reads the command line when PETSc is first imported, and mpi4py initializes MPI when imported:
# every module that imports either (options, catalog, run, study, libpetsc) is imported only where a
# command needs it, after _petsc for `run`.

EXIT_USER, EXIT_SOLVE, EXIT_INTERNAL = 2, 3, 1

# what a warm-started command would import after the fork (core/warm.py) that initializes nothing: the libraries the
# runs import below the package's own modules (numpy.unique imports numpy.ma; petsc4py's set-up configparser, ...)
WARM_PRELOAD = ("numpy.ma", "numpy.ctypeslib", "configparser", "difflib", "glob", "hashlib", "heapq", "resource",
                "zipfile")


def _petsc(argv):
    """(petsc4py.PETSc initialized with argv, the options files argv reads)."""
    files = _check_options_files(argv)
    import petsc4py
    petsc4py.init([sys.argv[0]] + list(argv))

    def initialize():
        from petsc4py import PETSc
        PETSc.COMM_WORLD.getSize()       # (the import initializes PETSc)
        if SETUP_SIGNALS is not None:    # (PETSc's initialization put its own handler in place of the run's)
            _hold_signals()
        return PETSc
    return _held_stderr(initialize), files


# SIGINT/SIGTERM that arrive while a run sets up (before its integrator takes the signals over): recorded here, from
# the command's first line, and honoured by the integrator before its first step, which stops with a checkpoint and
# the restart line as it does later (PETSc's own handler printed its banner and aborted: exit 59, an empty FILE.h5.d/)
SETUP_SIGNALS = None


def _hold_signals(fresh=False):
    """Record SIGINT and SIGTERM in SETUP_SIGNALS (a new list where fresh: a run's first line) instead of acting on
    them."""
    global SETUP_SIGNALS
    if SETUP_SIGNALS is None or fresh:
        SETUP_SIGNALS = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, frame: SETUP_SIGNALS.append(signum))


def _recipes(argv):
    """The arguments with every `-options_file NAME` that names no file here but one of the package's recipes
    (`gamg`, `gamg.opts` or the guide's `options/gamg.opts`) pointing at that recipe: recipes work from any
    directory, an installed package included."""
    out = list(argv)
    for i, a in enumerate(out[:-1]):
        if a == "-options_file":
            found = recipe_path(out[i + 1])
            if found:
                out[i + 1] = found
    return out


def _check_options_files(argv, chain=()):
    """Every `-options_file F` of the arguments, and those the files include in turn, must be a
    readable regular UTF-8 file that does not include itself: PETSc itself would print a multi-line
    error and leave no communicator (missing file), wait forever (a FIFO), or recurse until SIGSEGV
    (a file that includes itself, or two that include each other). Returns their paths (the inputs an
    output must not overwrite)."""
    files = []
    for i, a in enumerate(argv):
        if a != "-options_file":
            continue
        if i + 1 >= len(argv):
            raise UserError("option -options_file: needs a file")
        path = argv[i + 1]
        real = os.path.realpath(path)
        files.append(path)
        if real in chain:
            names = " -> ".join([os.path.basename(c) for c in chain] + [os.path.basename(real)])
            raise UserError(f"options file '{path}' includes itself ({names})")
        if not os.path.isfile(path):
            why = "does not exist" if not os.path.exists(path) else "is not a regular file"
            raise UserError(f"options file '{path}' {why} (the package's recipes, by name from any directory: "
                            f"{', '.join(recipes())})")
        try:
            with open(path, encoding="utf-8") as fh:
                text = fh.read()
        except OSError as e:
            raise UserError(f"options file '{path}': cannot be read ({e.strerror})") from None
        except UnicodeDecodeError:
            raise UserError(f"options file '{path}': not UTF-8 text") from None
        if "\0" in text:
            raise UserError(f"options file '{path}': holds NUL bytes (not a text file)")
        lines = option_lines(text, f"options file '{path}'")
        if not lines:
            raise UserError(f"options file '{path}': holds no options")
        inner = [w for _, key, value in lines for w in ["-" + key] + ([] if value is None else [value])]
        files += _check_options_files(inner, chain + (real,))
    return files


NUMBER = re.compile(r"-[0-9.]")      # a negative number (or a list starting with one) is a value, not an option


def _check_words(args):
    """PETSc reads `-option [value]` pairs and skips any other word, and `--name` is an option of its own
    that nothing reads: each is one error line here."""
    value_ok = False
    for a in args:
        if a.startswith("-") and not NUMBER.match(a):
            if a == "-" or a.startswith("--"):
                raise UserError(f"argument '{a[:40]}': options are -name [value] (one '-')")
            value_ok = True
        elif value_ok:
            value_ok = False
        else:
            raise UserError(f"argument '{a[:40]}': neither an option nor an option's value (options are "
                            "-name [value]; the scene comes first)")


def _held_stderr(fn):
    """fn() with file descriptor 2 sent to a temporary file: PETSc prints its own multi-line error report
    when its initialization fails (a malformed option value); the caller prints the one line. On success
    what was written is passed on to stderr."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            out = fn()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        tmp.seek(0)
        text = tmp.read()
    if text:
        sys.stderr.buffer.write(text)
        sys.stderr.flush()
    return out


def _restart_args(argv):
    """(scene file, PETSc arguments, checkpoint state) for `run --restart FILE [options]`: the options
    recorded in FILE, then the command line's (which win), writing on into FILE."""
    from mpi4py import MPI
    if len(argv) < 2 or argv[1].startswith("-"):
        raise UserError("run --restart: needs the FILE.h5 of an earlier run")
    path = argv[1]
    rest = list(argv[2:])
    for i, a in enumerate(rest[:-1]):
        if a == "-output" and os.path.realpath(rest[i + 1]) != os.path.realpath(path):
            raise UserError(f"run --restart: continues '{path}' in place; -output {rest[i + 1]} cannot name another "
                            f"file (copy '{path}' there first and restart the copy)")
    res = err = None
    if MPI.COMM_WORLD.rank == 0:
        try:
            state, attrs = read_checkpoint(path)
            recorded = []
            for line in str(attrs.get("options", "")).splitlines():
                key, _, val = line.partition(" ")
                if key.lstrip("-") != "output":
                    recorded.append((key.lstrip("-"), val))
            given = {a.lstrip("-") for a in rest if a.startswith("-") and len(a) > 1 and not _number(a)}
            kept, left = replayed(recorded, given)
            if left:      # (a note: printed under -quiet too)
                print(f"note: --restart: not replayed from '{path}': {', '.join(left)} (viewers are the first "
                      "part's; a mesh's recipe is its mesh's)", file=sys.stderr, flush=True)
            args = [a for key, val in kept for a in ([f"-{key}"] + ([val] if val else []))]
            res = (attrs["scene_file"], args + ["-output", path] + list(argv[2:]), state)
        except UserError as e:
            err = str(e)
        except Exception as e:     # any other defect must not leave the other ranks waiting
            err = f"--restart '{path}': not a hyperelastic output file with a checkpoint ({type(e).__name__}: {e})"
    err = MPI.COMM_WORLD.bcast(err, root=0)
    if err:
        raise UserError(err)
    # the state holds no mesh-sized array: its x, v (and pressure) are read by every rank in slices
    # (files.StateRows, Space.read_state)
    return MPI.COMM_WORLD.bcast(res, root=0)


def _number(word):
    """Whether a word that starts with '-' is a negative number (a value, not an option)."""
    try:
        float(word)
        return True
    except ValueError:
        return False


def run_cmd(argv):
    """`hyperelastic run SCENE [options]` or `run --restart FILE.h5 [options]` (run.py does the work)."""
    restart = None
    if argv and argv[0] in ("--help", "-help", "-h"):
        print(catalog_help())
        return 0
    _hold_signals(fresh=True)
    if argv and argv[0] == "--restart":
        scene_arg, petsc_args, restart = _restart_args(argv)
    elif not argv or argv[0].startswith("-"):
        raise UserError("run: needs a SCENE (a built-in name or an options file); see `hyperelastic scenes`")
    else:
        scene_arg, petsc_args = argv[0], argv[1:]
    petsc_args = _recipes(petsc_args)
    _check_words(petsc_args)
    _, options_files = _petsc(petsc_args)
    # deferred on purpose: petsc4py reads the command line when PETSc is first imported, so every module
    # that imports it comes after _petsc
    from ..app.run import run_scene
    return run_scene(scene_arg, options_files, restart, argv[1] if restart is not None else None, SETUP_SIGNALS)


def catalog_help():
    """`run --help`: every option with its default (needs PETSc for the options module; nothing is read)."""
    from ..app.catalog import help_text     # deferred: imports petsc4py (see run_cmd)
    return help_text()


def mesh_cmd(argv):
    ap = ArgParser(prog="hyperelastic mesh", description="Generate a tetrahedral mesh with gmsh, keeping the "
                   "geometry's physical groups.")
    ap.add_argument("geometry", help="a .geo or .step file, or the name of a .geo file under meshes/ (e.g. bar)")
    ap.add_argument("--level", type=int, help="refinement level: 1..8 = thesis L1..L8, 9.. finer (~2x tets each)")
    ap.add_argument("--size", type=float, help="target edge length instead of a level")
    ap.add_argument("--refine", type=int, default=0, help="also write N uniformly refined meshes OUT_r1 .. OUT_rN")
    ap.add_argument("--order", type=int, default=1, help="2: 10-node tetrahedra, edge nodes on curved geometry")
    ap.add_argument("--graded", action="store_true", help="keep the geometry's own mesh sizes (its size fields, its "
                    "points' lengths), --size being the largest edge (without it every edge is --size)")
    ap.add_argument("--prepare", action="store_true", help="GEOMETRY is a mesh file (any a run reads): check it, "
                    "order it and write it as an .h5 every rank of a run reads its own slice of (-mesh OUT.h5)")
    ap.add_argument("-o", "--output", required=True, help="output .msh file (.h5 with --prepare)")
    a = ap.parse_args(argv)
    if a.prepare:
        return prepare_cmd(a)
    if (a.level is None) == (a.size is None):
        raise UserError("hyperelastic mesh: give exactly one of --level N or --size H")
    if a.refine < 0:
        raise UserError(f"hyperelastic mesh: --refine {a.refine} must be >= 0")
    if a.graded and a.size is None:
        raise UserError("hyperelastic mesh: --graded keeps the geometry's sizes up to --size H: give --size")
    st = generate(a.geometry, a.level, a.output, a.size, a.refine, a.order, a.graded)
    for s in (st if a.refine else [st]):
        nodes = f" ({s['nodes']} nodes of 10-node tets)" if s["order"] == 2 else ""
        print(f"{s['file']}: level {a.level or '-'} target edge {s['target_size']:.4g}: {s['vertices']} vertices"
              f"{nodes}, {s['tets']} tets, min edge {s['min_edge']:.4g}")
    first = st[0] if a.refine else st
    written = [f"{name} ({kind})" for kind, name, n in first["groups"] if n]
    if written and not first["auto_named"]:
        print(f"physical groups written: {', '.join(written)}")
    for line in empty_group_lines(first["groups"], first["extent"]):
        print(line, file=sys.stderr)
    if first["flattened"]:
        print(f"note: the geometry declares its own mesh sizes (a background field); every edge was made {a.size:g} "
              f"(give --graded to keep its sizes, at most {a.size:g})" if a.size else
              "note: the geometry declares its own mesh sizes (a background field); the level's edge length "
              "overrode them (give --size H --graded to keep them)")
    if first["auto_named"]:
        print("the geometry has no physical groups: each surface and volume is named by its tag; pick surfaces "
              "by these names (-fix surface_3) or by geometry (-fix x=0, box=..., normal=+z)")
    elif first["surfaces"]:
        print("the geometry's physical surfaces (pick them by name, -fix NAME, or by geometry: -fix x=0, box=..., "
              "normal=+z):")
    if first["surfaces"]:
        print(f"  {'surface':<14} {'facets':>7} {'area':>11}  {'centroid':<36} outward normal")
        for name, nf, area, c, u in first["surfaces"]:
            cen = "(" + ", ".join(f"{v:.4g}" for v in c) + ")"
            print(f"  {name:<14} {nf:>7} {area:>11.4g}  {cen:<36} {format_normal(u)}")
    return 0


def prepare_cmd(a):
    """`hyperelastic mesh MESH --prepare -o OUT.h5` (mesh/prepared.py)."""
    from ..mesh.prepared import check_prepare_output, prepare
    from ..mesh.read import read_mesh
    if a.level is not None or a.size is not None or a.refine or a.graded or a.order != 1:
        raise UserError("hyperelastic mesh --prepare: takes a mesh file and -o only (mesh it first, then prepare it)")
    check_prepare_output(a.geometry, a.output)
    st = prepare(read_mesh(a.geometry), a.output)
    print(f"{a.output}: {st['vertices']} vertices, {st['cells']} tets, {st['boundary_facets']} boundary facets, "
          "ordered along a Z-curve; a run with -mesh reads it in slices, every rank its own")
    for name, kind, n in st["groups"]:
        print(f"  {name}: {n} {kind}")
    return 0


def plot_cmd(argv):
    ap = ArgParser(prog="hyperelastic plot", description="Render a frame of an output file to PNG (off-screen, as "
                   "ParaView shows it): the deformed body coloured by a field, the reference outline, the obstacles.")
    ap.add_argument("file")
    ap.add_argument("-o", "--output", default=None)
    ap.add_argument("--frame", type=int, default=-1)
    ap.add_argument("--field", default=None, metavar="NAME[:C]", help="the field to colour by (default |displacement|): "
                    "any field of the frame (von_mises, J, pressure, contact_pressure, stress, ...), a component "
                    "x|y|z of a vector, xx..zz of a tensor, 1|2|3 of principal_stress (largest first; default 1)")
    ap.add_argument("--view", default="iso", help="the camera: iso (default), x, y or z")
    ap.add_argument("--scale", type=float, default=None, help="the displacement's scale (default: 1, or larger where "
                    "the motion is under 2%% of the part's size, so that it shows)")
    ap.add_argument("--range", default=None, metavar="LO,HI", help="the colour scale's range (default: the frame's)")
    ap.add_argument("--clip", default=None, metavar="AXIS=VALUE", help="cut the part by the plane x, y or z = VALUE "
                    "(as drawn) and show what lies below it, its inside on the cut")
    ap.add_argument("--slice", default=None, metavar="AXIS=VALUE", help="show the field on the plane x, y or z = "
                    "VALUE alone (as drawn), with the part's outline")
    ap.add_argument("--frames", default=None, metavar="A:B", help="frames A to B (both included) as an animated GIF "
                    "(-o FILE.gif) or an MP4 video (-o FILE.mp4), one camera, colour range and scale for all")
    a = ap.parse_args(argv)
    out = a.output if a.output is not None else os.path.splitext(a.file)[0] + (".gif" if a.frames else ".png")
    frames = None
    if a.frames is not None:
        lo, colon, hi = a.frames.partition(":")
        if not (colon and lo.strip().isdigit() and hi.strip().isdigit() and int(lo) <= int(hi)):
            raise UserError(f"plot: --frames '{a.frames[:40]}': give A:B, frame numbers with A <= B (e.g. 0:10)")
        frames = (int(lo), int(hi))
    if a.clip is not None and a.slice is not None:
        raise UserError("plot: give one of --clip and --slice")
    clim = None
    if a.range is not None:
        try:
            clim = [float(v) for v in a.range.split(",")]
        except ValueError:
            clim = []
        if len(clim) != 2 or not all(map(math.isfinite, clim)) or clim[0] >= clim[1]:
            raise UserError(f"plot: --range '{a.range[:40]}': give LO,HI with LO < HI")
    if a.scale is not None and not (math.isfinite(a.scale) and a.scale > 0):
        raise UserError(f"plot: --scale {a.scale}: give a number > 0")
    from ..output.picture import animation, parse_cut, picture    # (deferred: it reaches physics/, which starts
    cut = parse_cut("clip", a.clip) or parse_cut("slice", a.slice)    # MPI and PETSc)
    if frames is not None:
        print(animation(a.file, out, frames, a.field, a.view, a.scale, clim, cut))
    else:
        print(picture(a.file, out, a.frame, a.field, a.view, a.scale, clim, cut))
    return 0


def scenes_cmd(argv):
    if argv:
        raise UserError(f"hyperelastic scenes: takes no arguments (got '{argv[0][:40]}')")
    from ..core.data import SCENES_DIR, builtin_scenes
    for s in builtin_scenes():
        with open(os.path.join(SCENES_DIR, s + ".opts")) as fh:
            first = fh.readline().lstrip("# ").strip()
        print(f"{s:10s} {first}")
    return 0


def report_cmd(argv):
    from ..output.report import main as report_main      # (imports the study package: only where it is needed)
    return report_main(argv)


def study_cmd(argv):
    from ..studies.command import main as study_main
    return study_main(argv)


def fit_cmd(argv):
    from ..studies.fit import main as fit_main
    return fit_main(argv)


def version_lines():
    """`hyperelastic --version`: this package's version, then the installed versions of what it runs on (read from
    the installed packages' metadata: nothing is imported or initialized)."""
    from importlib.metadata import PackageNotFoundError, version
    from .. import __version__
    lines = [f"hyperelastic {__version__}"]
    for name in ("petsc", "petsc4py", "mpi4py", "mpich", "numpy", "h5py", "gmsh", "ipctk"):
        try:
            lines.append(f"  {name} {version(name)}")
        except PackageNotFoundError:
            lines.append(f"  {name} (no installed package of that name: a system build, or absent)")
    return "\n".join(lines)


COMMANDS = {"run": run_cmd, "mesh": mesh_cmd, "plot": plot_cmd, "report": report_cmd, "scenes": scenes_cmd,
            "study": study_cmd, "fit": fit_cmd}


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    # SIGPIPE blocked: PETSc's initialization (wherever `from petsc4py import PETSc` first runs: `report` too) puts its
    # handler on SIGPIPE, which printed its crash banner and aborted (exit 15 here) when the reader of the output left
    # (`hyperelastic report FILE | head -1`); a blocked signal is never delivered, whoever handles it: the write
    # fails with EPIPE, Python raises BrokenPipeError and the command exits 141 as a shell's pipeline expects (below)
    signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGPIPE})
    debug = "-debug" in argv
    if debug:
        argv.remove("-debug")
    if not argv or argv[0] in ("-h", "--help", "help"):
        print(__doc__)
        return 0
    if argv[0] in ("--version", "-version", "version"):
        print(version_lines())
        return 0
    for a in argv:
        try:
            a.encode("utf-8")
        except UnicodeEncodeError:
            _error(f"argument '{a.encode('utf-8', 'replace').decode()}': not valid UTF-8 (file names and options "
                   "must be: PETSc, HDF5 and gmsh read them as UTF-8)")
            return EXIT_USER
    cmd = COMMANDS.get(argv[0])
    if cmd is None:
        _error(f"unknown command '{argv[0]}' (choose from {', '.join(COMMANDS)})")
        return EXIT_USER
    alike = _alike_world()
    try:
        return cmd(argv[1:])
    except UserError as e:
        if alike is not None and not _all_reach(alike):
            print(f"hyperelastic: error: {_cut(str(e))}", file=sys.stderr, flush=True)
            os._exit(EXIT_USER)      # (mpiexec ends the ranks waiting in a collective call: one line, exit status 2)
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
    except BrokenPipeError:          # (`hyperelastic report ... | head`: the reader left; as a shell's SIGPIPE)
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 128 + signal.SIGPIPE
    except Exception as e:
        if type(e).__name__ == "Error" and hasattr(e, "ierr"):   # petsc4py.PETSc.Error
            from ..core.libpetsc import error_message     # deferred: imports petsc4py (see run_cmd)
            _error(f"PETSc: {error_message(e.ierr)}")
            return EXIT_USER
        if debug:
            traceback.print_exc()
        else:
            msg = " ".join(str(e).split())[:300] or type(e).__name__
            _error(f"internal error: {type(e).__name__}: {msg} (rerun with -debug for a traceback)", any_rank=True)
        _abort_if_parallel(EXIT_INTERNAL)
        return EXIT_INTERNAL


# A bad-input error is raised on every rank alike (core.errors.raise_agreed makes a check of one rank's own data so):
# then rank 0 prints it and every rank returns. One that some ranks raise alone would leave the others waiting in a
# collective call for ever: where not every rank reaches the error within ALIKE_WAIT_S, a rank that has it prints it
# and leaves at once, and mpiexec ends the others (issue 73: 4 hangs).
ALIKE_WAIT_S = 2.0


def _alike_world():
    """Under mpiexec with more than one rank (Hydra's PMI_SIZE): a duplicate of MPI's world, made by every rank at the
    start of its command, for the agreement above alone (its barrier never meets a collective call of the run's);
    else None."""
    if int(os.environ.get("PMI_SIZE", "1") or 1) < 2:
        return None
    if "mpi4py.MPI" not in sys.modules:
        import mpi4py
        mpi4py.rc.thread_level = "funneled"      # (PETSc's own MPI_Init_thread's level: not mpi4py's "multiple")
    from mpi4py import MPI
    return MPI.COMM_WORLD.Dup() if MPI.COMM_WORLD.size > 1 else None


def _all_reach(world):
    """Whether every rank of `world` reaches this call within ALIKE_WAIT_S."""
    req = world.Ibarrier()
    end = time.monotonic() + ALIKE_WAIT_S
    while not req.Test():
        if time.monotonic() > end:
            return False
        time.sleep(0.005)
    return True


def _comm():
    """PETSc's world where PETSc is initialized (a warm-started run's server holds its module imported before)."""
    if "petsc4py.PETSc" in sys.modules:
        from petsc4py import PETSc
        if PETSc.Sys.isInitialized():
            return PETSc.COMM_WORLD
    return None


def _abort_if_parallel(code):
    """An error raised on some ranks only would leave the others waiting in a collective call."""
    comm = _comm()
    try:
        mpi = comm.tompi4py() if comm is not None else None
    except ValueError:          # PETSc was not (successfully) initialized
        mpi = None
    if mpi is None:             # (a command without PETSc: MPI's own world)
        from mpi4py import MPI
        mpi = MPI.COMM_WORLD
    if mpi.size > 1:
        sys.stderr.flush()
        time.sleep(ABORT_DRAIN_S)
        mpi.Abort(code)


# Before MPI_Abort, the time this rank gives mpiexec to forward the error line it has just written: Hydra's abort ends
# the proxies, and a line still in the pipe between a rank and its proxy was lost ~1 run in 40
# (tests/test_install.py's two-rank internal error). Less than ANY_RANK_GRACE_S, after which the other ranks print.
ABORT_DRAIN_S = 0.25


# An error that only some ranks may have (an internal one) is printed by rank 0 at once and by any other rank after
# this grace: where rank 0 has it too, its abort ends the job first, so that N ranks print it once.
ANY_RANK_GRACE_S = 2.0


MAX_ERROR = 1000       # characters of the error line's message (a value a user gave may be a million)


def _cut(msg):
    return msg if len(msg) <= MAX_ERROR else f"{msg[:MAX_ERROR]}... ({len(msg) - MAX_ERROR:,} characters more)"


def _error(msg, any_rank=False):
    """The one error line: printed by rank 0 (errors of the user and of the solver are raised on every rank alike);
    with any_rank (an internal error, maybe on some ranks only) by the others too, after ANY_RANK_GRACE_S."""
    comm = _comm()
    if comm is not None:   # no 'unused options' report after an error: the one line says what is wrong
        from petsc4py import PETSc
        PETSc.Options().setValue("options_left", "0")
    try:
        rank, size = comm.getRank(), comm.getSize()
    except (AttributeError, ValueError):   # PETSc not (or not successfully) initialized: ask MPI
        from mpi4py import MPI
        rank, size = MPI.COMM_WORLD.rank, MPI.COMM_WORLD.size
    if any_rank and rank != 0 and size > 1:
        sys.stderr.flush()
        time.sleep(ANY_RANK_GRACE_S)
    if any_rank or rank == 0:
        print(f"hyperelastic: error: {_cut(msg)}", file=sys.stderr, flush=True)


if __name__ == "__main__":
    sys.exit(main())
