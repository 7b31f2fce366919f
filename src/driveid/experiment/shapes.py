"""Simulated records of every test shape ``identify auto`` recognises, with known truth.

One function, :func:`simulate_shape_record`, draws a plant (a rigid body with asymmetric
viscous and Coulomb friction, a spring where the test needs one) and runs the test on it:
a free decay (exact stick–slip, :func:`driveid.sim.simulate_free_decay`), a PHO run
(delayed PD, :class:`driveid.experiment.plant.SimulatedPlant`), a sine, a DC-biased square
wave, force ramps with dwells, PRBS or multisine excitation
(:mod:`driveid.signal.excitation`), speed plateaus, and an operating record (point-to-point
moves under PD control). The position gets white noise and, at random, encoder
quantisation; the force gets noise of its own. Used by the classifier's tests and by
``benchmarks/bench_auto.py`` (confusion table).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from driveid.errors import ParameterError
from driveid.io.record import Record
from driveid.signal import excitation as exc
from driveid.sim.drive import simulate_drive
from driveid.sim.drive_types import BodyParams, DriveParams, PDFeedback
from driveid.sim.oscillator import OscillatorParams, measure, simulate_free_decay

__all__ = ["SHAPE_GENERATORS", "simulate_shape_record"]


def _plant(rng: np.random.Generator, spring: bool) -> dict[str, float]:
    J = float(rng.uniform(0.5, 2.0))
    omega0 = float(rng.uniform(3.0, 12.0))
    return {"J": J, "K": J * omega0**2 if spring else 0.0,
            "c_mean": float(rng.uniform(0.02, 0.1)) * 2 * J * omega0,
            "c_delta": float(rng.uniform(-0.2, 0.2)) * 0.05 * J * omega0,
            "fk_mean": float(rng.uniform(0.02, 0.1)) * J * omega0**2 * 0.1,
            "fk_delta": float(rng.uniform(-0.3, 0.3)) * 0.01 * J * omega0**2}


def _forced(rng, truth, u, fs, x0=0.0) -> Record:
    body = BodyParams(**truth)
    res = simulate_drive(DriveParams(bodies=(body,)), duration=(u.size - 1) / fs, fs=fs,
                         x0=[x0], torque=u[None, :])
    return Record(t=res.t, x=res.x[0], u=u[:res.t.size])


def _free_decay(rng, fs):
    truth = _plant(rng, True)
    p = OscillatorParams(**truth)
    x0 = float(rng.choice([-1, 1]) * rng.uniform(0.5, 2.0))
    rec = simulate_free_decay(p, x0=x0, duration=float(rng.uniform(8, 20)), fs=fs).record
    return rec.replace(u=None), truth


def _pho(rng, fs):
    from driveid.experiment.plant import SimulatedPlant

    truth = _plant(rng, False)
    P = truth["J"] * float(rng.uniform(20, 80))
    D = truth["J"] * float(rng.uniform(-0.3, 0.5))
    plant = SimulatedPlant(DriveParams(bodies=(BodyParams(**truth),)))
    rec = plant.run_pd(P=P, D=D, x0=float(rng.uniform(0.5, 1.5)), duration=5.0, fs=fs)
    return rec, {**truth, "P": P, "D": D}


def _sine(rng, fs):
    truth = _plant(rng, True)
    f0 = math.sqrt(truth["K"] / truth["J"]) / (2 * math.pi)
    sig = exc.sine(frequency=f0 * float(rng.uniform(0.5, 1.5)), duration=30.0, fs=fs,
                   amplitude=5 * truth["fk_mean"] + 0.5)
    return _forced(rng, truth, np.asarray(sig.u), fs), truth


def _step(rng, fs):
    truth = _plant(rng, True)
    f0 = math.sqrt(truth["K"] / truth["J"]) / (2 * math.pi)
    amp = 5 * truth["fk_mean"] + 0.5
    sig = exc.square_wave(frequency=f0 / float(rng.uniform(6, 12)), duration=12.0, fs=fs,
                          amplitude=amp, bias=amp * float(rng.uniform(0, 1)))
    return _forced(rng, truth, np.asarray(sig.u), fs), truth


def _ramp(rng, fs):
    truth = _plant(rng, False)
    amp = truth["fk_mean"] * float(rng.uniform(1.5, 3.0)) + 0.05
    sig = exc.ramps_with_dwell(amplitude=amp, ramp_time=float(rng.uniform(1, 3)),
                               dwell_time=float(rng.uniform(0.5, 1.5)), fs=fs, n_cycles=2)
    return _forced(rng, truth, np.asarray(sig.u), fs), truth


def _broadband(rng, fs):
    truth = _plant(rng, True)
    f0 = math.sqrt(truth["K"] / truth["J"]) / (2 * math.pi)
    amp = 5 * truth["fk_mean"] + 1.0
    if rng.uniform() < 0.5:
        sig = exc.prbs(f_clock=min(10 * f0, fs / 4), duration=10.0, fs=fs, amplitude=amp,
                       )
    else:
        sig = exc.multisine(f_min=0.2 * f0, f_max=min(5 * f0, fs / 4), duration=10.0, fs=fs,
                            amplitude=amp)
    return _forced(rng, truth, np.asarray(sig.u), fs), truth


def _plateaus(rng, fs):
    truth = _plant(rng, False)
    truth["c_mean"] = max(truth["c_mean"], 0.5 * truth["J"])  # settles within ~2 s
    tau = truth["J"] / truth["c_mean"]
    levels = rng.permutation([1.0, 2.0, 3.0, -1.0, -2.0, -3.0])
    hold = max(6 * tau, 1.0)
    n_hold = int(hold * fs)
    u = np.concatenate([np.full(n_hold, truth["fk_mean"] * 1.2 + lv * truth["c_mean"] * 0.5
                                if lv > 0 else -truth["fk_mean"] * 1.2 + lv * truth["c_mean"]
                                * 0.5) for lv in levels])
    return _forced(rng, truth, u, fs), truth


def _operating(rng, fs):
    truth = _plant(rng, False)
    n = int(20.0 * fs)
    t = np.arange(n) / fs
    # point-to-point moves with smooth (raised-cosine) transitions and random dwells
    ref = np.zeros(n)
    pos, k = 0.0, 0
    while k < n:
        move = int(float(rng.uniform(0.3, 1.0)) * fs)
        dwell = int(float(rng.uniform(0.0, 0.8)) * fs)
        target = float(rng.uniform(-2, 2))
        s = 0.5 - 0.5 * np.cos(np.pi * np.arange(move) / max(move - 1, 1))
        seg = np.r_[pos + (target - pos) * s, np.full(dwell, target)]
        ref[k:k + seg.size] = seg[:n - k]
        pos, k = target, k + seg.size
    P = truth["J"] * 400.0
    D = truth["J"] * 30.0
    params = DriveParams(bodies=(BodyParams(**truth),), feedback=PDFeedback(P=P, D=D))
    res = simulate_drive(params, duration=t[-1], fs=fs, reference=ref)
    cmd = res.command if res.command.ndim == 1 else res.command[0]
    return Record(t=res.t, x=res.x[0], u=cmd), truth


#: Generators by shape name: ``f(rng, fs) -> (Record, truth dict)``.
SHAPE_GENERATORS = {"free-decay": _free_decay, "pho": _pho, "sine": _sine, "step": _step,
                    "ramp": _ramp, "broadband": _broadband, "plateaus": _plateaus,
                    "operating": _operating}


def simulate_shape_record(shape: str, rng: np.random.Generator | int | None = None, *,
                          fs: float | None = None, noise: float | None = None
                          ) -> tuple[Record, dict[str, Any]]:
    """Simulate one record of a test shape on a random plant, with measurement noise.

    Parameters
    ----------
    shape : str
        A key of :data:`SHAPE_GENERATORS`.
    rng : Generator or int, optional
        Random generator or seed.
    fs : float, optional
        Sample rate [Hz]; default drawn from 200, 500, 1000, 2000.
    noise : float, optional
        Position noise relative to the record's range [-]; default drawn from 1e-4..1e-2.

    Returns
    -------
    record : Record
        ``t`` [s], ``x`` [rad], ``u`` [N·m] (none for a free decay).
    truth : dict
        The plant's ``J, K, c_mean, c_delta, fk_mean, fk_delta`` [SI] (and P, D).

    Raises
    ------
    ParameterError
        For an unknown shape.
    """
    if shape not in SHAPE_GENERATORS:
        raise ParameterError(f"unknown test shape {shape!r}; choose one of "
                             f"{', '.join(SHAPE_GENERATORS)}")
    gen = np.random.default_rng(rng)
    fs = float(fs) if fs is not None else float(gen.choice([200.0, 500.0, 1000.0, 2000.0]))
    rel = float(noise) if noise is not None else float(10 ** gen.uniform(-4, -2))
    rec, truth = SHAPE_GENERATORS[shape](gen, fs)
    # sensors resolve far finer than the travel: noise relative to the oscillation, or to
    # one second of travel for records that move far (plateaus, ramps, operating)
    speed = float(np.max(np.abs(np.diff(rec.x)))) * fs
    span = min(float(np.ptp(rec.x)), speed * 1.0) or 1.0
    counts = float(gen.choice([0, 0, 4096, 16384]))
    rec = measure(rec, noise_std=rel * span, counts_per_rev=counts or None, rng=gen)
    if rec.u is not None and shape != "pho":
        u = np.asarray(rec.u, float)
        u_noise = rel * float(np.ptp(u) or 1.0) * gen.standard_normal(u.size)
        rec = rec.replace(u=u + u_noise)
    return rec, truth
