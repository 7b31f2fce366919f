"""Force–displacement loops: σ0 of a LuGre body, backlash gap and contact stiffness.

Truth: the simulator's parameters (``driveid.sim.simulate_drive`` with a LuGre body, and a
displacement-controlled actuator driving a Coulomb damper through a ``BacklashLink``).
"""

import numpy as np
import pytest

from driveid.errors import IdentificationError, RecordError
from driveid.identify.forced.loops import (
    estimate_backlash_loop,
    estimate_presliding_loop,
    loop_branches,
)
from driveid.identify.friction.idim import estimate_idim
from driveid.io.record import Record
from driveid.models.dynamic_friction import LuGreParams
from driveid.sim import BacklashLink, BodyParams, DriveParams, PDFeedback, simulate_drive


def _lugre_loop(seed: int = 0) -> Record:
    fs, duration = 2000.0, 4.0
    t = np.arange(int(duration * fs) + 1) / fs
    p = LuGreParams(sigma0=1e5, sigma1=300.0, sigma2=10.0, fc=8.0, fs=10.0, vs=1e-3,
                    check_passivity=False)
    force = 6.0 * np.sin(2 * np.pi * 1.0 * t)  # below fc: a pure presliding loop
    res = simulate_drive(DriveParams(bodies=(BodyParams(J=1.0, lugre=p),)),
                         duration=duration, fs=fs, torque=force[None, :])
    rng = np.random.default_rng(seed)
    return Record(t=t, x=res.x[0] + 1e-8 * rng.standard_normal(t.size),
                  u=force + 0.01 * rng.standard_normal(t.size),
                  meta={"units": {"x": "m", "u": "N"}})


@pytest.fixture(scope="module")
def backlash_test():
    # a servo actuator (displacement controlled) drives a friction damper through backlash
    fs, duration = 2000.0, 6.0
    t = np.arange(int(duration * fs) + 1) / fs
    drive = DriveParams(
        bodies=(BodyParams(J=0.05, c_mean=0.5), BodyParams(J=0.5, c_mean=50.0, fk_mean=100.0)),
        links=(BacklashLink(gap_plus=2e-3, gap_minus=1e-3, k=2e5, c=200.0),),
        feedback=PDFeedback(P=2e6, D=2e3))
    res = simulate_drive(drive, duration=duration, fs=fs,
                         reference=0.01 * np.sin(2 * np.pi * 0.5 * t))
    rng = np.random.default_rng(0)
    return Record(t=t, x=res.x[0], u=res.command + 0.5 * rng.standard_normal(t.size),
                  meta={"units": {"x": "m", "u": "N"}})


def test_presliding_loop_of_lugre_body_gives_sigma0():
    est = estimate_presliding_loop(_lugre_loop())
    # acceptance of issue 14: σ0 within 10 % (measured: 1.5 %; the Dahl branch is LuGre's
    # limit far below the Stribeck velocity)
    assert est.value("sigma0") == pytest.approx(1e5, rel=0.10)
    assert est["sigma0"].unit == "N/m"
    assert est.diagnostics["n_branches"] >= 3


def test_backlash_loop_gives_gap_and_stiffness(backlash_test):
    est = estimate_backlash_loop(backlash_test)
    # acceptance: total gap (2 + 1 mm) within 5 % (measured 0.4 %)
    assert est.value("gap") == pytest.approx(3e-3, rel=0.05)
    # contact stiffness 2e5 N/m: the fitted line lies on the contact (damping small)
    assert est.value("K") == pytest.approx(2e5, rel=0.05)
    # sliding level: Coulomb 100 N plus viscous 50 N·s/m at up to 0.03 m/s
    assert 100.0 <= est.value("f_plus") <= 102.0
    assert any("gap/2" in w for w in est.warnings)


def test_idim_on_backlash_loop_warns_instead_of_negative_mass(backlash_test):
    est = estimate_idim(backlash_test, cutoff_hz=20.0)
    # the rigid-body model does not hold: the issue saw a silent −10 t; we must flag it
    # bounded fit (issue 24): a mass below 0 is held at 0 and said
    assert est.value("M") >= 0
    if est.value("M") == 0:
        assert any(w.startswith("M held at its bound 0") for w in est.warnings)
    assert est.warnings


def test_loop_errors():
    t = np.arange(1000) / 1000.0
    with pytest.raises(RecordError, match="needs the applied force"):
        estimate_presliding_loop(Record(t=t, x=np.sin(t)))
    with pytest.raises(IdentificationError, match="two reversals"):
        loop_branches(t)
    flat = Record(t=t, x=np.sin(2 * np.pi * 3 * t), u=np.full(t.size, 1.0))
    with pytest.raises(IdentificationError):
        estimate_backlash_loop(flat)
