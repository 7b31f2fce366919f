"""``driveid pho run`` and ``driveid pho analyse`` end to end (invoked on the click group)."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.commands.pho import pho_group, preset_campaign_defaults
from driveid.experiment import SimulatedPlant
from driveid.sim.presets import TABLE_5_2_PUBLISHED

A = TABLE_5_2_PUBLISHED["A"]
SMALL = ["--P", "5,7", "--D-start", "0.1", "--D-step", "0.02", "--n-D", "2", "--duration",
         "2.5", "--counts-per-rev", "4000", "--seed", "1"]


@pytest.fixture(scope="module")
def campaign(tmp_path_factory):
    out = tmp_path_factory.mktemp("pho") / "campaign"
    result = CliRunner().invoke(pho_group, ["run", "--out", str(out), *SMALL])
    assert result.exit_code == 0, result.output
    return out, result


def test_run_writes_the_campaign_and_prints_a_summary(campaign):
    out, result = campaign
    assert "8 of 8 runs accepted" in result.output
    assert f"manifest: {out / 'manifest.json'}" in result.output
    lines = [ln.split() for ln in result.output.splitlines() if ln.strip()[:1].isdigit()]
    # run, P, D, x0 for the grid P = 5, 7 and D = 0.1, 0.12
    assert [tuple(ln[:4]) for ln in lines[:4]] == [("1", "5", "0.1", "1"), ("2", "5", "0.1", "-1"),
                                                  ("3", "5", "0.12", "1"),
                                                  ("4", "5", "0.12", "-1")]
    assert len(list(out.glob("run-*.csv"))) == 8
    data = json.loads((out / "manifest.json").read_text())
    assert data["protocol"]["D_values"] == [0.1, 0.12]


def test_second_run_into_the_same_folder_is_refused(campaign):
    out, _ = campaign
    before = (out / "manifest.json").read_bytes()
    result = CliRunner().invoke(pho_group, ["run", "--out", str(out), *SMALL])
    assert result.exit_code == 2
    assert "choose another folder (CLI: --out)" in result.output
    assert (out / "manifest.json").read_bytes() == before


def test_default_campaign_of_testbed_a():
    d = preset_campaign_defaults("testbed-a")
    # P·[0.4, 0.6, 0.8], D·[0.3, 0.4, 0.5] of the preset's P = 5, D = 0.1; x0 = 50 fk/P ≈ 1.1
    assert d["P_values"] == [2.0, 3.0, 4.0]
    assert (d["D_start"], d["D_step"], d["n_D"], d["x0"]) == (0.03, 0.01, 3, 1.0)


def test_run_rejects_conflicting_options(tmp_path):
    result = CliRunner().invoke(pho_group, ["run", "--out", str(tmp_path / "x"), "--P", "5",
                                            "--P-range", "5", "1", "2"])
    assert result.exit_code == 2 and "--P or --P-range" in result.output
    result = CliRunner().invoke(pho_group, ["run", "--out", str(tmp_path / "y"), "--P", "a,b"])
    assert result.exit_code == 2 and "comma-separated numbers" in result.output


def test_analyse_campaign_json_and_uncompensated(campaign):
    out, _ = campaign
    runner = CliRunner()
    result = runner.invoke(pho_group, ["analyse", str(out), "--json", "--K", "0"])
    assert result.exit_code == 0, result.output
    est = json.loads(result.stdout)["parameters"]
    assert {"J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "delay"} <= set(est)
    # issue 5 acceptance: J within 0.5 %, fk_mean within 1 % (delay known from the manifest)
    assert est["J"]["value"] == pytest.approx(A["J"], rel=0.005)
    assert est["fk_mean"]["value"] == pytest.approx(A["fk_mean"], rel=0.01)
    assert est["delay"]["value"] == A["delay"]
    unc = json.loads(runner.invoke(pho_group, ["analyse", str(out / "manifest.json"),
                                               "--json", "--K", "0", "--uncompensated"]
                                   ).stdout)["parameters"]
    # ignoring the delay books its negative damping P·Δ ≈ 0.07-0.1 N·m·s/rad into c_mean
    # (the wrong-sign viscous friction of the thesis's Table 5.2)
    assert unc["delay"]["value"] == 0.0 and unc["c_mean"]["value"] < -0.05
    text = runner.invoke(pho_group, ["analyse", str(out), "--K", "0"]).output
    assert "8 accepted run(s), 0 rejected; delay 0.01377 s" in text and "fk_mean" in text
    # record options apply to every run file: a window that drops the first 0.1 s
    cut = json.loads(runner.invoke(pho_group, ["analyse", str(out), "--json", "--K", "0",
                                               "--t-start", "0.1"]).stdout)
    assert all(i["window"][0] >= 0.1 for i in cut["inputs"])
    assert cut["parameters"]["J"]["value"] == pytest.approx(A["J"], rel=0.005)  # as above
    assert cut["parameters"]["K"]["fixed"] and cut["parameters"]["K"]["stderr"] is None
    fig = out.parent / "pho.png"
    res = runner.invoke(pho_group, ["analyse", str(out), "--K", "0", "--figure", str(fig)])
    assert res.exit_code == 0 and fig.stat().st_size > 10_000, res.output
    res = runner.invoke(pho_group, ["analyse", str(out), "--K", "0", "--figure", str(fig)])
    assert res.exit_code == 2 and "--overwrite" in res.stderr  # never overwritten silently


def test_analyse_hand_written_manifest_of_plain_csv_files(tmp_path):
    plant = SimulatedPlant("testbed-a", counts_per_rev=4000, seed=2)
    runs = []
    for P in (5.0, 7.0):
        for D in (0.1, 0.14):
            for sign in (1, -1):
                rec = plant.run_pd(P=P, D=D, x0=sign * 1.0, duration=2.5, fs=1000.0)
                name = f"r{len(runs) + 1}{'pos' if sign > 0 else 'neg'}.csv"
                np.savetxt(tmp_path / name, np.column_stack([rec.t, rec.x, rec.u]),
                           delimiter=",", header="t,x,u", comments="")
                runs.append({"file": name, "P": P, "D": D})
    (tmp_path / "pd.json").write_text(json.dumps({"delay_s": A["delay"], "K": 0,
                                                  "runs": runs}))
    result = CliRunner().invoke(pho_group, ["analyse", str(tmp_path / "pd.json"), "--json"])
    assert result.exit_code == 0, result.output
    # same acceptance bound as above: the hand-written route loses nothing
    est = json.loads(result.stdout)
    assert est["parameters"]["J"]["value"] == pytest.approx(A["J"], rel=0.005)
    assert len(est["inputs"]) == 8 and est["inputs"][0]["path"].endswith("r1pos.csv")


def test_analyse_errors(tmp_path):
    runner = CliRunner()
    result = runner.invoke(pho_group, ["analyse", str(tmp_path)])
    assert result.exit_code == 2 and "no campaign manifest" in result.output
    np.savetxt(tmp_path / "r.csv", np.column_stack([np.arange(20) * 1e-3, np.zeros(20)]),
               delimiter=",", header="t,x", comments="")
    (tmp_path / "manifest.json").write_text(json.dumps(
        {"runs": [{"file": "r.csv", "P": 5, "D": 0.1, "accepted": False}]}))
    result = runner.invoke(pho_group, ["analyse", str(tmp_path)])
    assert result.exit_code == 2 and "no accepted run" in result.output
    result = runner.invoke(pho_group, ["analyse", str(tmp_path), "--delay", "0.01",
                                       "--uncompensated"])
    assert result.exit_code == 2 and "at most one of" in result.output


def test_analyse_reads_outside_the_folder_only_when_allowed(tmp_path):
    plant = SimulatedPlant("testbed-a", counts_per_rev=4000, seed=2)
    (tmp_path / "data").mkdir()
    (tmp_path / "campaign").mkdir()
    runs = []
    for P in (5.0, 7.0):
        for D in (0.1, 0.14):
            for sign in (1, -1):
                rec = plant.run_pd(P=P, D=D, x0=sign * 1.0, duration=2.5, fs=1000.0)
                name = f"r{len(runs) + 1}.csv"
                np.savetxt(tmp_path / "data" / name, np.column_stack([rec.t, rec.x, rec.u]),
                           delimiter=",", header="t,x,u", comments="")
                runs.append({"file": f"../data/{name}", "P": P, "D": D})
    manifest = tmp_path / "campaign" / "manifest.json"
    manifest.write_text(json.dumps({"delay_s": A["delay"], "K": 0, "runs": runs}))
    runner = CliRunner()
    res = runner.invoke(pho_group, ["analyse", str(manifest)])
    assert res.exit_code == 2 and "--allow-outside" in res.stderr
    res = runner.invoke(pho_group, ["analyse", str(manifest), "--allow-outside", "--json"])
    assert res.exit_code == 0, res.output
    assert json.loads(res.stdout)["parameters"]["J"]["value"] == pytest.approx(A["J"],
                                                                               rel=0.005)


def test_pho_run_help_states_the_real_defaults():
    # issue 15: --help once promised P x 1, 1.2, 1.4 and D x 1 while the code used others
    from driveid.commands import pho as pho_commands
    from driveid.sim.presets import preset

    d = pho_commands.preset_campaign_defaults("testbed-a")
    fb = preset("testbed-a").feedback
    factors = [p / fb.P for p in d["P_values"]]
    assert factors == pytest.approx(pho_commands.P_FACTORS, rel=1e-9)
    assert d["D_start"] / fb.D == pytest.approx(pho_commands.D_START_FACTOR, rel=1e-9)
    assert d["D_step"] / fb.D == pytest.approx(pho_commands.D_STEP_FACTOR, rel=1e-9)
    result = CliRunner().invoke(pho_commands.pho_group, ["run", "--help"], terminal_width=200)
    assert "P × 0.4, 0.6, 0.8" in result.output
    assert "0.3 × the preset's D" in result.output and "0.1 × the preset's D" in result.output


def test_pho_run_refuses_an_absurd_plan_before_starting(tmp_path):
    from driveid.cli import cli

    result = CliRunner().invoke(cli, ["pho", "run", "--out", str(tmp_path / "c"),
                                      "--n-D", "5000", "--max-runs", "100"])
    assert result.exit_code == 2
    assert "--max-runs" in result.output and "PHO runs" not in result.output
    assert not (tmp_path / "c").exists()


def test_pho_run_with_an_asymmetric_plant_is_identified(tmp_path):
    # issue 17: `pho run` on asymmetric plants; Δfk = 10 % and Δc = 30 % of the means,
    # noise-free runs: the campaign analysis recovers them (within 3 %, the PHO tests' bound
    # for asymmetric campaigns, tests/identify/test_pho_friction.py)
    from driveid.cli import cli
    from driveid.sim.presets import preset

    body = preset("testbed-a").bodies[0]
    c_delta, fk_delta = 0.3 * body.c_mean, 0.1 * body.fk_mean
    out = tmp_path / "asym"
    res = CliRunner().invoke(cli, ["pho", "run", "--out", str(out), "--c-delta", str(c_delta),
                                   "--fk-delta", str(fk_delta), "--duration", "4"])
    assert res.exit_code == 0, res.output
    res = CliRunner().invoke(cli, ["pho", "analyse", str(out), "--K", "0", "--json"])
    assert res.exit_code == 0, res.output
    par = json.loads(res.stdout)["parameters"]
    assert par["fk_mean"]["value"] == pytest.approx(body.fk_mean, rel=0.03)
    assert par["fk_delta"]["value"] == pytest.approx(fk_delta, rel=0.03)
    res = CliRunner().invoke(cli, ["pho", "run", "--out", str(tmp_path / "bad"),
                                   "--fk-delta", "10"])
    assert res.exit_code == 2 and res.output.startswith("error:")


def test_analyse_methods_oe_and_peaks(campaign):
    # issue 13 item 3: `--method oe` is the whole-record fit (the default `auto` picks it
    # for a campaign this size), `--method peaks` today's peak analysis; both give the
    # same fields. The plant is "testbed-a" (symmetric friction), so the truth is known.
    out, _ = campaign
    runner = CliRunner()
    res = {}
    for method in ("oe", "peaks", "auto"):
        r = runner.invoke(pho_group, ["analyse", str(out), "--json", "--K", "0", "--method",
                                      method, "--bootstrap", "25", "--seed", "1"])
        assert r.exit_code == 0, r.output
        res[method] = json.loads(r.stdout)
    assert res["oe"]["method"] == res["auto"]["method"] == "pho-output-error"
    assert res["peaks"]["method"] == "pho-campaign"
    oe, pk = res["oe"]["parameters"], res["peaks"]["parameters"]
    assert set(oe) == set(pk)
    truth = {"J": A["J"], "c_mean": A["c_mean"], "c_delta": 0.0, "fk_mean": A["fk_mean"],
             "fk_delta": 0.0}
    for name, value in truth.items():
        # 4 se: a calibrated error exceeds it once in 15 000 (the peaks' bars do not pass
        # this on J: 4.1 se here, the issue-13 finding)
        assert abs(oe[name]["value"] - value) <= 4 * oe[name]["stderr"], name
    assert oe["J"]["value"] == pytest.approx(A["J"], rel=0.005)  # the issue-5 bound above
    assert oe["delay"]["fixed"] and oe["K"]["fixed"]
    text = runner.invoke(pho_group, ["analyse", str(out), "--K", "0", "--uncompensated"]).output
    assert "uncompensated (delay 0); peak analysis" in text  # the thesis's situation: peaks
    bad = runner.invoke(pho_group, ["analyse", str(out), "--quantisation", "fine"])
    assert bad.exit_code == 2 and "--quantisation" in bad.output


def test_auto_on_a_campaign_too_large_to_fit_whole_says_so(campaign, monkeypatch):
    # `auto` falls back to the peaks above OE_MAX_SAMPLES; that must not be silent, since the
    # peaks' error bars on encoder records are the issue-13 finding (40-50 % coverage)
    import driveid.commands.pho as pho_cmd

    monkeypatch.setattr(pho_cmd, "OE_MAX_SAMPLES", 100)
    out, _ = campaign
    r = CliRunner().invoke(pho_group, ["analyse", str(out), "--json", "--K", "0"])
    assert r.exit_code == 0, r.output
    data = json.loads(r.stdout)
    assert data["method"] == "pho-campaign"
    assert any("--method oe" in w for w in data["warnings"])
