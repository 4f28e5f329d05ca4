"""The hard-case matrix: scenes x materials x stiffness x Poisson ratio x time step x Jacobian mode,
each cell a real `python -m hyperelastic run` whose exit status, stderr and HDF5 output are read back
and checked. Used by scripts/stability_matrix.py (the whole matrix) and tests/test_stability.py (a
subset).

A cell's outcome is `finished` (no step rejected), `recovered` (finished after step control rejected
and retried steps) or `failed` (non-zero exit; its one-line message is kept).
"""
import argparse
import json
import math
import os
import sys
import time
from dataclasses import asdict, dataclass

import h5py
import numpy as np

from ..solving import stats
from .experiments import table
from .experiments.recipes import MODES as JACOBIAN_MODES
from .experiments.runner import last_line, parallel_map, run_hyperelastic
from ..output.figures import pyplot
from ..physics.materials import MATERIALS as MATERIAL_CLASSES, REGISTRY
from ..mesh.generate import generate
from ..mesh.sets import signed_volumes
from ..discretization.space import reference_geometry

USAGE = """The hard-case matrix (issue 5): run every cell as `python -m hyperelastic run`, then write
OUT/stability.csv, OUT/stability.md (table, properties, locking) and OUT/stability.png (outcome heatmap).

    scripts/stability_matrix.py OUT            # the quick subset (the one `make test` checks), ~2 min
    scripts/stability_matrix.py OUT --full     # the whole matrix (see hyperelastic/studies/stability.py)
    scripts/stability_matrix.py OUT --integrators   # the quick subset, backward Euler beside generalized-alpha
    scripts/stability_matrix.py OUT --from-csv --compare OLD/stability.csv   # report again, beside an older run
    scripts/stability_matrix.py OUT --full --materials ogden   # one material's row of the whole matrix (a new one's)
"""
MATERIALS = REGISTRY        # every registered material, in the registry's order
# E axis [Pa]: named values of the thesis framework's presets (materials.PRESETS), nu and rho kept at
# the defaults so that only the stiffness changes along the axis
E_AXIS = {"1e2": 1e2, "1e6": 1e6, "rubber": 1e7, "cancellous_bone": 4.5e8, "bone": 1.6e10, "steel": 2.1e11,
          "1e15": 1e15}
NU_AXIS = (0.0, 0.3, 0.45, 0.49, 0.499, 0.4999)
SPLIT_MATERIALS = tuple(m for m in MATERIALS if MATERIAL_CLASSES[m].volumetric)   # (the mixed formulation's)
H_AXIS = (1e-1, 1e-2, 1e-3)
# the matrix's modes: the exact tangent assembled, and PETSc's MFFD operator with it as preconditioner
MODES = {"assembled": JACOBIAN_MODES["assembled"], "mf_operator": JACOBIAN_MODES["snes_mf_operator"],
         # generalized-alpha through PETSc TS (issue 18), exact assembled tangent, rho_inf = 1
         "alpha2": JACOBIAN_MODES["assembled"] + ["-integrator", "ts"],
         # the mixed displacement-pressure formulation (issue 33): quadratic tets, a pressure field, its field split
         "mixed": JACOBIAN_MODES["assembled"] + ["-order", "2", "-formulation", "mixed"]}
# cell scene -> (built-in scene, extra options); 'sliver' is squeeze-free: stretch on a sliver mesh
SCENES = {
    "twist3": ("twist3", []), "bend3": ("bend3", []), "squeeze": ("squeeze", []), "stretch": ("stretch", []),
    "spin": ("spin", []), "drop": ("drop", []), "rotated": ("rotated", []), "invert": ("invert", []),
    "unfold": ("unfold", []), "sliver": ("stretch", ["-mesh", "{sliver}"]), "bend2": ("bend2", []),
}
NO_EXTERNAL_WORK = {"spin", "drop", "rotated", "unfold"}   # total energy must not grow
RIGID = {"drop", "rotated"}                                 # exact solution: a rigid motion


@dataclass(frozen=True)
class Cell:
    scene: str
    material: str
    E: str = "1e6"
    nu: float = 0.3
    h: float = 1e-2
    mode: str = "assembled"

    @property
    def id(self):
        return f"{self.scene}-{self.material}-E{self.E}-nu{self.nu:g}-h{self.h:g}-{self.mode}"

    def args(self, out, sliver):
        base, extra = SCENES[self.scene]
        level = [] if "-mesh" in extra else ["-level", "1"]     # (a scene with its own mesh: -level would refuse it)
        return (["run", base, *level, "-material", self.material, "-E", repr(E_AXIS[self.E]),
                 "-nu", repr(self.nu), "-dt", repr(self.h), "-output", out, "-quiet"]
                + [a.format(sliver=sliver) for a in extra] + MODES[self.mode])


def full_matrix():
    """Every scene x material x mode at the base point (E = 1e6, nu = 0.3, h = 1e-2); the E axis on
    twist3, squeeze and stretch; the nu axis on squeeze and bend2; the h axis on twist3 and spin
    (assembled tangent for the axes, both modes at the extremes of E)."""
    cells = [Cell(s, m, mode=md) for s in SCENES if s != "bend2" for m in MATERIALS for md in MODES
             if md not in ("alpha2", "mixed")]
    cells += [Cell(s, m, E=e) for s in ("twist3", "squeeze", "stretch") for m in MATERIALS for e in E_AXIS]
    cells += [Cell(s, m, E=e, mode="mf_operator") for s in ("twist3", "stretch") for m in MATERIALS
              for e in ("steel", "1e15")]
    cells += [Cell(s, m, nu=nu) for s in ("squeeze", "bend2") for m in MATERIALS for nu in NU_AXIS]
    cells += [Cell(s, m, nu=nu, mode="mixed") for s in ("squeeze", "bend2") for m in SPLIT_MATERIALS
              for nu in (0.3, 0.499, 0.4999)]
    cells += [Cell(s, m, h=h) for s in ("twist3", "spin") for m in MATERIALS for h in H_AXIS]
    return list(dict.fromkeys(cells))


def quick_matrix():
    """The subset `make test` runs (a few minutes on 2 cores): one cell per property to assert."""
    cells = [Cell(s, m) for s in ("drop", "rotated") for m in MATERIALS]
    cells += [Cell("spin", m) for m in ("stvk", "snh", "corotational")]
    cells += [Cell("unfold", m) for m in ("snh", "stvk")]
    cells += [Cell("invert", m) for m in ("neohookean", "snh")]
    cells += [Cell("stretch", m, E=e) for m in ("stvk", "neohookean", "snh") for e in ("steel", "1e15")]
    cells += [Cell("twist3", "neohookean", E="1e15", mode="mf_operator"), Cell("squeeze", "neohookean", E="steel")]
    cells += [Cell("squeeze", "neohookean", nu=nu) for nu in (0.3, 0.499)]
    cells += [Cell("squeeze", "stvk")]
    return cells


def integrator_matrix():
    """The quick subset's backward Euler cells (assembled tangent) and the same cells with generalized-alpha
    (scripts/stability_matrix.py OUT --integrators): where each integrator survives."""
    be = [c for c in quick_matrix() if c.mode == "assembled"]
    return be + [Cell(c.scene, c.material, c.E, c.nu, c.h, "alpha2") for c in be]


def sliver_mesh(out_dir):
    """The sliver-tetrahedra mesh (meshes/sliver_bar.geo), generated once into out_dir."""
    path = os.path.join(out_dir, "sliver_bar.msh")
    if not os.path.exists(path):
        generate("sliver_bar", 1, path)
    return path


def _strain(X, x, tets):
    """max over cells of |F^T F - I| (entrywise), F = Ds Dm^-1 from reference X to current x."""
    Dminv, _ = reference_geometry(X, tets)
    d = np.stack([x[tets[:, a]] - x[tets[:, 0]] for a in (1, 2, 3)], axis=-1)
    F = d @ Dminv
    return float(np.abs(np.swapaxes(F, 1, 2) @ F - np.eye(3)).max())


def analyse(cell, path, rc, stderr, wall):
    """One row of the matrix from a finished (or failed) run."""
    row = asdict(cell) | {"id": cell.id, "rc": rc, "wall_s": round(wall, 2), "message": ""}
    if rc != 0:
        row["message"] = last_line(stderr, rc)
    if not os.path.exists(path):
        row.update(outcome="failed", nonfinite=False)
        return row
    with h5py.File(path, "r") as f:
        st = stats.read(f)
        X, tets = f["mesh/points"][:], f["mesh/tetra"][:]
        xs = f["x"][:]
        times = f["time"][:]
        Eyoung = float(f.attrs["E"])
    n = len(st.get("step", []))
    acc = stats.accepted(st)
    rej = ~acc
    row["steps"] = int(acc.sum())
    row["rejections"] = int(rej.sum())
    row["newton_its"] = int(st["newton_its"].sum()) if n else 0
    row["ksp_its"] = int(st["ksp_its"].sum()) if n else 0
    row["inversion_cuts"] = int(st.get("inversion_cuts", np.zeros(1)).sum())
    row["dt_min_used"] = float(st["dt"].min()) if n else float("nan")
    row["outcome"] = "failed" if rc != 0 else ("recovered" if row["rejections"] else "finished")
    row["t_end"] = float(times[-1]) if len(times) else 0.0
    # no NaN or Inf anywhere in what was written: frames, and the statistics of accepted steps
    numeric = [v[acc] for k, v in st.items() if v.dtype.kind == "f" and len(v) == n]
    row["nonfinite"] = bool(not np.isfinite(xs).all() or any(not np.isfinite(v).all() for v in numeric))
    if acc.any():
        row["J_min"] = float(st["J_min"][acc].min())
        row["J_min_final"] = float(st["J_min"][acc][-1])
        row["J_max_final"] = float(st["J_max"][acc][-1])
        tot = stats.total_energy(st, with_work=False)
        V0 = float(signed_volumes(X, tets).sum())
        parts = np.abs(st["kinetic"][acc]) + np.abs(st["elastic"][acc]) + np.abs(st.get("gravity_potential",
                                                                                        np.zeros(n))[acc])
        # relative to the energies summed (their rounding error; a falling body's total is ~0 while its
        # kinetic and potential energies are large) + a roundoff floor of O(E) energies
        scale = float(max(np.abs(tot).max(), parts.max())) + 1e-10 * Eyoung * V0
        row["energy_growth"] = float(max(np.diff(tot).max(initial=0.0), 0.0) / scale)
        row["elastic_max_rel"] = float(np.abs(st["elastic"][acc]).max() / (Eyoung * V0))
        row["volume_ratio"] = float(signed_volumes(xs[-1], tets).sum() / V0)
        row["strain_final"] = _strain(X, xs[-1], tets)
        row["max_displacement"] = float(np.linalg.norm(xs[-1] - X, axis=1).max())
        row["energy"] = json.dumps([float(v) for v in tot[:: max(1, len(tot) // 20)]])
    return row


def run_cell(cell, out_dir, timeout=900):
    runs = os.path.join(out_dir, "runs")
    os.makedirs(runs, exist_ok=True)
    path = os.path.join(runs, cell.id + ".h5")
    sliver = sliver_mesh(out_dir) if cell.scene == "sliver" else ""
    rc, err, wall = run_hyperelastic(cell.args(path, sliver), path, timeout=timeout)
    return analyse(cell, path, rc, err, wall)


def run_matrix(cells, out_dir, jobs=2, log=None):
    if any(c.scene == "sliver" for c in cells):
        sliver_mesh(out_dir)           # once, before the workers start
    return parallel_map(lambda c: run_cell(c, out_dir), cells, jobs, log)


# ---- the properties that must hold ---------------------------------------------------------------
ENERGY_TOL = 1e-6        # relative step-to-step growth of kinetic + elastic (+ gravity) energy
RIGID_TOL = 1e-8         # elastic energy / (E V) and |F^T F - I| for a rigid motion


def explained_by_physics(r):
    """Why a failed cell could not have finished with any solver ('' when nothing explains it): the
    motion it is asked to follow leaves the material's domain, or starts where its energy has no
    derivative. Every other failure is the solver's, and a violation."""
    m = MATERIAL_CLASSES.get(r["material"])
    nh = m is not None and not m.defined_when_inverted       # (Neo-Hookean and every material undefined at J <= 0)
    what = "Neo-Hookean" if r["material"] == "neohookean" else r["material"]
    if nh and r["scene"] == "invert":
        return f"{what} is undefined at J <= 0, and the prescribed ends reach each other at t = 0.5"
    if nh and r["scene"] == "unfold":
        return f"{what} is undefined at J <= 0, and the start is mirrored (J = -1)"
    if nh and r["E"] == "1e2" and r["scene"] in ("twist3", "squeeze"):
        return ("the prescribed ends move faster than the wave speed sqrt(E/rho) = 0.3 m/s: the cells next "
                f"to them must collapse, which {what} cannot")
    if r["material"] == "corotational" and r["scene"] == "unfold":
        return ("the start is an exact reflection, where corotational's rotation R(F) jumps: its energy has "
                "no derivative there")
    return ""


def violations(rows):
    """[(cell id, what is wrong)] for the properties of the issue, over the cells given."""
    bad = []
    for r in rows:
        if r.get("nonfinite"):
            bad.append((r["id"], "NaN or Inf in the output"))
        if r["outcome"] == "failed" and (not r["message"] or "Traceback" in r["message"]):
            bad.append((r["id"], "failed without a one-line message"))
        ok = r["outcome"] != "failed"
        if ok and r["scene"] in NO_EXTERNAL_WORK and r["energy_growth"] > ENERGY_TOL:
            bad.append((r["id"], f"energy grew by {r['energy_growth']:.3g} (relative) in one step"))
        if ok and r["scene"] in RIGID and r["material"] != "linear":
            if r["elastic_max_rel"] > RIGID_TOL or r["strain_final"] > RIGID_TOL:
                bad.append((r["id"], f"rigid motion deformed: elastic/(E V) {r['elastic_max_rel']:.3g}, "
                                     f"|F^T F - I| {r['strain_final']:.3g}"))
        if r["scene"] == "unfold" and r["material"] == "snh" and not (ok and r["J_min_final"] > 0):
            bad.append((r["id"], "snh did not recover a positive-volume shape from the inverted start"))
        if not ok and not explained_by_physics(r):
            bad.append((r["id"], f"failed, and no physics explains it: {r['message']}"))
    return bad


def locking(rows):
    """Rows of the nu axis (scenes run at more than one nu) with their volume ratio and max
    displacement relative to nu = 0.3 (same scene, material, E, h, mode)."""
    key = lambda r: (r["scene"], r["material"], r["E"], r["h"], r["mode"])  # noqa: E731
    nus = {}
    for r in rows:
        nus.setdefault(key(r), set()).add(r["nu"])
    ref = {key(r): r for r in rows if r["nu"] == 0.3}
    out = []
    for r in sorted(rows, key=lambda r: (key(r), r["nu"])):
        k = key(r)
        if len(nus[k]) > 1 and k in ref and r.get("max_displacement") is not None \
                and ref[k].get("max_displacement") is not None:
            out.append((r, r["max_displacement"] / ref[k]["max_displacement"]))
    return out


NUMERIC = {"nu": float, "h": float, "rc": int, "steps": int, "rejections": int, "newton_its": int, "ksp_its": int,
           "inversion_cuts": int, "dt_min_used": float, "J_min": float, "J_min_final": float, "J_max_final": float,
           "energy_growth": float, "elastic_max_rel": float, "strain_final": float, "volume_ratio": float,
           "max_displacement": float, "wall_s": float, "t_end": float}


def read_rows(path):
    """Rows of a stability.csv back with their types (empty fields: None), to redo the report."""
    rows = table.read_csv(path, {k: (lambda v, typ=typ: typ(float(v))) for k, typ in NUMERIC.items()})
    for r in rows:
        r["nonfinite"] = r.get("nonfinite") == "True"
        r["steps"] = r.get("steps") or 0
    return rows


def fmt(v, spec=".3g"):
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    return format(v, spec) if isinstance(v, float) else str(v)


# ---- the matrix script's CSV, heatmap and report ------------------------------------------------------
COLUMNS = ("id", "scene", "material", "E", "nu", "h", "mode", "outcome", "rc", "steps", "rejections",
           "newton_its", "ksp_its", "inversion_cuts", "dt_min_used", "t_end", "J_min", "J_min_final", "J_max_final",
           "energy_growth", "elastic_max_rel", "strain_final", "volume_ratio", "max_displacement", "wall_s",
           "nonfinite", "message", "energy")


def write_csv(rows, path):
    table.write_csv(path, rows, COLUMNS, float_format=None)


def heatmap(rows, path):
    plt = pyplot()
    from matplotlib.colors import ListedColormap    # (matplotlib: deferred, see figures.py)

    def label(r):   # a heatmap row: scene and mode, with the axis values when off the base point
        if r["E"] == "1e6" and r["nu"] == 0.3 and r["h"] == 1e-2:
            return f"{r['scene']} {r['mode']}"
        return f"{r['scene']} E={r['E']} nu={r['nu']:g} h={r['h']:g} {r['mode']}"
    ylab = sorted({label(r) for r in rows})
    mats = list(MATERIALS)
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
    bad = violations(rows)
    counts = {k: sum(r["outcome"] == k for r in rows) for k in ("finished", "recovered", "failed")}
    lines = [f"# Hard-case matrix ({len(rows)} cells)", "", f"Made by `{command}` on {time.strftime('%Y-%m-%d')}.",
             "", f"Outcomes: {counts['finished']} finished, {counts['recovered']} recovered by step control, "
             f"{counts['failed']} failed.", "", "## Properties that must hold", ""]
    if bad:
        lines += [f"- **violated** {cid}: {what}" for cid, what in bad]
    else:
        lines += ["All hold: no NaN/Inf in any output; total energy of the scenes without external work never "
                  f"grows by more than {ENERGY_TOL:g} (relative) in a step; rigid motions carry no elastic "
                  f"energy and no strain (< {RIGID_TOL:g}) for stvk, neohookean, snh, corotational; snh unfolds "
                  "the inverted start; no cell fails except where physics explains it (listed below)."]
    failed = [r for r in rows if r["outcome"] == "failed" and explained_by_physics(r)]
    if failed:
        lines += ["", "Failed cells, each explained by physics:", ""]
        lines += [f"- {r['id']}: {explained_by_physics(r)}" for r in failed]
    lin = [r for r in rows if r["material"] == "linear" and r["scene"] in ("rotated", "spin", "drop")
           and r["outcome"] != "failed"]
    if lin:
        lines += ["", "Linear elasticity under rigid motions (its rotation artifacts are reported, not hidden; "
                  "a translation is exact):", ""]
        lines += [f"- {r['id']}: elastic energy / (E V) up to {r['elastic_max_rel']:.3g}, final |F^T F - I| "
                  f"{r['strain_final']:.3g}, final max J {r['J_max_final']:.4g}, volume ratio "
                  f"{r['volume_ratio']:.4g}" for r in lin]
    lock = locking(rows)
    if lock:
        lines += ["", "## Locking (nu axis): volume ratio and displacement relative to nu = 0.3", "",
                  "| scene | material | nu | outcome | volume ratio | max displacement / (nu = 0.3) |",
                  "|---|---|---|---|---|---|"]
        lines += [f"| {r['scene']} | {r['material']} | {r['nu']:g} | {r['outcome']} | {fmt(r.get('volume_ratio'), '.4f')} "
                  f"| {fmt(q, '.3f')} |" for r, q in lock]
    lines += ["", "## Every cell", "",
              "| scene | material | E | nu | h | mode | outcome | steps | rejected | Newton | Krylov | min J | "
              "final min J | energy growth | wall s | message |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['scene']} | {r['material']} | {r['E']} | {r['nu']:g} | {r['h']:g} | {r['mode']} | "
                     f"{r['outcome']} | {r.get('steps', 0)} | {r.get('rejections', 0)} | {r.get('newton_its', 0)} | "
                     f"{r.get('ksp_its', 0)} | {fmt(r.get('J_min'))} | {fmt(r.get('J_min_final'))} | "
                     f"{fmt(r.get('energy_growth'), '.2g')} | {r['wall_s']} | {r['message'][:160]} |")
    with open(os.path.join(out, "stability.md"), "w") as fh:
        fh.write("\n".join(lines) + "\n")
    return bad


def totals(rows):
    """Outcome counts and summed cost of a matrix."""
    t = {k: sum(r["outcome"] == k for r in rows) for k in ("finished", "recovered", "failed")}
    for k in ("rejections", "newton_its", "ksp_its", "wall_s"):
        t[k] = sum(r.get(k) or 0 for r in rows)
    return t


def compare(old, new):
    """Markdown lines: two matrices side by side (totals, then every cell whose outcome, rejections
    or failure differ), cells matched by id."""
    old_by = {r["id"]: r for r in old}
    both = [r for r in new if r["id"] in old_by]
    a, b = totals([old_by[r["id"]] for r in both]), totals(both)
    lines = [f"| over the {len(both)} cells in both | before | now |", "|---|---|---|"]
    lines += [f"| {k.replace('_', ' ')} | {fmt(a[k], '.0f')} | {fmt(b[k], '.0f')} |" for k in a]
    clean = [r for r in both if r["outcome"] == "finished" and old_by[r["id"]]["outcome"] == "finished"]
    diff = [abs(r["max_displacement"] - old_by[r["id"]]["max_displacement"]) / max(r["max_displacement"], 1e-300)
            for r in clean if r.get("max_displacement") and old_by[r["id"]].get("max_displacement")]
    if diff:
        lines += ["", f"Cells finished without a rejected attempt both times ({len(clean)}): the final max "
                  f"displacement differs by at most {max(diff):.2g} (relative; median {sorted(diff)[len(diff) // 2]:.2g})."]
    lines += ["", "Cells whose outcome or number of rejected attempts changed:", "",
              "| cell | before: outcome, rejected, Newton | now: outcome, rejected, Newton | now: message |",
              "|---|---|---|---|"]
    for r in both:
        o = old_by[r["id"]]
        if (o["outcome"], o.get("rejections")) != (r["outcome"], r.get("rejections")):
            lines.append(f"| {r['id']} | {o['outcome']}, {o.get('rejections', 0)}, {o.get('newton_its', 0)} | "
                         f"{r['outcome']}, {r.get('rejections', 0)}, {r.get('newton_its', 0)} | "
                         f"{r['message'][:120]} |")
    return lines


def main(argv=None):
    """scripts/stability_matrix.py OUT [--full] [--jobs N] [--from-csv]"""
    ap = argparse.ArgumentParser(prog="scripts/stability_matrix.py", description=USAGE,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--full", action="store_true", help="the whole matrix instead of the quick subset")
    ap.add_argument("--integrators", action="store_true", help="the quick subset with backward Euler and with "
                    "generalized-alpha (-integrator ts) side by side")
    ap.add_argument("--materials", default=None, help="only the cells of these materials (a comma list: a new "
                    "material's row of the matrix)")
    ap.add_argument("--jobs", type=int, default=2, help="runs in parallel (default 2)")
    ap.add_argument("--from-csv", action="store_true", help="redo stability.md and .png from OUT/stability.csv")
    ap.add_argument("--compare", metavar="OLD_CSV", help="append a side-by-side comparison with an earlier "
                    "stability.csv to OUT/stability.md")
    a = ap.parse_args(argv)
    os.makedirs(a.out, exist_ok=True)
    command = "scripts/stability_matrix.py " + " ".join(argv if argv is not None else sys.argv[1:])
    if a.from_csv:
        rows = read_rows(os.path.join(a.out, "stability.csv"))
        made = "--full" if len(rows) == len(full_matrix()) else ""
        command = f"scripts/stability_matrix.py OUT {made}".rstrip() + " (report redone with --from-csv)"
        heatmap(rows, os.path.join(a.out, "stability.png"))
        bad = report(rows, a.out, command)
        _append_comparison(a.compare, rows, a.out)
        print(f"rewrote {a.out}/stability.md, stability.png; {len(bad)} property violations")
        return 1 if bad else 0
    cells = full_matrix() if a.full else integrator_matrix() if a.integrators else quick_matrix()
    if a.materials:
        keep = a.materials.split(",")
        unknown = [m for m in keep if m not in MATERIALS]
        if unknown:
            ap.error(f"--materials: unknown {', '.join(unknown)} (choose from {', '.join(MATERIALS)})")
        cells = [c for c in cells if c.material in keep]
    print(f"{len(cells)} cells, {a.jobs} at a time", flush=True)

    def log(r):
        print(f"{r['id']:58s} {r['outcome']:9s} steps {r.get('steps', 0):4d} rejected {r.get('rejections', 0):3d} "
              f"min J {fmt(r.get('J_min')):>8s} {r['wall_s']:6.1f} s {r['message'][:90]}", flush=True)
    rows = run_matrix(cells, a.out, a.jobs, log)
    write_csv(rows, os.path.join(a.out, "stability.csv"))
    heatmap(rows, os.path.join(a.out, "stability.png"))
    bad = report(rows, a.out, command)
    _append_comparison(a.compare, rows, a.out)
    print(f"wrote {a.out}/stability.csv, stability.md, stability.png; {len(bad)} property violations")
    for cid, what in bad:
        print(f"  VIOLATED {cid}: {what}")
    return 1 if bad else 0


def _append_comparison(old_csv, rows, out):
    if old_csv:
        lines = ["", f"## Compared with {old_csv}", ""] + compare(read_rows(old_csv), rows)
        with open(os.path.join(out, "stability.md"), "a") as fh:
            fh.write("\n".join(lines) + "\n")
