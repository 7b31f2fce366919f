"""`driveid identify auto` on lab-shaped exports."""

import json

import numpy as np
from click.testing import CliRunner

from driveid.cli import cli
from driveid.sim import OscillatorParams, measure, simulate_free_decay


def _cassy_like(path, rec):
    # CASSY-like: preamble, ';' delimiter, decimal comma, German header with units
    lines = ["MCS7", "Messung 1", "Zeit t / s;Winkel phi / rad"]
    lines += [f"{t:.3f};{x:.4f}".replace(".", ",") for t, x in zip(rec.t, rec.x, strict=True)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def test_auto_on_a_cassy_export(tmp_path):
    p = OscillatorParams(J=1.0, K=4.0, c_mean=0.05, fk_mean=0.01)
    rec = measure(simulate_free_decay(p, x0=1.0, duration=60, fs=50).record, noise_std=1e-3,
                  rng=1)
    f = tmp_path / "cassy.txt"
    _cassy_like(f, rec)
    res = CliRunner().invoke(cli, ["identify", "auto", str(f), "--mass", "1", "--json"])
    assert res.exit_code == 0, res.output
    out = json.loads(res.stdout)
    assert out["diagnostics"]["auto"]["shape"] == "free-decay"
    # omega0 = 2 rad/s exactly; 1e-3 rad noise on 3000 samples: within 0.5 %
    assert abs(out["parameters"]["omega0"]["value"] - 2.0) < 0.01
    assert out["parameters"]["J"]["fixed"] is True and out["parameters"]["J"]["stderr"] is None


def test_auto_refuses_a_record_without_a_test(tmp_path):
    f = tmp_path / "flat.csv"
    t = np.arange(500) / 100.0
    f.write_text("t,x\n" + "\n".join(f"{a},{0.001 * a}" for a in t) + "\n")
    res = CliRunner().invoke(cli, ["identify", "auto", str(f)])
    assert res.exit_code == 2
    assert res.output.count("error:") == 1 and "Traceback" not in res.output
