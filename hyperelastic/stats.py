"""The statistics a run writes: FILE.h5:stats/<column>, one entry per step attempt (rejected attempts
included). Declared here once: the integrator writes these columns (output.Writer refuses others),
and the studies, the hard-case matrix, the reproduction scripts and the tests read them from here.
"""
import numpy as np

# column: (type, meaning)
COLUMNS = {
    "step": (int, "number of the step this attempt tries to complete (accepted steps before it + 1)"),
    "time": (float, "time at the end of the attempt [s]"),
    "dt": (float, "size of the attempt [s] (step control halves it after a rejection)"),
    "snes_reason": (int, "SNES converged reason (negative: diverged)"),
    "newton_its": (int, "Newton iterations"),
    "ksp_its": (int, "Krylov iterations, summed over the Newton iterations"),
    "residual_evals": (int, "residual evaluations (MFFD's included)"),
    "residual_seconds": (float, "wall time in residual evaluations [s]"),
    "objective_evals": (int, "evaluations of the incremental potential (the energy line search's merit)"),
    "objective_seconds": (float, "wall time in objective evaluations [s]"),
    "inversion_cuts": (int, "Newton updates the inversion guard shortened"),
    "rejected": (int, "1: step control refused the attempt (the state did not move); 0: accepted"),
    "wall_s": (float, "wall time of the attempt [s]"),
    "kinetic": (float, "kinetic energy 1/2 v^T M v after the step [J] (accepted attempts)"),
    "elastic": (float, "elastic energy after the step [J] (accepted attempts)"),
    "J_min": (float, "smallest volume ratio det F over the cells after the step"),
    "J_max": (float, "largest volume ratio det F over the cells after the step"),
    "gravity_potential": (float, "potential of gravity -f.x [J] (scenes with gravity)"),
    "traction_work": (float, "work potential f.x of the dead-load traction [J] (scenes with traction)"),
    "energy_total": (float, "kinetic + elastic + gravity potential - traction work after the step [J]"),
    "energy_dissipated": (float, "total energy at t = 0 minus energy_total [J]: physical damping plus the "
                                 "integrator's numerical dissipation (and the work of prescribed motions)"),
    "error_estimate": (float, "-integrator ts with an adaptor: the step's weighted local error estimate "
                              "(TSEvaluateWLTE, accepted when <= 1)"),
    "dt_next": (float, "-integrator ts: the step size chosen for the next step [s]"),
}
# effect_<name>_<kind>, for every effect the run built
EFFECT_COLUMNS = {
    "evals": (int, "residual evaluations of the effect"),
    "applies": (int, "tangent applications, diagonals and assemblies of the effect"),
    "seconds": (float, "wall time in the effect [s]"),
}


def effect_column(effect, kind):
    return f"effect_{effect}_{kind}"


def column_type(name):
    """int or float for a declared column; KeyError for any other name."""
    if name in COLUMNS:
        return COLUMNS[name][0]
    if name.startswith("effect_"):
        kind = name.rsplit("_", 1)[-1]
        if kind in EFFECT_COLUMNS:
            return EFFECT_COLUMNS[kind][0]
    raise KeyError(f"'{name}' is not a declared statistics column (hyperelastic/stats.py)")


def read(f):
    """{column: array} of an open output file (h5py.File)."""
    return {k: f["stats"][k][:] for k in f["stats"]}


def accepted(st):
    """Boolean mask of the accepted attempts."""
    n = len(st.get("step", []))
    return ~st.get("rejected", np.zeros(n, np.int64)).astype(bool)


def total_energy(st, with_traction=True):
    """kinetic + elastic + gravity potential (- traction work) of the accepted attempts."""
    acc = accepted(st)
    tot = st["kinetic"][acc] + st["elastic"][acc]
    if "gravity_potential" in st:
        tot = tot + st["gravity_potential"][acc]
    if with_traction and "traction_work" in st:
        tot = tot - st["traction_work"][acc]
    return tot
