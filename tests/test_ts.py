"""Issue 18: dynamics through PETSc TS (-integrator ts, TSALPHA2): second order, energy kept, the same
answer in every Jacobian mode and on 2 ranks, adaptive steps that reject and retry, checkpoints."""
import numpy as np
import pytest

from conftest import hyperelastic, read_h5, run_ok
from test_bad_input import one_line_error
from test_checkpoint import same_run

TIGHT = ["-snes_rtol", "1e-12", "-snes_atol", "1e-9", "-ksp_rtol", "1e-12"]


def ts_run(tmp_path, name, args, nprocs=1):
    out = tmp_path / f"{name}.h5"
    run_ok(["run", *args, "-integrator", "ts", "-quiet", "-output", out], nprocs=nprocs)
    return read_h5(out)


def test_second_order(tmp_path):
    """bend2 on L1 to t = 0.2: halving the step divides generalized-alpha's trajectory error (every
    frame, against alpha2 at dt/8) by about 4 for rho_inf = 1 and 0.5; backward Euler's by about 2."""
    base = ["bend2", "-level", 1, "-final_time", 0.2, "-frames_per_second", 50, *TIGHT]

    def run(tag, dt, extra):
        out = tmp_path / f"{tag}_{dt}.h5"
        run_ok(["run", *base, "-dt", dt, *extra, "-quiet", "-output", out])
        return read_h5(out)["x"]
    ref = run("ref", 0.000625, ["-integrator", "ts"])
    scale = np.abs(ref - ref[0]).max()
    err = {}
    for tag, extra in (("a1", ["-integrator", "ts"]), ("a05", ["-integrator", "ts", "-ts_alpha_radius", "0.5"]),
                       ("be", ["-integrator", "beuler"])):
        err[tag] = [np.abs(run(tag, dt, extra) - ref).max() / scale for dt in (0.005, 0.0025)]
    order = {k: np.log2(e[0] / e[1]) for k, e in err.items()}
    assert order["a1"] >= 1.9 and order["a05"] >= 1.9, (order, err)
    assert 0.8 <= order["be"] <= 1.3, (order, err)
    assert err["a1"][1] < 0.05 * err["be"][1]


def test_energy_kept_and_free_fall_exact(tmp_path):
    """The undamped spin keeps its total energy (rho_inf = 1): within 5e-3 over 0.5 s at dt = 1e-2, where
    backward Euler loses over 20%; drop falls exactly -g t^2/2 (uniform acceleration is integrated exactly)."""
    spin = ["spin", "-level", 1, "-final_time", 0.5]
    ts = ts_run(tmp_path, "spin", spin)
    st = ts["stats"]
    e0 = st["energy_total"][0] + st["energy_dissipated"][0]          # the energy at t = 0
    assert np.abs(st["energy_dissipated"]).max() < 5e-3 * e0
    be = tmp_path / "spin_be.h5"
    run_ok(["run", *spin, "-quiet", "-output", be])
    assert read_h5(be)["stats"]["energy_dissipated"][-1] > 0.2 * e0
    drop = ts_run(tmp_path, "drop", ["drop", "-level", 1, "-final_time", 0.3])
    dz = drop["x"][:, :, 2].mean(axis=1) - drop["x"][0, :, 2].mean()
    assert np.allclose(dz, -0.5 * 9.81 * drop["time"] ** 2, rtol=0, atol=1e-8)


def test_energy_momentum_conserves_energy(tmp_path):
    """-energy_momentum (the discrete-gradient elastic force in the midpoint step): the undamped spin keeps
    its total energy to 1e-6 over 2 s at dt = 1e-2 where plain alpha2 drifts by more than 1e-3; 2 ranks
    agree; an integrator or radius it does not apply to is one error line."""
    spin = ["spin", "-level", 1, "-final_time", 2]
    em = ts_run(tmp_path, "em", spin + ["-energy_momentum"])
    st = em["stats"]
    e0 = st["energy_total"][0] + st["energy_dissipated"][0]
    assert np.abs(st["energy_dissipated"]).max() < 1e-6 * e0
    plain = ts_run(tmp_path, "plain", spin)["stats"]
    assert np.abs(plain["energy_dissipated"]).max() > 1e-3 * e0
    two = ts_run(tmp_path, "em2", ["spin", "-level", 1, "-final_time", 0.2, "-energy_momentum"], nprocs=2)
    one = ts_run(tmp_path, "em1", ["spin", "-level", 1, "-final_time", 0.2, "-energy_momentum"])
    assert np.abs(two["x"] - one["x"]).max() <= 1e-8 * np.abs(one["x"]).max()
    one_line_error(hyperelastic(["run", "spin", "-level", 1, "-energy_momentum"]), "-integrator ts")
    # -step_forces under TS was ignored without a word (the statistics' forces are backward Euler's): now one line
    one_line_error(hyperelastic(["run", "spin", "-level", 1, "-integrator", "ts", "-step_forces", "1"]),
                   "-integrator ts records none")
    one_line_error(hyperelastic(["run", "spin", "-level", 1, "-energy_momentum", "-integrator", "ts",
                                 "-ts_alpha_radius", "0.5"]), "-ts_alpha_radius 1")


def test_jacobian_modes_and_ranks_agree(tmp_path):
    """The same generalized-alpha trajectory with the assembled tangent (both fills; the AIJ or its SBAIJ copy
    (the default) as the Krylov operator), the shell, PETSc's MFFD with and without our preconditioner, and on 2 ranks."""
    base = ["bend2", "-level", 1, "-final_time", 0.1, *TIGHT]
    ref = ts_run(tmp_path, "asm", base)
    variants = {"coo": ["-assembly", "coo"], "shell": ["-jacobian", "shell"], "aij": ["-operator_storage", "aij"],
                "mf": ["-snes_mf", "-ksp_type", "gmres", "-ksp_rtol", "1e-9"],
                "mf_operator": ["-snes_mf_operator", "-ksp_type", "gmres", "-ksp_rtol", "1e-9"]}
    for name, extra in variants.items():
        r = ts_run(tmp_path, name, base + extra)
        assert np.array_equal(r["time"], ref["time"]), name
        tol = 1e-8 if "mf" in name else 1e-10          # MFFD: differencing error ~ sqrt(eps)
        assert np.abs(r["x"] - ref["x"]).max() <= tol * np.abs(ref["x"]).max(), name
    two = ts_run(tmp_path, "np2", base, nprocs=2)
    assert np.abs(two["x"] - ref["x"]).max() <= 1e-8 * np.abs(ref["x"]).max()
    assert ref["attrs"]["integrator"] == "ts"


def test_adaptive_steps_reject_retry_and_hit_frames(tmp_path):
    """-ts_adapt_type basic: the first attempts are rejected and retried smaller (rows with rejected = 1),
    every accepted step has an error estimate <= 1, frames land exactly on their times, and a
    tighter tolerance takes more steps."""
    base = ["bend2", "-level", 1, "-final_time", 0.1, "-ts_adapt_type", "basic", "-ts_atol", "1e-4"]
    r = ts_run(tmp_path, "ad4", base + ["-ts_rtol", "1e-4"])
    st = r["stats"]
    rej = st["rejected"].astype(bool)
    assert rej.any() and not rej[-1]
    est = st["error_estimate"][~rej]
    assert np.all(est[np.isfinite(est)] <= 1.0) and np.isfinite(est).sum() > 10
    assert len(np.unique(st["dt"][~rej])) > 5                      # the step size varies
    frames = np.array([i * 0.03 for i in range(4)] + [0.1])
    assert np.abs(r["time"] - frames).max() < 1e-12
    loose = ts_run(tmp_path, "ad3", base + ["-ts_rtol", "1e-3", "-ts_atol", "1e-3"])
    assert (~loose["stats"]["rejected"].astype(bool)).sum() < (~rej).sum()


@pytest.mark.parametrize("adapt,extra", [("none", []), ("basic", []), ("none", ["-energy_momentum"])])
def test_restart_from_a_checkpoint_is_bitwise(tmp_path, adapt, extra):
    """A run continued from its last -checkpoint_every checkpoint to a later time equals the run made
    to that time directly (a checkpoint is a TS restart point in both)."""
    common = ["bend2", "-level", 1, "-checkpoint_every", 5, "-integrator", "ts", "-ts_adapt_type", adapt,
              "-ts_rtol", "1e-3", "-ts_atol", "1e-3", "-quiet", *extra]
    run_ok(["run", *common, "-final_time", 0.12, "-output", tmp_path / "a.h5"])
    run_ok(["run", "--restart", tmp_path / "a.h5", "-final_time", 0.25])
    run_ok(["run", *common, "-final_time", 0.25, "-output", tmp_path / "b.h5"])
    a, b = read_h5(tmp_path / "a.h5"), read_h5(tmp_path / "b.h5")
    same_run(a, b)
    assert a["attrs"]["restarts"] == 1


def test_ts_bad_input(tmp_path):
    one_line_error(hyperelastic(["run", "bend", "-level", 1, "-integrator", "ts", "-ts_type", "bdf"]), "alpha2")
    one_line_error(hyperelastic(["run", "bend", "-level", 1, "-integrator", "ts", "-quasistatic"]), "quasistatic")
    one_line_error(hyperelastic(["run", "bend", "-level", 1, "-integrator", "rk4"]), "-integrator")


def test_signal_stop_and_restart(tmp_path):
    """SIGTERM stops a TS run after a step with a checkpoint and one line; --restart finishes it. The frames
    before the stop are the uninterrupted run's bitwise; after it they agree to the integrator's accuracy
    (TSALPHA2 re-estimates its acceleration at a restart that the uninterrupted run did not make)."""
    import signal
    from test_checkpoint import RUN, stopped_run
    extra = ["-integrator", "ts"]
    ref_path = tmp_path / "ref.h5"
    run_ok(["run", *RUN, *extra, "-output", ref_path])
    ref = read_h5(ref_path)
    out = tmp_path / "o.h5"
    stopped_run(out, signal.SIGTERM, extra=extra)
    n = len(read_h5(out)["time"])
    assert 0 < n < len(ref["time"]) and np.array_equal(read_h5(out)["x"], ref["x"][:n])
    run_ok(["run", "--restart", out, "-quiet"])
    r = read_h5(out)
    assert np.array_equal(r["time"], ref["time"])
    scale = np.abs(ref["x"] - ref["x"][0]).max()
    assert np.abs(r["x"] - ref["x"]).max() <= 1e-3 * scale
