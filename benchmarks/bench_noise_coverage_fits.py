r"""Coverage and efficiency of the IDIM, forced-response and friction-map fits, every noise class.

Issue 24: for each estimator, noise class and quantisation, ``--repeats`` seeded
realisations are identified and the 95 % intervals ``±1.96 s.e.`` checked against the truth
(binomial sd of a 95 % coverage: 1.5 % at 200 repeats, 3.4 % at 40). Printed per estimator,
noise and parameter: coverage; sd/se, the observed sd over the mean reported s.e. (1 when the
error bars are honest); bias/se, the mean error over the mean s.e.; efficiency, the
Cramér–Rao variance over the observed one (:func:`driveid.identify.crlb.regression_crlb`
with the record's noise-free sensitivities and a long AR fit of the class's spectrum; for
``+q`` rows the bound ignores the encoder, which only adds error); the realisations that
ran, failed (``err``: an IdentificationError) and warned (``warn``: a warning in the
Estimate or a DriveIdWarning).

Noise classes (``_noise_classes.py``, shared with ``bench_noise_coverage.py``): white,
AR(1) 0.5 / 0.9 / 0.97, a 4th-order Butterworth low-pass at 5x the bandwidth that matters
for each record (below), 1/f-like (AR(1) poles 0.5, 0.9, 0.99, 0.999 per sample) and a 50 Hz
mains line (70 % of the variance) plus white noise. All records at 500 Hz. ``+q``: the
measured position rounded to an encoder step (random phase), size per record below.

``idim`` (``estimate_idim(cutoff_hz=50, decimate=1, edge=20, noise="ar")``; ``idim-dec10``
the default decimation by 10 and edge, 290 rows of block means, what a user gets; ``idim-white``
the same with ``noise="white"``, the ordinary least-squares error bars of before issue 24):
6 s, ``x = 0.05 sin(0.8πt) + 0.01 sin(2.2πt)`` [m], force ``u = 10 a + 50 v + 3 sgn v − 0.5``
[N] plus noise of sd 0.5 N on ``u`` (the force or current channel). Truth M = 10 kg,
Fv = 50 N·s/m, Fc = 3 N, offset = −0.5 N. Low-pass at 5.5 Hz (5x the top motion frequency,
1.1 Hz); encoder step 1 µm.

``forced`` (``estimate_forced_response(settle_tol=0.05)``): a linear J = 0.02 kg·m²,
c = 0.05 N·m·s/rad, K = 16 N·m/rad (ω0 = 28.3 rad/s, 4.5 Hz) driven by a unit torque at
0.6, 1.0 and 1.6 ω0, 20 periods each, exact steady response plus noise on ``x`` of sd 1 % of
the smallest amplitude (0.40 mrad). Low-pass at 22.5 Hz (5x the mode); encoder step
2π/8000 rad (8000 counts/rev, q/√12 = 0.23 mrad). The bound counts each run's offset and
drift, which the sine fits estimate.

``friction-map`` (``estimate_friction_map(models=("coulomb_viscous",))``, velocity from the
differentiated position): a slow speed-controlled staircase, plateaus of 1.5 s at
+s, −s for s = 0.01, 0.02, 0.04, 0.07, 0.1 m/s joined by 0.2 s raised-cosine speed changes
(17 s); force ``u = M a + sgn v (Fc± + Fv± |v|)`` with M = 10 kg, Fc+ = 3.5 N, Fc− = 2.5 N,
Fv+ = 55 N·s/m, Fv− = 45 N·s/m, plus noise of sd 0.5 N on ``u``. Low-pass at 25 Hz (5x the
speed profile's 5 Hz, the inverse of its transition time); encoder step 1 µm. The bound is
that of the whole record with M unknown: the map uses the plateaus alone, so an
efficiency below 1 is expected of it.

    python benchmarks/bench_noise_coverage_fits.py --repeats 200 --workers 16   # every cell
    python benchmarks/bench_noise_coverage_fits.py --repeats 20 --estimators idim \
        --classes white,ar0.9 --quantised no                                   # a quick look
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import time
import warnings
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass

import numpy as np
from _noise_classes import CLASSES, noise, noise_ar
from threadpoolctl import threadpool_limits

from driveid.errors import DriveIdError, DriveIdWarning
from driveid.identify.crlb import regression_crlb
from driveid.identify.forced.forced import estimate_forced_response
from driveid.identify.friction.friction_map import estimate_friction_map
from driveid.identify.friction.idim import estimate_idim
from driveid.io.record import Record

FS = 500.0
SEED = 2024


def _encoder(x: np.ndarray, quantum: float, rng: np.random.Generator,
             quantised: bool) -> np.ndarray:
    """Round ``x`` to the encoder grid of random phase (drawn always: paired realisations)."""
    phase = rng.uniform(0.0, quantum)
    return quantum * np.round((x - phase) / quantum) + phase if quantised else x


# --- IDIM ------------------------------------------------------------------------------

IDIM_TRUTH = {"M": 10.0, "Fv": 50.0, "Fc": 3.0, "offset": -0.5}


def _idim_motion() -> tuple[np.ndarray, ...]:
    t = np.arange(3000) / FS
    w1, w2 = 2 * np.pi * 0.4, 2 * np.pi * 1.1
    x = 0.05 * np.sin(w1 * t) + 0.01 * np.sin(w2 * t)
    v = 0.05 * w1 * np.cos(w1 * t) + 0.01 * w2 * np.cos(w2 * t)
    a = -0.05 * w1**2 * np.sin(w1 * t) - 0.01 * w2**2 * np.sin(w2 * t)
    return t, x, v, a


def _idim_records(kind: str, quantised: bool, rng: np.random.Generator) -> list[Record]:
    t, x, v, a = _idim_motion()
    tr = IDIM_TRUTH
    u = tr["M"] * a + tr["Fv"] * v + tr["Fc"] * np.sign(v) + tr["offset"]
    u = u + noise(kind, t.size, rng, fs=FS, sigma=0.5, lowpass_hz=5.5)
    x = _encoder(x, 1e-6, rng, quantised)
    return [Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})]


def _idim_jacobians() -> list[np.ndarray]:
    _, _, v, a = _idim_motion()
    return [np.column_stack([a, v, np.sign(v), np.ones_like(v)])]


def _fit_idim(records: list[Record], noise_kind: str = "ar"):
    # the default cut-off sensitivity check stays on: its warning is part of what a user sees
    return estimate_idim(records, cutoff_hz=50.0, decimate=1, edge=20, noise=noise_kind)


# --- forced response -------------------------------------------------------------------

FORCED_TRUTH = {"J": 0.02, "c_mean": 0.05, "K": 16.0}
_RATIOS = (0.6, 1.0, 1.6)


def _forced_runs() -> list[tuple[float, np.ndarray, complex]]:
    tr = FORCED_TRUTH
    w0 = math.sqrt(tr["K"] / tr["J"])
    runs = []
    for ratio in _RATIOS:
        w = ratio * w0
        t = np.arange(int(20 * 2 * math.pi / w * FS) + 1) / FS
        runs.append((w, t, tr["K"] - tr["J"] * w**2 + 1j * w * tr["c_mean"]))
    return runs


def _forced_sd() -> float:
    return 0.01 * min(1.0 / abs(H) for _, _, H in _forced_runs())


def _forced_records(kind: str, quantised: bool, rng: np.random.Generator) -> list[Record]:
    sd = _forced_sd()
    out = []
    for w, t, H in _forced_runs():
        x = np.imag(np.exp(1j * w * t) / H)
        x = _encoder(x + noise(kind, t.size, rng, fs=FS, sigma=sd, lowpass_hz=22.5),
                     2 * math.pi / 8000, rng, quantised)
        out.append(Record(t=t, x=x, u=np.sin(w * t)))
    return out


def _forced_jacobians() -> list[np.ndarray]:
    runs = _forced_runs()
    jacs = []
    for r, (w, t, H) in enumerate(runs):
        e = np.exp(1j * w * t) / H**2  # d(e^{iwt}/H)/dθ = -e^{iwt} dH/dθ / H²
        cols = [np.imag(-e * -(w**2)), np.imag(-e * 1j * w), np.imag(-e)]
        nuisance = np.zeros((t.size, 2 * len(runs)))
        nuisance[:, 2 * r] = 1.0        # offset of this run's sine fit
        nuisance[:, 2 * r + 1] = t      # its linear drift
        jacs.append(np.column_stack(cols + [nuisance]))
    return jacs


def _fit_forced(records: list[Record]):
    # steady from the first sample; the settling check (white per-period errors) would
    # read coloured noise as an unsettled transient at the default 1e-4
    return estimate_forced_response(records, settle_tol=0.05)


# --- friction map ----------------------------------------------------------------------

MAP_TRUTH = {"Fc_plus": 3.5, "Fv_plus": 55.0, "Fc_minus": 2.5, "Fv_minus": 45.0}
_MAP_M, _PLATEAU, _RAMP = 10.0, 1.5, 0.2
_SPEEDS = (0.01, 0.02, 0.04, 0.07, 0.1)


def _map_motion() -> tuple[np.ndarray, ...]:
    """Closed-form position, speed and acceleration of the staircase."""
    levels = [0.0] + [s * sign for s in _SPEEDS for sign in (1.0, -1.0)]
    t = np.arange(int(round((len(levels) - 1) * (_RAMP + _PLATEAU) * FS))) / FS
    x, v, a = np.zeros_like(t), np.zeros_like(t), np.zeros_like(t)
    start, x_start = 0.0, 0.0
    for v1, v2 in zip(levels[:-1], levels[1:], strict=True):
        tau = t - start
        ramp = (tau >= 0) & (tau < _RAMP)
        flat = (tau >= _RAMP) & (tau < _RAMP + _PLATEAU)
        s = tau[ramp]
        dv = v2 - v1
        v[ramp] = v1 + dv * (1 - np.cos(math.pi * s / _RAMP)) / 2
        a[ramp] = dv * math.pi / (2 * _RAMP) * np.sin(math.pi * s / _RAMP)
        x[ramp] = x_start + v1 * s + dv / 2 * (s - _RAMP / math.pi * np.sin(math.pi * s / _RAMP))
        x_ramp_end = x_start + v1 * _RAMP + dv / 2 * _RAMP
        v[flat] = v2
        x[flat] = x_ramp_end + v2 * (tau[flat] - _RAMP)
        x_start = x_ramp_end + v2 * _PLATEAU
        start += _RAMP + _PLATEAU
    return t, x, v, a


def _map_records(kind: str, quantised: bool, rng: np.random.Generator) -> list[Record]:
    t, x, v, a = _map_motion()
    tr = MAP_TRUTH
    friction = np.where(v > 0, tr["Fc_plus"] + tr["Fv_plus"] * v, 0.0) \
        + np.where(v < 0, -tr["Fc_minus"] + tr["Fv_minus"] * v, 0.0)
    u = _MAP_M * a + friction + noise(kind, t.size, rng, fs=FS, sigma=0.5, lowpass_hz=25.0)
    x = _encoder(x, 1e-6, rng, quantised)
    return [Record(t=t, x=x, u=u, meta={"units": {"x": "m", "u": "N"}})]


def _map_jacobians() -> list[np.ndarray]:
    _, _, v, a = _map_motion()
    pos, neg = (v > 0).astype(float), (v < 0).astype(float)
    # Fc_plus, Fv_plus, Fc_minus, Fv_minus, then the inertia as a nuisance
    return [np.column_stack([pos, v * pos, -neg, v * neg, a])]


def _fit_map(records: list[Record]):
    return estimate_friction_map(records, models=("coulomb_viscous",)).estimate


# --- the benchmark ---------------------------------------------------------------------


@dataclass(frozen=True)
class _Design:
    truth: dict[str, float]
    records: Callable[[str, bool, np.random.Generator], list[Record]]
    fit: Callable[[list[Record]], object]
    jacobians: Callable[[], list[np.ndarray]]
    sigma: Callable[[], float]
    lowpass_hz: float


DESIGNS = {
    "idim": _Design(IDIM_TRUTH, _idim_records, _fit_idim, _idim_jacobians, lambda: 0.5, 5.5),
    "idim-dec10": _Design(IDIM_TRUTH, _idim_records,
                          lambda r: estimate_idim(r, cutoff_hz=50.0, sensitivity=False),
                          _idim_jacobians, lambda: 0.5, 5.5),
    "idim-white": _Design(IDIM_TRUTH, _idim_records, lambda r: _fit_idim(r, "white"),
                          _idim_jacobians, lambda: 0.5, 5.5),
    "forced": _Design(FORCED_TRUTH, _forced_records, _fit_forced, _forced_jacobians,
                      _forced_sd, 22.5),
    "friction-map": _Design(MAP_TRUTH, _map_records, _fit_map, _map_jacobians, lambda: 0.5,
                            25.0),
}
DEFAULT_ESTIMATORS = ("idim", "forced", "friction-map")


def one_fit(task: tuple[str, str, bool, int]) -> tuple[dict | None, bool]:
    """Identify realisation ``i`` of one cell: ({name: (value, s.e.)} or None, warned)."""
    estimator, kind, quantised, i = task
    design = DESIGNS[estimator]
    rng = np.random.default_rng([SEED, i])  # the same seed whatever the worker count
    records = design.records(kind, quantised, rng)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            est = design.fit(records)
        except DriveIdError:
            return None, False
    warned = bool(est.warnings) or any(issubclass(w.category, DriveIdWarning) for w in caught)
    return {n: (est.value(n), est.stderr(n)) for n in design.truth}, warned


@functools.lru_cache
def bound_sd(estimator: str, kind: str) -> dict[str, float]:
    """Coloured-noise Cramér–Rao sd of every parameter of the cell."""
    design = DESIGNS[estimator]
    ar = noise_ar(kind, fs=FS, lowpass_hz=design.lowpass_hz)
    cov = regression_crlb(design.jacobians(), noise_std=design.sigma(), noise_ar=ar or None)
    return {n: float(math.sqrt(cov[j, j])) for j, n in enumerate(design.truth)}


def _one_thread() -> None:
    threadpool_limits(1)


def summarise(estimator: str, kind: str, quantised: bool,
              results: list[tuple[dict | None, bool]]) -> list[str]:
    """The printed rows of one cell."""
    truth = DESIGNS[estimator].truth
    ok = [r for r, _ in results if r is not None]
    failures = len(results) - len(ok)
    warned = sum(w for _, w in results)
    try:
        bound = bound_sd(estimator, kind)
    except DriveIdError:
        bound = {}
    label = kind + ("+q" if quantised else "")
    rows = []
    for name, true in truth.items():
        vals = np.array([r[name][0] for r in ok])
        ses = np.array([r[name][1] for r in ok])
        if vals.size < 3:
            rows.append(f"{estimator:<13}{label:<10}{name:<9}  too few fits ({vals.size})")
            continue
        sd, se = float(np.std(vals, ddof=1)), float(np.mean(ses))
        cover = float(np.mean(np.abs(vals - true) <= 1.96 * ses))
        eff = f"{bound[name] ** 2 / sd ** 2:11.2f}" if name in bound else " " * 11
        rows.append(f"{estimator:<13}{label:<10}{name:<9}{cover:9.2f}{sd / se:7.2f}"
                    f"{(vals.mean() - true) / se:8.2f}{eff}{vals.size:5d}{failures:4d}"
                    f"{warned:5d}")
    return rows


def _timing(estimators: list[str], classes: list[str]) -> dict[tuple[str, str], float]:
    """Seconds of one fit of each estimator and class here (after one warm-up fit each)."""
    out = {}
    with threadpool_limits(1):
        for est in estimators:
            one_fit((est, "white", False, 0))
            for kind in classes:
                start = time.perf_counter()
                one_fit((est, kind, False, 1))
                out[est, kind] = time.perf_counter() - start
    return out


def main() -> None:
    """Print the coverage table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=200)
    ap.add_argument("--classes", default=",".join(CLASSES))
    ap.add_argument("--estimators", default=",".join(DEFAULT_ESTIMATORS),
                    help=f"comma-separated of {', '.join(DESIGNS)}")
    ap.add_argument("--quantised", choices=["no", "yes", "both"], default="both")
    ap.add_argument("--workers", type=int, default=1, help="processes (one BLAS thread each)")
    args = ap.parse_args()
    estimators = args.estimators.split(",")
    classes = args.classes.split(",")
    bad = [e for e in estimators if e not in DESIGNS] + [c for c in classes if c not in CLASSES]
    if bad:
        ap.error(f"unknown estimator or class {bad}; estimators {list(DESIGNS)}, classes "
                 f"{list(CLASSES)}")
    quant = {"no": [False], "yes": [True], "both": [False, True]}[args.quantised]
    cells = [(e, k, q) for e in estimators for k in classes for q in quant]
    per_fit = _timing(estimators, classes)
    cost = sum(per_fit[e, k] for e, k, _ in cells)  # seconds for one realisation of each cell
    print("seconds a fit here (one thread, mean over the classes asked for): "
          + ", ".join(f"{e} {np.mean([per_fit[e, k] for k in classes]):.3f}"
                      for e in estimators))
    print(f"{len(cells)} cells x {args.repeats} repeats on {args.workers} worker(s): about "
          f"{cost * args.repeats / args.workers:.0f} s; 200 repeats of these cells on 16 "
          f"workers: about {cost * 200 / 16:.0f} s (from one fit per cell)", flush=True)
    print(f"{'estimator':<13}{'noise':<10}{'param':<9}{'coverage':>9}{'sd/se':>7}"
          f"{'bias/se':>8}{'efficiency':>11}{'runs':>5}{'err':>4}{'warn':>5}")
    tasks = [(e, k, q, i) for e, k, q in cells for i in range(args.repeats)]
    start = time.perf_counter()
    if args.workers > 1:
        os.environ["OMP_NUM_THREADS"] = "1"
        with ProcessPoolExecutor(args.workers, initializer=_one_thread) as pool:
            results = iter(pool.map(one_fit, tasks, chunksize=max(1, args.repeats // 4)))
            for e, k, q in cells:
                rows = summarise(e, k, q, [next(results) for _ in range(args.repeats)])
                print("\n".join(rows), flush=True)
    else:
        with threadpool_limits(1):
            for e, k, q in cells:
                cell_start = time.perf_counter()
                res = [one_fit((e, k, q, i)) for i in range(args.repeats)]
                print("\n".join(summarise(e, k, q, res)))
                print(f"# {e} {k}{'+q' if q else ''}: "
                      f"{(time.perf_counter() - cell_start) / args.repeats:.3f} s a fit",
                      flush=True)
    print(f"# {time.perf_counter() - start:.0f} s wall in all, {len(tasks)} fits")


if __name__ == "__main__":
    main()
