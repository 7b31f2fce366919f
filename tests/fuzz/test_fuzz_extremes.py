"""Extreme shapes (issue 28): very long fields, wrong database files, all-zero inputs and
magnitudes scaled by 1e±300, through several commands: one error line or a right answer.

Each of these once ended in exit 70 ("internal error, this is a bug"): a 1 MB column name
(the csv module's field limit), ``catalog add`` to a file that is no database (the SQL
driver's error), ``identify idim`` on a zero force (a division by zero) and ``identify
logdec`` on positions ×1e300 and ×1e-310 (numerical warnings, then a scipy error). The
conftest's :class:`Outcome` fails any run that exits 70.
"""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest

from tests.fuzz.conftest import snapshot

# 8 s of a 4 rad/s decay with a force, 1 kHz: enough periods for every free-decay method
_T = np.arange(8000) * 1e-3
_X = 10.0 * np.exp(-0.1 * _T) * np.cos(4.0 * _T)
_U = 0.5 * np.sin(2.0 * _T)


def _write(path, header="t [s],x [rad],u [N·m]", t=_T, x=_X, u=_U, comment=None):
    lines = ["# driveid record"] + ([comment] if comment is not None else []) + [header]
    rows = zip(t.tolist(), x.tolist(), u.tolist(), strict=True)
    lines += [f"{a!r},{b!r},{c!r}" for a, b, c in rows]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


IDENTIFY = ["logdec", "hilbert", "wavelet", "envelope", "step", "friction-map", "idim"]
LONG = "a" * 1_000_000  # over csv.field_size_limit() (131072)


@pytest.mark.parametrize("where", ["header", "comment", "data"])
@pytest.mark.parametrize("command", ["logdec", "idim", "friction-map"])
def test_a_megabyte_field_is_one_error_line(run, tmp_path, where, command):
    path = tmp_path / "long.csv"
    if where == "header":
        _write(path, header=f"t [s],x [rad],{LONG}")
    elif where == "comment":
        _write(path, comment=f"# t,x,{LONG}")
    else:
        _write(path)
        text = path.read_text().splitlines()
        text[100] = f"0.1,{LONG},0"
        path.write_text("\n".join(text) + "\n")
    before = snapshot(tmp_path)
    out = run("identify", command, path)
    if where == "header":
        out.assert_clean_error("field limit")
        assert LONG[:100] not in out.stderr  # the message never echoes the field
    else:
        out.assert_ok_or_clean_error()
    assert snapshot(tmp_path) == before


@pytest.fixture
def result_json(run, tmp_path):
    path = tmp_path / "decay.csv"
    _write(path, u=np.zeros_like(_T))
    out = run("identify", "logdec", path, "--method", "peaks", "--json")
    out.assert_ok()
    res = tmp_path / "res.json"
    res.write_text(out.stdout)
    return res


def _foreign_sqlite(path):
    con = sqlite3.connect(path)
    con.execute("create table invoices (id integer, amount real)")
    con.commit()
    con.close()


WRONG_DATABASES = {
    "text": lambda p: p.write_bytes(b"this is not a database file at all\n" * 100),
    "binary": lambda p: p.write_bytes(bytes(range(256)) * 64),
    "json": lambda p: p.write_text(json.dumps({"entries": []})),
    "truncated-sqlite": lambda p: p.write_bytes(b"SQLite format 3\x00" + b"\x00" * 80),
    "foreign-sqlite": _foreign_sqlite,
    "folder": lambda p: p.mkdir(),
}


@pytest.mark.parametrize("verb", ["add", "list", "export"])
@pytest.mark.parametrize("kind", WRONG_DATABASES)
def test_a_file_that_is_no_catalogue_is_one_error_line(run, tmp_path, result_json, kind,
                                                        verb):
    db = tmp_path / "cat.sqlite"
    WRONG_DATABASES[kind](db)
    before = snapshot(tmp_path)
    args = {"add": ["add", result_json, "--machine", "m", "--axis", "a"],
            "list": ["list"], "export": ["export", "--csv", tmp_path / "out.csv"]}[verb]
    out = run("catalog", *args, "--catalog", db)
    out.assert_clean_error()
    # the wrong file is neither changed nor joined by -wal/-shm files or tables of ours
    assert snapshot(tmp_path) == before


def test_a_foreign_sqlite_file_gets_no_driveid_tables(run, tmp_path, result_json):
    db = tmp_path / "other.sqlite"
    _foreign_sqlite(db)
    out = run("catalog", "add", result_json, "--machine", "m", "--axis", "a",
              "--catalog", db)
    out.assert_clean_error("not a driveid catalogue")
    con = sqlite3.connect(db)
    tables = {r[0] for r in con.execute("select name from sqlite_master where type='table'")}
    con.close()
    assert tables == {"invoices"}


@pytest.mark.parametrize("column", ["x", "u", "xu"])
@pytest.mark.parametrize("command", IDENTIFY)
def test_all_zero_inputs(run, tmp_path, command, column):
    zero = np.zeros_like(_T)
    path = _write(tmp_path / "zero.csv", x=zero if "x" in column else _X,
                  u=zero if "u" in column else _U)
    run("identify", command, path).assert_ok_or_clean_error()


def test_idim_on_a_zero_force_names_the_cause(run, tmp_path):
    path = _write(tmp_path / "zero.csv", u=np.zeros_like(_T))
    run("identify", "idim", path).assert_clean_error("force of every record is all zero")


SCALES = [1e300, 1e-300, 1e-310, -1e300]


@pytest.mark.parametrize("scale", SCALES, ids=lambda s: f"{s:g}")
@pytest.mark.parametrize("column", ["x", "u"])
@pytest.mark.parametrize("command", IDENTIFY)
def test_extreme_magnitudes_are_one_error_line(run, tmp_path, command, column, scale):
    path = _write(tmp_path / "scaled.csv", x=_X * scale if column == "x" else _X,
                  u=_U * scale if column == "u" else _U)
    out = run("identify", command, path)
    out.assert_clean_error("--scale")


@pytest.mark.parametrize("scale", [1e6, 1e-6], ids=lambda s: f"{s:g}")
def test_ordinary_scales_still_fit(run, tmp_path, scale):
    """Micrometres or megaradians are odd but fine: the guard leaves them alone."""
    path = _write(tmp_path / "scaled.csv", x=_X * scale, u=np.zeros_like(_T))
    out = run("identify", "logdec", path, "--method", "peaks", "--json")
    out.assert_ok()
    omega = json.loads(out.stdout)["parameters"]["omega0"]["value"]
    assert omega == pytest.approx(4.0, rel=0.01)  # the decay's 4 rad/s; 1 %: peak timing


def test_a_scaled_record_is_rescued_by_the_named_fix(run, tmp_path):
    """The message's ``--scale x=...`` is a working fix."""
    path = _write(tmp_path / "scaled.csv", x=_X * 1e-310, u=np.zeros_like(_T))
    out = run("identify", "logdec", path, "--method", "peaks")
    out.assert_clean_error("--scale x=1e300")
    fixed = run("identify", "logdec", path, "--method", "peaks", "--scale", "x=1e300",
                "--json")
    fixed.assert_ok()


@pytest.mark.parametrize("command", [("identify", "logdec"), ("pho", "analyse")])
def test_an_absurd_bootstrap_count_is_refused_before_any_fit(run, tmp_path, command):
    """``--bootstrap 1e8`` once started 1e8 whole-record fits without a word."""
    path = _write(tmp_path / "decay.csv", u=np.zeros_like(_T))
    out = run(*command, path, "--bootstrap", "100000000")
    out.assert_clean_error("--bootstrap")


@pytest.mark.parametrize("scale", [1e-99, 1e-60, 1e-20, 1e20, 1e60, 1e99],
                         ids=lambda s: f"{s:g}")
@pytest.mark.parametrize("command", ["friction-map", "idim", "hilbert", "step", "logdec"])
def test_odd_magnitudes_inside_the_band_fit_or_fail_cleanly(run, tmp_path, command, scale):
    """Inside [1e-100, 1e100] nothing is refused at reading; no estimator may then crash
    (friction-map once ended in exit 70 below speeds of about 1e-15)."""
    path = _write(tmp_path / "scaled.csv", x=_X * scale, u=_U * scale)
    run("identify", command, path).assert_ok_or_clean_error()


@pytest.mark.parametrize("url", ["sqlite://", "sqlite:///", "sqlite:///:memory:"])
@pytest.mark.parametrize("verb", ["catalog add", "fleet identify"])
def test_an_in_memory_catalogue_is_refused(run, tmp_path, result_json, url, verb):
    """``--catalog sqlite:///`` once printed 'added as entry 1' and kept nothing."""
    args = ([result_json, "--machine", "m", "--axis", "a"] if verb == "catalog add"
            else [str(tmp_path / "*.csv"), "--mass", "1", "--quiet"])
    run(*verb.split(), *args, "--catalog", url).assert_clean_error("names no file")
