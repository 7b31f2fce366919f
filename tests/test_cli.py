"""The command line as a user runs it: exit codes, files, JSON keys, errors without tracebacks."""

import json

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.cli import cli


@pytest.fixture
def runner():
    return CliRunner()


def test_simulate_then_identify_json(runner, tmp_path):
    out = tmp_path / "decay.csv"
    res = runner.invoke(cli, ["simulate", "free-decay", "--out", str(out),
                              "--counts-per-rev", "8000"])
    assert res.exit_code == 0, res.output
    res = runner.invoke(cli, ["identify", "logdec", str(out), "--mass", "1", "--json"])
    assert res.exit_code == 0, res.output
    data = json.loads(res.output)
    for key in ("omega0", "zeta_plus", "zeta_minus", "J", "K", "c_mean", "c_delta", "fk_mean",
                "fk_delta"):
        assert set(data[key]) == {"value", "stderr", "unit"}
    # defaults of `simulate free-decay` are Table 5.1 case 3 with Δc = 0.1, Δfk = 0.03
    assert data["fk_mean"]["value"] == pytest.approx(0.07, rel=5e-3)  # encoder bound of issue
    assert data["c_delta"]["value"] == pytest.approx(0.1, rel=5e-3)


def test_refuses_to_overwrite(runner, tmp_path):
    out = tmp_path / "decay.csv"
    assert runner.invoke(cli, ["simulate", "free-decay", "--out", str(out)]).exit_code == 0
    res = runner.invoke(cli, ["simulate", "free-decay", "--out", str(out)])
    assert res.exit_code == 2 and "--force" in res.output and "Traceback" not in res.output
    assert runner.invoke(cli, ["simulate", "free-decay", "--out", str(out),
                               "--force"]).exit_code == 0


def test_plain_csv_header_and_table(runner, tmp_path):
    from driveid.sim import OscillatorParams, simulate_free_decay

    rec = simulate_free_decay(OscillatorParams(J=1, K=16, c_mean=0.3, fk_mean=0.07), x0=1.0,
                              duration=15.0).record
    path = tmp_path / "plain.csv"
    path.write_text("t,x\n" + "\n".join(f"{a:.17g},{b:.17g}" for a, b in
                                         zip(rec.t, rec.x, strict=True)))
    res = runner.invoke(cli, ["identify", "logdec", str(path), "--stiffness", "16"])
    assert res.exit_code == 0, res.output
    assert "fk_mean" in res.output and "N·m" in res.output


@pytest.mark.parametrize(
    "content, message",
    [
        ("t,x\n" + "\n".join(f"{i / 1000},{np.nan if i == 5 else 0.0}" for i in range(50)),
         "non-finite"),
        ("t,x\n" + "\n".join(f"{(49 - i) / 1000},0" for i in range(50)), "time is not increasing"),
        ("t,x\n" + "\n".join(f"{i / 1000},1.0" for i in range(50)), "constant"),
        ("t,x\n0,1\n", "at least 8 samples"),
    ],
)
def test_bad_input_exits_2_with_message(runner, tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    res = runner.invoke(cli, ["identify", "logdec", str(path)])
    assert res.exit_code == 2, res.output
    assert message in res.output and "Traceback" not in res.output


def test_demo_writes_a_new_numbered_folder(runner, tmp_path):
    res = runner.invoke(cli, ["demo", "--out", str(tmp_path)])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "run-001" / "free_decay_logdec.png").stat().st_size > 10_000
    est = json.loads((tmp_path / "run-001" / "estimate.json").read_text())
    assert est["fk_mean"]["value"] == pytest.approx(0.07, rel=5e-3)  # 8000 counts/rev bound
    res = runner.invoke(cli, ["demo", "--out", str(tmp_path)])
    assert res.exit_code == 0 and (tmp_path / "run-002").is_dir()  # run-001 kept as it was
