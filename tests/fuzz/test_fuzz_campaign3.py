"""Issue 28, third hostile campaign: shapes no earlier campaign tried.

Each once ended in exit 70, a hang or a silently wrong exit 0: empty arrays in an .npz, a
cross-test record without force, ``--seed -1`` (every command with the option), a TOML
nested 5000 deep or saved as UTF-16, hand-edited results with a list or a string where an
object or a number belongs, ``--min-axes 0``/``--first -1``/``--baseline 0``, a negative
``--segment`` (an endless loop), 1e9 ramp cycles, a multisine of 4e4 lines (one cosine at a
time), a folder given as FILE ("no such record file"), a service that is no Dask scheduler
("out of memory"), a feedback delay of 1e6 s ("out of memory"), ``--period 0``, ``--input``
= ``--output`` and ``--fix J_m=-1`` (fitted, exit 0), ``--fs`` over a time column (the
file's clock dropped silently), a load expression reaching 1e304 (nan estimates, exit 0), a
catalogue locked by another process (exit 70 after 60 s) and an empty machine name.
The block after them holds what that campaign left open: a duplicated header, ``--free k``,
``--input-unit parsec``, NaN and 1e999 in a result, ``--bins 1e8``, ``--models ""``, a
1e-9 Hz cut-off, a text file named .mat, a float16 clock, ``--baseline`` beyond the
history, ``--every 1e-9``.
The last block holds shapes that passed, kept so that they stay so.
"""

from __future__ import annotations

import io
import sqlite3

import numpy as np
import pytest

from tests.fuzz.conftest import snapshot
from tests.test_cli_identify_drive import TOML as DRIVE_TOML

# the one-body drive under delayed PD of the identify-drive tests, 0.5 s long
_DRIVE_TOML = DRIVE_TOML.replace("duration = 2.0", "duration = 0.5")
assert "duration = 0.5" in _DRIVE_TOML


@pytest.fixture(scope="module")
def idim_record(tmp_path_factory):
    """2.5 s of sine motion with viscous and Coulomb friction (t, x, u)."""
    t = np.arange(0, 2.5, 1e-3)
    x = 0.5 * np.sin(2 * np.pi * 0.5 * t) + 0.2 * np.sin(2 * np.pi * 1.3 * t)
    v = np.gradient(x, t)
    a = np.gradient(v, t)
    u = 0.05 * a + 0.3 * v + 0.8 * np.tanh(v / 0.01)
    u = u + 0.01 * np.random.default_rng(0).normal(size=t.size)
    path = tmp_path_factory.mktemp("idim") / "idim.csv"
    path.write_text("t [s],x [rad],u [N·m]\n" + "".join(
        f"{a_:.6f},{b:.9g},{c:.9g}\n" for a_, b, c in zip(t, x, u, strict=True)))
    return path


# --- once exit 70 -------------------------------------------------------------------------

@pytest.mark.parametrize("command", [("inspect",), ("identify", "logdec")])
def test_empty_arrays_in_an_npz(run, tmp_path, command):
    buf = io.BytesIO()
    np.savez(buf, t=np.array([]), x=np.array([]))
    (tmp_path / "e.npz").write_bytes(buf.getvalue())
    run(*command, "e.npz").assert_clean_error("hold no samples")


def test_idim_cross_test_on_a_record_without_force():
    # CLI: identify idim FIT.csv --validate DECAY.csv (a free decay: u = 0); exit 70 before
    from driveid.errors import IdentificationError
    from driveid.identify.friction.idim import estimate_idim, validate_idim
    from driveid.io.record import Record

    t = np.arange(2000) / 1000.0
    x = 0.1 * np.sin(2 * np.pi * t)
    v, a = 0.2 * np.pi * np.cos(2 * np.pi * t), -0.4 * np.pi**2 * np.sin(2 * np.pi * t)
    u = 2.0 * a + 3.0 * v + 1.5 * np.sign(v) + 0.01 * np.random.default_rng(0).normal(size=t.size)
    units = {"units": {"x": "m", "u": "N"}}
    est = estimate_idim(Record(t=t, x=x, u=u, meta=units), decimate=1, cutoff_hz=50.0,
                        sensitivity=False, noise="white")
    with pytest.raises(IdentificationError, match="cross-test record's force is all zero"):
        validate_idim(est, Record(t=t, x=x, u=np.zeros_like(t), meta=units))


@pytest.mark.parametrize("args", [
    ("identify", "logdec", "{record}", "--mass", "1"),
    ("simulate", "free-decay", "--out", "o.csv", "--noise", "0.01"),
    ("excite", "random", "--f-min", "1", "--f-max", "10", "--duration", "1",
     "--amplitude", "1", "--out", "e.csv"),
    ("fleet", "simulate", "f", "--axes", "1", "--months", "1"),
    ("pho", "run", "--out", "c", "--P", "2", "--n-D", "1", "--duration", "1"),
    ("pho", "analyse", "."),
    ("simulate", "contour", "{record}", "--out", "c.csv"),
], ids=lambda a: " ".join(a[:2]))
def test_a_negative_seed(run, tmp_path, good_record, args):
    before = snapshot(tmp_path)
    out = run(*[a.format(record=good_record) for a in args], "--seed", "-1")
    out.assert_clean_error("--seed")
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("content, match", [
    ("a = " + "[" * 5000 + "]" * 5000 + "\n", "deeper than the TOML parser"),
    (_DRIVE_TOML.encode("utf-16"), "not UTF-8"),
], ids=["nested-5000", "utf16"])
@pytest.mark.parametrize("command", [("simulate", "drive", "c.toml", "--out", "o.csv"),
                                     ("identify", "subsystems", "c.toml")],
                         ids=["simulate-drive", "subsystems"])
def test_hostile_toml(run, tmp_path, content, match, command):
    path = tmp_path / "c.toml"
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    run(*command).assert_clean_error(match)


@pytest.mark.parametrize("edit, match", [
    (lambda d: d.__setitem__("parameters", [1, 2]), "'parameters' must be an object"),
    (lambda d: d["parameters"]["J"].__setitem__("value", "heavy"), "must be numbers"),
    (lambda d: d["parameters"].__setitem__("J", 5), "a parameter must be an object"),
    (lambda d: d.__setitem__("inputs", {"a": 1}), "'inputs' must be a list"),
    (lambda d: d.__setitem__("method", 7), "'method' must be a string"),
], ids=["params-list", "value-string", "param-number", "inputs-object", "method-number"])
@pytest.mark.parametrize("verb", ["validate", "report"])
def test_hand_edited_result(run, tmp_path, good_record, result_json, edit, match, verb):
    import json

    data = json.loads(result_json.read_text())
    edit(data)
    path = tmp_path / "r.json"
    path.write_text(json.dumps(data))
    args = (path, good_record) if verb == "validate" else (path, "--out", "r.html")
    run(verb, *args).assert_clean_error(match)


@pytest.mark.parametrize("args, match", [
    (("blueprint", "make", "--machine-type", "x", "--out", "b.json", "--min-axes", "0"),
     "--min-axes"),
    (("blueprint", "make", "--machine-type", "x", "--out", "b.json", "--first", "-1"),
     "--first"),
    (("health", "m/x", "--blueprint", "{record}", "--baseline", "0"), "--baseline"),
])
def test_health_counts(run, good_record, args, match):
    run(*[a.format(record=good_record) for a in args]).assert_clean_error(match)


def test_health_library_refuses_what_the_options_refuse():
    from driveid.errors import ConfigError, ParameterError
    from driveid.health import assess_axis, make_blueprint
    from tests.health.test_health import _fleet

    entries = _fleet(np.random.default_rng(1), n_axes=6, n_months=4)
    with pytest.raises(ParameterError, match="min_axes"):
        make_blueprint(entries, machine_type="demo", min_axes=0)
    with pytest.raises(ParameterError, match="first"):
        make_blueprint(entries, machine_type="demo", first=-1)
    bp = make_blueprint(entries, machine_type="demo")
    axis = [e for e in entries if e.machine == "m000"]
    with pytest.raises(ConfigError, match="baseline"):
        assess_axis(axis, bp, baseline=0)


def test_catalogue_locked_by_another_process(run, tmp_path, result_json, monkeypatch):
    from driveid.catalog import _sqlite

    cat = tmp_path / "c.sqlite"
    run("catalog", "add", result_json, "--machine", "m", "--axis", "x",
        "--catalog", cat).assert_ok()
    import json

    other = json.loads(result_json.read_text())
    other["inputs"][0]["sha256"] = "0" * 64  # another record: a new entry
    (tmp_path / "r2.json").write_text(json.dumps(other))
    monkeypatch.setattr(_sqlite, "LOCK_WAIT", 0.2)
    holder = sqlite3.connect(cat, isolation_level=None)
    holder.execute("BEGIN EXCLUSIVE")
    try:
        run("catalog", "add", tmp_path / "r2.json", "--machine", "m2", "--axis", "x",
            "--catalog", cat).assert_clean_error("locked by another process")
    finally:
        holder.execute("ROLLBACK")
        holder.close()


# --- once a hang --------------------------------------------------------------------------

def test_identify_drive_negative_segment(run, tmp_path):
    from driveid.errors import ParameterError
    from driveid.identify.drive.drive_fit import estimate_drive
    from driveid.sim.config import load_drive_config

    (tmp_path / "c.toml").write_text(_DRIVE_TOML)
    run("simulate", "drive", "c.toml", "--out", "a.csv").assert_ok()
    run("identify", "drive", "c.toml", "a.csv", "--estimate", "body1.J",
        "--segment", "-1").assert_clean_error("--segment")
    from driveid.identify.drive.records import read_drive_record

    params, _ = load_drive_config(tmp_path / "c.toml")
    rec = read_drive_record(tmp_path / "a.csv", n_bodies=1)
    with pytest.raises(ParameterError, match="segment"):
        estimate_drive([rec], params, estimate=["body1.J"], segment=-1.0)


@pytest.mark.parametrize("args, match", [
    (("ramp", "--ramp-time", "1", "--cycles", "1000000000"), "memory"),
    (("multisine", "--f-min", "1", "--f-max", "10", "--duration", "1", "--period", "1e-9"),
     "no multiple of 1/period"),
    (("multisine", "--f-min", "1", "--f-max", "10", "--duration", "1", "--period", "100"),
     "longer than the duration"),
])
def test_excite_refusals(run, tmp_path, args, match):
    before = snapshot(tmp_path)
    run("excite", *args, "--amplitude", "1", "--out", "u.csv").assert_clean_error(match)
    assert snapshot(tmp_path) == before


def test_a_multisine_of_many_lines_is_one_inverse_fft():
    from driveid.signal.excitation import multisine

    # 4e4 lines over 1e5 samples: summed one cosine at a time this took minutes
    sig = multisine(f_min=0.01, f_max=400, duration=100, fs=1000, amplitude=1.0)
    assert sig.u.size == 100_000 and np.max(np.abs(sig.u)) == pytest.approx(1.0)
    # the same lines as the sum of cosines, on a small case
    small = multisine(f_min=1, f_max=20, duration=10, fs=1000, amplitude=0.5)
    k = np.arange(10, 201)
    j = np.arange(1, k.size + 1)
    u = sum(np.cos(2 * np.pi * kk * 0.1 * small.t - np.pi * jj * (jj - 1) / k.size)
            for kk, jj in zip(k, j, strict=True))
    np.testing.assert_allclose(small.u, 0.5 * u / np.max(np.abs(u)), atol=1e-12)


# --- once a misleading line ---------------------------------------------------------------

@pytest.mark.parametrize("command", [("identify", "logdec"), ("inspect",),
                                     ("fleet", "identify")])
def test_a_folder_given_as_file(run, tmp_path, command):
    (tmp_path / "runs.csv").mkdir()
    extra = ("--catalog", "c.sqlite") if command[0] == "fleet" else ()
    run(*command, "runs.csv", *extra).assert_clean_error("is a folder, not a record file")


def test_a_scheduler_address_that_is_no_scheduler(run, tmp_path, good_record):
    run("fleet", "identify", good_record, "--scheduler", "garbage://x",
        "--catalog", "c.sqlite").assert_clean_error("cannot use the Dask scheduler")


def test_a_dead_scheduler_address_gives_up_after_the_timeout(run, tmp_path, good_record):
    # issue 28: Dask tried a stopped scheduler for its own 30 s every time; now
    # --scheduler-timeout (10 s by default), and the line names the option
    import socket

    with socket.socket() as sock:  # a port nothing listens on once closed
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    result = run("fleet", "identify", good_record, "--scheduler", f"tcp://127.0.0.1:{port}",
                 "--scheduler-timeout", "1", "--catalog", "c.sqlite")
    result.assert_clean_error("cannot use the Dask scheduler")
    assert "after 1 s" in result.stderr and "--scheduler-timeout" in result.stderr
    run("fleet", "identify", good_record, "--scheduler", f"tcp://127.0.0.1:{port}",
        "--scheduler-timeout", "0", "--catalog", "c.sqlite").assert_clean_error(
        "scheduler timeout must be a positive number of seconds")


def test_a_feedback_delay_of_days(run, tmp_path):
    (tmp_path / "c.toml").write_text(_DRIVE_TOML.replace("delay = 0.01377", "delay = 1e6"))
    run("simulate", "drive", "c.toml", "--out", "o.csv").assert_clean_error(
        "feedback's state history")


# --- once a silently wrong exit 0 ---------------------------------------------------------

_TR = ("identify", "transfer", "{fixture}", "--input", "u1", "--output", "z1", "--fs", "50",
       "--output-nonlinearity", "abs")


@pytest.mark.parametrize("extra, match", [
    (("--period", "0"), "--period"),
    (("--period", "1e9"), "--period"),
    (("--structure", "two-mass", "--fix", "J_m=-1"), "J_m must be > 0"),
    (("--structure", "two-mass", "--fix", "c=-0.1"), "c must be >= 0"),
])
def test_transfer_options_that_were_fitted_anyway(run, extra, match):
    from pathlib import Path

    fixture = Path(__file__).resolve().parents[1] / "fixtures/transfer/ced_like.csv"
    run(*[a.format(fixture=fixture) for a in _TR], *extra).assert_clean_error(match)


def test_transfer_input_equal_to_output(run):
    from pathlib import Path

    fixture = Path(__file__).resolve().parents[1] / "fixtures/transfer/ced_like.csv"
    run("identify", "transfer", fixture, "--input", "u1", "--output", "u1",
        "--fs", "50").assert_clean_error("both name column 'u1'")


def test_fs_over_a_time_column_warns(run, good_record):
    out = run("inspect", good_record, "--fs", "50")
    out.assert_ok()
    assert "warning:" in out.stderr and "replaces by k/fs" in out.stderr
    quiet = run("inspect", good_record, "--fs", "50", "--time", "none")
    quiet.assert_ok()
    assert "replaces" not in quiet.stderr


def test_load_expression_beyond_the_magnitude_band(run, idim_record):
    run("identify", "idim", idim_record, "--load-expr", "exp(1000*x)",
        "--no-sensitivity").assert_clean_error("above the 1e+100")


@pytest.mark.parametrize("machine, axis, match", [
    ("", "x", "machine name"), ("m", " ", "axis name"), ("m", "x/y", "must not contain")])
def test_catalogue_names(run, result_json, machine, axis, match):
    run("catalog", "add", result_json, "--machine", machine, "--axis", axis,
        "--catalog", "c.sqlite").assert_clean_error(match)


def test_a_channel_of_no_body(run, tmp_path):
    (tmp_path / "c.toml").write_text(_DRIVE_TOML)
    run("simulate", "drive", "c.toml", "--out", "a.csv").assert_ok()
    run("identify", "drive", "c.toml", "a.csv", "--estimate", "body1.J",
        "--channel", "x9=x1").assert_clean_error("name no body")


# --- left open by the campaign, closed after ----------------------------------------------

def _with_copy(good_arrays, factor):
    """The record as CSV with its position column repeated (times ``factor``)."""
    t, x, u = good_arrays["t"], good_arrays["x"], good_arrays["u"]
    return "t [s],x [rad],u [N·m],x [rad]\n" + "".join(
        f"{a:.17g},{b:.17g},{c:.17g},{b * factor:.17g}\n"
        for a, b, c in zip(t, x, u, strict=True))


def test_a_repeated_header(run, tmp_path, good_arrays):
    # pandas-style renaming to x.1 read the first 'x' without a word
    (tmp_path / "same.csv").write_text(_with_copy(good_arrays, 1.0))
    out = run("inspect", "same.csv")
    out.assert_ok()
    assert "warning: same.csv: the header 'x' names 2 columns ([1] 'x', [3] 'x.1') with " \
           "the same values; read [1] 'x' as the position" in out.stderr
    (tmp_path / "differ.csv").write_text(_with_copy(good_arrays, 2.0))
    run("inspect", "differ.csv").assert_clean_error(
        "the header 'x' names 2 columns with different values")
    run("inspect", "differ.csv", "--position", "3").assert_ok()


@pytest.mark.parametrize("extra, match", [
    (("--structure", "two-mass", "--free", "k"), "--free k: k is estimated already"),
    (("--structure", "two-mass", "--free", "gain", "--fix", "gain=2"), "contradict"),
    (("--input-unit", "parsec"), "--input-unit 'parsec' is no unit driveid knows"),
])
def test_transfer_options_that_did_nothing(run, extra, match):
    from pathlib import Path

    fixture = Path(__file__).resolve().parents[1] / "fixtures/transfer/ced_like.csv"
    run(*[a.format(fixture=fixture) for a in _TR], *extra).assert_clean_error(match)


@pytest.mark.parametrize("text, match", [
    ("NaN", "value must be a finite number or null"),
    ("1e999", "value must be a finite number or null"),
], ids=["nan", "1e999"])
@pytest.mark.parametrize("verb", ["report", "catalog", "validate"])
def test_non_finite_numbers_in_a_result(run, tmp_path, good_record, result_json, text, match,
                                        verb):
    import json

    data = json.loads(result_json.read_text())
    name = next(n for n, p in data["parameters"].items() if not p["fixed"])
    raw = json.dumps(data).replace(f'"{name}": {{"value": ', f'"{name}": {{"value": {text}, '
                                   '"was": ', 1)
    (tmp_path / "r.json").write_text(raw)
    args = {"report": ("report", "r.json", "--out", "r.html"),
            "catalog": ("catalog", "add", "r.json", "--machine", "m", "--axis", "x",
                        "--catalog", "c.sqlite"),
            "validate": ("validate", "r.json", good_record)}[verb]
    run(*args).assert_clean_error(match)


def test_a_result_with_missing_numbers_still_reads(run, tmp_path, result_json):
    # null (what driveid writes) and a NaN standard error are missing numbers, not errors
    import json

    from driveid.errors import FileFormatError
    from driveid.identify.core.estimate import Estimate, Parameter

    data = json.loads(result_json.read_text())
    name = next(n for n, p in data["parameters"].items() if not p["fixed"])
    data["parameters"][name]["value"] = None
    (tmp_path / "r.json").write_text(json.dumps(data).replace(
        '"stderr": null', '"stderr": NaN'))
    run("report", "r.json", "--out", "r.html").assert_ok()
    run("catalog", "add", "r.json", "--machine", "m", "--axis", "x",
        "--catalog", "c.sqlite").assert_ok()
    # the library refuses what the commands refuse, with the same classes
    with pytest.raises(ValueError, match="value must be a finite number"):
        Parameter.from_dict({"value": float("inf"), "stderr": None})
    with pytest.raises(ValueError, match="standard error must be a finite number"):
        Estimate.from_dict({**data, "parameters": {"J": {"value": 1.0,
                                                         "stderr": float("inf")}}})
    from driveid.catalog import Catalog

    with Catalog(tmp_path / "d.sqlite") as cat, pytest.raises(FileFormatError, match="nan"):
        cat.add_result({**data, "parameters": {"J": {"value": float("nan")}}},
                       machine="m", axis="x")


def test_friction_map_bins_and_models(run, idim_record):
    run("identify", "friction-map", idim_record, "--inertia", "0.05", "--bins",
        "100000000").assert_clean_error("give at most --bins")
    run("identify", "friction-map", idim_record, "--models", "").assert_clean_error(
        "--models names no map")
    from driveid.errors import IdentificationError
    from driveid.identify.friction.friction_map import binned_points
    from driveid.io import read_record

    with pytest.raises(IdentificationError, match=r"give at most bins=\d+"):
        binned_points(read_record(idim_record), inertia=0.05, bins=10**8)


def test_idim_cutoff_below_what_the_record_resolves(run, idim_record):
    # 2.5 s at 1 kHz: 1e-9 Hz once 'dropped 3000000000000 edge samples'
    out = run("identify", "idim", idim_record, "--cutoff-hz", "1e-9")
    out.assert_clean_error("is below what this record resolves")
    lowest = float(out.lines[-1].split("give at least --cutoff-hz ")[1].split()[0])
    run("identify", "idim", idim_record, "--cutoff-hz", str(lowest * 0.99),
        "--no-sensitivity").assert_clean_error("below what this record resolves")
    from driveid.errors import ParameterError
    from driveid.identify.friction.idim import estimate_idim
    from driveid.io import read_record

    with pytest.raises(ParameterError, match="cutoff_hz=1e-09 Hz is below"):
        estimate_idim(read_record(idim_record), cutoff_hz=1e-9, sensitivity=False)


def test_a_text_file_named_mat(run, tmp_path):
    (tmp_path / "t.mat").write_text("this is not a mat file\n1,2,3\n")
    out = run("inspect", "t.mat")
    out.assert_clean_error("t.mat is text, not a MATLAB .mat file")
    assert "IndexError" not in out.stderr
    (tmp_path / "e.mat").write_bytes(b"")
    run("inspect", "e.mat").assert_clean_error("e.mat is empty, not a MATLAB .mat file")
    (tmp_path / "r.mat").write_bytes(bytes(range(256)) * 2)
    run("inspect", "r.mat").assert_clean_error("has no MAT-file header")


def test_a_float16_clock(run, tmp_path, good_arrays):
    buf = io.BytesIO()
    np.savez(buf, t=good_arrays["t"].astype(np.float16), x=good_arrays["x"])
    (tmp_path / "h.npz").write_bytes(buf.getvalue())
    run("inspect", "h.npz").assert_clean_error("stored as float16")
    run("inspect", "h.npz", "--fs", "1000", "--time", "none").assert_ok()
    buf = io.BytesIO()  # float32 resolves 6 s at 1 kHz: read as before
    np.savez(buf, t=good_arrays["t"].astype(np.float32), x=good_arrays["x"])
    (tmp_path / "s.npz").write_bytes(buf.getvalue())
    run("inspect", "s.npz").assert_ok()


def test_health_baseline_beyond_the_history_is_said():
    from driveid.health import assess_axis, make_blueprint
    from tests.health.test_health import _fleet

    entries = _fleet(np.random.default_rng(1), n_axes=6, n_months=4)
    bp = make_blueprint(entries, machine_type="demo")
    axis = [e for e in entries if e.machine == "m000"]
    short = assess_axis(axis, bp, baseline=50)
    assert short.notes and "drift test (CUSUM) did not run: baseline=50" in short.notes[0]
    assert "baseline=3 (CLI: --baseline) would run it" in short.notes[0]
    assert short.to_dict()["notes"] == list(short.notes)
    assert assess_axis(axis, bp, baseline=3).notes == ()


def test_health_cli_notes_a_drift_test_that_did_not_run(run, tmp_path):
    from driveid.health import make_blueprint, write_blueprint
    from tests.health.test_health import _catalogue, _fleet

    entries = _fleet(np.random.default_rng(2), n_axes=6, n_months=4)
    _catalogue(str(tmp_path / "c.sqlite"), entries)
    write_blueprint(make_blueprint(entries, machine_type="demo"), tmp_path / "bp.json")
    out = run("health", "m000/x", "--blueprint", "bp.json", "--catalog", "c.sqlite",
              "--baseline", "50")
    assert out.code in (0, 3), out.describe()
    assert "note: m000/x: the drift test (CUSUM) did not run: --baseline 50 needs at " \
           "least 51" in out.stderr


def test_track_every_below_a_block_or_a_sample(run, tmp_path, idim_record):
    run("track", idim_record, "--every", "1e-9").assert_clean_error(
        "--every 1e-09 s is shorter than one update block")
    lines = idim_record.read_text().splitlines()
    (tmp_path / "slow.csv").write_text("\n".join([lines[0], *lines[1::200]]) + "\n")
    run("track", "slow.csv", "--every", "0.15").assert_clean_error(
        "shorter than the sampling interval")
    from driveid.errors import ParameterError
    from driveid.identify.friction.online import track_friction
    from driveid.io import read_record

    with pytest.raises(ParameterError, match="output_every=1e-09 s"):
        track_friction(read_record(idim_record), output_every=1e-9)


# --- shapes that passed: kept so ----------------------------------------------------------

@pytest.mark.parametrize("suffix, match", [
    ("@5:1", "before its end"), ("@a:b", "not a number"), ("@1e309:2", "finite"),
    ("@100:200", "holds 0 sample"), ("@1:2:3", "not a number")])
def test_window_specs(run, good_record, suffix, match):
    run("identify", "logdec", f"{good_record}{suffix}", "--mass", "1").assert_clean_error(match)


def test_a_utf8_bom_and_a_unicode_path_read(run, tmp_path, good_record):
    path = tmp_path / "ünïcødé ✓ run.csv"
    path.write_text("\ufeff" + good_record.read_text(), encoding="utf-8")
    run("inspect", path).assert_ok()


def test_a_spike_of_1e30_and_a_huge_time_gap(run, tmp_path, good_record):
    lines = good_record.read_text().splitlines()
    spike = list(lines)
    cells = spike[1000].split(",")
    spike[1000] = ",".join([cells[0], "1e30", *cells[2:]])
    (tmp_path / "s.csv").write_text("\n".join(spike) + "\n")
    run("identify", "logdec", "s.csv", "--mass", "1").assert_clean_error("corrupted")
    gap = list(lines)
    for i in range(2000, len(gap)):
        cells = gap[i].split(",")
        gap[i] = ",".join([f"{float(cells[0]) + 1e6}", *cells[1:]])
    (tmp_path / "g.csv").write_text("\n".join(gap) + "\n")
    run("identify", "logdec", "g.csv", "--mass", "1").assert_clean_error("not uniform")


@pytest.mark.parametrize("args, match", [
    (("identify", "idim", "{idim}", "--decimate", "0"), "--decimate"),
    (("identify", "idim", "{idim}", "--cutoff-hz", "1e6"), "below fs/2"),
    (("identify", "idim", "{idim}", "--regressor", "__import__('os')"), "may only use"),
    (("excite", "multisine", "--f-min", "1", "--f-max", "5000", "--duration", "1",
      "--amplitude", "1", "--out", "u.csv"), "Nyquist"),
    (("catalog", "add", "{result}", "--machine", "m", "--axis", "x", "--time", "9999-99-99",
      "--catalog", "c.sqlite"), "ISO 8601"),
    (("simulate", "drive", "{toml}", "--out", "o.csv"), "must be a number"),
])
def test_refusals_that_held(run, tmp_path, idim_record, result_json, args, match):
    toml = tmp_path / "s.toml"
    toml.write_text(_DRIVE_TOML.replace("J = 0.0115355", 'J = "0.0115355"'))
    run(*[a.format(idim=idim_record, result=result_json, toml=toml) for a in args]
        ).assert_clean_error(match)
