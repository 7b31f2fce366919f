"""Blueprints and drift tests against closed forms and seeded synthetic histories."""

from __future__ import annotations

import datetime as dt
import json
import math

import numpy as np
import pytest
from click.testing import CliRunner
from scipy.stats import norm

from driveid.catalog import Catalog, CatalogEntry
from driveid.commands.health import blueprint_group, health_command
from driveid.errors import ConfigError, FileFormatError
from driveid.health import (
    assess_axis,
    cusum_threshold,
    level_threshold,
    make_blueprint,
    read_blueprint,
    write_blueprint,
)
from driveid.identify.core.estimate import Parameter

NOMINAL = {"K": 160.0, "fk_mean": 0.3}
BETWEEN = {"K": 6.0, "fk_mean": 0.02}   # axis-to-axis spread
WITHIN = {"K": 0.5, "fk_mean": 0.005}   # month-to-month scatter of one axis
SE = {"K": 0.2, "fk_mean": 0.002}       # reported standard errors


def _entry(machine, axis, month, values, se=SE, ident=0):
    params = {n: Parameter(v, se[n], "-") for n, v in values.items()}
    params["J"] = Parameter(1.0, math.nan, "kg", fixed=True)
    return CatalogEntry(id=ident, key=f"{machine}{axis}{month}", machine=machine, axis=axis,
                        machine_type="demo", measured_at=dt.datetime(2026, 1, 1)
                        + dt.timedelta(days=30 * month), method="logdec-lsq", status="ok",
                        error=None, driveid_version="test", parameters=params)


def _fleet(rng, n_axes=60, n_months=12, drift=None):
    """Healthy axes; ``drift`` = (parameter, per-month change, onset) applied to axis 0."""
    entries = []
    for a in range(n_axes):
        own = {n: NOMINAL[n] + BETWEEN[n] * rng.standard_normal() for n in NOMINAL}
        for m in range(n_months):
            values = {n: own[n] + WITHIN[n] * rng.standard_normal() for n in own}
            if drift is not None and a == 0 and m >= drift[2]:
                values[drift[0]] += drift[1] * (m - drift[2] + 1)
            entries.append(_entry(f"m{a:03d}", "x", m, values))
    return entries


def test_level_threshold_is_the_bonferroni_normal_quantile():
    # two-sided alpha/(2p) per parameter: P(|z| > c) = alpha/(2p)
    c = level_threshold(0.01, 5)
    assert 2 * norm.sf(c) == pytest.approx(0.001, rel=1e-9)


def test_cusum_threshold_matches_closed_form_for_one_step():
    # one step: S = max(0, z - k) > h  <=>  z > h + k, so h = isf(alpha/(4p)) - k exactly;
    # 2e5 draws put the 0.0025 quantile within about 2 % (binomial error of ~500 tail draws)
    h = cusum_threshold(0.01, 1, horizon=1, k_ref=0.5)
    assert h == pytest.approx(norm.isf(0.01 / 4) - 0.5, rel=0.03)


def test_cusum_threshold_grows_with_horizon_and_strictness():
    assert cusum_threshold(0.01, 5, horizon=12) > cusum_threshold(0.01, 5, horizon=3)
    assert cusum_threshold(0.01, 5) > cusum_threshold(0.1, 5)


def test_blueprint_recovers_spread_and_repeatability():
    rng = np.random.default_rng(1)
    bp = make_blueprint(_fleet(rng, n_axes=200), machine_type="demo", first=6)
    assert bp.monitored == ("K", "fk_mean")  # J is fixed: never monitored
    for n in NOMINAL:
        p = bp.parameters[n]
        # 200 axes: the median of axis means is within ~3·1.25·BETWEEN/sqrt(200) = 0.27 BETWEEN
        assert p.nominal == pytest.approx(NOMINAL[n], abs=0.3 * BETWEEN[n])
        # spread of single values is sqrt(BETWEEN² + WITHIN²); SD of 1200 draws of 200 axes
        # is within about 15 % (dominated by the 200 axis offsets)
        assert p.spread == pytest.approx(math.hypot(BETWEEN[n], WITHIN[n]), rel=0.15)
        # pooled within-axis SD from 1000 degrees of freedom: within about 7 % (3 sigma)
        assert p.repeatability == pytest.approx(WITHIN[n], rel=0.07)
        assert p.se_ref == SE[n]
    assert bp.correlation["matrix"].shape == (2, 2)


def test_healthy_axes_rarely_alarm():
    # 300 healthy axes × 12 months at alpha = 1 %: the Bonferroni design bounds the rate by
    # 1 %; with 3600 axis-months a true rate of 1 % would give 36 ± 6, so <= 1.5 % holds
    rng = np.random.default_rng(2)
    entries = _fleet(rng, n_axes=300)
    bp = make_blueprint(entries, machine_type="demo", first=3)
    by_axis = {}
    for e in entries:
        by_axis.setdefault(e.machine, []).append(e)
    verdicts = [v for rows in by_axis.values() for v in assess_axis(rows, bp).verdicts]
    assert verdicts.count("degraded") / len(verdicts) <= 0.015


def test_a_slow_drift_is_found_and_named():
    # fk_mean rising by one within-axis SD a month from month 4: far inside the blueprint's
    # band (BETWEEN = 4 WITHIN), so only the CUSUM on the axis's own history can see it
    rng = np.random.default_rng(3)
    entries = _fleet(rng, drift=("fk_mean", WITHIN["fk_mean"], 4))
    bp = make_blueprint(entries, machine_type="demo", first=3)
    rows = [e for e in entries if e.machine == "m000"]
    health = assess_axis(rows, bp)
    assert health.verdict == "degraded"
    assert health.reasons[0].startswith("degraded: fk_mean +")
    assert "baseline" in health.reasons[0] and "CUSUM" in health.reasons[0]
    assert "degraded" not in health.verdicts[:4]  # no alarm before the onset


def test_a_jump_outside_the_band_is_degraded_at_once():
    rng = np.random.default_rng(4)
    entries = _fleet(rng)
    bp = make_blueprint(entries, machine_type="demo", first=3)
    rows = [e for e in entries if e.machine == "m001"]
    values = {n: rows[-1].parameters[n].value for n in NOMINAL}
    values["K"] = NOMINAL["K"] - 8 * BETWEEN["K"]
    rows.append(_entry("m001", "x", 12, values))
    health = assess_axis(rows, bp)
    assert health.verdicts[-1] == "degraded"
    assert health.reasons[0].startswith("degraded: K -")


def test_a_noisy_measurement_is_judged_with_its_own_error():
    # the same 5-spread deviation with a standard error 10 spreads wide is not significant
    rng = np.random.default_rng(5)
    entries = _fleet(rng)
    bp = make_blueprint(entries, machine_type="demo", first=3)
    rows = [e for e in entries if e.machine == "m002"][:2]
    values = {"K": NOMINAL["K"] + 5 * bp.parameters["K"].spread, "fk_mean": NOMINAL["fk_mean"]}
    noisy = dict(SE, K=10 * bp.parameters["K"].spread)
    health = assess_axis(rows + [_entry("m002", "x", 3, values, se=noisy)], bp)
    assert health.verdict == "healthy"
    sharp = assess_axis(rows + [_entry("m002", "x", 3, values)], bp)
    assert sharp.verdict == "degraded"


def test_errors(tmp_path):
    rng = np.random.default_rng(6)
    entries = _fleet(rng, n_axes=6, n_months=3)
    with pytest.raises(ConfigError, match="at least 10 axes; got 6"):
        make_blueprint(entries, machine_type="demo", min_axes=10)
    with pytest.raises(ConfigError, match=r"parameters \['gap_plus'\] are not estimated"):
        make_blueprint(entries, machine_type="demo", parameters=["gap_plus"])
    bp = make_blueprint(entries, machine_type="demo")
    with pytest.raises(ConfigError, match="entries of one axis"):
        assess_axis(entries, bp)
    with pytest.raises(ConfigError, match="need 0 < alpha"):
        assess_axis(entries[:3], bp, alpha=0.7)
    bad = tmp_path / "bp.json"
    bad.write_text(json.dumps({"schema": "x"}))
    with pytest.raises(FileFormatError, match="not a blueprint"):
        read_blueprint(bad)


def test_blueprint_file_round_trip(tmp_path):
    rng = np.random.default_rng(7)
    bp = make_blueprint(_fleet(rng, n_axes=10, n_months=3), machine_type="demo")
    path = write_blueprint(bp, tmp_path / "bp.json")
    again = read_blueprint(path)
    assert again.monitored == bp.monitored
    assert again.parameters["K"] == bp.parameters["K"]
    np.testing.assert_allclose(again.correlation["matrix"], bp.correlation["matrix"])


def _catalogue(path, entries):
    with Catalog(path) as cat:
        for k, e in enumerate(entries):
            result = {"method": e.method, "inputs": [{"path": f"{k}.csv",
                                                      "sha256": f"{k:064x}"}],
                      "parameters": {n: {"value": p.value, "stderr": p.stderr, "unit": p.unit,
                                         "fixed": p.fixed} for n, p in e.parameters.items()}}
            result["parameters"]["J"]["stderr"] = None
            cat.add_result(result, machine=e.machine, axis=e.axis, measured_at=e.measured_at,
                           machine_type="demo")


def test_cli_blueprint_and_health(tmp_path):
    rng = np.random.default_rng(8)
    entries = _fleet(rng, n_axes=20, drift=("fk_mean", 3 * WITHIN["fk_mean"], 4))
    cat = str(tmp_path / "c.sqlite")
    _catalogue(cat, entries)
    runner = CliRunner()
    bp_path = tmp_path / "bp.json"
    out = runner.invoke(blueprint_group, ["make", "--catalog", cat, "--machine-type", "demo",
                                          "--out", str(bp_path)])
    assert out.exit_code == 0, out.output
    assert "from 20 axes" in out.output and bp_path.is_file()
    out = runner.invoke(health_command, ["m005/x", "--catalog", cat, "--blueprint",
                                         str(bp_path)])
    assert out.exit_code == 0 and "m005/x: " in out.output
    fig = tmp_path / "h.png"
    out = runner.invoke(health_command, ["m000/x", "--catalog", cat, "--blueprint",
                                         str(bp_path), "--figure", str(fig)])
    assert out.exit_code == 3, out.output  # degraded
    assert "degraded: fk_mean +" in out.output and fig.stat().st_size > 1000
    out = runner.invoke(health_command, ["m000/x", "--catalog", cat, "--blueprint",
                                         str(bp_path), "--json"])
    data = json.loads(out.output)
    assert data["verdict"] == "degraded" and len(data["parameters"]["K"]["values"]) == 12
    out = runner.invoke(health_command, ["nope", "--catalog", cat, "--blueprint",
                                         str(bp_path)])
    assert out.exit_code == 2 and out.output.startswith("error: name the axis as MACHINE/AXIS")
    out = runner.invoke(blueprint_group, ["make", "--catalog", cat, "--machine-type", "demo",
                                          "--out", str(bp_path)])
    assert out.exit_code == 2 and "exists" in out.output
