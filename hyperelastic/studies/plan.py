"""The accuracy study's plan: which runs (configuration x setting), their references, and the
command line of each run (modes and preconditioners from the solver recipes in options/*.opts)."""
from dataclasses import dataclass, field, replace

import numpy as np

from .experiments.recipes import pc_of, without_pc

# (4.5, 1.5, 1.5): the thesis framework's test point, near the loaded end; then the centre of the
# loaded end face and the middle of the bar's top edge
MATERIAL_POINTS = np.array([[4.5, 1.5, 1.5], [5.0, 0.0, 0.0], [0.0, 2.0, 2.0]])
POINT_NAMES = ("test point (4.5,1.5,1.5)", "tip (5,0,0)", "top edge (0,2,2)")

# Jacobian mode -> options of its solver recipe without the PC (the PC is set separately; -snes_mf has
# none); seed_fd with fixed steps as in the thesis' framework (step control would retry each of its
# failures ten times at 50 Newton iterations each); the reference: exact tangent, linear solves to 1e-12
# (GMRES: twist's follower load is not symmetric), generalized-alpha (second order; rho_inf = 0.5 damps the
# modes its step does not resolve) -- a backward Euler reference at h/4 is itself ~1e-3 off, more than
# the second-order runs' errors
MODES = {"assembled": without_pc("exact"), "shell": without_pc("shell"), "snes_mf": without_pc("mffd"),
         "snes_mf_operator": without_pc("mffd_operator"), "seed_fd": without_pc("seed_fd") + ["-step_control", "0"],
         "reference": without_pc("reference") + ["-integrator", "ts", "-ts_alpha_radius", "0.5"],
         # the integrators (issue 18): PETSc TS generalized-alpha, fixed steps at two spectral radii, and
         # adaptive steps (h: the first step; Run.ts_rtol: the adaptor's tolerance), exact assembled tangent
         "alpha2": without_pc("exact") + ["-integrator", "ts"],
         "alpha2_r05": without_pc("exact") + ["-integrator", "ts", "-ts_alpha_radius", "0.5"],
         "alpha2_adapt": without_pc("exact") + ["-integrator", "ts", "-ts_adapt_type", "basic"]}
# preconditioner -> the PC options of the recipe that has it
PCS = {"jacobi": pc_of("exact"), "bjacobi_icc": pc_of("bjacobi_icc"), "gamg": pc_of("gamg"), "none": pc_of("mffd"),
       "ilu": pc_of("reference")}
SCENE_EXTRA = {"sag": ["-preset", "steel"]}    # sag is run stiff: steel's E, nu and rho
REF_FACTOR = 4              # reference h = smallest swept h / REF_FACTOR
REF_SNES_RTOL, REF_SNES_ATOL = 1e-10, 1e-12
TARGETS = (1e-1, 1e-2, 1e-3, 1e-4)
COST_TARGET = 1e-2          # the target of the cost-vs-E figure
DISC_H = 0.01               # time step of the discretisation-error runs (the same on every level)
FPS = 10                    # frames every 0.1 s: every swept h divides it
E_NAMES = {1e6: "1e6", 1e7: "rubber", 1e8: "1e8", 4.52e8: "cancellous bone", 1.616e10: "bone", 2.1e11: "steel"}


@dataclass(frozen=True)
class Run:
    scene: str
    material: str
    E: float
    level: int
    mode: str
    pc: str
    h: float
    snes_rtol: float
    ksp_rtol: float = 1e-5
    role: str = "sweep"              # sweep | reference | check | disc
    final_time: float = 0.3
    ts_rtol: float = 0.0             # alpha2_adapt: -ts_rtol = -ts_atol
    order: int = 1                   # element order (-order): the discretisation runs are made at 1 and 2

    @property
    def config(self):
        return (self.scene, self.material, self.E, self.level)

    @property
    def id(self):
        return (f"{self.scene}-{self.material}-E{self.E:g}-L{self.level}-{self.mode}-{self.pc}-h{self.h:g}"
                f"-r{self.snes_rtol:g}-k{self.ksp_rtol:g}-{self.role}" + (f"-a{self.ts_rtol:g}" if self.ts_rtol else "")
                + (f"-p{self.order}" if self.order != 1 else ""))

    def args(self, out):
        a = ["run", self.scene, "-level", self.level, "-material", self.material, "-order", self.order]
        a += SCENE_EXTRA.get(self.scene, [])
        a += ["-E", repr(self.E), "-dt", repr(self.h), "-final_time", repr(self.final_time),
              "-frames_per_second", FPS, "-snes_rtol", repr(self.snes_rtol), "-ksp_rtol", repr(self.ksp_rtol),
              "-output", out, "-quiet"]
        if self.role != "sweep":
            a += ["-snes_atol", repr(REF_SNES_ATOL), "-snes_max_it", "100"]
        if self.ts_rtol:
            a += ["-ts_rtol", repr(self.ts_rtol), "-ts_atol", repr(self.ts_rtol)]
        return a + MODES[self.mode] + PCS[self.pc]


def reference_of(run, h_min):
    return Run(run.scene, run.material, run.E, run.level, "reference", "ilu", h_min / REF_FACTOR, REF_SNES_RTOL,
               1e-12, "reference", run.final_time)


@dataclass
class Plan:
    """The sweep: runs grouped by configuration, plus what the report should headline."""
    runs: list
    final_time: float
    finest_level: int
    main: tuple = None               # the configuration of the Pareto headline
    notes: list = field(default_factory=list)
    disc_h: float = DISC_H           # the discretisation runs' time step (--smoke: a larger one)


def _grid(scene, material, E, level, modes, pcs, hs, rtols, ksps=(1e-5,), T=0.3):
    return [Run(scene, material, E, level, m, ("none" if m == "snes_mf" else pc), h, r, k, final_time=T)
            for m in modes for pc in pcs for h in hs for r in rtols for k in ksps]


def _adaptive(cfg, tols, T, h0=0.01, pc="jacobi"):
    return [Run(*cfg, "alpha2_adapt", pc, h0, 1e-8, final_time=T, ts_rtol=tol) for tol in tols]


def smoke_plan():
    """--smoke: the smallest sweep with every part of the study — every Jacobian mode, the thesis' operator failing,
    tolerance ladders, generalized-alpha (fixed and adaptive), another preconditioner, steel, Neo-Hookean, a second
    scene and a second level, references, checks and the discretisation runs on L1-L3 — about 70 runs, ~20 s on
    2 cores (what `make test` checks the study with). To t = 0.2 s, not the quick plan's 0.3: every swept h still
    divides it and the frames' 0.1 s, and the suite's sweep costs 30 cpu-seconds instead of 40."""
    T, main = 0.2, ("bend2", "stvk", 1e6, 1)
    runs = _grid(*main, ("assembled",), ("jacobi",), (0.1, 0.05, 0.02, 0.01, 0.005), (1e-2, 1e-4, 1e-8), T=T)
    runs += _grid(*main, ("shell", "snes_mf", "snes_mf_operator"), ("jacobi",), (0.05, 0.01), (1e-6,), T=T)
    runs += _grid(*main, ("seed_fd",), ("jacobi",), (0.1,), (1e-6,), T=T)
    runs += _grid(*main, ("alpha2",), ("jacobi",), (0.02, 0.01, 0.005, 0.0025), (1e-6, 1e-8), T=T)
    runs += _adaptive(main, (1e-3, 1e-5), T)
    runs += _grid(*main, ("assembled",), ("gamg",), (0.01,), (1e-6,), T=T)
    runs += _grid("bend2", "stvk", 2.1e11, 1, ("assembled",), ("jacobi",), (0.1, 0.02, 0.01), (1e-2, 1e-4, 1e-8), T=T)
    runs += _grid("bend2", "stvk", 1e6, 2, ("assembled",), ("jacobi",), (0.1, 0.01), (1e-2, 1e-8), T=T)
    runs += _grid("bend2", "neohookean", 1e6, 1, ("assembled",), ("jacobi",), (0.1, 0.01), (1e-2, 1e-8), T=T)
    runs += _grid("squeeze", "stvk", 1e6, 1, ("assembled",), ("jacobi",), (0.1, 0.01), (1e-2, 1e-8), T=T)
    # (the discretisation runs at 6 steps, not 30: their P2 runs on L1-L3 were 14 of the smoke sweep's 45 cpu-seconds)
    return Plan(list(dict.fromkeys(runs)), T, 3, main=main, disc_h=0.05)


def plan(full=False):
    """The quick default (~3.5 min on 2 cores: bend2 and squeeze on L1/L2, St.VK and Neo-Hookean, E up
    to steel), --full (four scenes, two materials, E up to steel, h 1e-1 ... 1e-4, L1-L3; hours), or
    full="smoke" (smoke_plan)."""
    modes = ("assembled", "shell", "snes_mf", "snes_mf_operator", "seed_fd")
    if full == "smoke":
        return smoke_plan()
    if not full:
        T = 0.3
        hs, h4 = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002), (0.1, 0.05, 0.02, 0.01)
        main = ("bend2", "stvk", 1e6, 1)
        runs = _grid(*main, ("assembled",), ("jacobi",), hs, (1e-2, 1e-4, 1e-8), T=T)
        runs += _grid(*main, modes[1:-1], ("jacobi",), hs, (1e-6,), T=T)
        # the thesis' operator at the two largest steps only: it fails there after 100 Newton iterations each (the
        # quick study's point), and at h = 0.002 it took 105 s of the quick study's 400 run-seconds (--full: all)
        runs += _grid(*main, modes[-1:], ("jacobi",), hs[:2], (1e-6,), T=T)
        runs += _grid(*main, ("alpha2", "alpha2_r05"), ("jacobi",), (0.05, 0.02, 0.01, 0.005, 0.0025), (1e-6, 1e-8), T=T)
        runs += _adaptive(main, (1e-2, 1e-3, 1e-4, 1e-5), T)
        runs += _grid(*main, ("alpha2",), ("gamg",), (0.02, 0.005), (1e-8,), T=T)
        runs += _grid(*main, ("assembled",), ("bjacobi_icc", "gamg"), (0.05, 0.01, 0.002), (1e-6,), T=T)
        runs += _grid(*main, ("assembled",), ("jacobi",), (0.05, 0.01, 0.002), (1e-8,), (1e-2, 1e-8), T=T)
        runs += _grid("bend2", "stvk", 1e6, 2, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        for E in (1e8, 2.1e11):   # (MFFD at steel: ~10 s per run, so one h only)
            runs += _grid("bend2", "stvk", E, 1, ("assembled", "shell"), ("jacobi",), h4, (1e-6,), T=T)
            runs += _grid("bend2", "stvk", E, 1, ("snes_mf_operator",), ("jacobi",), (0.1,), (1e-6,), T=T)
        # at steel the motion is quasi-static and the time error tiny: there the tolerances matter
        runs += _grid("bend2", "stvk", 2.1e11, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-4, 1e-8), T=T)
        runs += _grid("bend2", "neohookean", 1e6, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        runs += _grid("squeeze", "stvk", 1e6, 1, ("assembled",), ("jacobi",), h4, (1e-2, 1e-8), T=T)
        return Plan(list(dict.fromkeys(runs)), T, 3, main=main)
    T = 0.5
    hs = (1e-1, 5e-2, 2e-2, 1e-2, 5e-3, 2e-3, 1e-3, 1e-4)
    rtols = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
    runs = []
    for scene in ("bend2", "squeeze", "twist", "sag"):
        for mat in ("stvk", "neohookean"):
            E0 = 2.1e11 if scene == "sag" else 1e6
            runs += _grid(scene, mat, E0, 1, modes, ("jacobi",), hs, rtols, T=T)
            runs += _grid(scene, mat, E0, 1, ("alpha2", "alpha2_r05"), ("jacobi", "gamg"), hs, (1e-6, 1e-8), T=T)
            runs += _adaptive((scene, mat, E0, 1), (1e-2, 1e-3, 1e-4, 1e-5, 1e-6), T)
            runs += _grid(scene, mat, E0, 1, ("assembled",), ("bjacobi_icc", "gamg"), hs, (1e-6,), T=T)
            runs += _grid(scene, mat, E0, 1, ("assembled", "snes_mf"), ("jacobi",), hs, (1e-8,), (1e-2, 1e-8, 1e-10),
                          T=T)
            runs += _grid(scene, mat, E0, 2, ("assembled",), ("jacobi",), hs, rtols, T=T)
            runs += _grid(scene, mat, E0, 3, ("assembled", "snes_mf_operator"), ("jacobi", "gamg"), hs, (1e-6,), T=T)
            if scene != "sag":
                for E in (1e8, 4.52e8, 1.616e10, 2.1e11):
                    runs += _grid(scene, mat, E, 1, modes, ("jacobi",), hs, (1e-6,), T=T)
    return Plan(list(dict.fromkeys(runs)), T, 5, main=("bend2", "stvk", 1e6, 1))


def with_references(p):
    """(references by configuration, the extra runs): each configuration's reference and its check
    run (at twice the reference's step), and for each (scene, material, E) swept on more than one
    level or headlined, reference-setting runs at the plan's disc_h on its levels and on the finest level, with linear
    and with quadratic tetrahedra (the mesh error of both against the finest level's quadratic run)."""
    by_cfg = {}
    for r in p.runs:
        by_cfg.setdefault(r.config, []).append(r)
    refs, extra = {}, []
    for cfg, rs in by_cfg.items():
        ref = reference_of(rs[0], min(r.h for r in rs))
        refs[cfg] = ref
        extra += [ref, replace(ref, h=ref.h * 2, role="check")]
    levels = {}
    for cfg in by_cfg:
        levels.setdefault(cfg[:3], set()).add(cfg[3])
    for key, lv in levels.items():
        if len(lv) > 1 or key == p.main[:3]:
            base = refs[next(c for c in by_cfg if c[:3] == key)]
            extra += [replace(base, level=L, h=p.disc_h, role="disc", order=o) for o in (1, 2)
                      for L in sorted(lv | {p.finest_level})]
    return refs, extra

