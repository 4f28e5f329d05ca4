"""What accuracy costs in time: `hyperelastic study accuracy` and `hyperelastic study refinement`.

Accuracy versus time. Each sweep point is a real `python -m hyperelastic run` (measure.py, through
experiments/runner.py) of one
*configuration* (scene, material, E, mesh level) with one *setting* (Jacobian mode, PC, Newton and
Krylov tolerances, time step h). Its error is measured against the configuration's *reference*: the
same scene and mesh run with h = h_min / REF_FACTOR (h_min the smallest h swept), the tightest
tolerances and the exact tangent (assembled; GMRES + ILU(0) to ksp_rtol 1e-12: as exact as LU here and
4x cheaper). The reference's own error is
estimated against a *check* run at twice its step: backward Euler is first order, so
e(h) ~ |x_2h - x_h|. Every run writes frames every 0.1 s; errors compare the frames at the same
times:

  err_final_max / err_final_rms   max / RMS over vertices of |x - x_ref| at the final time [m]
  err_traj_max / err_traj_rms     the same over every frame of the trajectory [m]
  rel_err                         err_traj_max / (largest vertex displacement of the reference)
  energy_drift                    (total energy - the reference's) at the final time / the reference's
                                  largest |total energy|; total = kinetic + elastic + gravity
                                  potential - traction work (negative: extra numerical dissipation)

Cost: solve time (the sum of the steps' wall time, rejected attempts included: what the setting
costs, without the process start-up), wall time of the whole command, Newton and Krylov iterations,
residual evaluations, rejected attempts, peak memory. A run that fails is a row with outcome
'failed' and its one-line message, never dropped.

The discretisation error is separate: runs with the reference's solver settings at one step (DISC_H; --smoke 0.05)
on each level, against the finest level's, P1-interpolated at fixed material points
(MATERIAL_POINTS, the thesis framework's test point first). The time error at DISC_H is nearly the
same on every mesh, so the difference is the mesh's.

Refinement: a quasi-static ramped bend on gmsh levels L1...; displacement at the material points
against the finest level, observed convergence order (least-squares slope of log error vs log
edge length) and time per load step vs tets.
"""
import math
import os
import shlex
import signal
import sys
import time

from ..core.errors import ArgParser, UserError
from ..core.files import writable_dir
from . import measure, part, plan, refinement, report
from ..output.watch import HELP

STUDIES = ("accuracy", "refinement", "price")


def _parser():
    ap = ArgParser(prog="hyperelastic study", description="What accuracy costs in time.")
    ap.add_argument("which", choices=STUDIES)
    ap.add_argument("-output_dir", "--output-dir", dest="output_dir", default=None)
    ap.add_argument("--full", action="store_true", help="the whole sweep (hours) instead of the quick default")
    ap.add_argument("--smoke", action="store_true", help="accuracy: the smallest sweep with every part of the study "
                    "(about a minute; what the test suite runs)")
    ap.add_argument("--jobs", type=int, default=2, help="runs at a time (default 2)")
    ap.add_argument("--budget", type=float, default=600.0, help="refinement: seconds for the finer levels; price: "
                    "seconds for the search (default 600)")
    ap.add_argument("--from-csv", action="store_true", help="accuracy: redo report and figures from accuracy.csv")
    ap.add_argument("--part", help="refinement: a .geo/.step of your own part (default: the thesis' bar)")
    ap.add_argument("--scene", help="refinement --part: the scene (options file) to run on each mesh")
    ap.add_argument("--size", type=float, help="refinement --part: edge length of the coarsest mesh")
    ap.add_argument("--refine", type=int, default=2, help="refinement --part: uniform refinements (default 2)")
    ap.add_argument("--graded", action="store_true", help="refinement --part, price: keep the part's own mesh sizes "
                    "(its size fields), --size the largest edge; the refinements split every tet (the grading stays)")
    ap.add_argument("--watch", default="max_displacement", help=f"refinement --part, price: the quantity: {HELP}")
    ap.add_argument("--run-args", default="", help="refinement --part: more options for every run (quoted)")
    ap.add_argument("--order", default=None, help="refinement --part: element orders, e.g. 1,2 (default 1); price: "
                    "the orders searched (default 1,2)")
    ap.add_argument("--target", type=float, help="price: the relative error wanted in --watch (e.g. 0.01)")
    ap.add_argument("--max-runs", type=int, default=40, help="price: at most this many runs (default 40)")
    ap.add_argument("--max-level", type=int, default=5, help="price: at most this many refinements (default 5)")
    return ap


def _check(a):
    if a.which == "price" and (a.part is None or a.scene is None or a.size is None or a.target is None):
        missing = [f"--{o}" for o in ("part", "scene", "size", "target") if getattr(a, o) is None]
        raise UserError(f"hyperelastic study price: needs --part PART, --scene SCENE.opts, --size H and --target ERR "
                        f"(missing {', '.join(missing)})")
    part_opts = [o for o in ("scene", "size", "target") if getattr(a, o) is not None]
    if a.part is None and part_opts:
        raise UserError(f"hyperelastic study: --{part_opts[0]} belongs to refinement --part PART or price")
    if a.part is not None and (a.which == "accuracy" or a.scene is None or a.size is None):
        raise UserError("hyperelastic study: --part goes with refinement or price, --scene SCENE.opts and --size H")
    if a.target is not None and a.which != "price":
        raise UserError("hyperelastic study: --target belongs to price")
    if a.smoke and (a.which != "accuracy" or a.full):
        raise UserError("hyperelastic study: --smoke is accuracy's smallest sweep (not with --full)")
    if a.part is not None and not (a.size > 0 and a.size < float("inf")):
        raise UserError(f"hyperelastic study: --size {a.size} must be a positive number")
    if a.target is not None and not (a.target > 0 and math.isfinite(a.target)):
        raise UserError(f"hyperelastic study: --target {a.target}: a relative error > 0 (e.g. 0.01 for 1%)")
    for name, value, ok, want in (("--jobs", a.jobs, a.jobs >= 1, ">= 1"), ("--max-runs", a.max_runs, a.max_runs >= 3,
                                  ">= 3"), ("--max-level", a.max_level, 1 <= a.max_level <= 8, "1..8")):
        if not ok:
            raise UserError(f"hyperelastic study: {name} {value}: must be {want}")
    if not (a.budget > 0 and math.isfinite(a.budget)):
        raise UserError(f"hyperelastic study: --budget {a.budget}: seconds, a finite number > 0")
    text = a.order if a.order is not None else ("1,2" if a.which == "price" else "1")
    orders = [w.strip() for w in text.split(",")]
    if not orders or any(w not in ("1", "2") for w in orders) or len(set(orders)) != len(orders):
        raise UserError(f"hyperelastic study: --order {a.order}: element orders 1 and/or 2 (e.g. 1,2)")
    if a.part is None and a.order is not None:
        raise UserError("hyperelastic study: --order belongs to refinement --part PART or price")
    a.orders = tuple(int(w) for w in orders)


def main(argv):
    """`hyperelastic study accuracy|refinement [-output_dir DIR] [--full] [--jobs N] ...`"""
    a = _parser().parse_args(argv)
    _check(a)
    out = a.output_dir or os.path.join("output", f"study_{a.which}")
    writable_dir(out, "-output_dir")
    command = "hyperelastic study " + " ".join(argv)
    t0 = time.perf_counter()

    def log(r):
        what = r.get("id") or (f"r{r['level']} ({r['tets']} tets)" if a.part else f"L{r['level']} np{r['nprocs']}")
        extra = f": {r['message']}" if r["outcome"] == "failed" else ""
        print(f"[{time.perf_counter() - t0:6.1f} s] {what} {r['outcome']}{extra}", file=sys.stderr, flush=True)
    if a.which == "accuracy":
        size = "smoke" if a.smoke else a.full
        if a.from_csv:
            path = os.path.join(out, "accuracy.csv")
            if not os.path.isfile(path):
                raise UserError(f"--from-csv: no {path}")
            rows, p = measure.read_csv(path), plan.plan(size)
        else:
            rows, p = measure.accuracy(out, size, a.jobs, log)
            measure.write_csv(rows, os.path.join(out, "accuracy.csv"))
        report.figures(rows, out)
        report.report(rows, p, out, command)
        print(os.path.join(out, "accuracy.md"))
    elif a.which == "price":
        return _price(a, out, command, t0)
    elif a.part is not None:
        rows = part.part_refinement(a.part, a.scene, a.watch, a.size, a.refine, out, a.jobs,
                                    shlex.split(a.run_args), log=log, orders=a.orders, graded=a.graded)
        part.part_report(rows, out, command, a.part, a.scene, a.watch)
        print(os.path.join(out, "refinement.md"))
    else:
        rows = refinement.refinement(out, a.full, a.jobs, a.budget, log=log)
        refinement.refinement_report(rows, out, command)
        print(os.path.join(out, "refinement.md"))
    return 0


def _price(a, out, command, t0):
    from .price import Search
    from .price_report import price_report

    def log(r):
        extra = f": {r['message']}" if r["outcome"] == "failed" else f": {r['quantity']:.6g}, {r['solve_s']:.3g} s"
        print(f"[{time.perf_counter() - t0:6.1f} s] run {r['run']} {r['setting'].label()} ({r['why']}) "
              f"{r['outcome']}{extra}", file=sys.stderr, flush=True)
    s = Search(a.part, a.scene, a.watch, a.target, a.size, out, a.orders, shlex.split(a.run_args), a.budget,
               a.max_runs, a.max_level, log=log, graded=a.graded)
    # Ctrl-C and SIGTERM (a scheduler's) end the search with its report: both raise KeyboardInterrupt here (Python
    # alone would end the process at a SIGTERM with no report); the run under way gets the signal too and stops after
    # its step
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.default_int_handler)
    interrupted = False
    try:
        s.search()
    except UserError:
        s.remove_files()
        raise
    except KeyboardInterrupt:        # Ctrl-C: the run under way was ended with it; report what the runs so far say
        interrupted = True
        s.stopped = "interrupted (Ctrl-C)"
    price_report(s, out, command)
    print(os.path.join(out, "price.md"))
    return 130 if interrupted else 0
