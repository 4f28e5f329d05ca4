"""Thesis sec. 7.3 (Figs. 6-9, 14-15) and sec. 7.4 (Figs. 10-13): cross-validation of the time step h
against a parameter P in {E, nu, L}.

For each P, material, vector family and operator we record, per test vector, ||approx - Kv||_inf,
||approx - Kv||_2 and the norms of Kv and Mv. The thesis' error is delta(h, P) = h^2 max ||approx -
Kv||_inf (Alg. 1, eq. 7.7). None of the approximations depends on h (the time step is not a
differencing step), so delta(h, P) = h^2 delta(1, P) exactly and the grid over h is a rescaling. Beside
it we report the relative error of the approximation of K v (independent of h) and the relative error
of the whole Newton operator J = M + h^2 K, which does depend on h.
"""
import os

import numpy as np

from ...output.figures import pyplot
from .common import FAMILIES, FAMILY_LABELS, OP_LABELS, OPERATORS, THESIS_MATERIALS, D_INF, Bench, delta, largest_feasible, measure, outdir, rel_J, rel_K, simulate_state, write_csv

PARAM_LABELS = {"E": "Young's modulus E [Pa]", "nu": "Poisson's ratio nu", "L": "mesh level L"}


def grids(full):
    return {
        "E": np.logspace(2, 15, 100 if full else 14),
        "nu": np.linspace(0.0, 0.49, 100 if full else 8),
        "L": np.arange(1, 9) if full else np.array([1, 2]),
        "h": np.logspace(-2, -15, 100 if full else 27),
    }


class Study:
    """Per-vector measurements m[(i, material, family, op)] for the values P_i of one parameter."""

    def __init__(self, param, values, hs, m, meta):
        self.param, self.values, self.hs, self.m, self.meta = param, np.asarray(values), np.asarray(hs), m, meta

    def combos(self):
        seen = []
        for (_, mat, fam, op) in self.m:
            if (mat, fam, op) not in seen:
                seen.append((mat, fam, op))
        return seen

    def surface(self, mat, fam, op, measure_name="delta"):
        """(len(hs), len(values)) array of the error measure."""
        f = delta if measure_name == "delta" else rel_J
        return np.stack([f(self.m[(i, mat, fam, op)], self.hs) for i in range(len(self.values))], axis=1)

    def rel_K(self, mat, fam, op):
        return np.array([rel_K(self.m[(i, mat, fam, op)]) for i in range(len(self.values))])

    def delta1(self, mat, fam, op):
        return np.array([self.m[(i, mat, fam, op)][:, D_INF].max() for i in range(len(self.values))])


def compute(param, values, hs, work_dir, level=1, nvec=30, seed=7, state_time=0.2, E0=1e6, nu0=0.3,
            materials=THESIS_MATERIALS, families=FAMILIES, ops=OPERATORS, log=print):
    """Measure every (P, material, family, operator). The state is the squeeze scene at t =
    state_time (exact tangent); for P = E and nu the geometry is held fixed and only the material
    changes, so k and K scale exactly with the Lame constants."""
    m = {}
    meta = {"level": level, "nvec": nvec, "seed": seed, "state_time": state_time, "E0": E0, "nu0": nu0}
    b, b_level = None, None
    vec_cache = {}
    for i, P in enumerate(values):
        L = int(P) if param == "L" else level
        if L != b_level:                         # one bench (mesh and state) at a time
            pts, tets, x, _ = simulate_state(work_dir, L, state_time)
            b, b_level = Bench(pts, tets, x), L
        E = float(P) if param == "E" else E0
        nu = float(P) if param == "nu" else nu0
        for fam in families:
            key = (L, fam)
            if key not in vec_cache:   # the same vectors for every E and nu (common random numbers)
                vec_cache[key] = b.vectors(fam, nvec, np.random.default_rng([seed, L, FAMILIES.index(fam)]))
        for mat in materials:
            b.set_material(mat, E, nu)
            for fam in families:
                res = measure(b, vec_cache[(L, fam)], ops)
                for op in ops:
                    m[(i, mat, fam, op)] = res[op]
        if param == "L":
            meta.setdefault("tets", {})[L] = b.nc
            meta.setdefault("vertices", {})[L] = b.n // 3
            meta.setdefault("mu_sigma", {})[L] = (b.mu_real, b.sigma_real)
        else:
            meta["tets"], meta["vertices"], meta["mu_sigma"] = b.nc, b.n // 3, (b.mu_real, b.sigma_real)
        log(f"  {param} = {P:.4g}: done")
    return Study(param, values, hs, m, meta)


def write(study, out, tol=1e-3, rel_tol=1e-3):
    """CSV (per P, and the whole (P, h) grid) and the blue/red points of the feasible area."""
    s, rows, feas = study, [], []
    grid_cols = {"value": np.repeat(s.values, len(s.hs)), "h": np.tile(s.hs, len(s.values))}
    for (mat, fam, op) in s.combos():
        d1, rk = s.delta1(mat, fam, op), s.rel_K(mat, fam, op)
        D, RJ = s.surface(mat, fam, op, "delta"), s.surface(mat, fam, op, "rel_J")
        grid_cols[f"delta:{mat}:{fam}:{op}"] = D.T.ravel()
        grid_cols[f"relJ:{mat}:{fam}:{op}"] = RJ.T.ravel()
        hd = [largest_feasible(s.hs, D[:, i], tol) for i in range(len(s.values))]
        hr = [largest_feasible(s.hs, RJ[:, i], rel_tol) for i in range(len(s.values))]
        for i, P in enumerate(s.values):
            rows.append({"param": s.param, "value": float(P), "material": mat, "family": fam, "operator": op,
                         "delta_at_h1": float(d1[i]), "rel_K": float(rk[i]),
                         "h_feasible_delta": hd[i], "h_feasible_relJ": hr[i]})
        for name, hv, t in (("delta", hd, tol), ("rel_J", hr, rel_tol)):
            feas.append({"param": s.param, "material": mat, "family": fam, "operator": op, "measure": name,
                         "tol": t, "P_first": float(s.values[0]), "h_first": hv[0],
                         "P_last": float(s.values[-1]), "h_last": hv[-1]})
    write_csv(os.path.join(out, f"crossval_{s.param}.csv"), rows)
    write_csv(os.path.join(out, f"feasible_{s.param}.csv"), feas)
    keys = list(grid_cols)
    write_csv(os.path.join(out, f"crossval_{s.param}_grid.csv"),
              [{k: float(grid_cols[k][j]) for k in keys} for j in range(len(grid_cols["h"]))], keys)
    return rows, feas


def _xaxis(param, values):
    return np.log10(values) if param == "E" else values


def plot_surfaces(study, out, tol=1e-3, rel_tol=1e-3, families=("e", "r", "t")):
    """One PNG per operator and measure: rows = vector families, columns = materials; log10 of the
    error over (P, h), the feasible boundary (black) and its end points (blue: first P, red: last P)."""
    plt = pyplot()
    s = study
    mats = sorted({c[0] for c in s.combos()}, key=THESIS_MATERIALS.index)
    fams = [f for f in families if any(c[1] == f for c in s.combos())]
    ops = [o for o in OPERATORS if any(c[2] == o for c in s.combos())]
    X = _xaxis(s.param, s.values)
    Y = np.log10(s.hs)
    paths = []
    for op in ops:
        for meas, t in (("delta", tol), ("rel_J", rel_tol)):
            fig, axes = plt.subplots(len(fams), len(mats), figsize=(5.2 * len(mats), 3.6 * len(fams)), squeeze=False)
            for r, fam in enumerate(fams):
                for c, mat in enumerate(mats):
                    ax = axes[r][c]
                    S = s.surface(mat, fam, op, meas)
                    Z = np.log10(np.maximum(S, 1e-300))
                    im = ax.pcolormesh(X, Y, Z, shading="nearest", cmap="viridis")
                    fig.colorbar(im, ax=ax, label=f"log10 {'delta' if meas == 'delta' else 'rel. error of J v'}")
                    if Z.min() <= np.log10(t) <= Z.max():
                        ax.contour(X, Y, Z, levels=[np.log10(t)], colors="k", linewidths=1.5, linestyles="solid")
                    for i, col in ((0, "tab:blue"), (-1, "tab:red")):
                        hf = largest_feasible(s.hs, S[:, i], t)
                        if np.isfinite(hf):
                            ax.plot(X[i], np.log10(hf), "o", color=col, ms=7, mec="w")
                            ax.annotate(f"{hf:.3g}", (X[i], np.log10(hf)), color=col, fontsize=8,
                                        xytext=(4, 4), textcoords="offset points")
                    ax.set_title(f"{mat}, {FAMILY_LABELS[fam]}", fontsize=9)
                    ax.set_xlabel(("log10 " if s.param == "E" else "") + PARAM_LABELS[s.param])
                    ax.set_ylabel("log10 time step h")
            what = "delta = ||h^2 (approx - Kv)||_inf" if meas == "delta" else "||h^2 (approx - Kv)|| / ||(M + h^2 K) v||"
            fig.suptitle(f"{OP_LABELS[op]}: {what}; black: tolerance {t:g}", fontsize=10)
            fig.tight_layout()
            p = os.path.join(out, f"crossval_{s.param}_{op}_{meas}.png")
            fig.savefig(p, dpi=90)
            plt.close(fig)
            paths.append(p)
    return paths


# --- sec. 7.4: the 2-D slices -------------------------------------------------------------------
# Table 5's eight curves (material x family x order) plus PETSc's MFFD for the real vectors
SLICE_CURVES = [(mat, fam, "seed_fd") for mat in THESIS_MATERIALS for fam in ("e", "r", "t")] + \
               [(mat, "t", "seed_fd2") for mat in THESIS_MATERIALS] + \
               [(mat, "t", op) for mat in THESIS_MATERIALS for op in ("mffd_wp", "mffd_ds")]


def _style(mat, fam, op):
    color = {"e": "tab:orange", "r": "tab:green", "t": "tab:blue", "tw": "tab:gray"}[fam]
    if op.startswith("mffd"):
        color = "tab:red" if op == "mffd_wp" else "tab:purple"
    ls = "-" if mat == "linear" else "--"
    marker = "s" if op == "seed_fd2" else ("o" if op.startswith("mffd") else None)
    return dict(color=color, ls=ls, marker=marker, ms=3)


def slice_at_h(study, h, out, name, tol=1e-3):
    """delta(P) at a fixed time step h (Figs. 10-12), for the Table 5 curves and MFFD."""
    plt = pyplot()
    s = study
    rows = []
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (mat, fam, op) in SLICE_CURVES:
        if (0, mat, fam, op) not in s.m:
            continue
        d = s.delta1(mat, fam, op) * h * h
        for P, v in zip(s.values, d):
            rows.append({"figure": name, "h": h, "param": s.param, "value": float(P), "material": mat,
                         "family": fam, "operator": op, "delta": float(v), "feasible": int(v <= tol)})
        ax.plot(s.values, d, label=f"{mat} {fam} {op}", **_style(mat, fam, op))
    if s.param == "E":
        ax.set_xscale("log")
    _finish_slice(plt, fig, ax, os.path.join(out, f"{name}.png"), tol, PARAM_LABELS[s.param],
                  "delta = ||h^2 (approx - Kv)||_inf", f"{name}: h = {h:g}; black: tolerance {tol:g}")
    return rows


def slice_at_level(study, level, out, name, tol=1e-3):
    """delta(h) at a fixed mesh level (Fig. 13) with the largest feasible h of each curve."""
    plt = pyplot()
    s = study
    i = int(np.flatnonzero(s.values == level)[0])
    rows = []
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for (mat, fam, op) in SLICE_CURVES:
        if (i, mat, fam, op) not in s.m:
            continue
        d = delta(s.m[(i, mat, fam, op)], s.hs)
        hf = largest_feasible(s.hs, d, tol)
        rows.append({"figure": name, "level": level, "material": mat, "family": fam, "operator": op,
                     "delta_at_h1": float(s.m[(i, mat, fam, op)][:, D_INF].max()), "h_feasible": hf})
        ln, = ax.plot(s.hs, d, label=f"{mat} {fam} {op}", **_style(mat, fam, op))
        if np.isfinite(hf):
            ax.plot([hf], [tol], "o", color=ln.get_color())
    ax.set_xscale("log")
    _finish_slice(plt, fig, ax, os.path.join(out, f"{name}.png"), tol, "time step h", "delta",
                  f"{name}: mesh L{level}; points: largest feasible h")
    return rows


def _finish_slice(plt, fig, ax, path, tol, xlabel, ylabel, title):
    """The tolerance line, log error axis, labels and legend of a slice figure; saved to path."""
    ax.axhline(tol, color="k", lw=1)
    ax.set_yscale("log")
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main_crossval(args):
    out = outdir(args.output_dir)
    g = grids(args.full)
    params = ["E", "nu", "L"] if args.param == "all" else [args.param]
    nvec = args.vectors or (30 if args.full else 5)
    for p in params:
        print(f"cross-validation of h x {p}: {len(g[p])} values x {len(g['h'])} time steps, {nvec} vectors per family")
        st = compute(p, g[p], g["h"], out, level=args.level, nvec=nvec, seed=args.seed,
                     state_time=args.state_time)
        _, feas = write(st, out, args.tol, args.rel_tol)
        if not getattr(args, "no_plots", False):
            plot_surfaces(st, out, args.tol, args.rel_tol)
        for f in feas:
            if f["family"] in ("t", "r", "e"):
                print(f"  {f['measure']:6s} {f['material']:6s} {f['family']:2s} {f['operator']:9s} "
                      f"largest feasible h: {p}={f['P_first']:.3g} -> {f['h_first']:.3g}; "
                      f"{p}={f['P_last']:.3g} -> {f['h_last']:.3g}")
    print(f"wrote {out}")


def main_slices(args):
    out = outdir(args.output_dir)
    g = grids(args.full)
    nvec = args.vectors or (30 if args.full else 5)
    rows = []
    levels = g["L"] if args.full else np.array([1, 2, 3])
    kw = dict(nvec=nvec, seed=args.seed, state_time=args.state_time, families=("e", "r", "t"))
    stE = compute("E", g["E"], g["h"], out, level=args.level, **kw)
    rows += slice_at_h(stE, 1e-4, out, "fig10_E_at_h1e-4", args.tol)
    stn = compute("nu", g["nu"], g["h"], out, level=args.level, **kw)
    rows += slice_at_h(stn, 1e-2, out, "fig11_nu_at_h1e-2", args.tol)
    stL = compute("L", levels, g["h"], out, **kw)
    rows += slice_at_h(stL, 1e-4, out, "fig12_L_at_h1e-4", args.tol)
    rows13 = slice_at_level(stL, 3, out, "fig13_L3", args.tol)
    write_csv(os.path.join(out, "slices.csv"), rows)
    write_csv(os.path.join(out, "fig13_L3.csv"), rows13)
    for r in rows13:
        print(f"  L3 {r['material']:6s} {r['family']} {r['operator']:9s} largest feasible h {r['h_feasible']:.3g}")
    print(f"wrote {out}")
