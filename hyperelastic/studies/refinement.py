"""The refinement study: a quasi-static ramped bend on gmsh levels L1..., the displacement at the
material points against the finest level, the observed convergence order and time per load step."""
import json
import os

import numpy as np

from .experiments.runner import last_line, parallel_map, run_hyperelastic
from .experiments.table import write_csv
from ..output.figures import legend, pyplot
from ..mesh.read import read
from ..mesh.generate import cached_bar, level_size
from .stability import fmt
from .measure import at_points, read_cost, slope
from .plan import PCS, POINT_NAMES

REFINE_SCENE = ["bend2", "-quasistatic", "-dt", "0.0625", "-final_time", "0.25", "-material", "stvk"]
REFINE_T = 0.25
REFINE_SOLVER = ["-jacobian", "assembled", "-ksp_type", "cg", "-snes_rtol", "1e-10", "-snes_atol", "1e-12",
                 "-ksp_rtol", "1e-10"] + PCS["gamg"]


def refine_levels(full):
    return [1, 2, 3, 4, 5, 8] if not full else list(range(1, 16))


def refinement(out_dir, full=False, jobs=2, budget=600.0, parallel_from=20000, log=None):
    """Run the refinement levels (quick: L1-L4; --full: L1-L8 and finer gmsh levels while the
    total stays within `budget` seconds, under mpiexec -n 2 from `parallel_from` tets on).
    Returns rows, one per level (and a 1-rank twin of the first parallel level)."""
    d = os.path.join(out_dir, "runs")
    os.makedirs(d, exist_ok=True)
    levels = refine_levels(full)
    meshes = {L: cached_bar(L) for L in levels[:8]}         # the cheap ones up front

    def one(level, nprocs):
        path = os.path.join(d, f"refine_L{level}_np{nprocs}.h5")
        rc, err, wall = run_hyperelastic(["run"] + REFINE_SCENE + ["-level", level, "-output", path, "-quiet"]
                                         + REFINE_SOLVER, path, nprocs=nprocs, timeout=3 * budget)
        row = {"level": level, "nprocs": nprocs, "rc": rc, "wall_s": wall, "path": path,
               "message": last_line(err, rc) if rc else ""}
        row.update(read_cost(path))
        row["outcome"] = "finished" if rc == 0 and abs((row.get("t_end") or 0.0) - REFINE_T) < 1e-9 else "failed"
        return row

    serial = [L for L in levels if L <= 8 and _tets(meshes[L]) < parallel_from]
    rows = parallel_map(lambda L: one(L, 1), serial, jobs, log)
    spent = sum(r["wall_s"] for r in rows)
    for L in [L for L in levels if L not in serial]:
        if rows and rows[-1]["outcome"] == "finished" and L > 8:
            # each level ~2x the tets: expect ~2.2x the time of the last one
            if spent + 2.2 * rows[-1]["wall_s"] > budget:
                break
        first_parallel = not any(r["nprocs"] == 2 for r in rows)
        r = one(L, 2)
        rows.append(r)
        if log:
            log(r)
        spent += r["wall_s"]
        if first_parallel:                      # the same level on one rank: is 2 ranks faster?
            r1 = one(L, 1)
            r1["twin"] = True
            rows.append(r1)
            if log:
                log(r1)
            spent += r1["wall_s"]
    analyse_refinement(rows)
    return rows


def _tets(path):
    return len(read(path)[1])


def analyse_refinement(rows):
    """Errors at the material points against the finest finished level, the observed orders, and
    time per load step (in place); returns the fit {quantity: slope}."""
    ok = [r for r in rows if r["outcome"] == "finished" and not r.get("twin")]
    if len(ok) < 3:
        return {}
    finest = max(ok, key=lambda r: r["tets"])
    uf = at_points(finest["path"])
    for r in rows:
        r["h_mesh"] = level_size(r["level"])
        if r["outcome"] == "finished":
            u = at_points(r["path"])
            r["u_points"] = json.dumps(u.round(9).tolist())
            err = np.linalg.norm(u - uf, axis=1)
            r["err_test_point"] = float(err[0])
            r["err_tip"] = float(err[1])
            r["err_points_max_rel"] = float(err.max() / np.linalg.norm(uf, axis=1).max())
            r["tip_displacement"] = float(np.linalg.norm(u[1]))
            r["s_per_step"] = r["solve_s"] / max(r["steps"], 1)
            r["finest_level"] = finest["level"]
    fit = [r for r in ok if r is not finest]
    out = {}
    for key in ("err_test_point", "err_tip"):
        out[key] = slope([r["h_mesh"] for r in fit], [r[key] for r in fit])
    out["s_per_step"] = slope([r["tets"] for r in ok], [r["s_per_step"] for r in ok])
    for r in rows:
        r["order_test_point"], r["order_tip"], r["time_exponent"] = out["err_test_point"], out["err_tip"], out["s_per_step"]
    return out


REFINE_COLUMNS = ("level", "nprocs", "twin", "outcome", "message", "tets", "h_mesh", "tip_displacement",
                  "err_test_point", "err_tip", "err_points_max_rel", "order_test_point", "order_tip", "steps",
                  "newton_its", "ksp_its", "solve_s", "s_per_step", "time_exponent", "wall_s", "peak_rss_mb",
                  "finest_level", "u_points")


def refinement_report(rows, out_dir, command):
    plt = pyplot()
    write_csv(os.path.join(out_dir, "refinement.csv"), rows, REFINE_COLUMNS)
    ok = [r for r in rows if r["outcome"] == "finished" and not r.get("twin")]
    fit = [r for r in ok if r.get("err_tip")]
    o_tp = ok[0].get("order_test_point") if ok else float("nan")
    o_tip = ok[0].get("order_tip") if ok else float("nan")
    t_exp = ok[0].get("time_exponent") if ok else float("nan")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for key, name, o in (("err_test_point", POINT_NAMES[0], o_tp), ("err_tip", POINT_NAMES[1], o_tip)):
        if fit:
            h = np.array([r["h_mesh"] for r in fit])
            e = np.array([r[key] for r in fit])
            a1.loglog(h, e, "o-", label=f"{name}: slope {o:.2f}")
    a1.set_xlabel("target edge length h_mesh [m]")
    a1.set_ylabel("|u - u_finest| [m]")
    a1.set_title(f"displacement error vs mesh size (finest: L{ok[-1]['level'] if ok else '-'})", fontsize=9)
    legend(a1, fontsize=7)
    for n in (1, 2):
        rs = [r for r in rows if r["outcome"] == "finished" and r["nprocs"] == n]
        if rs:
            a2.loglog([r["tets"] for r in rs], [r["s_per_step"] for r in rs], "o-" if n == 1 else "s--",
                      label=f"{n} rank{'s' if n > 1 else ''}")
    a2.set_xlabel("tets")
    a2.set_ylabel("solve time per load step [s]")
    a2.set_title(f"time per step vs tets (fitted exponent {t_exp:.2f})", fontsize=9)
    legend(a2, fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "refinement.png"), dpi=110)
    plt.close(fig)
    L = ["# Mesh refinement (gmsh)", ""]
    if ok:
        fin = ok[-1]
        L += [f"**Observed convergence order of the displacement at the thesis' test point (4.5, 1.5, 1.5): "
              f"{o_tp:.2f}; at the tip: {o_tip:.2f}** (least-squares slope of log error vs log edge length, "
              f"L{ok[0]['level']}–L{fit[-1]['level'] if fit else '-'} against the finest level L{fin['level']}, "
              f"{fin['tets']:,} tets). Time per load step grows as tets^{t_exp:.2f}.", ""]
    L += [f"Command: `{command}`. Problem: `hyperelastic run {' '.join(REFINE_SCENE)}` (four quasi-static load "
          f"steps of the ramped end traction, to 5 kPa), solver `{' '.join(REFINE_SOLVER)}`. Figure: `refinement.png`.", "",
          "| level | ranks | tets | h_mesh | tip displacement (m) | error at test point (m) | error at tip (m) | "
          "Newton | Krylov | solve (s) | s / step | wall (s) | peak MB | outcome |", "|" + "---|" * 14]
    for r in rows:
        out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:80]}"
        L.append(f"| L{r['level']} | {r['nprocs']} | {fmt(r.get('tets'), ',')} | {r.get('h_mesh', 0):.3g} | "
                 f"{fmt(r.get('tip_displacement'), '.5g')} | {fmt(r.get('err_test_point'), '.2g')} | "
                 f"{fmt(r.get('err_tip'), '.2g')} | {fmt(r.get('newton_its'))} | {fmt(r.get('ksp_its'))} | "
                 f"{fmt(r.get('solve_s'))} | {fmt(r.get('s_per_step'))} | {r['wall_s']:.3g} | "
                 f"{fmt(r.get('peak_rss_mb'), '.0f')} | {out} |")
    twins = [r for r in rows if r.get("twin") and r["outcome"] == "finished"]
    for t in twins:
        par = next((r for r in rows if r["level"] == t["level"] and r["nprocs"] == 2 and r["outcome"] == "finished"), None)
        if par:
            L += ["", f"L{t['level']} on 1 vs 2 ranks: {t['s_per_step']:.3g} vs {par['s_per_step']:.3g} s per load "
                      f"step ({t['s_per_step'] / par['s_per_step']:.2f}× on 2 ranks); the levels from there on run under "
                      "`mpiexec -n 2`."]
    with open(os.path.join(out_dir, "refinement.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


