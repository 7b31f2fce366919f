"""The PHO campaign runner: protocol grid, files, manifest, settle detection, quality checks."""

import dataclasses
import json
import math

import numpy as np
import pytest

from driveid.errors import OverwriteError, ParameterError, RecordWarning
from driveid.experiment import (
    LoopbackPlant,
    SimulatedPlant,
    assess_run,
    run_pho_campaign,
    settle_time,
)
from driveid.io import read_record
from driveid.io.manifest import read_manifest
from driveid.io.record import Record
from driveid.sim.drive import simulate_drive
from driveid.sim.presets import preset


def _campaign(tmp_path, **kw):
    plant = kw.pop("plant", None) or SimulatedPlant("testbed-a", counts_per_rev=4000, seed=1)
    args = dict(P_values=[5.0, 7.0], D_values=[0.1, 0.14], x0=1.0, duration=2.5,
                out_dir=tmp_path / "c")
    args.update(kw)
    return run_pho_campaign(plant, **args)


def test_campaign_runs_the_grid_in_pairs_and_writes_numbered_files(tmp_path):
    seen = []
    campaign = _campaign(tmp_path, progress=lambda k, n, run: seen.append((k, n)))
    assert seen == [(k, 8) for k in range(1, 9)]
    order = [(r.P, r.D, r.x0) for r in campaign.runs]
    assert order == [(5.0, 0.1, 1.0), (5.0, 0.1, -1.0), (5.0, 0.14, 1.0), (5.0, 0.14, -1.0),
                     (7.0, 0.1, 1.0), (7.0, 0.1, -1.0), (7.0, 0.14, 1.0), (7.0, 0.14, -1.0)]
    names = sorted(p.name for p in (tmp_path / "c").iterdir())
    assert names[0] == "manifest.json"
    assert names[1:] == [f"run-{k:03d}-P{p:g}-D{d:g}-{'pos' if x > 0 else 'neg'}.csv"
                         for k, (p, d, x) in enumerate(order, 1)]
    assert all(r.accepted for r in campaign.runs)
    # the written files hold the records and the run's gains
    back = read_record(campaign.runs[3].path)
    np.testing.assert_array_equal(back.x, campaign.runs[3].record.x)
    assert (back.meta["P"], back.meta["D"], back.meta["x0_sign"]) == (5.0, 0.14, -1)

    data = json.loads(campaign.manifest_path.read_text())
    assert data["complete"] is True and data["plant"] == "testbed-a"
    assert data["delay_s"] == preset("testbed-a").feedback.delay
    assert data["protocol"]["P_values"] == [5.0, 7.0]
    assert data["protocol"]["abort_limit"] == 2 * 7.0 * 1.0  # default 2 max(P) x0
    run = data["runs"][2]
    assert (run["index"], run["file"], run["P"], run["D"], run["x0"], run["accepted"]) == (
        3, names[3], 5.0, 0.14, 1.0, True)
    manifest = read_manifest(tmp_path / "c")
    assert len(manifest.load_records()) == 8


def test_settled_at_matches_the_simulated_stick_time(tmp_path):
    campaign = _campaign(tmp_path, P_values=[5.0], D_values=[0.1])
    fb = dataclasses.replace(preset("testbed-a").feedback, P=5.0, D=0.1)
    exact = simulate_drive(dataclasses.replace(preset("testbed-a"), feedback=fb),
                           duration=2.5, fs=1000.0, x0=[1.0])
    moving = np.flatnonzero(exact.v[0] != 0)
    t_stick = exact.t[moving[-1] + 1]
    settled = campaign.runs[0].assessment.settled_at
    # the last swing before sticking is smaller than the 3-count settle band, so the
    # detected time lies within the final half period (0.15 s at 3.3 Hz) before the stick
    assert t_stick - 0.16 <= settled <= t_stick + 1e-3


def test_settle_time_of_a_decay_that_does_not_settle_is_none():
    t = np.arange(3000) * 1e-3
    x = np.exp(-0.5 * t) * np.cos(20 * t)
    assert settle_time(Record(t=t, x=x)) is None
    # faster decay: it settles once the envelope exp(-2 t) is inside the band, at the last
    # peak outside it, i.e. within half a period (0.157 s) before the envelope time
    x = np.exp(-2.0 * t) * np.cos(20 * t)
    t_env = -math.log(0.05) / 2.0
    settled = settle_time(Record(t=t, x=x), tol=0.05)
    assert t_env - 0.158 <= settled <= t_env


def test_an_existing_campaign_is_never_overwritten(tmp_path):
    first = _campaign(tmp_path, P_values=[5.0], D_values=[0.1])
    before = {p.name: p.read_bytes() for p in (tmp_path / "c").iterdir()}
    with pytest.raises(OverwriteError, match="choose another folder"):
        _campaign(tmp_path, P_values=[6.0], D_values=[0.1])
    after = {p.name: p.read_bytes() for p in (tmp_path / "c").iterdir()}
    assert after == before
    assert first.manifest_path.exists()


def test_a_clashing_record_file_is_refused_before_any_run(tmp_path):
    folder = tmp_path / "c"
    folder.mkdir()
    mine = folder / "run-002-P5-D0.1-neg.csv"
    mine.write_text("user data")
    with pytest.raises(OverwriteError, match="run-002"):
        _campaign(tmp_path, P_values=[5.0], D_values=[0.1])
    assert mine.read_text() == "user data"
    assert sorted(p.name for p in folder.iterdir()) == [mine.name]


def test_tiny_abort_limit_rejects_every_run_as_aborted(tmp_path):
    campaign = _campaign(tmp_path, P_values=[5.0], D_values=[0.1], abort_limit=0.5)
    for run in campaign.runs:
        assert not run.accepted
        assert run.assessment.reason.startswith("aborted")
    data = json.loads(campaign.manifest_path.read_text())
    assert all(r["aborted"] and not r["accepted"] for r in data["runs"])


def test_growing_oscillation_trips_the_default_abort(tmp_path):
    # D = 0.06 < P·delay = 0.096: negative net damping, the motion grows until aborted
    campaign = _campaign(tmp_path, P_values=[7.0], D_values=[0.06], duration=5.0)
    assert [r.assessment.reason.split(":")[0] for r in campaign.runs] == ["aborted"] * 2


def test_overdamped_run_never_oscillates(tmp_path):
    # D = 0.4 N·m·s/rad: net damping 0.33, ζ ≈ 0.33/(2 sqrt(5·0.0115)) ≈ 0.7 before
    # Coulomb friction stops the first swing; (much larger D destabilises the delayed loop)
    campaign = _campaign(tmp_path, P_values=[5.0], D_values=[0.4])
    reasons = [r.assessment.reason for r in campaign.runs]
    assert all(r.startswith("never oscillated") for r in reasons), reasons
    assert read_manifest(tmp_path / "c").accepted == ()


def test_release_inside_the_static_friction_band_never_oscillates():
    # P x0 = 0.05 N·m < fk = 0.109 N·m: the axis never leaves x0
    rec = SimulatedPlant("testbed-a").run_pd(P=5.0, D=0.1, x0=0.01, duration=1.0, fs=1e3)
    result = assess_run(rec)
    assert not result.accepted and result.reason.startswith("never oscillated")
    assert result.settled_at == 0.0


def test_too_few_peaks_and_saturation_are_rejected(tmp_path):
    plant = SimulatedPlant("testbed-a")
    rec = plant.run_pd(P=5.0, D=0.14, x0=0.5, duration=2.0, fs=1000.0)
    a = assess_run(rec, min_peaks=8)
    assert not a.accepted and a.reason.startswith("too few peaks") and 3 <= a.n_peaks < 8
    assert assess_run(rec, min_peaks=a.n_peaks).accepted
    params = preset("testbed-a")
    limited = dataclasses.replace(params, feedback=dataclasses.replace(params.feedback,
                                                                       saturation=2.0))
    sat = SimulatedPlant(limited).run_pd(P=5.0, D=0.1, x0=0.5, duration=2.0, fs=1000.0)
    result = assess_run(sat)
    assert not result.accepted and result.reason.startswith("saturated: the command reached ±2")


class _GlitchyPlant:
    """A hardware-like adapter whose acquisition corrupts a burst of samples (App. B.3.1)."""

    name, units, delay = "glitchy", "rad", 0.01377

    def __init__(self):
        self._inner = SimulatedPlant("testbed-a")

    def run_pd(self, *, P, D, x0, duration, fs, abort_limit=math.inf):
        rec = self._inner.run_pd(P=P, D=D, x0=x0, duration=duration, fs=fs,
                                 abort_limit=abort_limit)
        x = np.array(rec.x)
        x[300:330] = 40.0
        with pytest.warns(RecordWarning, match="corrupted"):
            return Record(t=rec.t, x=x, u=rec.u, meta=dict(rec.meta))


def test_corrupted_samples_are_rejected(tmp_path):
    with pytest.warns(RecordWarning, match="corrupted"):
        campaign = _campaign(tmp_path, plant=_GlitchyPlant(), P_values=[5.0], D_values=[0.1])
    assert all(r.assessment.reason.startswith("corrupted samples") for r in campaign.runs)
    assert json.loads(campaign.manifest_path.read_text())["plant"] == "glitchy"


def test_equally_stepped_D_and_bad_grids(tmp_path):
    campaign = _campaign(tmp_path, P_values=[5.0], D_values=None, D_start=0.1, D_step=0.02,
                         n_D=2)
    assert [r.D for r in campaign.runs] == [0.1, 0.1, 0.12, 0.12]
    with pytest.raises(ParameterError, match="D_start, D_step and n_D"):
        _campaign(tmp_path, D_values=None, D_start=0.1, out_dir=tmp_path / "x")
    with pytest.raises(ParameterError, match="x0"):
        _campaign(tmp_path, x0=-1.0, out_dir=tmp_path / "y")
    with pytest.raises(ParameterError, match="P_values"):
        _campaign(tmp_path, P_values=[], out_dir=tmp_path / "z")
    assert not (tmp_path / "x").exists()


def test_real_time_loopback_campaign_records_its_delay_and_timing(tmp_path):
    plant = LoopbackPlant(delay_samples=2)
    campaign = run_pho_campaign(plant, P_values=[5.0], D_values=[0.1], x0=0.3, duration=0.3,
                                out_dir=tmp_path / "rt")
    assert [r.record.n for r in campaign.runs] == [301, 301]
    data = json.loads(campaign.manifest_path.read_text())
    # known only once fs is: (2 samples + half a sample of hold) at 1 kHz
    assert data["delay_s"] == pytest.approx(2.5e-3) and data["plant"] == "loopback"
    back = read_record(campaign.runs[1].path)
    assert back.meta["timing"]["rate"] > 0 and back.meta["x0"] == -0.3
