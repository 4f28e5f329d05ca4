"""Thesis sec. 7.2, Fig. 5: is kappa(tau) = k(x + tau t) linear in tau in [0, 10]? Every component is
fitted with the least-squares line kappa = alpha + beta tau (eqs. 7.5-7.6); we report the fit's
relative residual ||kappa - (alpha + beta tau)|| / ||kappa - mean(kappa)|| over all components, and
the same for a cubic fit: St.VK's first Piola stress is a cubic polynomial in F, and F is affine in tau,
so St.VK's kappa is exactly cubic, the linear material's exactly linear.
"""
import os

import numpy as np

from ...output.figures import pyplot
from .common import FAMILY_LABELS, Bench, outdir, simulate_state, write_csv


def lls_line(x, Y):
    """alpha, beta of eqs. 7.5-7.6 for every column of Y (N points x m components)."""
    N, sx, sxx = len(x), x.sum(), (x * x).sum()
    sy, sxy = Y.sum(axis=0), x @ Y
    den = N * sxx - sx * sx
    return (sxx * sy - sx * sxy) / den, (N * sxy - sx * sy) / den


def fit_residual(x, Y, degree):
    if degree == 1:
        a, b = lls_line(x, Y)
        fit = a + np.outer(x, b)
    else:
        V = np.vander(x, degree + 1)
        fit = V @ np.linalg.lstsq(V, Y, rcond=None)[0]
    return float(np.linalg.norm(Y - fit) / max(np.linalg.norm(Y - Y.mean(axis=0)), 1e-300))


def main(args):
    out = outdir(args.output_dir)
    pts, tets, x, t = simulate_state(out, args.level, args.state_time)
    b = Bench(pts, tets, x)
    taus = np.linspace(0.0, 10.0, args.points or (101 if args.full else 21))
    rows, curves = [], []
    fams = ("t", "tw", "r")
    for mat in ("stvk", "linear"):
        b.set_material(mat, 1e6, 0.3)
        for fam in fams:
            tv = b.vectors(fam, 1, np.random.default_rng([args.seed, 5]))[0]
            K = np.array([b.k(b.x + tau * tv) for tau in taus])
            r1, r2, r3 = (fit_residual(taus, K, d) for d in (1, 2, 3))
            a, beta = lls_line(taus, K)
            rows.append({"material": mat, "family": fam, "points": len(taus), "tau_max": float(taus[-1]),
                         "linear_fit_residual": r1, "quadratic_fit_residual": r2, "cubic_fit_residual": r3,
                         "norm_t": float(np.linalg.norm(tv)), "max_abs_t": float(np.abs(tv).max())})
            dofs = np.argsort(-np.abs(K[-1] - K[0]))[:3]
            curves.append((mat, fam, K[:, dofs], a[dofs], beta[dofs], dofs, r1))
            print(f"{mat:6s} {fam:2s} ({FAMILY_LABELS[fam]}): relative residual of the LLS line {r1:.3e}, "
                  f"of a cubic {r3:.3e}  (|t|_max = {np.abs(tv).max():.3g} m)")
    write_csv(os.path.join(out, "fig5_linearity.csv"), rows)
    series = []
    for (mat, fam, Kd, a, beta, dofs, _) in curves:
        for j, d in enumerate(dofs):
            for tau, kv in zip(taus, Kd[:, j]):
                series.append({"material": mat, "family": fam, "dof": int(d), "tau": float(tau), "kappa": float(kv),
                               "lls": float(a[j] + beta[j] * tau)})
    write_csv(os.path.join(out, "fig5_kappa.csv"), series)
    plt = pyplot()
    fig, axes = plt.subplots(2, len(fams), figsize=(4.6 * len(fams), 7), squeeze=False)
    for k, (mat, fam, Kd, a, beta, dofs, r1) in enumerate(curves):
        ax = axes[k // len(fams)][k % len(fams)]
        for j in range(Kd.shape[1]):
            ax.plot(taus, Kd[:, j], "o", ms=3, color=f"C{j}", label=f"dof {dofs[j]}")
            ax.plot(taus, a[j] + beta[j] * taus, "-", color=f"C{j}", lw=1)
        ax.set_title(f"{mat}, {FAMILY_LABELS[fam]}\nLLS line residual {r1:.2g}", fontsize=9)
        ax.set_xlabel("tau")
        ax.set_ylabel("kappa_i(tau) = k_i(x + tau t) [N]")
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(out, "fig5_linearity.png"), dpi=90)
    plt.close(fig)
    print(f"wrote {out}")
