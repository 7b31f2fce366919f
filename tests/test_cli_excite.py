"""``driveid excite`` (invoked directly; the integrator registers it in cli.py)."""

import numpy as np
import pytest
from click.testing import CliRunner

from driveid.commands.excite import excite_command
from driveid.io.tables import read_table


def _run(args):
    return CliRunner().invoke(excite_command, [str(a) for a in args])


def test_multisine_csv_has_columns_t_u(tmp_path):
    out = tmp_path / "u.csv"
    res = _run(["multisine", "--f-min", 1, "--f-max", 20, "--duration", 10, "--fs", 1000,
                "--amplitude", 0.5, "--out", out])
    assert res.exit_code == 0, res.output
    assert "crest factor" in res.output
    table = read_table(out)
    names = [c.split(" ")[0] for c in table.columns]
    assert names[:2] == ["t", "u"]
    data = np.loadtxt(out, delimiter=",", comments="#", skiprows=2)
    assert data.shape == (10000, 2)
    assert np.abs(data[:, 1]).max() == pytest.approx(0.5, rel=1e-12)


def test_refuses_to_overwrite_and_overwrites_with_flag(tmp_path):
    out = tmp_path / "u.csv"
    out.write_text("keep")
    args = ["square", "--frequency", 1, "--duration", 4, "--amplitude", 1, "--bias", 0.1,
            "--out", out]
    res = _run(args)
    assert res.exit_code == 2 and "error:" in res.output and "--overwrite" in res.output
    assert out.read_text() == "keep"
    res = _run(args + ["--overwrite"])
    assert res.exit_code == 0, res.output
    assert out.read_text() != "keep"


@pytest.mark.parametrize("args", [
    ["chirp", "--f-min", 1, "--f-max", 10, "--duration", 2, "--amplitude", 1],
    ["prbs", "--f-clock", 50, "--duration", 2, "--amplitude", 1],
    ["random", "--f-min", 1, "--f-max", 10, "--duration", 2, "--amplitude", 1, "--seed", 1],
    ["ramp", "--ramp-time", 1, "--dwell-time", 0.5, "--amplitude", 1],
    ["sine", "--frequency", 2, "--duration", 2, "--amplitude", 1],
])
def test_every_kind_writes(tmp_path, args):
    res = _run(args + ["--out", tmp_path / "u.csv"])
    assert res.exit_code == 0, res.output


def test_bad_input_is_one_error_line(tmp_path):
    res = _run(["chirp", "--f-min", 1, "--f-max", 900, "--duration", 2, "--amplitude", 1,
                "--out", tmp_path / "u.csv"])
    assert res.exit_code == 2 and res.output.startswith("error:") and "Nyquist" in res.output
    res = _run(["chirp", "--duration", 2, "--amplitude", 1, "--out", tmp_path / "u.csv"])
    assert res.exit_code == 2 and "--f-min" in res.output
    assert not (tmp_path / "u.csv").exists()
