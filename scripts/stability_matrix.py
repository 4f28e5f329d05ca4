#!/usr/bin/env python
"""The hard-case matrix (issue 5): run every cell as `python -m hyperelastic run`, then write
OUT/stability.csv, OUT/stability.md (table, properties, locking) and OUT/stability.png (outcome heatmap).

    scripts/stability_matrix.py OUT            # the quick subset (the one `make test` checks), ~2 min
    scripts/stability_matrix.py OUT --full     # the whole matrix (see hyperelastic/stability.py)
"""
import argparse
import csv
import os
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic import stability as S  # noqa: E402

COLUMNS = ("id", "scene", "material", "E", "nu", "h", "mode", "outcome", "rc", "steps", "rejections",
           "newton_its", "ksp_its", "inversion_cuts", "dt_min_used", "t_end", "J_min", "J_min_final", "J_max_final",
           "energy_growth", "elastic_max_rel", "strain_final", "volume_ratio", "max_displacement", "wall_s",
           "nonfinite", "message", "energy")


def write_csv(rows, path):
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow(r)


def heatmap(rows, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    from matplotlib.colors import ListedColormap

    def label(r):   # a heatmap row: scene and mode, with the axis values when off the base point
        if r["E"] == "1e6" and r["nu"] == 0.3 and r["h"] == 1e-2:
            return f"{r['scene']} {r['mode']}"
        return f"{r['scene']} E={r['E']} nu={r['nu']:g} h={r['h']:g} {r['mode']}"
    ylab = sorted({label(r) for r in rows})
    mats = list(S.MATERIALS)
    code = {"finished": 0, "recovered": 1, "failed": 2}
    A = np.full((len(ylab), len(mats)), np.nan)
    for r in rows:
        A[ylab.index(label(r)), mats.index(r["material"])] = code[r["outcome"]]
    fig, ax = plt.subplots(figsize=(7.5, 0.18 * len(ylab) + 1.5))
    ax.imshow(A, cmap=ListedColormap(["#3a9d3a", "#e0b020", "#c83232"]), vmin=0, vmax=2, aspect="auto",
              interpolation="nearest")
    ax.set_xticks(range(len(mats)), mats)
    ax.set_yticks(range(len(ylab)), ylab, fontsize=6)
    ax.xaxis.tick_top()
    ax.set_title("outcome per cell: green finished, yellow recovered by step control, red failed, white not run",
                 fontsize=7, pad=18)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(rows, out, command):
    bad = S.violations(rows)
    counts = {k: sum(r["outcome"] == k for r in rows) for k in ("finished", "recovered", "failed")}
    lines = [f"# Hard-case matrix ({len(rows)} cells)", "", f"Made by `{command}` on {time.strftime('%Y-%m-%d')}.",
             "", f"Outcomes: {counts['finished']} finished, {counts['recovered']} recovered by step control, "
             f"{counts['failed']} failed.", "", "## Properties that must hold", ""]
    if bad:
        lines += [f"- **violated** {cid}: {what}" for cid, what in bad]
    else:
        lines += ["All hold: no NaN/Inf in any output; total energy of the scenes without external work never "
                  f"grows by more than {S.ENERGY_TOL:g} (relative) in a step; rigid motions carry no elastic "
                  f"energy and no strain (< {S.RIGID_TOL:g}) for stvk, neohookean, snh, corotational; snh unfolds "
                  "the inverted start; at steel and 1e15 (h = 1e-2) stretch does not fail for any material, nor "
                  "twist3 and squeeze for neohookean; nu = 0.499 finishes for neohookean and snh."]
    lin = [r for r in rows if r["material"] == "linear" and r["scene"] in ("rotated", "spin", "drop")
           and r["outcome"] != "failed"]
    if lin:
        lines += ["", "Linear elasticity under rigid motions (its rotation artifacts are reported, not hidden; "
                  "a translation is exact):", ""]
        lines += [f"- {r['id']}: elastic energy / (E V) up to {r['elastic_max_rel']:.3g}, final |F^T F - I| "
                  f"{r['strain_final']:.3g}, final max J {r['J_max_final']:.4g}, volume ratio "
                  f"{r['volume_ratio']:.4g}" for r in lin]
    lock = S.locking(rows)
    if lock:
        lines += ["", "## Locking (nu axis): volume ratio and displacement relative to nu = 0.3", "",
                  "| scene | material | nu | outcome | volume ratio | max displacement / (nu = 0.3) |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['scene']} | {r['material']} | {r['nu']:g} | {r['outcome']} | {S.fmt(r.get('volume_ratio'), '.4f')} "
                  f"| {S.fmt(q, '.3f')} |" for r, q in lock]
    lines += ["", "## Every cell", "",
              "| scene | material | E | nu | h | mode | outcome | steps | rejected | Newton | Krylov | min J | "
              "final min J | energy growth | wall s | message |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['material']} | {r['E']} | {r['nu']:g} | {r['h']:g} | {r['mode']} | "
                     f"{r['outcome']} | {r.get('steps', 0)} | {r.get('rejections', 0)} | {r.get('newton_its', 0)} | "
                     f"{r.get('ksp_its', 0)} | {S.fmt(r.get('J_min'))} | {S.fmt(r.get('J_min_final'))} | "
                     f"{S.fmt(r.get('energy_growth'), '.2g')} | {r['wall_s']} | {r['message'][:160]} |")
    with open(os.path.join(out, "stability.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return bad


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--full", action="store_true", help="the whole matrix instead of the quick subset")
    ap.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2)")
    ap.add_argument("--from-csv", action="store_true", help="redo stability.md and .png from OUT/stability.csv")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    command = "scripts/stability_matrix.py " + " ".join(argv if argv is not None else sys.argv[1:])
    if a.from_csv:
        rows = S.read_rows(os.path.join(a.out, "stability.csv"))
        made = "--full" if len(rows) == len(S.full_matrix()) else ""
        command = f"scripts/stability_matrix.py OUT {made}".rstrip() + " (report redone with --from-csv)"
        heatmap(rows, os.path.join(a.out, "stability.png"))
        bad = report(rows, a.out, command)
        print(f"rewrote {a.out}/stability.md, stability.png; {len(bad)} property violations")
        return 1 if bad else 0
    cells = S.full_matrix() if a.full else S.quick_matrix()
    print(f"{len(cells)} cells, {a.jobs} at a time", flush=True)

    def log(r):
        print(f"{r['id']:58s} {r['outcome']:9s} steps {r.get('steps', 0):4d} rejected {r.get('rejections', 0):3d} "
              f"min J {S.fmt(r.get('J_min')):>8s} {r['wall_s']:6.1f} s {r['message'][:90]}", flush=True)
    rows = S.run_matrix(cells, a.out, a.jobs, log)
    write_csv(rows, os.path.join(a.out, "stability.csv"))
    heatmap(rows, os.path.join(a.out, "stability.png"))
    bad = report(rows, a.out, command)
    print(f"wrote {a.out}/stability.csv, stability.md, stability.png; {len(bad)} property violations")
    for cid, what in bad:
        print(f"  VIOLATED {cid}: {what}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
