"""Mesh refinement on a user's part: `hyperelastic study refinement --part PART.geo --scene SCENE.opts
--size H --refine N --watch Q`. The part is meshed at edge length H and refined uniformly N times with
gmsh (`hyperelastic mesh`, physical groups kept, 8x the tets each time, h halved), the scene runs on
every mesh, and the watched quantity's convergence is reported: its change against the finest mesh,
the observed order (slope of log change vs log h), and a Richardson estimate of its limit from the
three finest meshes (q_inf = q_N + (q_N - q_{N-1}) / (2^p - 1), p = log2 of the ratio of the last two
changes; Roache, "Verification and Validation in Computational Science", 1998, ch. 5). With several element
orders (--order 1,2) each order has its own meshes, as `study price` makes them: order 2 on gmsh's 10-node meshes,
their edge nodes on the curved geometry (straight-sided cells on a curved part are off by their faceted geometry:
-5% to -17% on a torsion case, issue 47), and the convergence is analysed per order."""
import math
import os

from ..core.errors import UserError
from .experiments.runner import last_line, parallel_map, run_hyperelastic
from .experiments.table import write_csv
from ..output.figures import legend, pyplot
from ..mesh.generate import generate
from .stability import fmt
from .measure import read_cost, slope
from ..output.watch import parse_watch, watched


def meshes(part, size, refine, out_dir, graded=False, order=1):
    """[(level, .msh path, tets, target h)] of the part at size (graded: its own sizes, at most size) and its N
    uniform refinements, at element order `order` (2: 10-node cells on the curved geometry)."""
    stem = os.path.splitext(os.path.basename(part))[0] + ("" if order == 1 else f"_p{order}")
    path = os.path.join(out_dir, stem + ".msh")
    st = generate(part, None, path, size, refine, order=order, graded=graded)
    st = st if refine else [st]
    return [(i, s["file"], s["tets"], size / 2 ** i) for i, s in enumerate(st)]


def part_refinement(part, scene, watch, size, refine, out_dir, jobs=1, run_args=(), parallel_from=20000, log=None,
                    orders=(1,), graded=False):
    """Rows, one per mesh and element order: tets, h, the watched quantity, its change against the finest
    mesh of that order, the run's cost; plus (in each row) the fitted order and the Richardson limit."""
    w = parse_watch(watch)
    if refine < 2:
        raise UserError(f"--refine {refine}: a convergence order needs at least 3 meshes (--refine 2)")
    if not os.path.isfile(scene):
        raise UserError(f"--scene '{scene}': no such file")
    d = os.path.join(out_dir, "runs")
    os.makedirs(d, exist_ok=True)
    levels = [(o,) + lv for o in orders for lv in meshes(part, size, refine, d, graded, o)]

    def one(level):
        o, i, msh, tets, h = level
        n = 2 if tets * (4 if o == 2 else 1) >= parallel_from else 1
        path = os.path.join(d, f"part_p{o}_r{i}.h5")
        rc, err, wall = run_hyperelastic(["run", scene, "-mesh", msh, "-order", str(o), "-output", path, "-quiet",
                                          *run_args], path, nprocs=n, timeout=3600)
        row = {"element_order": o, "level": i, "mesh": msh, "nprocs": n, "tets": tets, "h": h, "rc": rc,
               "wall_s": wall, "outcome": "finished" if rc == 0 else "failed",
               "message": last_line(err, rc) if rc else ""}
        row.update(read_cost(path))
        if rc == 0:
            row["quantity"] = watched(path, w, msh)
            row["s_per_step"] = row["solve_s"] / max(row["steps"], 1)
        return row

    rows = parallel_map(one, levels, jobs, log)
    for o in orders:
        analyse([r for r in rows if r["element_order"] == o], expected_order(w.kind_of_error, o))
    return rows


def expected_order(kind, element_order):
    """The order at which the watched quantity converges for a smooth solution with elements of degree k:
    k + 1 for displacements (L2 / pointwise), 2k for the energy (the energy norm's square; Strang & Fix,
    "An Analysis of the Finite Element Method", 1973, ch. 3) and for reactions computed from the residual
    (a functional of the solution like the energy)."""
    return 2 * element_order if kind in ("energy", "reaction") else element_order + 1


ASYMPTOTIC = (0.6, 1.5)     # the observed order within these multiples of the expected one
MESH_INDEPENDENT = 1e-6     # a relative change between the two finest meshes below this: the solver's noise


def asymptotic(p, order, expected):
    """'' when the three finest meshes look asymptotic (their changes shrink monotonically and the
    Richardson order p and the fitted order agree with the element's within ASYMPTOTIC), else why not."""
    lo, hi = ASYMPTOTIC[0] * expected, ASYMPTOTIC[1] * expected
    if not math.isfinite(p):
        return "the changes between the three finest meshes do not shrink monotonically"
    for name, v in (("Richardson's", p), ("the fitted", order)):
        if not lo <= v <= hi:
            return f"{name} observed order {v:.2f} is far from the element's {expected} (outside {lo:.2g}-{hi:.2g})"
    return ""


def analyse(rows, expected=2):
    """In place: change against the finest finished mesh, the observed order over the others,
    Richardson's limit from the three finest (needs the changes to shrink monotonically), whether the
    meshes look asymptotic (`asymptotic_note`: '' if they do, else why not), and what the next refinement
    would cost (8x the tets; its solve time from the growth between the two finest)."""
    ok = [r for r in rows if r["outcome"] == "finished"]
    if len(ok) < 3:
        return
    qf = ok[-1]["quantity"]
    for r in ok:
        r["change"] = abs(r["quantity"] - qf)
    order = slope([r["h"] for r in ok[:-1]], [r["change"] for r in ok[:-1]])
    q1, q2, q3 = (r["quantity"] for r in ok[-3:])
    d1, d2 = q2 - q1, q3 - q2
    p = math.log2(d1 / d2) if d1 * d2 > 0 and abs(d2) < abs(d1) else float("nan")
    limit = q3 + d2 / (2 ** p - 1) if math.isfinite(p) else float("nan")
    note = asymptotic(p, order, expected)
    growth = ok[-1]["solve_s"] / ok[-2]["solve_s"] if ok[-2].get("solve_s") else float("nan")
    for r in rows:
        r["order"], r["richardson_p"], r["richardson_limit"] = order, p, limit
        r["expected_order"], r["asymptotic_note"] = expected, note
        r["next_tets"], r["next_solve_s"] = 8 * ok[-1]["tets"], ok[-1]["solve_s"] * growth


COLUMNS = ("element_order", "level", "nprocs", "tets", "h", "quantity", "change", "order", "richardson_p",
           "richardson_limit", "expected_order", "asymptotic_note",
           "outcome", "message", "steps", "newton_its", "ksp_its", "solve_s", "s_per_step", "wall_s",
           "peak_rss_mb", "mesh")


def _verdict(o, watch, ok):
    """The report's first line for element order o: the answer, and whether to trust its extrapolation."""
    r0, last = ok[0], ok[-1]
    head = (f"**P{o}: {watch} {last['quantity']:.6g} on the finest mesh ({last['tets']:,} tets); observed order "
            f"{r0['order']:.2f} (slope of the change against the finest mesh vs h)")
    nxt = (f"The next refinement (~{r0['next_tets']:,} tets) would take about {fmt(r0['next_solve_s'], '.3g')} s of "
           "solve time (the growth between the two finest meshes).")
    if not r0.get("asymptotic_note"):
        return (head + f"; Richardson's limit from the three finest: {fmt(r0['richardson_limit'], '.6g')} (p = "
                f"{fmt(r0['richardson_p'], '.2f')}, expected {r0['expected_order']}).** " + nxt)
    prev = ok[-2]["quantity"]
    rel = abs(last["quantity"] - prev) / abs(last["quantity"]) if last["quantity"] else float("nan")
    if rel < MESH_INDEPENDENT:
        return (head + f". It changes by {fmt(100 * rel, '.2g')}% between the two finest meshes: it does not depend "
                "on the mesh here beyond the solver's tolerance (a reaction balancing a dead load, say).** " + nxt)
    return (head + f". Not in the asymptotic range: {r0['asymptotic_note']}; no limit is extrapolated (Richardson "
            f"would give {fmt(r0['richardson_limit'], '.6g')}, p = {fmt(r0['richardson_p'], '.2f')}). The change "
            f"from the previous mesh, {fmt(100 * rel, '.2g')}%, is the only error indication: refine further"
            + (" (or use --order 2)" if o == 1 else "") + ".** " + nxt)


def part_report(rows, out_dir, command, part, scene, watch):
    plt = pyplot()
    write_csv(os.path.join(out_dir, "refinement.csv"), rows, COLUMNS)
    orders = sorted({r["element_order"] for r in rows})
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for o in orders:
        ok = [r for r in rows if r["outcome"] == "finished" and r["element_order"] == o]
        if not ok:
            continue
        a1.semilogx([r["h"] for r in ok], [r["quantity"] for r in ok], "o-", label=f"P{o}: {watch}")
        if math.isfinite(ok[0].get("richardson_limit", float("nan"))) and not ok[0].get("asymptotic_note"):
            a1.axhline(ok[0]["richardson_limit"], ls="--", color="gray", label=f"P{o} Richardson limit")
        ch = [r for r in ok[:-1] if r.get("change")]
        if ch:
            a2.loglog([r["h"] for r in ch], [r["change"] for r in ch], "s-",
                      label=f"P{o} |q - q_finest|, slope {ok[0].get('order', float('nan')):.2f}")
    for a, yl in ((a1, watch), (a2, "change against the finest mesh")):
        a.set_xlabel("target edge length h")
        a.set_ylabel(yl)
        legend(a, fontsize=7)
    fig.suptitle(f"{os.path.basename(part)} with {os.path.basename(scene)}", fontsize=9)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "refinement.png"), dpi=110)
    plt.close(fig)
    L = [f"# Mesh refinement of {os.path.basename(part)}", ""]
    for o in orders:
        ok = [r for r in rows if r["outcome"] == "finished" and r["element_order"] == o]
        if len(ok) >= 3:
            L += [_verdict(o, watch, ok), ""]
        else:
            L += [f"P{o}: fewer than three meshes finished: no order.", ""]
    L += [f"Command: `{command}`. Scene: `{scene}`; each mesh is the previous one split uniformly (8x the tets, "
          "h halved; `hyperelastic mesh --refine`). Figure: `refinement.png`.", "",
          "| order | mesh | ranks | tets | h | quantity | change vs finest | Newton | Krylov | solve (s) | wall (s) "
          "| outcome |", "|" + "---|" * 12]
    for r in rows:
        out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:80]}"
        L.append(f"| P{r['element_order']} | r{r['level']} | {r['nprocs']} | {r['tets']:,} | {r['h']:.4g} | "
                 f"{fmt(r.get('quantity'), '.6g')} | "
                 f"{fmt(r.get('change'), '.3g')} | {fmt(r.get('newton_its'))} | {fmt(r.get('ksp_its'))} | "
                 f"{fmt(r.get('solve_s'))} | {r['wall_s']:.3g} | {out} |")
    with open(os.path.join(out_dir, "refinement.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")
