"""Online friction tracking (issue 17): bounded memory, speed, coverage and lag.

Workload: the drifting drive of ``tests/identify/test_online.py`` (J = 0.0115 kg·m², Coulomb
friction 0.10 N·m rising by 30 % with τ = 1200 s, viscous 0.002 N·m·s/rad drifting +50 %
over 2 h, asymmetric parts 0.0004 N·m·s/rad and 0.01 N·m), PD-tracking a two-sine
reference, command noise 0.02 N·m, generated chunk-wise (60 s chunks) by an RK4 integrator
and streamed into :func:`driveid.identify.friction.online.track_friction` (memory τ/10 = 120 s).

Printed per record length (0.5, 1, 2 h at 200 Hz):
* peak traced memory of the streaming tracker (tracemalloc; generator included) against the
  baseline of a batch least-squares fit that holds the regressor of the whole record;
* wall time of the tracker against the time to generate the data (same run);
* fraction of outputs inside the ±2σ bands for fk_mean and c_mean, compared with the
  truth one memory earlier (the stated lag), and without the lag correction.

Run: ``.venv/bin/python benchmarks/bench_tracking.py``.
"""

import sys
import time
import tracemalloc
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests.identify.test_online import TAU, c_true, drift_chunks, fk_true  # noqa: E402

from driveid.identify.friction.online import track_friction  # noqa: E402

FS = 200.0


def generate_only(hours):
    t0 = time.perf_counter()
    for _ in drift_chunks(hours=hours, fs=FS):
        pass
    return time.perf_counter() - t0


def streamed(hours):
    tracemalloc.start()
    t0 = time.perf_counter()
    res = track_friction(drift_chunks(hours=hours, fs=FS), drift_time=TAU, output_every=30.0)
    wall = time.perf_counter() - t0
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return res, wall, peak


def batch_baseline_peak(hours):
    """Peak memory of a batch LS that keeps the whole regressor (the baseline)."""
    tracemalloc.start()
    rows = []
    for ch in drift_chunks(hours=hours, fs=FS):
        v = ch["v"]
        rows.append(np.column_stack([np.gradient(v, 1 / FS), v, np.abs(v), np.sign(v),
                                     np.ones_like(v), ch["u"]]))
    data = np.vstack(rows)
    np.linalg.lstsq(data[:, :5], data[:, 5], rcond=None)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    return peak


def coverage(res, name, truth, lag):
    val, se = res.trajectory(name)
    late = res.t > 3 * res.memory
    return float(np.mean((np.abs(val - truth(res.t - lag)) <= 2 * se)[late]))


def main():
    drift_chunks(hours=1 / 60, fs=FS).__next__()  # compile the integrator
    print(f"{'hours':>5} {'track MB':>9} {'batch MB':>9} {'ratio':>6} {'track s':>8} "
          f"{'gen s':>6} {'fk cov':>7} {'c cov':>6} {'fk cov(no lag)':>15}")
    for hours in (0.5, 1.0, 2.0):
        gen = generate_only(hours)
        res, wall, peak = streamed(hours)
        base = batch_baseline_peak(hours)
        lag = res.lag
        print(f"{hours:5.1f} {peak / 1e6:9.2f} {base / 1e6:9.1f} {base / peak:6.0f} "
              f"{wall:8.1f} {gen:6.1f} {coverage(res, 'fk_mean', fk_true, lag):7.2f} "
              f"{coverage(res, 'c_mean', c_true, lag):6.2f} "
              f"{coverage(res, 'fk_mean', fk_true, 0.0):15.2f}")
    print(f"lag (memory of the window): {lag:.0f} s; rule: drift time {TAU:.0f} s / 10")


if __name__ == "__main__":
    main()
