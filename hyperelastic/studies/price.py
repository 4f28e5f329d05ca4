"""The price of accuracy on a user's part: `hyperelastic study price --part GEO --scene OPTS --watch Q
--target ERR`. The cheapest setting found whose estimated error in Q is below ERR (relative), by a search
over the dimensions that set the error and the cost, every run a real `hyperelastic run`.

Dimensions of a setting (Setting): the element order (1, 2; the mixed formulation comes with order 2 where the
material asks for it, `-formulation auto`), the mesh level (the part meshed at --size and refined uniformly:
h halved, 8x the tets; order-2 meshes get gmsh's curved edge nodes), for dynamic scenes the time step
(the scene's, halved j times) and the integrator (backward Euler; generalized-alpha; energy-momentum),
the Newton/Krylov tolerances (loose, PETSc's defaults, tight) and the preconditioner (the default; GAMG).

Error estimates, from the runs themselves (each along one dimension with the others fixed, and assumed
additive across dimensions: space + time + solver):
- space, per order: Richardson's extrapolation along the mesh levels, with the observed order where three
  levels give one (the smaller of it and the element's, so a pre-asymptotic sequence is not trusted beyond
  what it shows; non-monotone changes: the last change itself), else the element's order (k + 1 for
  displacements, 2k for energies and reactions);
- time, per order and integrator: the same along dt halvings with the integrator's order (1 backward Euler, 2
  the others), measured on the order's coarsest mesh;
- solver: the change from each tolerance to the tightest run.
A run's estimate is |q - limit| in each dimension; a setting not run is extrapolated at the order.

The search starts coarse (the two coarsest meshes of each order; for dynamic scenes dt and dt/2 of each
integrator on each order's coarsest; one tighter tolerance) and then repeats: for each order, the plan is the
cheapest setting the models predict to meet the target (cost predicted from the runs' measured growth per
dimension); the order with the cheapest plan moves one notch toward it, in the dimension whose error falls
most per second of the next run; every run updates the models. It stops when no order's plan is predicted
cheaper than the cheapest run already meeting the target, or at --budget / --max-runs. The linear solver (the
Jacobian mode and the preconditioner: the assembled tangent with the default preconditioner or GAMG, the
matrix-free exact tangent with Jacobi; on quadratic tetrahedra also p-multigrid) is a cost-only dimension: on each
order's first run over PC_TRIAL seconds the other solvers run at the same setting (each stopped once it is TRIAL_STOP
times slower than the fastest so far) and the fastest is kept. (PETSc's
MFFD, -snes_mf_operator, is not tried: it costs a residual per Krylov iteration and is never faster than the exact
tangent, BENCHMARKS.md.)
"""
import math
import os
import time
from dataclasses import dataclass, replace

from ..core.data import OPTIONS_DIR
from ..core.errors import UserError
from .experiments.runner import GRACE_S, last_line, run_hyperelastic
from ..core.files import option_lines, output_names
from ..mesh.generate import generate
from ..app.scene import Scene
from .measure import read_cost
from .part import expected_order
from ..output.watch import parse_watch, watched

INTEGRATORS = {   # name: (options, order of accuracy in time)
    "beuler": (["-integrator", "beuler"], 1),
    "alpha2": (["-integrator", "ts"], 2),
    "energy_momentum": (["-integrator", "ts", "-ts_alpha_radius", "1", "-energy_momentum"], 2),
}
TOLERANCES = (("loose", ["-snes_rtol", "1e-4", "-ksp_rtol", "1e-3"]), ("default", []),
              ("tight", ["-snes_rtol", "1e-10", "-ksp_rtol", "1e-9"]))
# the linear solver: the Jacobian mode and the preconditioner (cost-only: the answer is the same to the tolerances);
# p-multigrid (options/pmg.opts) only where it applies, on quadratic tetrahedra: there the default Jacobi took ~970 CG
# iterations per Newton step on the bar's second refinement and p-multigrid ~20 (BENCHMARKS.md, issue 48 item 6)
SOLVERS = {"default": [], "gamg": ["-pc_type", "gamg"], "shell": ["-jacobian", "shell"],
           "pmg": ["-options_file", os.path.join(OPTIONS_DIR, "pmg.opts")]}
SOLVER_NAMES = {"default": "assembled, default PC", "gamg": "assembled, GAMG", "shell": "matrix-free tangent, Jacobi",
                "pmg": "assembled, p-multigrid"}
SOLVER_ORDERS = {"pmg": (2,)}     # the element orders a solver is tried on (others: every order)
PC_TRIAL = 0.5          # s: an order's first run at least this long also runs with the other solvers
# a solver trial is stopped at TRIAL_STOP x the wall time of the fastest trial of the same setting so far, plus
# TRIAL_FLOOR s (a process's start, ~0.5 s, twice): it cannot be the fastest then (the bar's matrix-free P2 trial ran
# 44 s where the default finished in 3.5 s). Nothing of a stopped trial is kept, so it is killed at once: given the
# usual grace it went on with its Newton step under way, 8 s past its limit on the bar's P2 r2 (issue 69 item 7)
TRIAL_STOP, TRIAL_FLOOR = 1.5, 1.0
# s: the defaults' setting is run for the comparison where predicted to take at most DEFAULTS_CAP, and stopped at
# DEFAULTS_STOP of wall time (a prediction from coarser runs can be far off: on the bar at 10%, P1 r4 with default
# tolerances was predicted under 30 s and took ~260 s, Jacobi's iterations growing with the mesh)
DEFAULTS_CAP, DEFAULTS_STOP = 30.0, 60.0
MAX_DT_HALVINGS = 6
DEFAULT_GROWTH = {"level": 8.0, "dt": 2.0, "tol": 1.3}


def solvers(order):
    """The linear solvers tried on runs of element order `order`."""
    return [k for k in SOLVERS if order in SOLVER_ORDERS.get(k, (order,))]


@dataclass(frozen=True)
class Setting:
    order: int
    level: int
    dt: int = 0                 # halvings of the scene's step
    integrator: str = "beuler"
    tol: int = 0                # index into TOLERANCES
    solver: str = "default"

    def key(self):
        """The setting without the preconditioner (which changes the cost, not the answer)."""
        return (self.order, self.level, self.dt, self.integrator, self.tol)

    def label(self):
        return (f"P{self.order} r{self.level}, {self.integrator} dt/{2 ** self.dt}, {TOLERANCES[self.tol][0]} "
                f"tolerances, {SOLVER_NAMES[self.solver]}")


def scene_facts(scene, run_args):
    """(dynamic, the scene's integrator, its step dt) from the scene file and the extra options."""
    with open(scene, encoding="utf-8", errors="replace") as fh:
        opts = {k: v for _, k, v in option_lines(fh.read(), f"scene '{scene}'")}
    words = list(run_args)
    for i, w in enumerate(words):
        if w.startswith("-") and len(w) > 1 and not _number(w):
            opts[w[1:]] = words[i + 1] if i + 1 < len(words) and (_number(words[i + 1]) or
                                                                  not words[i + 1].startswith("-")) else None
    integ = "beuler"
    if opts.get("integrator") == "ts":
        integ = "energy_momentum" if "energy_momentum" in opts else "alpha2"
    return "quasistatic" not in opts, integ, float(opts.get("dt") or Scene.dt)


def _number(w):
    try:
        float(w)
        return True
    except ValueError:
        return False


class Search:
    """The runs of one price study, the error and cost models they make, and the search's steps."""

    def __init__(self, part, scene, watch, target, size, out_dir, orders=(1, 2), run_args=(), budget=600.0,
                 max_runs=40, max_level=5, max_tets=3e6, log=None, graded=False):
        if not os.path.isfile(scene):
            raise UserError(f"--scene '{scene}': no such file")
        if not (target > 0 and math.isfinite(target)):
            raise UserError(f"--target {target}: a relative error > 0 (e.g. 0.01 for 1%)")
        self.part, self.scene, self.w, self.target, self.size = part, scene, parse_watch(watch), target, size
        self.out, self.orders, self.run_args = out_dir, tuple(orders), list(run_args)
        self.budget, self.max_runs, self.max_level, self.max_tets, self.log = budget, max_runs, max_level, max_tets, log
        self.graded = graded       # the part's own mesh sizes kept (mesh --graded), refined uniformly
        self.dynamic, self.integrator0, self.dt0 = scene_facts(scene, self.run_args)
        self.fps = 1.0 / self.dt0       # frames at the multiples of the scene's step in every run (@T, @max)
        self.integrators = tuple(INTEGRATORS) if self.dynamic else ("beuler",)
        self.rows, self.by_key, self.meshes, self.tets, self.written = [], {}, {}, {}, []
        self.solver = {o: None for o in orders}     # the linear solver kept per order (None: not tried yet)
        self.t0 = time.perf_counter()
        self.stopped = ""          # why the search stopped before its plan was done ("" : it was not)
        self.skipped = {}          # {order: why the search left it} (linear tetrahedra that lock)
        os.makedirs(os.path.join(out_dir, "runs"), exist_ok=True)

    # ---- runs -------------------------------------------------------------------------------------------
    def mesh(self, order, level):
        """The .msh of the part at `level` for `order` (made on first use with its coarser levels)."""
        if (order, level) not in self.meshes:
            base = os.path.join(self.out, "runs", f"part_p{order}.msh")
            st = generate(self.part, None, base, self.size, level, order, self.graded)
            for i, s in enumerate(st if level else [st]):
                self.meshes[(order, i)], self.tets[(order, i)] = s["file"], s["tets"]
        return self.meshes[(order, level)]

    def args(self, s, path):
        a = ["run", self.scene, "-mesh", self.mesh(s.order, s.level), "-order", str(s.order), "-output", path,
             "-quiet", *self.run_args]
        a += ["-dt", repr(self.dt0 / 2 ** s.dt), "-frames_per_second", repr(self.fps)]
        if self.dynamic:
            a += INTEGRATORS[s.integrator][0]
        return a + TOLERANCES[s.tol][1] + SOLVERS[s.solver]

    def run(self, s, why, limit=None):
        """Run setting s (once), record its row; returns the row. The run is stopped where the budget ends, or at
        `limit` seconds where that comes first (the row then records `stopped_at`; the search goes on)."""
        if s in self.by_key.get(s.key(), {}):
            return self.by_key[s.key()][s]
        path = os.path.join(self.out, "runs", f"p{s.order}_r{s.level}_dt{s.dt}_{s.integrator}_t{s.tol}_{s.solver}.h5")
        args = self.args(s, path)
        self.written += output_names(path)
        remaining = max(1.0, self.budget - self.elapsed())
        capped = limit is not None and limit < remaining
        rc, err, wall = run_hyperelastic(args, path, nprocs=1, timeout=min(3600, limit if capped else remaining),
                                         grace=0 if capped else GRACE_S)
        stopped_at = None
        if rc == -1 and err.startswith("timed out") and capped:
            stopped_at, err = limit, f"stopped at {limit:.3g} s, the limit of this run ({why})"
        elif rc == -1 and err.startswith("timed out"):
            self.stopped = f"--budget {self.budget:g} s spent (run {len(self.rows) + 1} was stopped at it)"
            err = f"stopped at the end of --budget ({remaining:.3g} s into the run)"
        row = {"run": len(self.rows) + 1, "why": why, "order": s.order, "level": s.level, "dt_halvings": s.dt,
               "integrator": s.integrator, "tolerances": TOLERANCES[s.tol][0], "pc": s.solver,
               "tets": self.tets.get((s.order, s.level)), "rc": rc, "wall_s": wall,
               "outcome": "finished" if rc == 0 else "failed", "message": last_line(err, rc) if rc else "",
               "setting": s, "path": path, "stopped_at": stopped_at}
        row.update(read_cost(path))
        if rc == 2 and not self.rows:   # the first run refused its input (an option, a value): so would every run
            raise UserError("study price: the first run refused its input (--scene, --run-args): "
                            + row["message"].replace("hyperelastic: error: ", ""))
        if rc == 0:      # (a watch the run's output cannot give is the user's error: it ends the study)
            row["quantity"] = watched(path, self.w, self.meshes[(s.order, s.level)])
            self._locking(s, path)
        self.rows.append(row)
        self.by_key.setdefault(s.key(), {})[s] = row
        if self.log:
            self.log(row)
        return row

    def _locking(self, s, path):
        """A finished run whose start-up notes say its linear tetrahedra lock (a nearly incompressible material):
        the search leaves that order (refining a locking element buys little accuracy per second) where another
        order is searched, and the report says why."""
        if s.order != 1 or len(self.orders) < 2 or 1 in self.skipped:
            return
        notes = _attr(path, "notes")
        line = next((ln for ln in notes.splitlines() if "linear tetrahedra lock" in ln), None)
        if line:
            self.skipped[1] = ("linear tetrahedra lock on this nearly incompressible material (its first run said: "
                               f"{line.split(':')[0]}); order 2 only from then on")

    def elapsed(self):
        return time.perf_counter() - self.t0

    def out_of_budget(self):
        """Whether --budget is spent (the search then stops, and its report says so)."""
        if self.elapsed() >= self.budget and not self.stopped:
            self.stopped = f"--budget {self.budget:g} s spent"
        return bool(self.stopped)

    def ok(self, s):
        """The finished row of a setting's answer (any preconditioner), or None."""
        rows = [r for r in self.by_key.get(s.key(), {}).values() if r["outcome"] == "finished"]
        return min(rows, key=lambda r: r["solve_s"]) if rows else None

    def cost(self, s):
        """Measured solve time of s (its cheaper preconditioner), else predicted (models.predict_cost)."""
        r = self.ok(s)
        return r["solve_s"] if r else None

    # ---- models ------------------------------------------------------------------------------------------
    def model(self, dim, **fixed):
        """The error model along `dim` ('level', 'dt' or 'tol') from the finished runs that differ only in it
        (for 'level' and 'dt' whatever their tolerances: each point the tightest run there), among those matching
        `fixed` (order=..., integrator=...): the line with the most points (then the finest)."""
        names = ("order", "level", "dt", "integrator", "tol")
        ignore = {dim} | ({"tol"} if dim != "tol" else set())
        lines = {}
        for key in sorted(self.by_key, key=lambda k: k[4]):          # tighter tolerances last: they win
            s = Setting(*key)
            r = self.ok(s)
            if r is None or "quantity" not in r or any(getattr(s, k) != v for k, v in fixed.items()):
                continue
            other = tuple(v for n, v in zip(names, key) if n not in ignore)
            lines.setdefault(other, {})[getattr(s, dim)] = (r["quantity"], r["solve_s"])
        if not lines:
            return None
        pts = max(lines.values(), key=lambda d: (len(d), max(d)))
        if dim == "tol":
            return SolverModel(pts)
        expected = (INTEGRATORS[fixed["integrator"]][1] if dim == "dt"
                    else expected_order(self.w.kind_of_error, fixed["order"]))
        return DimModel(pts, expected)

    def models(self):
        """{('level', order) | ('dt', order, integrator) | 'tol': model} of the runs so far. Time is modelled per
        order from that order's runs (its coarsest mesh's step halvings), else from the other order's: a time
        error carried from a much stiffer discretisation misjudges it (the swinging bracket's backward Euler
        error is 5% on P1's coarsest mesh and 20% on P2's)."""
        m = {("level", o): self.model("level", order=o) for o in self.orders}
        if self.dynamic:
            m.update({("dt", o, i): self.model("dt", order=o, integrator=i) or self.model("dt", integrator=i)
                      for o in self.orders for i in self.integrators})
        m["tol"] = self.model("tol")
        return m

    def estimate(self, s, m):
        """(space, time, solver) error estimates of setting s (absolute; None where no model says)."""
        sp = m[("level", s.order)].error(s.level) if m[("level", s.order)] else None
        tm = m.get(("dt", s.order, s.integrator))
        tm = (tm.error(s.dt) if tm else None) if self.dynamic else 0.0
        so = m["tol"].error(s.tol) if m["tol"] else None
        return sp, tm, so

    def scale(self):
        """|q| of the most refined finished run: what errors are relative to."""
        done = [r for r in self.rows if "quantity" in r]
        if not done:
            return 1.0
        r = max(done, key=lambda r: (r["order"], r["level"], r["dt_halvings"], TOL_INDEX[r["tolerances"]]))
        return abs(r["quantity"]) or max(abs(x["quantity"]) for x in done) or 1.0

    def total(self, s, m):
        parts = self.estimate(s, m)
        return float("inf") if any(p is None for p in parts) else sum(parts) / self.scale()

    def predict_cost(self, s, m):
        """The measured solve time of s, else the nearest run's of its order scaled by the measured growth per
        notch in each dimension (DEFAULT_GROWTH where none is measured yet)."""
        c = self.cost(s)
        if c is not None:
            return c
        base = [self.ok(Setting(*k)) for k in self.by_key if k[0] == s.order]
        base = [r for r in base if r is not None]
        if not base:
            return float("inf")
        r = min(base, key=lambda r: (3 * abs(r["level"] - s.level) + abs(r["dt_halvings"] - s.dt) +
                                     abs(TOL_INDEX[r["tolerances"]] - s.tol) + 2 * (r["integrator"] != s.integrator)))
        g = {"level": _growth(m[("level", s.order)], "level"),
             "dt": _growth(m.get(("dt", s.order, s.integrator)), "dt"),
             "tol": _growth(m["tol"], "tol")}
        c = r["solve_s"] * g["level"] ** (s.level - r["level"]) * g["dt"] ** (s.dt - r["dt_halvings"])
        c *= g["tol"] ** (s.tol - TOL_INDEX[r["tolerances"]])
        if r["integrator"] != s.integrator:
            c *= 1.5
        return c

    def failed(self, s):
        rows = self.by_key.get(s.key(), {}).values()
        return bool(rows) and all(r["outcome"] == "failed" for r in rows)

    def predicted_tets(self, order, level):
        if (order, level) in self.tets:
            return self.tets[(order, level)]
        known = [(i, t) for (o, i), t in self.tets.items() if o == order]
        i, t = max(known) if known else (0, 0)
        return t * 8 ** (level - i)

    def plan(self, order, m):
        """(predicted cost, Setting): the cheapest setting of `order` the models predict to meet the target
        (None when none does within the limits)."""
        best = None
        for i in range(self.max_level + 1):
            if self.predicted_tets(order, i) > self.max_tets:
                break
            for j in (range(MAX_DT_HALVINGS + 1) if self.dynamic else (0,)):
                for integ in self.integrators:
                    for t in range(len(TOLERANCES)):
                        s = Setting(order, i, j, integ, t)
                        if self.failed(s) or self.total(s, m) > self.target:
                            continue
                        c = self.predict_cost(s, m)
                        if best is None or c < best[0]:
                            best = (c, s)
        return best

    def remove_files(self):
        """Remove what this search wrote (its runs' outputs and meshes, then the runs folder if empty): a study
        that fails on the user's error leaves nothing behind."""
        for p in self.written + list(self.meshes.values()):
            if os.path.exists(p):
                os.remove(p)
        d = os.path.join(self.out, "runs")
        if os.path.isdir(d) and not os.listdir(d):
            os.rmdir(d)

    # ---- the search ---------------------------------------------------------------------------------------
    def go(self, s, why):
        """Run setting s with its order's linear solver; an order's first run over PC_TRIAL seconds also runs
        with the others, and the fastest is kept for that order."""
        s = replace(s, solver=self.solver[s.order] or "default")
        row = self.run(s, why)
        if s.order in self.skipped:         # (an order left after this run: no solver trials for it)
            return row
        if self.solver[s.order] is None and row["outcome"] == "finished" and row.get("solve_s", 0) >= PC_TRIAL:
            if _formulation(row["path"]) == "mixed":
                self.solver[s.order] = "default"       # its Schur field split (GAMG inside): nothing to try
            else:
                trials = [row]
                for k in solvers(s.order):
                    if k != s.solver:       # (stopped once it cannot be the fastest: TRIAL_STOP)
                        fastest = min(r["wall_s"] for r in trials if r["outcome"] == "finished")
                        trials.append(self.run(replace(s, solver=k), "linear solver trial",
                                               limit=TRIAL_STOP * fastest + TRIAL_FLOOR))
                done = [r for r in trials if r["outcome"] == "finished"]
                self.solver[s.order] = min(done, key=lambda r: r["solve_s"])["setting"].solver
        return row

    def probes(self):
        """The coarse start: the two coarsest meshes of each order; on each order's coarsest mesh dt/2 of the
        scene's integrator and dt, dt/2 of the others (dynamic scenes); the default tolerances on the first's. A
        spent budget ends them early."""
        o1, i0 = self.orders[0], self.integrator0
        todo = [(Setting(o, lv, 0, i0, 0), "start: space") for o in self.orders for lv in (0, 1)]
        if self.dynamic:
            todo += [(Setting(o, 0, j, integ, 0), "start: time") for o in self.orders
                     for integ in [i0] + [i for i in self.integrators if i != i0] for j in (0, 1)]
        todo.append((Setting(o1, 0, 0, i0, 1), "start: solver tolerances"))
        for s, why in todo:
            if self.out_of_budget():
                break
            if s.order in self.skipped:       # (the tolerances' probe moves to an order still searched)
                alt = [o for o in self.orders if o not in self.skipped]
                if why != "start: solver tolerances" or not alt:
                    continue
                s = replace(s, order=alt[0])
            self.go(s, why)
        return {o: Setting(o, 1, 0, i0, 0) for o in self.orders}

    def step(self, c, p, m):
        """The next setting from c toward the plan p: one notch in the dimension whose estimated error falls
        most per second of the new run (a dimension where p is coarser than c jumps back to p's value)."""
        moves = []
        if p.level != c.level:
            moves.append(replace(c, level=c.level + 1 if p.level > c.level else p.level))
        if p.integrator != c.integrator:
            moves.append(replace(c, integrator=p.integrator, dt=p.dt))
        elif p.dt != c.dt:
            moves.append(replace(c, dt=c.dt + 1 if p.dt > c.dt else p.dt))
        if p.tol != c.tol:
            moves.append(replace(c, tol=c.tol + 1 if p.tol > c.tol else p.tol))
        e_c = self.total(c, m)

        def gain(s):
            return (e_c - self.total(s, m)) / max(self.predict_cost(s, m), 1e-3)
        return max(moves, key=gain) if moves else p

    def search(self):
        """Probes, then plan-and-step until no order's plan is predicted cheaper than the cheapest run that
        meets the target; returns the rows (every run)."""
        cur = self.probes()
        exhausted = set()
        for _ in range(4 * self.max_runs):
            m = self.models()
            best = self.best(m)
            plans = {o: self.plan(o, m) for o in self.orders if o not in exhausted and o not in self.skipped}
            open_ = [(pl[0], o, pl[1]) for o, pl in plans.items() if pl and (best is None or pl[0] < best["solve_s"])
                     and (self.ok(pl[1]) is None or not self.confirmed(pl[1], m))]
            if len(self.rows) >= self.max_runs:
                self.stopped = f"--max-runs {self.max_runs} made"
            if not open_ or self.stopped or self.out_of_budget():
                break
            cost, o, p = min(open_, key=lambda t: t[0])
            if self.ok(p) is None:
                nxt, why = self.step(cur[o], p, m), f"toward {p.label()} (predicted {cost:.3g} s)"
            else:
                nxt, why = self.confirm_step(p, m), f"confirming the error estimate of {p.label()}"
            if self.ok(nxt) is not None and why.startswith("toward"):
                cur[o] = nxt
                continue
            if (self.ok(nxt) is not None or self.failed(nxt) or self.predict_cost(nxt, m) > self.budget - self.elapsed()
                    or self.predicted_tets(nxt.order, nxt.level) > self.max_tets):
                exhausted.add(o)
                continue
            row = self.go(nxt, why)
            if row["outcome"] == "finished" and why.startswith("toward"):
                cur[o] = nxt
        self.compare_defaults()
        return self.rows

    def confirmed(self, s, m):
        """Whether s's error estimate rests on observed orders: three mesh levels of its order (and, for a dynamic
        scene, three steps of its integrator). With two the element's order is only assumed: the P2 bar bends at
        an observed 1.8, not 3, and its coarsest mesh missed 1% by a fifth with the assumed order."""
        sp = m[("level", s.order)]
        if sp is None or len(sp.q) < 3:
            return False
        tm = m.get(("dt", s.order, s.integrator))
        return not self.dynamic or (tm is not None and len(tm.q) >= 3)

    def confirm_step(self, s, m):
        """The run that gives s's estimate its third point: the next mesh level at s's other settings, else (time)
        the next step halving of its integrator on the coarsest mesh of its order."""
        sp = m[("level", s.order)]
        if sp is None or len(sp.q) < 3:
            return replace(s, level=_next_notch(sp.q) if sp else s.level + 1, solver="default")
        tm = self.model("dt", order=s.order, integrator=s.integrator)
        return Setting(s.order, 0, _next_notch(tm.q) if tm else s.dt + 1, s.integrator, s.tol)

    def meets(self, s, m):
        return self.total(s, m) <= self.target and self.confirmed(s, m)

    def best(self, m):
        """The cheapest finished run whose estimated error meets the target, on observed orders (None if none)."""
        ok = [r for r in self.rows if "quantity" in r and self.meets(r["setting"], m)]
        return min(ok, key=lambda r: r["solve_s"]) if ok else None

    def defaults(self, m):
        """The setting a user gets by refining alone: P1 (or the first order), the scene's step and integrator,
        PETSc's tolerances, the default preconditioner, on the first mesh the space model predicts to meet
        the target with them."""
        o = 1 if 1 in self.orders else self.orders[0]
        for i in range(self.max_level + 1):
            if self.predicted_tets(o, i) > self.max_tets:
                break
            s = Setting(o, i, 0, self.integrator0, 1)
            if self.total(s, m) <= self.target:
                return s
        return None

    def compare_defaults(self):
        """Run the defaults' setting when it is cheap enough (DEFAULTS_CAP, and within the budget left), stopped at
        DEFAULTS_STOP; else its cost stays predicted."""
        m = self.models()
        s = self.defaults(m)
        if s is not None and self.ok(s) is None and self.predict_cost(s, m) <= min(DEFAULTS_CAP,
                                                                                   self.budget - self.elapsed()):
            self.run(s, "the defaults, for comparison", limit=DEFAULTS_STOP)


def _next_notch(points):
    """The notch a model's line lacks first: a gap among its points (r0 and r2 run: r1), else one past them."""
    return min(set(range(max(points) + 2)) - set(points))


def _formulation(path):
    return _attr(path, "formulation") or "displacement"


def _attr(path, name):
    """A run's output attribute as text ("" where the file or the attribute is missing)."""
    import h5py
    try:
        with h5py.File(path, "r") as f:
            return str(f.attrs.get(name, ""))
    except OSError:
        return ""


class DimModel:
    """Richardson along one dimension (notch k: h or dt times 2^-k): the limit from the two finest points at the
    smaller of the observed order (from the three finest, where their changes shrink as a power law can make
    them) and the expected one; where they do not, the last change is the finest point's error (no
    extrapolation is trusted). Roache, "Verification and Validation in Computational Science", 1998, ch. 5."""

    def __init__(self, pts, expected):
        self.q = {k: v[0] for k, v in pts.items()}
        self.t = {k: v[1] for k, v in pts.items()}
        ks = sorted(pts)
        self.expected, self.p, self.note, self.kmax = expected, float(expected), "", ks[-1]
        self.limit = self.err_max = None
        if len(ks) < 2:
            return
        ka, kb = ks[-2], ks[-1]
        d2 = self.q[kb] - self.q[ka]
        if len(ks) >= 3:
            p_obs = observed_order(ks[-3], ka, kb, self.q[ka] - self.q[ks[-3]], d2)
            if math.isfinite(p_obs):
                self.p = max(0.3, min(p_obs, expected))
                if p_obs < 0.6 * expected:
                    self.note = f"observed order {p_obs:.2f} below the expected {expected}"
            elif d2 != 0:
                self.p, self.note = float("nan"), "the changes do not shrink: the last change taken as the error"
        if math.isfinite(self.p):
            f = 2 ** (self.p * (kb - ka)) - 1
            self.err_max, self.limit = abs(d2) / f, self.q[kb] + d2 / f
        else:
            self.err_max, self.limit = abs(d2), self.q[kb]

    def error(self, k):
        if self.err_max is None:
            return None
        if k in self.q and k < self.kmax:
            return abs(self.q[k] - self.limit)
        p = self.p if math.isfinite(self.p) else 1.0
        return self.err_max * 2 ** (-p * (k - self.kmax))


def observed_order(k1, k2, k3, d1, d2):
    """The p with q_k = q_inf + C 2^(-p k) through three points at notches k1 < k2 < k3 whose changes are
    d1 = q2 - q1, d2 = q3 - q2 (bisection; nan when no p in 0.05..12 gives their ratio)."""
    if d1 * d2 <= 0:
        return float("nan")
    ratio = d1 / d2

    def r(p):
        return (2 ** (-p * k1) - 2 ** (-p * k2)) / (2 ** (-p * k2) - 2 ** (-p * k3))
    lo, hi = 0.05, 12.0
    if not r(lo) <= ratio <= r(hi):
        return float("nan")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if r(mid) < ratio else (lo, mid)
    return 0.5 * (lo + hi)


class SolverModel:
    """The tolerances' effect: each run's change against the tightest run; the tightest's own error a
    hundredth of the last change (a notch tightens the Newton tolerance 1e4-fold, Krylov's 1e2 to 1e6)."""

    def __init__(self, pts):
        self.q = {k: v[0] for k, v in pts.items()}
        self.t = {k: v[1] for k, v in pts.items()}
        self.kmax = max(self.q)
        below = [k for k in self.q if k < self.kmax]
        self.err_max = abs(self.q[max(below)] - self.q[self.kmax]) * 1e-2 if below else None

    def error(self, k):
        if self.err_max is None:
            return None
        if k < self.kmax:
            return abs(self.q[k] - self.q[self.kmax]) if k in self.q else None
        return self.err_max * 1e-2 ** (k - self.kmax)


TOL_INDEX = {name: i for i, (name, _) in enumerate(TOLERANCES)}


def _growth(model, dim):
    """The measured cost growth per notch along a model's line (its two finest points), else the default."""
    if model is None:
        return DEFAULT_GROWTH[dim]
    ks = sorted(model.t)
    if len(ks) >= 2 and model.t[ks[-2]] > 0 and model.t[ks[-1]] > 0:
        g = (model.t[ks[-1]] / model.t[ks[-2]]) ** (1.0 / (ks[-1] - ks[-2]))
        return max(g, 1.0)
    return DEFAULT_GROWTH[dim]
