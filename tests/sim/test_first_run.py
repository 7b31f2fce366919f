"""The interpreted drive kernel of a first run on a cold cache (driveid.sim._first_run)."""

import os
import subprocess
import sys

import numpy as np
import pytest

from driveid.errors import ConfigError
from driveid.sim import _first_run
from driveid.sim.batch import simulate_drive_batch
from driveid.sim.drive import (
    BacklashLink,
    BodyParams,
    DriveParams,
    PDFeedback,
    ShaftLink,
    simulate_drive,
)
from driveid.sim.presets import preset


@pytest.fixture
def cold(monkeypatch):
    """Pretend numba's cache is empty, with a large budget; count the interpreted calls."""
    calls = []
    kernel = _first_run._interpreted_kernel()

    def counted(*args):
        calls.append(1)
        return kernel(*args)

    monkeypatch.setenv(_first_run.BUDGET_ENV, "10000000")
    monkeypatch.setattr(_first_run, "_spent", 0.0)
    monkeypatch.setattr(_first_run, "is_compiled_or_cached", lambda args: False)
    monkeypatch.setattr(_first_run, "_interpreted_kernel", lambda: counted)
    return calls


def _w3(feedback=None):
    bodies = (BodyParams(J=0.0115, c_mean=1e-3, fk_mean=0.02),
              BodyParams(J=0.0035, ripple_amplitude=0.0, fk_mean=0.0),
              BodyParams(J=0.016, c_mean=2e-3, fk_mean=0.05, fk_delta=0.01))
    links = (BacklashLink(gap_plus=0.01, gap_minus=0.01, k=1e4, c=2.0),
             ShaftLink(k=50.0, c=0.05))
    return DriveParams(bodies=bodies, links=links, feedback=feedback)


_IMPACT = DriveParams(
    bodies=(BodyParams(J=0.0115, fk_mean=0.01), BodyParams(J=0.0035)),
    links=(BacklashLink(gap_plus=0.01, gap_minus=1.0, k=1e4, c=2.0, contact="restitution",
                        restitution=0.5),))
_RIPPLE = DriveParams(bodies=(BodyParams(J=0.01, c_mean=1e-3, fk_mean=0.05,
                                         ripple_amplitude=0.02, ripple_period=0.3),))

CASES = {
    # the first `driveid simulate drive --preset testbed-a`: delayed PD, stick-slip
    "testbed-a": (preset("testbed-a"), dict(duration=2.0, x0=[1.0])),
    "testbed (3 bodies, backlash, shaft)": (preset("testbed"), dict(duration=1.0,
                                                                     x0=[1.0] * 3)),
    "delayed PD on a backlash chain": (
        _w3(PDFeedback(P=2.0, D=0.05, delay=0.003, reference=0.2, saturation=2.0)),
        dict(duration=1.0)),
    "restitution impacts": (_IMPACT, dict(duration=0.3, torque=[0.4, 0.0])),
    "friction ripple": (_RIPPLE, dict(duration=1.0, v0=[2.0], method="rk4")),
    "strides (rtol)": (preset("testbed-a"), dict(duration=2.0, x0=[1.0], rtol=1e-8)),
    "sampled controller": (_w3(), dict(duration=0.5, controller=lambda t, x, v: 0.3 - x[0],
                                       control_rate=200.0)),
    # the per-body friction maps and the dwell clock (issue 25 item 4) interpreted too
    "Stribeck map with dwell, stick-slip": (
        DriveParams(bodies=(BodyParams(J=0.01, K=1.0, c_mean=0.05, c_delta=0.01, fk_mean=0.1,
                                       fk_delta=0.02, fs_mean=0.3, fs_delta=0.05,
                                       stribeck="lorentzian", v_s=0.2, v_s_delta=0.05,
                                       dwell_gamma=0.5, dwell_kappa=0.8),)),
        dict(duration=2.0, x0=[0.5])),
    # frictional memory: the velocity rings in the history array (Eq. 2.12)
    "Stribeck map with memory, stick-slip": (
        DriveParams(bodies=(BodyParams(J=0.01, K=1.0, c_mean=0.05, fk_mean=0.1, fs_mean=0.3,
                                       fs_delta=0.05, stribeck="bo_pavelescu", v_s=0.2,
                                       v_s_delta=0.05, memory=0.013),)),
        dict(duration=2.0, x0=[0.5])),
}


@pytest.mark.parametrize("name", list(CASES))
def test_interpreted_kernel_is_the_compiled_one_to_round_off(name, cold):
    params, kw = CASES[name]
    with _first_run.compiled_only():
        compiled = simulate_drive(params, **kw)
    assert not cold
    interpreted = simulate_drive(params, **kw)
    assert cold, "the run was not interpreted"
    # the same RK4 steps and events in the same order; the compiled loop may multiply by a
    # reciprocal where Python divides (fastmath arcp): round-off, measured <= 1e-14 of the
    # largest state on these cases (bitwise equal on two), so 1e-12 leaves 100x
    for got, ref in ((interpreted.x, compiled.x), (interpreted.v, compiled.v)):
        scale = np.nanmax(np.abs(ref))
        np.testing.assert_allclose(got, ref, rtol=0, atol=1e-12 * scale)
    assert (interpreted.n_mode_switches, interpreted.n_impacts) == (
        compiled.n_mode_switches, compiled.n_impacts)
    # the energy pass reruns on the engine of the first: the same trajectory
    n = len(cold)
    balance = interpreted.energy["dissipated"]
    assert len(cold) > n or "controller" in name  # (a controller run keeps its energy rows)
    ref = compiled.energy["dissipated"]
    np.testing.assert_allclose(balance, ref, rtol=0, atol=1e-12 * np.nanmax(np.abs(ref)))


def test_budget_then_compiled(cold, monkeypatch):
    params, kw = CASES["testbed-a"]  # 2000 grid steps of one body
    monkeypatch.setenv(_first_run.BUDGET_ENV, "5000")
    for _ in range(3):
        simulate_drive(params, **kw)
    assert len(cold) == 2  # 4000 body-steps interpreted; the third run would pass 5000
    simulate_drive(params, **kw)
    assert len(cold) == 2  # compiled from now on
    monkeypatch.setattr(_first_run, "_spent", 0.0)
    with _first_run.compiled_only():  # driveid warmup
        simulate_drive(params, **kw)
    assert len(cold) == 2
    monkeypatch.setenv(_first_run.BUDGET_ENV, "0")  # 0: always compiled (the test suite)
    simulate_drive(params, **kw)
    assert len(cold) == 2


def test_batch_runs_interpreted_while_the_budget_lasts(cold):
    params, kw = CASES["testbed-a"]
    runs = simulate_drive_batch([params] * 3, duration=0.5, x0=[1.0])
    assert len(cold) == 3
    with _first_run.compiled_only():
        ref = simulate_drive(params, duration=0.5, x0=[1.0])
    np.testing.assert_allclose(runs[2].x, ref.x, rtol=0, atol=1e-12)  # round-off (arcp)


def test_arithmetic_python_refuses_falls_back_to_the_compiled_kernel(cold, monkeypatch):
    def refuses(*args):
        raise ValueError("math domain error")

    monkeypatch.setattr(_first_run, "_interpreted_kernel", lambda: refuses)
    params, kw = CASES["testbed-a"]
    got = simulate_drive(params, **kw)
    monkeypatch.setenv(_first_run.BUDGET_ENV, "0")
    np.testing.assert_array_equal(got.x, simulate_drive(params, **kw).x)  # compiled both


def test_budget_variable_is_checked(monkeypatch):
    for bad in ("lots", "-1", "inf", "nan"):
        monkeypatch.setenv(_first_run.BUDGET_ENV, bad)
        with pytest.raises(ConfigError, match=f"DRIVEID_INTERPRET_STEPS='{bad}' must be a "
                                              "number of steps >= 0"):
            _first_run.interpret_budget()
    monkeypatch.setenv(_first_run.BUDGET_ENV, "2e5")
    assert _first_run.interpret_budget() == 200_000
    monkeypatch.setenv(_first_run.BUDGET_ENV, "")
    assert _first_run.interpret_budget() == _first_run.DEFAULT_BUDGET


def test_a_bad_budget_is_one_clean_line_on_the_command_line(tmp_path, monkeypatch):
    from click.testing import CliRunner

    from driveid.cli import cli

    monkeypatch.setenv(_first_run.BUDGET_ENV, "lots")
    res = CliRunner().invoke(cli, ["simulate", "drive", "--preset", "testbed-a", "--duration",
                                   "0.1", "--out", str(tmp_path / "a.csv")])
    assert res.exit_code == 2, res.output
    assert res.stderr.strip().splitlines() == [
        "error: DRIVEID_INTERPRET_STEPS='lots' must be a number of steps >= 0 (0: always "
        "compile); unset it for the default 100000"]
    assert not (tmp_path / "a.csv").exists()


_ARGS = """(np.zeros(2), np.ones(1, dtype=np.int64), np.zeros((3, 11)), np.zeros((2, 1)),
        float("inf"), 1000.0, 10, 1, 100, False, np.zeros(2), 0.0, 1)"""


def test_cold_cache_is_detected_without_compiling(tmp_path):
    # an empty NUMBA_CACHE_DIR: numba's index has no entry, so a first short run would be
    # interpreted; nothing is compiled to find out
    probe = ("import numpy as np; from driveid.sim import _first_run; "
             f"print(_first_run.is_compiled_or_cached({_ARGS}))")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True,
                         text=True, timeout=120, check=True).stdout
    assert out.strip() == "False"
    assert not list(tmp_path.rglob("*.nbi"))
    # here the suite compiled it (or loaded it): the same arguments find it
    simulate_drive(preset("testbed-a"), duration=0.01, x0=[1.0])
    assert _first_run.is_compiled_or_cached(eval(_ARGS))
