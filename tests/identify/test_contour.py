"""Friction and backlash from simulated circle tests (issue 27, acceptance (b)).

Truth: the parameters of ``examples/drive_configs/contour_xy.toml``. The friction the
command sees is the sum over the bodies of an axis (motor bearings plus guides); the gap is
``gap_plus + gap_minus``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.contour.circle import (
    ContourRecord,
    compensation_from_estimate,
    estimate_contour,
)
from driveid.sim.contour import simulate_contour
from driveid.sim.contour_config import load_contour_config

EXAMPLE = "examples/drive_configs/contour_xy.toml"
CONFIG = load_contour_config(EXAMPLE)


def _truth(config):
    out = {}
    for a, axis in config.axes.items():
        bodies = axis.drive.bodies
        link = axis.drive.links[0]
        out[a] = {"fk_mean": sum(b.fk_mean for b in bodies),
                  "fk_delta": sum(b.fk_delta for b in bodies),
                  "c_mean": sum(b.c_mean for b in bodies),
                  "gap": link.gap_plus + link.gap_minus}
    return out


TRUTH = _truth(CONFIG)


def _with_path(radius, feed):
    return dataclasses.replace(CONFIG, path=dataclasses.replace(CONFIG.path, radius=radius,
                                                                feed=feed))


@pytest.fixture(scope="module")
def circles():
    """Noise-free simulated circles at three feeds and radii (shared by the tests)."""
    return {(r, f): simulate_contour(_with_path(r, f))
            for r, f in ((0.05, 0.1), (0.025, 0.1), (0.1, 0.25))}


@pytest.mark.parametrize("key", [(0.05, 0.1), (0.025, 0.1), (0.1, 0.25)])
def test_friction_and_gap_within_the_acceptance(circles, key):
    cfg = _with_path(*key)
    rec = ContourRecord.from_columns(circles[key].columns(cfg.noise))
    est = estimate_contour(rec, cfg, validate=False, compensation=False)
    for a, truth in TRUTH.items():
        fk = truth["fk_mean"]
        # the acceptance: fk_mean within 10 %, fk_delta within 0.15 fk_mean, gap
        # within 10 %; measured today the errors are below 0.1 %, 0.2 % and 3.5 %, so
        # tighter bounds check the estimator, not only the acceptance
        assert abs(est.value(f"{a}.fk_mean") / fk - 1) < 0.01
        assert abs(est.value(f"{a}.fk_delta") - truth["fk_delta"]) < 0.01 * fk
        assert abs(est.value(f"{a}.c_mean") / truth["c_mean"] - 1) < 0.02
        assert abs(est.value(f"{a}.gap") / truth["gap"] - 1) < 0.05
        for name in ("fk_mean", "fk_delta", "c_mean", "gap"):
            assert est.stderr(f"{a}.{name}") > 0


def test_seeded_monte_carlo_intervals_cover_the_truth(circles):
    # small MC over the measurement noise (benchmarks/bench_contour.py runs the large one
    # over feeds, radii and start angles): every 95 % interval should hold the truth in at
    # least 8 of 10 runs (the standard errors include the model-error part of the residual,
    # so they are conservative for noise alone: measured sd/se 0.2-0.8)
    cfg = _with_path(0.025, 0.1)
    res = circles[(0.025, 0.1)]
    hits = {}
    for seed in range(10):
        noise = dataclasses.replace(cfg.noise, seed=seed)
        est = estimate_contour(ContourRecord.from_columns(res.columns(noise)), cfg,
                               validate=False, compensation=False)
        for a, truth in TRUTH.items():
            for name, value in truth.items():
                z = (est.value(f"{a}.{name}") - value) / est.stderr(f"{a}.{name}")
                hits.setdefault(f"{a}.{name}", []).append(abs(z) < 1.96)
    assert all(np.mean(h) >= 0.8 for h in hits.values()), {k: np.mean(h)
                                                            for k, h in hits.items()}


def test_validation_and_compensation_preview(circles):
    cfg = _with_path(0.025, 0.1)
    rec = ContourRecord.from_columns(circles[(0.025, 0.1)].columns(cfg.noise))
    est = estimate_contour(rec, cfg)
    # the identified model reproduces the measured radial deviation (glitches and steps)
    assert est.diagnostics["validation"]["radial_fit_pct"] > 90
    comp = est.diagnostics["compensation"]
    # the acceptance: the identified compensation lowers the peak >= 3x
    assert comp["peak_ratio"] >= 3
    for wrong in ("friction_low", "friction_high"):  # ±20 % friction still helps
        assert comp[wrong]["peak"] < comp["without"]["peak"]
    # and in the true plant too (the record's own config), not only in the model
    truth_comp = simulate_contour(cfg, compensation=compensation_from_estimate(est, config=cfg))
    assert circles[(0.025, 0.1)].metrics["peak"] / truth_comp.metrics["peak"] >= 3


def test_whiteness_is_reported():
    cfg = _with_path(0.025, 0.1)
    res = simulate_contour(cfg)
    est = estimate_contour(ContourRecord.from_columns(res.columns(cfg.noise)), cfg,
                           validate=False, compensation=False)
    for a in ("x", "y"):
        assert 0.0 <= est.diagnostics[f"{a}.whiteness_p"] <= 1.0


def test_without_motor_encoder_the_gap_is_not_identified(circles):
    cfg = _with_path(0.05, 0.1)
    cols = circles[(0.05, 0.1)].columns(cfg.noise)
    del cols["x_motor"]
    est = estimate_contour(ContourRecord.from_columns(cols), cfg, validate=False,
                           compensation=False)
    assert math.isnan(est.value("x.gap"))
    assert any("x_motor" in w for w in est.warnings)
    assert math.isfinite(est.value("y.gap"))


def test_ball_bar_record_gives_coulomb_friction_and_gap(circles):
    # radial deviation only (1e-7 m noise), the config's friction and gaps 15 % off as the
    # start: fk_mean and the gap are fitted, c_mean and fk_delta are given (and say so)
    cfg = _with_path(0.025, 0.1)
    res = circles[(0.025, 0.1)]
    rng = np.random.default_rng(3)
    rec = ContourRecord(t=res.t, reference={}, position={},
                        radial=res.metrics["radial"] + 1e-7 * rng.standard_normal(res.t.size))
    axes = {}
    for a, ax in cfg.axes.items():
        bodies = tuple(dataclasses.replace(b, fk_mean=0.85 * b.fk_mean, fs_mean=None)
                       for b in ax.drive.bodies)
        links = tuple(dataclasses.replace(ln, gap_plus=1.15 * ln.gap_plus,
                                          gap_minus=1.15 * ln.gap_minus)
                      for ln in ax.drive.links)
        axes[a] = dataclasses.replace(ax, drive=dataclasses.replace(ax.drive, bodies=bodies,
                                                                    links=links))
    est = estimate_contour(rec, dataclasses.replace(cfg, axes=axes))
    assert est.method == "contour-ballbar"
    for a, truth in TRUTH.items():
        # acceptance: within 10 %; measured today within 0.3 % (the fitted model puts all
        # friction on the table, the truth has some on the motor)
        assert abs(est.value(f"{a}.fk_mean") / truth["fk_mean"] - 1) < 0.02
        assert abs(est.value(f"{a}.gap") / truth["gap"] - 1) < 0.02
        assert est[f"{a}.c_mean"].fixed and est[f"{a}.fk_delta"].fixed
    assert any("taken from the config" in w for w in est.warnings)
    short = ContourRecord(t=res.t[:50], reference={}, position={},
                          radial=res.metrics["radial"][:50])
    with pytest.raises(IdentificationError, match="no constant-feed part"):
        estimate_contour(short, cfg)


def test_missing_command_and_bad_settings():
    cfg = _with_path(0.05, 0.1)
    t = np.arange(100) / 2000.0
    rec = ContourRecord(t=t, reference={"x": t, "y": t}, position={"x": t, "y": t})
    with pytest.raises(RecordError, match="command of axis x"):
        estimate_contour(rec, cfg)
    with pytest.raises(ParameterError, match="min_speed_fraction"):
        estimate_contour(rec, cfg, min_speed_fraction=1.5)
    with pytest.raises(ParameterError, match="no per-axis friction"):
        compensation_from_estimate({"driveid": "0", "schema": "driveid-result/1",
                                    "method": "x", "parameters": {}})
