"""Issue 28, fourth hostile campaign (2026-11-28): shapes the first three did not try.

Each once ended in exit 70 or a silently wrong exit 0: a clock in Unix milliseconds (the
free-decay fit's Jacobian vanished), a presliding loop without force, a TOML integer of 401
digits, a text ``published`` value and a repeated section name in ``identify subsystems``,
JSON nested 5000 deep (results, blueprints and a record), a result with ``omega0 = 1e308``,
hand-edited blueprints, IDIM with the force as its own load or a regressor that is zero,
a band-limited random excitation shorter than its lowest period, an HDF5 soft-link loop,
``--counts-per-rev 1e-300`` (every sample rounded to 0), an IDIM result with negative
viscous friction (validated to a fit of -1e98 %), a simulated body with negative damping
(grew to 3e34 in silence), ``--report r.pdf`` (HTML inside) and ``identify envelope`` on a
driven record (nan, no word).
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from tests.fuzz.test_fuzz_campaign3 import _DRIVE_TOML


def _motion_csv(path, *, load_is_force=False):
    """2 s of sine motion with viscous and Coulomb friction: t, x, u."""
    t = np.arange(0, 2.0, 1e-3)
    x = 0.5 * np.sin(2 * np.pi * t)
    v = np.pi * np.cos(2 * np.pi * t)
    a = -2 * np.pi**2 * np.sin(2 * np.pi * t)
    u = 0.05 * a + 0.3 * v + 0.8 * np.tanh(v / 0.01)
    u = u + 0.01 * np.random.default_rng(0).normal(size=t.size)
    path.write_text("t [s],x [rad],u [N·m]\n" + "".join(
        f"{a_:.6f},{b:.9g},{c:.9g}\n" for a_, b, c in zip(t, x, u, strict=True)))
    return path


# --- once exit 70 -------------------------------------------------------------------------

def test_a_free_decay_on_a_unix_millisecond_clock(run, tmp_path):
    t = np.arange(3000)
    x = 10 * np.exp(-0.2 * t / 1000) * np.cos(4 * t / 1000)
    x = x + 1e-3 * np.random.default_rng(0).normal(size=t.size)
    (tmp_path / "epoch.csv").write_text("t [ms],x [rad]\n" + "".join(
        f"{1_700_000_000_000 + k},{v:.9g}\n" for k, v in zip(t, x, strict=True)))
    out = run("identify", "logdec", "epoch.csv", "--mass", "1", "--json")
    out.assert_ok()
    data = json.loads(out.stdout)
    # 10 e^(-0.2 t) cos 4t: ω0 = √(4² + 0.2²)
    assert data["parameters"]["omega0"]["value"] == pytest.approx(16.04**0.5, rel=1e-3)
    # the release is reported on the file's clock, in seconds
    assert data["data_used"]["release_t"][0] == pytest.approx(1.7e9, rel=1e-9)


def test_a_presliding_loop_without_force(run, tmp_path, good_record):
    run("identify", "loop", "--kind", "presliding", str(good_record)).assert_clean_error(
        "force is zero")


@pytest.mark.parametrize("command", [("simulate", "drive", "c.toml", "--out", "o.csv"),
                                     ("identify", "drive", "c.toml", "{record}",
                                      "--estimate", "body1.J")],
                         ids=["simulate", "identify"])
def test_a_toml_integer_of_401_digits(run, tmp_path, good_record, command):
    text = _DRIVE_TOML.replace("J = ", "J = " + "1" + "0" * 400 + " # ", 1)
    (tmp_path / "c.toml").write_text(text)
    run(*[c.format(record=good_record) for c in command]).assert_clean_error("401 digits")


@pytest.mark.parametrize("extra, match", [
    ('[section.published]\nJ = "abc"\n', "must be a finite number"),
    ('[section.published]\nbogus = 1\n', "unknown quantity"),
    ("", "section names must differ"),
], ids=["text", "unknown", "same-name"])
def test_subsystems_manifests_refused_before_any_fit(run, tmp_path, extra, match):
    (tmp_path / "d.toml").write_text(_DRIVE_TOML)
    (tmp_path / "r.csv").write_text("t,x1\n" + "".join(f"{k / 1000},{0.0}\n"
                                                       for k in range(200)))
    section = '[[section]]\nname = "A"\nconfig = "d.toml"\nfiles = ["r.csv"]\n'
    (tmp_path / "m.toml").write_text(section + section + extra)
    run("identify", "subsystems", "m.toml").assert_clean_error(match)


@pytest.mark.parametrize("verb", ["validate", "report", "catalog"])
def test_a_result_nested_5000_deep(run, tmp_path, good_record, result_json, verb):
    data = json.loads(result_json.read_text())
    text = json.dumps(data)[:-1] + ', "x": ' + "[" * 5000 + "]" * 5000 + "}"
    (tmp_path / "r.json").write_text(text)
    args = {"validate": ("validate", "r.json", str(good_record)),
            "report": ("report", "r.json", "--out", "r.html"),
            "catalog": ("catalog", "add", "r.json", "--machine", "m", "--axis", "x",
                        "--catalog", "c.sqlite")}[verb]
    run(*args).assert_clean_error("nested 5001 levels")


def test_a_record_nested_100000_deep(run, tmp_path):
    (tmp_path / "r.json").write_text("[" * 100_000 + "]" * 100_000)
    run("inspect", "r.json").assert_clean_error("nested")


def test_a_result_with_omega0_1e308(run, tmp_path, good_record, result_json):
    data = json.loads(result_json.read_text())
    data["parameters"]["omega0"]["value"] = 1e308
    (tmp_path / "r.json").write_text(json.dumps(data))
    run("validate", "r.json", str(good_record)).assert_clean_error("omega0")


@pytest.mark.parametrize("edit, match", [
    (lambda b: b["parameters"]["J"].update(nominal=None), "'nominal' must be a number"),
    (lambda b: b["parameters"]["J"].update(spread=0.0), "'spread' must be a finite number"),
    (lambda b: b["parameters"]["J"].update(nominal=1e308), "reasonable size"),
    (lambda b: b.update(monitored=[]), "monitors no parameter"),
    (lambda b: b.update(correlation="x"), "'correlation' must be an object"),
    (lambda b: b.pop("parameters"), "missing 'parameters'"),
], ids=["nominal-null", "spread-0", "huge", "monitored-empty", "correlation-text",
        "no-parameters"])
def test_hand_edited_blueprints(tmp_path, edit, match):
    from driveid.errors import FileFormatError
    from driveid.health.blueprint import read_blueprint

    good = {"schema": "driveid-blueprint/1", "machine_type": "T", "monitored": ["J"],
            "parameters": {"J": {"nominal": 1.0, "spread": 0.1, "repeatability": None,
                                 "se_ref": None, "unit": "kg·m²"}}}
    read_blueprint(_write(tmp_path / "ok.json", good))  # the shape itself reads
    edit(good)
    with pytest.raises(FileFormatError, match=match):
        read_blueprint(_write(tmp_path / "b.json", good))


def _write(path, data):
    path.write_text(json.dumps(data))
    return path


@pytest.mark.parametrize("args, match", [
    (("--load", "u"), "force minus the known load is zero"),
    (("--regressor", "0*v"), "is zero on every row"),
], ids=["load-is-force", "zero-regressor"])
def test_idim_with_nothing_left_to_fit(run, tmp_path, args, match):
    _motion_csv(tmp_path / "m.csv")
    run("identify", "idim", "m.csv", *args).assert_clean_error(match)


def test_a_random_excitation_shorter_than_its_lowest_period(run, tmp_path):
    run("excite", "random", "--f-min", "1", "--f-max", "1.0001", "--duration", "0.01",
        "--amplitude", "1", "--out", "e.csv").assert_clean_error("too short")
    assert not (tmp_path / "e.csv").exists()


def test_an_hdf5_soft_link_loop(run, tmp_path):
    h5py = pytest.importorskip("h5py")
    with h5py.File(tmp_path / "loop.h5", "w") as fh:
        fh["a"] = h5py.SoftLink("/b")
        fh["b"] = h5py.SoftLink("/a")
    run("inspect", "loop.h5").assert_clean_error("links cannot be followed")


# --- once a silent, wrong exit 0 ----------------------------------------------------------

def test_an_encoder_of_1e_300_counts_per_rev(run, tmp_path):
    run("simulate", "free-decay", "--counts-per-rev", "1e-300",
        "--out", "o.csv").assert_clean_error("--counts-per-rev")


def test_validate_refuses_a_model_that_runs_away(run, tmp_path):
    _motion_csv(tmp_path / "m.csv")
    out = run("identify", "idim", "m.csv", "--json")
    out.assert_ok()
    data = json.loads(out.stdout)
    data["parameters"]["Fv"]["value"] = -50.0
    (tmp_path / "r.json").write_text(json.dumps(data))
    out = run("validate", "r.json", "m.csv")
    out.assert_clean_error()  # either guard: the simulation stops, or it ran away
    assert "runs away from the record" in out.stderr or "unstable" in out.stderr


def test_a_body_with_negative_damping_is_said_to_be_active(run, tmp_path):
    out = run("simulate", "free-decay", "--c-mean", "-1", "--out", "o.csv")
    out.assert_ok()
    assert "not passive" in out.stderr and "feeds energy in" in out.stderr


def test_a_report_named_pdf(run, tmp_path, good_record):
    run("identify", "logdec", str(good_record), "--mass", "1",
        "--report", "r.pdf").assert_clean_error("name it .html")
    assert not (tmp_path / "r.pdf").exists()


def test_the_envelope_of_a_driven_record_is_warned(run, tmp_path):
    # two sines driven through inertia, viscous and Coulomb friction (the campaign's record)
    t = np.arange(0, 10, 1e-3)
    x = 0.5 * np.sin(2 * np.pi * t) + 0.2 * np.sin(2 * np.pi * 2.7 * t)
    v = np.gradient(x, t)
    u = 2 * np.gradient(v, t) + 0.5 * v + 1.2 * np.sign(v)
    u = u + 0.01 * np.random.default_rng(0).normal(size=t.size)
    (tmp_path / "m.csv").write_text("t [s],x [rad],u [N·m]\n" + "".join(
        f"{a:.6f},{b:.9g},{c:.9g}\n" for a, b, c in zip(t, x, u, strict=True)))
    out = run("identify", "envelope", "m.csv")
    out.assert_ok()  # nan standard errors and no word before
    assert "force or torque input" in out.stderr and "without a standard error" in out.stderr


@pytest.mark.parametrize("bad", ["abc", {"omega": "x"}], ids=["text", "field-text"])
def test_a_hand_edited_second_mode(run, tmp_path, bad):
    # the + second mode structure's data_used (found in the review: exit 70)
    from driveid.io import write_record
    from tests.identify.test_free_decay_honesty import _two_mode_decay

    write_record(_two_mode_decay(0), tmp_path / "m.csv")
    out = run("identify", "logdec", "m.csv", "--mass", "1", "--json")
    out.assert_ok()
    data = json.loads(out.stdout)
    assert data["diagnostics"]["structure"] == "+ second mode"
    data["data_used"]["second_mode"] = bad
    (tmp_path / "r.json").write_text(json.dumps(data))
    run("validate", "r.json", "m.csv").assert_clean_error("second_mode")
