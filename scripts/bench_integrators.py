#!/usr/bin/env python
"""What accuracy costs with each integrator (issue 18): backward Euler, generalized-alpha (PETSc TSALPHA2,
rho_inf = 1 and 0.5) at fixed steps, and alpha2 with PETSc's basic adaptor at several tolerances, on
bend2 (L1, St.VK, t <= 0.3 s, frames every 0.1 s). Error: the largest vertex distance from a tight
alpha2 reference at h = 1.25e-4 over the frames, relative to the largest displacement. Cost: the
solve time (the runs' summed wall_s over step attempts). Then the undamped spin's energy over
-spin_time seconds at dt = 1e-2 and 1e-3 for both integrators.

  .venv/bin/python scripts/bench_integrators.py [--jobs 2] [--spin_time 10] [--out DIR]
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
from hyperelastic.experiments.runner import run_hyperelastic  # noqa: E402

BASE = ["bend2", "-level", "1", "-final_time", "0.3", "-frames_per_second", "10", "-quiet"]
TIGHT = ["-snes_rtol", "1e-12", "-snes_atol", "1e-9", "-ksp_rtol", "1e-12"]
SETTINGS = {
    "beuler": (["-integrator", "beuler"], [("h", h) for h in (1e-2, 5e-3, 2.5e-3, 1.25e-3, 6.25e-4, 3.125e-4)]),
    "alpha2 rho=1": (["-integrator", "ts"], [("h", h) for h in (2e-2, 1e-2, 5e-3, 2.5e-3, 1.25e-3)]),
    "alpha2 rho=0.5": (["-integrator", "ts", "-ts_alpha_radius", "0.5"],
                       [("h", h) for h in (2e-2, 1e-2, 5e-3, 2.5e-3, 1.25e-3)]),
    "alpha2 adaptive": (["-integrator", "ts", "-ts_adapt_type", "basic"],
                        [("rtol", r) for r in (1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5)]),
}


def read(path):
    import h5py
    with h5py.File(path, "r") as f:
        st = {k: f["stats"][k][:] for k in f["stats"]}
        return f["time"][:], f["x"][:], st


def one(args, out):
    rc, err, wall = run_hyperelastic(["run"] + args + ["-output", out], out)
    if rc != 0:
        raise SystemExit(f"{' '.join(map(str, args))}: exit {rc}: {err.strip()[-300:]}")
    return read(out)


def loglog_at(target, errs, costs):
    """('', cost) at error `target`, interpolated log-log between the two sweep points around it; ('<=', the
    cheapest run's cost) when every run meets it; None when no run does."""
    pts = sorted(zip(errs, costs))
    if pts and pts[-1][0] <= target:          # every run meets it: the cheapest one bounds the cost
        return ("<=", min(costs))
    for (e0, c0), (e1, c1) in zip(pts, pts[1:]):
        if e0 <= target <= e1:
            w = np.log(target / e0) / np.log(e1 / e0)
            return ("", float(np.exp(np.log(c0) + w * np.log(c1 / c0))))
    return None


def accuracy(out_dir, jobs):
    from concurrent.futures import ThreadPoolExecutor
    ref_t, ref_x, _ = one(BASE + TIGHT + ["-integrator", "ts", "-dt", "1.25e-4"], os.path.join(out_dir, "ref.h5"))
    scale = np.abs(ref_x - ref_x[0]).max()
    tasks = []
    for name, (extra, sweep) in SETTINGS.items():
        for kind, val in sweep:
            a = BASE + extra + (["-dt", str(val)] if kind == "h" else ["-dt", "1e-2", "-ts_rtol", str(val),
                                                                        "-ts_atol", str(val)])
            tasks.append((name, kind, val, a, os.path.join(out_dir, f"{name.replace(' ', '_')}_{val:g}.h5")))
    with ThreadPoolExecutor(jobs) as ex:
        results = list(ex.map(lambda t: one(t[3], t[4]), tasks))
    rows = []
    print(f"{'integrator':18s} {'h or rtol':>9s} {'steps':>6s} {'rejected':>8s} {'newton':>6s} {'error':>9s} "
          f"{'solve s':>8s}")
    for (name, kind, val, _, _), (t, x, st) in zip(tasks, results):
        assert np.allclose(t, ref_t, rtol=0, atol=1e-9), (name, val, t)
        err = float(np.abs(x - ref_x).max() / scale)
        acc = ~st["rejected"].astype(bool)
        cost = float(st["wall_s"].sum())
        rows.append((name, kind, val, int(acc.sum()), int((~acc).sum()), int(st["newton_its"].sum()), err, cost))
        print(f"{name:18s} {val:9.3g} {rows[-1][3]:6d} {rows[-1][4]:8d} {rows[-1][5]:6d} {err:9.2e} {cost:8.3f}")
    print("\ncost at a given error (log-log interpolation between sweep points; '-': not reached)")
    for target in (1e-2, 1e-3):
        line = []
        for name in SETTINGS:
            rs = [r for r in rows if r[0] == name]
            c = loglog_at(target, [r[6] for r in rs], [r[7] for r in rs])
            line.append(f"{name} {c[0]}{c[1]:.3f} s" if c else f"{name} -")
        print(f"  error {target:g}: " + "; ".join(line))
    print("\nadaptive: requested tolerance vs measured error")
    for r in rows:
        if r[1] == "rtol":
            print(f"  rtol {r[2]:8.1e}: error {r[6]:.2e} (ratio {r[6] / r[2]:.2f}), {r[3]} steps, {r[4]} rejected")
    return rows


def spin_energy(out_dir, T):
    print(f"\nspin, no damping, {T:g} s: total energy, max |E(t) - E(0)| / E(0) and E(T) drift")
    for dt in (1e-2, 1e-3):
        for name, extra in (("beuler", ["-integrator", "beuler"]), ("alpha2 rho=1", ["-integrator", "ts"])):
            out = os.path.join(out_dir, f"spin_{name.split()[0]}_{dt:g}.h5")
            _, _, st = one(["spin", "-level", "1", "-final_time", str(T), "-dt", str(dt), "-frames_per_second", "1",
                            "-quiet"] + extra, out)
            d = st["energy_dissipated"]
            e0 = st["energy_total"][0] + d[0]
            print(f"  dt {dt:g} {name:14s}: max {np.abs(d).max() / e0:.2e}, end {d[-1] / e0:+.2e} "
                  f"(second half mean {d[len(d) // 2:].mean() / e0:+.2e})")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--spin_time", type=float, default=10.0)
    ap.add_argument("--out", default="output/bench_integrators")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    accuracy(a.out, a.jobs)
    spin_energy(a.out, a.spin_time)


if __name__ == "__main__":
    main()
