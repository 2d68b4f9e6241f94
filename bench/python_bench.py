"""Speed of the Python package (the issue's table), one run on this machine.

    python bench/python_bench.py            # all rows
    python bench/python_bench.py --quick    # skip the 1000-run Dask campaign
    python bench/python_bench.py --batch    # the batch table only

1. one predict + update, 15 states / 6 measurements, called from Python:
   aidnav.KalmanFilter against FilterPy's KalmanFilter (same matrices as
   bench/filterpy_step.py);
2. the batch call (a whole measurement array in one call) against
   FilterPy's loop, per epoch, for 4/2 (constant velocity), 6/3, 9/3, 15/6
   and 21/6 states/measurements, 12/6 (six constant-velocity axes), and
   15/6 and 12/6 with 10 % of the values missing, with the step's flop
   count: the rate the batch reaches and the rate 50× FilterPy would need
   (the arithmetic floor), and the epochs computed in the steady state
   (the constant-velocity models from epoch 145, 6/3 from epoch ≈ 1800;
   9/3, 15/6 and 21/6 never settle in 3000
   epochs, and a missing value breaks the steady state at every gap);
3. process on the drive from Python against the CLI binary (same build);
4. reproduce anomalies at 1000 runs on a two-worker LocalCluster against
   one worker (each worker one thread and RAYON_NUM_THREADS=1: one core).
Medians over repeats; the machine is shared, so ratios are of one run.
"""

import os
import shutil
import subprocess
import sys
import time
import timeit
from pathlib import Path

import numpy as np

import aidnav

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "bench"))
from filterpy_step import problem  # noqa: E402  (the C++/Rust benchmarks' matrices)


def median_per_call(fn, number, repeat=7):
    times = timeit.repeat(fn, number=number, repeat=repeat)
    return sorted(t / number for t in times)[repeat // 2]


def step_rows():
    from filterpy.kalman import KalmanFilter as FpKf

    rows = []
    for n, m in [(15, 6), (21, 6)]:
        phi, q, h, r, p0, z = problem(n, m)
        fp = FpKf(dim_x=n, dim_z=m)
        fp.F, fp.Q, fp.H, fp.R, fp.P = phi, q, h, r, p0
        fp.x = np.zeros((n, 1))

        def fp_step():
            fp.predict()
            fp.update(z)

        ours = aidnav.KalmanFilter(np.zeros(n), p0)

        def our_step():
            ours.predict(phi, q)
            ours.update(z, h, r)

        t_fp = median_per_call(fp_step, 2000)
        t_us = median_per_call(our_step, 2000)
        rows.append((f"predict + update {n}/{m}", t_fp, t_us))
    return rows


def step_flops(n, m):
    """Floating-point operations of one predict + update as the engine
    computes them (kalman.rs: P = Φ P Φᵀ + Q; H P, H P Hᵀ, Cholesky of S,
    K from it, the Joseph form grouped as A = P − K H P, P = A + (K R − A
    Hᵀ) Kᵀ; x updates): a multiply-add is two."""
    predict = 4 * n**3 + 2 * n * n
    update = 2 * m * n * n + 2 * m * m * n + m**3 / 3 + 2 * m * m * n + 6 * m * n * n + 2 * n * m * m + 6 * m * n
    return predict + update


def constant_velocity(axes):
    """``axes`` constant-velocity axes (positions measured), Q = 1e-3 I,
    R = I, P0 = I: 2·axes states, axes measurements. Its Riccati recursion
    reaches a bit-for-bit fixed point (epoch 144), so the batch's steady
    state engages for most of the 2000 epochs. Of the ``problem`` models
    only 6/3 settles, from epoch ≈ 1800 of 2000 (only the last ≈ 200
    epochs are steady): on a fixed point with this P0 (numpy's product),
    on a cycle of two covariances with the Rust tests' (nalgebra's; the
    batch follows either); 9/3, 15/6 and 21/6 still change after 3000
    epochs."""
    phi = np.kron(np.eye(axes), np.array([[1.0, 1.0], [0.0, 1.0]]))
    h = np.kron(np.eye(axes), np.array([[1.0, 0.0]]))
    n = 2 * axes
    return phi, np.eye(n) * 1e-3, h, np.eye(axes), np.eye(n)


def batch_models():
    """The batch table's models: constant velocity 4/2 (steady from epoch
    145), the ``problem`` models 6/3 (steady from epoch ≈ 1800), 9/3,
    15/6 and 21/6 (never steady: the full step at
    every epoch), constant velocity 12/6 (steady from epoch 145)."""
    models = {"4/2 (constant velocity)": constant_velocity(2)}
    for n, m in [(6, 3), (9, 3), (15, 6), (21, 6)]:
        models[f"{n}/{m}"] = problem(n, m)[:5]
    models["12/6 (constant velocity)"] = constant_velocity(6)
    return models


def batch_rows(missing=0.1):
    """The batch call against FilterPy's loop, per epoch, for a table of
    sizes; the last row with a fraction of the values missing (NaN; FilterPy
    given the rows of H and R present at each epoch, as the batch selects
    them)."""
    from filterpy.kalman import KalmanFilter as FpKf

    rows = []
    epochs = 2000
    rng = np.random.default_rng(1)
    models = batch_models()
    cases = [(name, model, 0.0) for name, model in models.items()]
    cases.append((f"15/6, {missing:.0%} of the values missing", models["15/6"], missing))
    cases.append((f"12/6 (c. v.), {missing:.0%} missing", models["12/6 (constant velocity)"], missing))
    for name, (phi, q, h, r, p0), gap in cases:
        n, m = phi.shape[0], h.shape[0]
        zs = rng.normal(size=(epochs, m))
        if gap:
            zs[rng.random(size=zs.shape) < gap] = np.nan

        def fp_loop():
            fp = FpKf(dim_x=n, dim_z=m)
            fp.F, fp.Q, fp.H, fp.R, fp.P = phi, q, h, r, p0.copy()
            fp.x = np.zeros((n, 1))
            for z in zs:
                fp.predict()
                if gap:
                    ok = ~np.isnan(z)
                    if ok.any():
                        fp.update(z[ok].reshape(-1, 1), R=r[np.ix_(ok, ok)], H=h[ok])
                else:
                    fp.update(z)

        def ours():
            return aidnav.KalmanFilter(np.zeros(n), p0).batch(zs, phi, q, h, r)

        # Epochs the batch computed in the steady state (state only; "-"
        # from a build without it).
        steady = ours().get("steady_epochs", "-")
        t_fp = median_per_call(fp_loop, 1, repeat=5) / epochs
        t_us = median_per_call(ours, 3, repeat=5) / epochs
        rows.append((f"batch {name}, per epoch", t_fp, t_us, step_flops(n, m), steady))
    return rows


def process_row():
    cli = os.environ.get("AIDNAV_CLI") or shutil.which("aidnav")
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    if cli is None and (target / "release" / "aidnav").exists():
        cli = str(target / "release" / "aidnav")
    if cli is None:
        return None
    drive = ROOT / "examples" / "drive_0708.toml"
    t_cli, t_py = [], []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run([cli, "process", str(drive), "--out", "/tmp/aidnav-bench-cli"], check=True, capture_output=True)
        t_cli.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        aidnav.process(drive).write("/tmp/aidnav-bench-py")
        t_py.append(time.perf_counter() - t0)
    return ("process drive (read, run, score, write)", sorted(t_cli)[1], sorted(t_py)[1])


def dask_row(runs=1000):
    from dask.distributed import Client, LocalCluster

    # One core per worker: each worker's Rust runs use a rayon pool of this
    # size (the workers inherit the variable), so one worker is one core and
    # two workers are two, on this 2-core machine.
    os.environ["RAYON_NUM_THREADS"] = "1"
    times = {}
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
            with Client(cluster) as client:
                aidnav.monte_carlo("anomalies", 8, 1, client=client)  # warm the workers
                t0 = time.perf_counter()
                summary = aidnav.monte_carlo("anomalies", runs, 20261123, client=client)
                times[workers] = time.perf_counter() - t0
                times[f"rms{workers}"] = summary["rms"]["developed"]
    assert times["rms1"] == times["rms2"], "1 and 2 workers disagree"
    return (f"reproduce anomalies {runs} runs, LocalCluster", times[1], times[2])


def main():
    quick = "--quick" in sys.argv
    if "--batch" in sys.argv:
        for label, ref, ours, flops, steady in batch_rows():
            print(f"{label:48} {ref * 1e6:9.2f} µs {ours * 1e6:9.2f} µs {ref / ours:6.1f}×  {flops / ours / 1e9:5.2f} Gflop/s, 50× needs {flops * 50 / ref / 1e9:5.2f}  steady {steady}/2000")
        return
    print(f"aidnav {aidnav.__version__}, numpy {np.__version__}, python {sys.version.split()[0]}, {os.cpu_count()} cores")
    print(f"{'case':48} {'reference':>12} {'aidnav':>12} {'ratio':>7}")
    for label, ref, ours in step_rows():
        print(f"{label:48} {ref * 1e6:9.2f} µs {ours * 1e6:9.2f} µs {ref / ours:6.1f}×   (FilterPy / aidnav)")
    # The floor: 50× FilterPy leaves FilterPy/50 per epoch for the step's
    # flops; "needs" is the rate that takes (one core).
    for label, ref, ours, flops, steady in batch_rows():
        print(
            f"{label:48} {ref * 1e6:9.2f} µs {ours * 1e6:9.2f} µs {ref / ours:6.1f}×   (FilterPy / aidnav)"
            f"  {flops / ours / 1e9:5.2f} Gflop/s done, 50× needs {flops * 50 / ref / 1e9:5.2f}, steady {steady}/2000 epochs"
        )
    row = process_row()
    if row:
        label, cli, py = row
        print(f"{label:48} {cli:10.2f} s {py:10.2f} s {py / cli:6.3f}   (Python / CLI)")
    if not quick:
        label, one, two = dask_row()
        print(f"{label:48} {one:10.2f} s {two:10.2f} s {one / two:6.2f}×   (1 worker / 2 workers)")


if __name__ == "__main__":
    main()
