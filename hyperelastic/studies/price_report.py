"""The price study's answer: price.csv (every run, failures included, with its estimated errors), price.png
(estimated error against solve time, the Pareto front, the target) and price.md, whose first paragraph is
the answer: the cheapest setting found that meets the target, its error by source, its time, and how much
cheaper it is than the defaults and than the other element order."""
import math
import os

from .experiments.table import write_csv
from ..output.figures import legend, pyplot
from .stability import fmt
from .price import DEFAULTS_CAP, Setting

COLUMNS = ("run", "why", "order", "level", "tets", "integrator", "dt_halvings", "dt", "tolerances", "pc", "outcome",
           "message", "quantity", "est_space", "est_time", "est_solver", "est_total", "meets_target", "solve_s",
           "wall_s", "steps", "newton_its", "ksp_its", "rejections", "peak_rss_mb")


def summarize(search):
    """In place on the rows: the estimated errors (relative, by source) under the final models; returns the
    summary: recommended row, the other order's cheapest (run or predicted), the defaults (run or predicted)."""
    m = search.models()
    scale = search.scale()
    for r in search.rows:
        r["dt"] = search.dt0 / 2 ** r["dt_halvings"]
        if "quantity" in r:
            parts = search.estimate(r["setting"], m)
            for name, v in zip(("est_space", "est_time", "est_solver"), parts):
                r[name] = v / scale if v is not None else None
            r["est_total"] = search.total(r["setting"], m)
            r["meets_target"] = int(search.meets(r["setting"], m))
    best = search.best(m)
    out = {"best": best, "models": m, "scale": scale, "others": {}, "defaults": None}
    for o in search.orders:
        if best is not None and o == best["order"]:
            continue
        ok = [r for r in search.rows if r["order"] == o and r.get("meets_target")]
        if ok:
            out["others"][o] = ("measured", min(ok, key=lambda r: r["solve_s"]))
        else:
            pl = search.plan(o, m)
            out["others"][o] = ("predicted", pl) if pl else ("none", None)
    d = search.defaults(m)
    if d is not None:
        r = search.ok(d)
        cut = [x["stopped_at"] for x in search.by_key.get(d.key(), {}).values() if x.get("stopped_at")]
        out["defaults"] = (("measured", d, r["solve_s"]) if r else ("stopped", d, cut[0]) if cut
                           else ("predicted", d, search.predict_cost(d, m)))
    # what the defaults' order cost without meeting it: a floor under their price
    o = 1 if 1 in search.orders else search.orders[0]
    short = [r for r in search.rows if r["order"] == o and "quantity" in r and not r["meets_target"]]
    out["short"] = max(short, key=lambda r: r["solve_s"]) if short else None
    return out


def _first_paragraph(search, s):
    b, w, tgt = s["best"], search.w.spec, search.target
    if b is None:
        return _no_answer(search, w, tgt)
    st: Setting = b["setting"]
    words = [f"**For {w} within {tgt:.3g} (relative), the cheapest setting found is {st.label()} "
             f"({b['tets']:,} tets): {b['solve_s']:.3g} s of solve time, {w} = {b['quantity']:.6g}, estimated error "
             f"{b['est_total']:.2g} (space {fmt(b['est_space'], '.2g')}, time {fmt(b['est_time'], '.2g')}, solver "
             f"{fmt(b['est_solver'], '.2g')})."]
    words.append(_defaults_sentence(search, s, b))
    for o, (how, x) in s["others"].items():
        if o in search.skipped:
            words.append(f"P{o} was left after its first run: {search.skipped[o]}.")
        elif how == "measured":
            words.append(f"The cheapest P{o} setting that meets it, {x['setting'].label()}, costs "
                         f"{x['solve_s']:.3g} s: "
                         f"{x['solve_s'] / b['solve_s']:.3g}x.")
        elif how == "predicted":
            words.append(f"P{o} would need {x[1].label()}, predicted {x[0]:.3g} s "
                         f"({x[0] / b['solve_s']:.3g}x; not run).")
        else:
            words.append(f"P{o} meets it on no mesh within the limits (--max-level {search.max_level}, "
                         f"{search.max_tets:.3g} tets), as far as its runs show.")
    return " ".join(words) + "**"


def _no_answer(search, w, tgt):
    """The first paragraph where no setting was confirmed to meet the target."""
    why = f" The search stopped early: {search.stopped}." if search.stopped else ""
    why += "".join(f" Order {o} was left: {w}." for o, w in search.skipped.items())
    done = sum(r["outcome"] == "finished" for r in search.rows)
    prov = [r for r in search.rows if "quantity" in r and r.get("est_total") is not None and r["est_total"] <= tgt]
    if prov:         # an answer on the element's expected order, where a third mesh level was out of reach
        p = min(prov, key=lambda r: r["solve_s"])
        return (f"**No setting was confirmed to meet {tgt:.3g} (relative) in {w} within the search's limits "
                f"(--budget {search.budget:g} s, --max-runs {search.max_runs}, --max-level {search.max_level}): "
                "an estimate is confirmed by three mesh levels of its order. On the order the element is expected "
                f"to converge at, the cheapest run whose estimate meets it is {p['setting'].label()} "
                f"({p['tets']:,} tets): {p['solve_s']:.3g} s of solve time, {w} = {p['quantity']:.6g}, "
                f"estimated error {p['est_total']:.2g} (unconfirmed).**" + why)
    return (f"**No setting of the search met {tgt:.3g} (relative) in {w} within its limits (--budget "
            f"{search.budget:g} s, --max-runs {search.max_runs}, --max-level {search.max_level}); the runs "
            f"below ({done} of {len(search.rows)} finished) and their estimated errors show how far each got.**"
            + why)


def _defaults_sentence(search, s, b):
    """What the defaults (the lowest order refined, PETSc's tolerances) cost against the answer b."""
    floor = s["short"]
    if s["defaults"] and s["defaults"][0] == "measured":
        _, d, c = s["defaults"]
        return (f"The defaults refined until they meet it ({d.label()}) cost {c:.3g} s (measured): "
                f"{c / b['solve_s']:.3g}x as much.")
    if s["defaults"] and s["defaults"][0] == "stopped":
        _, d, c = s["defaults"]
        more = f"; more than {c / b['solve_s']:.3g}x as much" if c > b["solve_s"] else ""
        return (f"The defaults refined until they meet it ({d.label()}) cost more than {c:.3g} s: their run, "
                f"predicted under {DEFAULTS_CAP:g} s, was stopped there{more}.")
    if floor is not None and floor["solve_s"] > b["solve_s"]:
        pred = f"; predicted to need {s['defaults'][1].label()}, {s['defaults'][2]:.3g} s" if s["defaults"] else ""
        return (f"The defaults (P{floor['order']} refined) cost more than {floor['solve_s']:.3g} s: the "
                f"search's costliest P{floor['order']} run, {floor['setting'].label()}, still has an estimated "
                f"error of {floor['est_total']:.2g}{pred}; more than {floor['solve_s'] / b['solve_s']:.3g}x as much.")
    if s["defaults"]:
        _, d, c = s["defaults"]
        return (f"The defaults refined until they meet it ({d.label()}) would cost {c:.3g} s (predicted): "
                f"{c / b['solve_s']:.3g}x as much.")
    d = Setting(1 if 1 in search.orders else search.orders[0], 0, 0, search.integrator0, 1)
    parts = search.estimate(d, s["models"])
    tm = f" (time alone {parts[1] / s['scale']:.2g})" if search.dynamic and parts[1] is not None else ""
    return f"The defaults ({d.label()} refined) meet it on no mesh within the limits{tm}."


def _models_lines(search, s):
    L = ["## Error models (from the runs)", ""]
    for key, mod in s["models"].items():
        if mod is None:
            continue
        if key == "tol":
            L.append(f"- solver tolerances: change against the tightest run at each; tightest's own error taken as "
                     f"{fmt(mod.err_max, '.2g')} (absolute)")
            continue
        name = f"space, P{key[1]}" if key[0] == "level" else f"time, P{key[1]} {key[2]}"
        L.append(f"- {name}: points at notches {sorted(mod.q)}; order used {fmt(mod.p, '.2f')} (expected "
                 f"{mod.expected}); limit {fmt(mod.limit, '.6g')}; finest point's error {fmt(mod.err_max, '.2g')}"
                 + (f" ({mod.note})" if mod.note else ""))
    return L + [""]


def price_report(search, out_dir, command):
    s = summarize(search)
    write_csv(os.path.join(out_dir, "price.csv"), search.rows, COLUMNS)
    _figure(search, s, out_dir)
    wall = sum(r["wall_s"] for r in search.rows)
    L = [f"# The price of {search.w.spec} within {search.target:.3g} on {os.path.basename(search.part)}", "",
         _first_paragraph(search, s), "",
         f"The search made {len(search.rows)} runs ({wall:.3g} s of wall time, {search.elapsed():.3g} s in all); "
         f"errors are relative to |{search.w.spec}| = {s['scale']:.6g}. Every run is in `price.csv` (failures "
         "with their message); `price.png` plots each run's estimated error against its solve time.", "",
         f"Command: `{command}`. Scene: `{search.scene}`" + (" (dynamic)" if search.dynamic else " (quasi-static)")
         + f"; the scene's step {search.dt0:g} s; meshes: the part at --size {search.size:g}"
         + (" (its own sizes kept: --graded)" if search.graded else "") + ", refined uniformly.", ""]
    L += _models_lines(search, s)
    L += ["## Runs", "", "| # | why | setting | tets | quantity | est. error (space / time / solver) | meets | "
          "solve s | outcome |", "|" + "---|" * 9]
    for r in search.rows:
        est = (f"{fmt(r.get('est_total'), '.2g')} ({fmt(r.get('est_space'), '.2g')} / {fmt(r.get('est_time'), '.2g')}"
               f" / {fmt(r.get('est_solver'), '.2g')})") if "quantity" in r else "-"
        out = r["outcome"] if r["outcome"] != "failed" else f"failed: {r['message'][:80]}"
        L.append(f"| {r['run']} | {r['why']} | {r['setting'].label()} | {fmt(r['tets'])} | "
                 f"{fmt(r.get('quantity'), '.6g')} "
                 f"| {est} | {'yes' if r.get('meets_target') else ''} | {fmt(r.get('solve_s'))} | {out} |")
    with open(os.path.join(out_dir, "price.md"), "w") as fh:
        fh.write("\n".join(L) + "\n")
    return s


def _figure(search, s, out_dir):
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.6))
    pts = [r for r in search.rows if r.get("est_total") is not None and math.isfinite(r["est_total"]) and r.get("solve_s")]
    for o, mk in ((1, "o"), (2, "s")):
        sel = [r for r in pts if r["order"] == o]
        if sel:
            ax.loglog([r["solve_s"] for r in sel], [max(r["est_total"], 1e-16) for r in sel], mk, label=f"P{o} runs")
    front, low = [], float("inf")
    for r in sorted(pts, key=lambda r: r["solve_s"]):
        if r["est_total"] < low:
            low = r["est_total"]
            front.append(r)
    if front:
        ax.step([r["solve_s"] for r in front], [max(r["est_total"], 1e-16) for r in front], where="post", color="gray",
                lw=1, label="Pareto front")
    ax.axhline(search.target, ls="--", color="red", lw=1, label=f"target {search.target:g}")
    if s["best"] is not None:
        ax.plot([s["best"]["solve_s"]], [max(s["best"]["est_total"], 1e-16)], "*", ms=16, color="gold", mec="k",
                label="cheapest meeting the target")
    ax.set_xlabel("solve time (s)")
    ax.set_ylabel(f"estimated relative error in {search.w.spec}")
    legend(ax, fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out_dir, "price.png"), dpi=110)
    plt.close(fig)
