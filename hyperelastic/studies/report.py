"""The accuracy study's report: accuracy_pareto.png, accuracy_cost_vs_E.png and accuracy.md (the
headline, the findings, the cheapest settings, cost vs E, references, mesh error, every run)."""
import math
import os

from ..output.figures import legend, pyplot
from .stability import fmt
from .measure import slope
from .plan import COST_TARGET, FPS, POINT_NAMES, REF_FACTOR, REF_SNES_RTOL, TARGETS, E_NAMES

def pareto(points):
    """Indices of the Pareto front of (cost, error) pairs: no other point is cheaper and as accurate."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


def label(r):
    pc = "" if r["pc"] in ("jacobi", "none", "ilu") else f"+{r['pc']}"
    ksp = f", ksp_rtol {r['ksp_rtol']:g}" if r["ksp_rtol"] != 1e-5 else ""
    if r.get("ts_rtol"):
        return f"{r['mode']}{pc}, ts_rtol {r['ts_rtol']:g}, snes_rtol {r['snes_rtol']:g}{ksp}"
    return f"{r['mode']}{pc}, h={r['h']:g}, snes_rtol {r['snes_rtol']:g}{ksp}"


def cfg_name(cfg):
    scene, mat, E, level = cfg
    return f"L{level} {scene}, {mat}, E = {E:g} Pa" + (" (steel preset)" if scene == "sag" else "")


def sweep_rows(rows, cfg=None):
    return [r for r in rows if r["role"] == "sweep" and (cfg is None or
            (r["scene"], r["material"], r["E"], r["level"]) == cfg)]


def cheapest(rows, target, modes=None):
    ok = [r for r in rows if r["outcome"] != "failed" and r.get("rel_err") is not None
          and r["rel_err"] <= target and (modes is None or r["mode"] in modes)]
    return min(ok, key=lambda r: r["solve_s"]) if ok else None


def other_modes(rs, target, best):
    """{mode: its cheapest run meeting target, or None} for every mode of rs other than best's."""
    return {m: cheapest(rs, target, (m,)) for m in dict.fromkeys(r["mode"] for r in rs) if m != best["mode"]}


def configs(rows):
    return list(dict.fromkeys((r["scene"], r["material"], r["E"], r["level"]) for r in sweep_rows(rows)))


def figures(rows, out_dir):
    plt = pyplot()
    cfgs = configs(rows)
    modes = list(dict.fromkeys(r["mode"] for r in sweep_rows(rows)))
    colors = dict(zip(modes, plt.rcParams["axes.prop_cycle"].by_key()["color"]))
    ncol = min(3, len(cfgs))
    nrow = math.ceil(len(cfgs) / ncol)
    fig, axes = plt.subplots(nrow, ncol, figsize=(5.2 * ncol, 4.2 * nrow), squeeze=False)
    for ax, cfg in zip(axes.flat, cfgs):
        rs = [r for r in sweep_rows(rows, cfg) if r["outcome"] != "failed" and r.get("rel_err") is not None]
        failed = [r for r in sweep_rows(rows, cfg) if r["outcome"] == "failed"]
        for m in modes:
            pts = [(r["solve_s"], r["rel_err"]) for r in rs if r["mode"] == m]
            nf = sum(r["mode"] == m for r in failed)
            if pts or nf:
                ax.scatter(*zip(*pts) if pts else ([], []), s=14, color=colors[m], alpha=0.75,
                           label=m + (f" ({nf} failed)" if nf else ""))
        pts = [(r["solve_s"], max(r["rel_err"], 1e-16)) for r in rs]
        if pts:
            front = [pts[i] for i in pareto(pts)]
            ax.step(*zip(*front), where="post", color="k", lw=1.2, label="Pareto front")
        for t in TARGETS:
            ax.axhline(t, color="0.8", lw=0.6, ls=":")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("solve time [s]")
        ax.set_ylabel("relative error (trajectory max)")
        ax.set_title(cfg_name(cfg), fontsize=9)
        legend(ax, fontsize=6)
    for ax in list(axes.flat)[len(cfgs):]:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "accuracy_pareto.png"), dpi=110)
    plt.close(fig)

    table = cost_vs_E(rows)
    fig, ax = plt.subplots(figsize=(6, 4.2))
    for (scene, mat, level), per_mode in table.items():
        for m, pts in per_mode.items():
            ok = [(E, r["solve_s"]) for E, r in pts if r is not None]
            if ok:
                ax.plot(*zip(*ok), "o-", label=f"L{level} {scene} {mat}: {m}")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("Young's modulus E [Pa]")
    ax.set_ylabel(f"cheapest solve time for {COST_TARGET:g} relative error [s]")
    legend(ax, fontsize=6)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "accuracy_cost_vs_E.png"), dpi=110)
    plt.close(fig)


def cost_vs_E(rows, target=COST_TARGET):
    """{(scene, material, level): {mode: [(E, cheapest row or None)]}} over configurations that
    differ only in E (and have more than one E)."""
    groups = {}
    for cfg in configs(rows):
        groups.setdefault((cfg[0], cfg[1], cfg[3]), []).append(cfg)
    out = {}
    for key, cfgs in groups.items():
        if len(cfgs) < 2:
            continue
        modes = list(dict.fromkeys(r["mode"] for c in cfgs for r in sweep_rows(rows, c)))
        out[key] = {m: [(c[2], cheapest(sweep_rows(rows, c), target, (m,))) for c in sorted(cfgs, key=lambda c: c[2])]
                    for m in modes if all(any(r["mode"] == m for r in sweep_rows(rows, c)) for c in cfgs)}
    return out


def headline(rows, cfg):
    """The report's first paragraph: the cheapest setting for the tightest target that some run of
    the main configuration meets, against the alternatives, in numbers."""
    rs = sweep_rows(rows, cfg)
    ref = next((r for r in rows if r["role"] == "reference" and (r["scene"], r["material"], r["E"], r["level"]) == cfg),
               None)
    for target in (1e-3, 1e-2, 1e-1):
        best = cheapest(rs, target)
        if best is not None:
            break
    else:
        return f"No run of {cfg_name(cfg)} reached 10% relative error."
    per_mode = other_modes(rs, target, best)
    others = sorted([o for o in per_mode.values() if o is not None], key=lambda o: o["solve_s"])
    s = (f"**For {target:g} relative error on {cfg_name(cfg)}, the cheapest setting is `{label(best)}`: "
         f"{best['solve_s']:.3g} s of solve time ({best['newton_its']} Newton, {best['ksp_its']} Krylov iterations)")
    if others:
        o = others[0]
        s += f", {o['solve_s'] / best['solve_s']:.1f}× less than the cheapest {o['mode']} setting that meets it (`{label(o)}`)"
        worst = others[-1]
        if worst is not o:
            s += f" and {worst['solve_s'] / best['solve_s']:.1f}× less than the cheapest {worst['mode']} one"
    missing = [m for m, o in per_mode.items() if o is None]
    if missing:
        s += f"; {', '.join(missing)} never meet{'s' if len(missing) == 1 else ''} it"
    if ref is not None and ref.get("solve_s"):
        s += f". The reference settings cost {ref['solve_s'] / best['solve_s']:.0f}× more."
    disc = next((r for r in rows if r["role"] == "disc" and r.get("disc_err") is not None
                 and (r["scene"], r["material"], r["E"], r["level"]) == cfg), None)
    if disc is not None:
        s += (f" The mesh itself is off by {disc['disc_err']:.2g} relative (at the material points, against "
              f"L{disc['disc_level']}), so on this mesh a time-integration/solver error much below that buys nothing.")
    return s + "**"


def findings(rows, cfg):
    """Computed statements for the report: the observed order in h and the step (and cost) a target
    not reached would need, the effect of the Newton tolerance, the failures per mode."""
    out = []
    rs = [r for r in sweep_rows(rows, cfg) if r["outcome"] != "failed" and r["mode"] == "assembled"
          and r["pc"] == "jacobi" and r["ksp_rtol"] == 1e-5]
    tight = min((r["snes_rtol"] for r in rs), default=None)
    rs = sorted([r for r in rs if r["snes_rtol"] == tight], key=lambda r: r["h"])
    if len(rs) >= 3:
        order = slope([r["h"] for r in rs], [r["rel_err"] for r in rs])
        cost = slope([r["h"] for r in rs], [r["solve_s"] for r in rs])
        s = (f"Time step ({cfg_name(cfg)}, assembled, snes_rtol {tight:g}): the error falls as h^{order:.2f} "
             f"(h = {rs[-1]['h']:g} … {rs[0]['h']:g}) and the solve time as h^{cost:.2f}.")
        for t in TARGETS:
            if rs[0]["rel_err"] > t and order > 0:
                h = rs[0]["h"] * (t / rs[0]["rel_err"]) ** (1.0 / order)
                s += (f" {t:g} relative error would need h ≈ {h:.2g}, about {rs[0]['solve_s'] * (h / rs[0]['h']) ** cost:.2g} "
                      "s (extrapolated).")
                break
        out.append(s)
    groups, spread = {}, 0.0
    for r in sweep_rows(rows):
        if r["outcome"] != "failed":
            groups.setdefault((r["scene"], r["material"], r["E"], r["level"], r["mode"], r["pc"], r["h"], r["ksp_rtol"],
                               r.get("ts_rtol")), []).append(r["rel_err"])
    n = 0
    for errs in groups.values():
        if len(errs) > 1 and min(errs) > 1e-8:     # (below: solver noise)
            n += 1
            spread = max(spread, (max(errs) - min(errs)) / max(errs))
    if n:
        out.append(f"Newton tolerance: over the {n} settings swept in snes_rtol (1e-2 … tightest) with errors above 1e-8, "
                   f"the error changes by "
                   f"at most {100 * spread:.2g}%: Newton converges quadratically, so a step that meets 1e-2 is "
                   "usually far past it, and the time step (or the mesh) sets the error.")
    fails = {}
    for r in sweep_rows(rows):
        if r["outcome"] == "failed":
            fails.setdefault(r["mode"], []).append(r)
    for m, fs in fails.items():
        out.append(f"{len(fs)} {m} run{'s' if len(fs) > 1 else ''} failed, e.g. {cfg_name((fs[0]['scene'], fs[0]['material'], fs[0]['E'], fs[0]['level']))}"
                   f", h = {fs[0]['h']:g}: \"{fs[0]['message'].replace('hyperelastic: error: ', '')}\"")
    return out


def _cheapest_table(rows, cfgs):
    """The cheapest setting per configuration and error target."""
    L = []
    L += ["## Cheapest setting per error target", "",
          "| configuration | target | cheapest setting | solve (s) | Newton | Krylov | error | vs cheapest other mode |",
          "|---|---|---|---|---|---|---|---|"]
    for cfg in cfgs:
        rs = sweep_rows(rows, cfg)
        for t in TARGETS:
            b = cheapest(rs, t)
            if b is None:
                L.append(f"| {cfg_name(cfg)} | {t:g} | none of the {len(rs)} runs | - | - | - | - | - |")
                continue
            alt = min((a for a in other_modes(rs, t, b).values() if a is not None), key=lambda a: a["solve_s"],
                      default=None)
            vs = f"{alt['solve_s'] / b['solve_s']:.1f}× ({alt['mode']})" if alt else "-"
            L.append(f"| {cfg_name(cfg)} | {t:g} | `{label(b)}` | {b['solve_s']:.3g} | {b['newton_its']} | "
                     f"{b['ksp_its']} | {b['rel_err']:.2g} | {vs} |")
    return L


def _cost_vs_E_table(rows):
    """The cost of COST_TARGET relative error against E (configurations differing in E only)."""
    L = []
    table = cost_vs_E(rows)
    if table:
        L += ["", f"## Cost of {COST_TARGET:g} relative error versus stiffness", "",
              "| configuration | mode | " + " | ".join("E = " + E_NAMES.get(E, f"{E:g}")
                                                       for E, _ in next(iter(next(iter(table.values())).values()))) + " |",
              "|---|---|" + "---|" * len(next(iter(next(iter(table.values())).values())))]
        for (scene, mat, level), per_mode in table.items():
            for m, pts in per_mode.items():
                cells = [f"{r['solve_s']:.3g} s (h={r['h']:g})" if r else "not met" for _, r in pts]
                L.append(f"| L{level} {scene} {mat} | {m} | " + " | ".join(cells) + " |")
    return L


def _references_table(rows):
    """Each configuration's reference and its own error estimate."""
    L = []
    L += ["", "## References and their own error", "",
          "| configuration | reference h | solve (s) | Newton | own error (|x_h − x_2h| / 3, rel.) |", "|---|---|---|---|---|"]
    for r in rows:
        if r["role"] == "reference":
            cfg = (r["scene"], r["material"], r["E"], r["level"])
            L.append(f"| {cfg_name(cfg)} | {r['h']:g} | {fmt(r.get('solve_s'))} | {fmt(r.get('newton_its'))} | "
                     f"{fmt(r.get('ref_err_est'), '.2g')} |")
    return L


def _disc_table(rows):
    """The mesh error of the discretisation runs."""
    L = []
    disc = [r for r in rows if r["role"] == "disc"]
    if disc:
        L += ["", f"## Discretisation error (mesh) at h = {disc[0]['h']:g}", "",
              "Displacement at the material points " + ", ".join(POINT_NAMES) + ", against the finest level, "
              "relative to the largest displacement there (reference solver settings).", "",
              "| scene, material, E | level | element | tets | mesh error (rel.) | solve (s) |", "|---|---|---|---|---|---|"]
        for r in disc:
            L.append(f"| {r['scene']}, {r['material']}, {r['E']:g} | L{r['level']} | P{r.get('order', 1)} | "
                     f"{fmt(r.get('tets'), ',')} | "
                     f"{fmt(r.get('disc_err'), '.2g') if r['outcome'] != 'failed' else 'failed: ' + r['message']} | "
                     f"{fmt(r.get('solve_s'))} |")
    return L


def _all_runs_tables(rows, cfgs):
    """Every sweep run of each configuration."""
    L = []
    for cfg in cfgs:
        rs = sweep_rows(rows, cfg)
        fails = [r for r in rs if r["outcome"] == "failed"]
        L += ["", f"## {cfg_name(cfg)}: all {len(rs)} runs ({len(fails)} failed)", "",
              "| mode | pc | h | snes_rtol | ksp_rtol | outcome | rel. error | final max err (m) | energy drift "
              "| solve (s) | Newton | Krylov | res. evals | rejected | peak MB |", "|" + "---|" * 15]
        for r in sorted(rs, key=lambda r: (r["mode"], r["pc"], -r["h"], -r["snes_rtol"], -r["ksp_rtol"])):
            out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:90]}"
            L.append(f"| {r['mode']} | {r['pc']} | {r['h']:g} | {r['snes_rtol']:g} | {r['ksp_rtol']:g} | {out} | "
                     f"{fmt(r.get('rel_err'), '.2g')} | {fmt(r.get('err_final_max'), '.2g')} | "
                     f"{fmt(r.get('energy_drift'), '.2g')} | {fmt(r.get('solve_s'))} | {fmt(r.get('newton_its'))} | "
                     f"{fmt(r.get('ksp_its'))} | {fmt(r.get('residual_evals'))} | {fmt(r.get('rejections'))} | "
                     f"{fmt(r.get('peak_rss_mb'), '.0f')} |")
    return L


def report(rows, p, out_dir, command):
    """accuracy.md: headline, findings and the tables."""
    cfgs = configs(rows)
    L = ["# Accuracy versus time", "", headline(rows, p.main if p.main in cfgs else cfgs[0]), "",
         f"Command: `{command}`. Figures: `accuracy_pareto.png` (error vs solve time per Jacobian mode and integrator, Pareto "
         f"front in black), `accuracy_cost_vs_E.png` (cost of {COST_TARGET:g} relative error vs E). All rows: "
         "`accuracy.csv`.", ""]
    nfail = sum(r["outcome"] == "failed" for r in rows if r["role"] == "sweep")
    L += [f"{len(sweep_rows(rows))} sweep runs ({nfail} failed, recorded below), final time {p.final_time:g} s, "
          f"frames every {1 / FPS:g} s. Error = largest vertex distance to the reference over the trajectory, "
          "relative to the reference's largest displacement; cost = solve time (steps' wall time including "
          "rejected attempts, without process start-up). The reference of each configuration: h = smallest "
          f"swept h / {REF_FACTOR}, generalized-alpha (PETSc TSALPHA2, rho_inf 0.5), snes_rtol {REF_SNES_RTOL:g}, "
          "exact tangent assembled, GMRES + ILU(0) to ksp_rtol 1e-12. Jacobi is the PC unless named; -snes_mf has "
          "none. Modes: the Jacobian modes with backward Euler; `alpha2`, `alpha2_r05`: generalized-alpha "
          "(-integrator ts) at fixed steps, rho_inf 1 and 0.5; `alpha2_adapt`: with PETSc's basic adaptor at "
          "-ts_rtol = -ts_atol = the listed tolerance, first step 0.01.", ""]
    L += ["## Findings", ""] + [f"- {f}" for f in findings(rows, p.main if p.main in cfgs else cfgs[0])] + [""]
    L += _cheapest_table(rows, cfgs) + _cost_vs_E_table(rows) + _references_table(rows)
    L += _disc_table(rows) + _all_runs_tables(rows, cfgs)
    with open(os.path.join(out_dir, "accuracy.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")


