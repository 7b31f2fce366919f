"""Interrupted PHO campaigns: no partial record, resume continues where it stopped."""

import json

import pytest

from driveid.errors import OverwriteError, ParameterError, RecordWarning
from driveid.experiment import SimulatedPlant, run_pho_campaign
from driveid.experiment.pho import MAX_RUNS
from driveid.io.manifest import read_manifest


class _CountingPlant:
    """A simulated plant that counts its runs and can be 'unplugged' after some."""

    def __init__(self, stop_after=None):
        self._plant = SimulatedPlant("testbed-a", counts_per_rev=4000, seed=2)
        self.calls = 0
        self.stop_after = stop_after
        self.units, self.name, self.delay = self._plant.units, self._plant.name, None

    def run_pd(self, **kw):
        if self.stop_after is not None and self.calls >= self.stop_after:
            raise KeyboardInterrupt
        self.calls += 1
        return self._plant.run_pd(**kw)


_GRID = dict(P_values=[2.0, 3.0], D_values=[0.03], x0=1.0, duration=1.5)


def test_interrupted_campaign_resumes_without_repeating_runs(tmp_path):
    out = tmp_path / "c"
    with pytest.raises(KeyboardInterrupt):
        run_pho_campaign(_CountingPlant(stop_after=3), out_dir=out, **_GRID)
    data = json.loads((out / "manifest.json").read_text())
    assert data["complete"] is False and len(data["runs"]) == 3
    # no partial record, no temporary file: 3 records and the manifest
    assert sorted(p.name for p in out.iterdir()) == sorted(
        ["manifest.json"] + [r["file"] for r in data["runs"]])
    with pytest.warns(RecordWarning, match="incomplete"):
        assert len(read_manifest(out).load_records()) == 3
    # a second run without resume is refused, naming --resume (not a --force)
    with pytest.raises(OverwriteError, match="--resume") as info:
        run_pho_campaign(_CountingPlant(), out_dir=out, **_GRID)
    assert "--force" not in str(info.value)
    plant = _CountingPlant()
    campaign = run_pho_campaign(plant, out_dir=out, resume=True, **_GRID)
    assert plant.calls == 1 and len(campaign.runs) == 4  # only the missing run was run
    final = json.loads((out / "manifest.json").read_text())
    assert final["complete"] is True and final["created"] == data["created"]
    assert [r["index"] for r in final["runs"]] == [1, 2, 3, 4]
    assert len(read_manifest(out).load_records()) == 4  # complete: no warning
    with pytest.raises(OverwriteError, match="complete campaign"):
        run_pho_campaign(_CountingPlant(), out_dir=out, resume=True, **_GRID)


def test_resume_refuses_other_settings_and_cleans_leftover_temporaries(tmp_path):
    out = tmp_path / "c"
    with pytest.raises(KeyboardInterrupt):
        run_pho_campaign(_CountingPlant(stop_after=1), out_dir=out, **_GRID)
    with pytest.raises(ParameterError, match="duration 1.5 .campaign. vs 2.0 .now."):
        run_pho_campaign(_CountingPlant(), out_dir=out, resume=True,
                         **{**_GRID, "duration": 2.0})
    # a temporary left by a killed process (SIGKILL, power cut) is removed on resume
    leftover = out / ".run-002-P2-D0.03-neg.csv.abcd.part.csv"
    leftover.write_text("partial")
    run_pho_campaign(_CountingPlant(), out_dir=out, resume=True, **_GRID)
    assert not leftover.exists()


def test_resume_without_a_campaign_starts_one(tmp_path):
    campaign = run_pho_campaign(_CountingPlant(), out_dir=tmp_path / "c", resume=True, **_GRID)
    assert len(campaign.runs) == 4


def test_absurd_campaigns_are_refused_before_the_first_run(tmp_path):
    plant = _CountingPlant()
    with pytest.raises(ParameterError, match=f"limit of {MAX_RUNS}.*max_runs"):
        run_pho_campaign(plant, out_dir=tmp_path / "a", P_values=[1.0] * 2,
                         D_values=[0.01] * 5001, x0=1.0, duration=1.0)
    with pytest.raises(ParameterError, match="memory"):
        run_pho_campaign(plant, out_dir=tmp_path / "b", P_values=[2.0], D_values=[0.03],
                         x0=1.0, duration=1e9)
    assert plant.calls == 0 and not (tmp_path / "a").exists()


def test_symlinked_campaign_folder_is_refused(tmp_path):
    (tmp_path / "real").mkdir()
    (tmp_path / "link").symlink_to(tmp_path / "real")
    with pytest.raises(ParameterError, match="symbolic link"):
        run_pho_campaign(_CountingPlant(), out_dir=tmp_path / "link", **_GRID)
