"""The catalogue on SQLite and on a real PostgreSQL server (tests/catalog/conftest.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest
import sqlalchemy as sa
from click.testing import CliRunner

from driveid.catalog import Catalog, entry_key, parse_time
from driveid.catalog import _schema as S
from driveid.catalog import catalog_url as to_url
from driveid.commands.catalog import catalog_group
from driveid.errors import ConfigError, FileFormatError


def _result(sha="ab" * 32, K=16.0, method="logdec-lsq", covariance=True):
    result = {
        "driveid": "0.2.0", "schema": "driveid-result/1",
        "command": ["driveid", "identify", "logdec", "run.csv", "--mass", "1"],
        "inputs": [{"path": "run.csv", "sha256": sha, "rows": 1601, "columns": ["t", "x"],
                    "window": [None, None], "units": {"t": "s", "x": "rad"}}],
        "method": method,
        "parameters": {
            "J": {"value": 1.0, "stderr": None, "unit": "kg·m²", "fixed": True},
            "K": {"value": K, "stderr": 0.25, "unit": "N·m/rad", "fixed": False},
            "fk_mean": {"value": 0.3, "stderr": 0.001, "unit": "N·m", "fixed": False},
        },
        "covariance": None,
        "diagnostics": {"n_peaks": 19},
        "warnings": ["few peaks"],
    }
    if covariance:
        result["covariance"] = {"names": ["K", "fk_mean"],
                                "matrix": [[0.0625, 1e-5], [1e-5, 1e-6]]}
    return result


def test_add_list_round_trip(catalog_url):
    with Catalog(catalog_url) as cat:
        out = cat.add_result(_result(), machine="m1", axis="x", measured_at="2026-03-01T08:00Z",
                             machine_type="mill")
        assert out.created
        (entry,) = cat.entries()
    assert (entry.machine, entry.axis, entry.machine_type) == ("m1", "x", "mill")
    assert entry.measured_at == parse_time("2026-03-01T08:00")
    assert entry.status == "ok" and entry.error is None and entry.driveid_version == "0.2.0"
    assert entry.parameters["K"].value == 16.0 and entry.parameters["K"].stderr == 0.25
    assert entry.parameters["J"].fixed and math.isnan(entry.parameters["J"].stderr)
    assert entry.covariance["names"] == ["K", "fk_mean"]
    np.testing.assert_array_equal(entry.covariance["matrix"], [[0.0625, 1e-5], [1e-5, 1e-6]])
    assert entry.inputs[0]["sha256"] == "ab" * 32 and entry.inputs[0]["rows"] == 1601
    assert entry.inputs[0]["units"] == {"t": "s", "x": "rad"}
    assert entry.command[:3] == ["driveid", "identify", "logdec"]
    assert entry.warnings == ("few peaks",) and entry.diagnostics == {"n_peaks": 19}


def test_same_input_twice_is_one_entry(catalog_url):
    with Catalog(catalog_url) as cat:
        first = cat.add_result(_result(), machine="m1", axis="x")
        again = cat.add_result(_result(), machine="m1", axis="x")
        other = cat.add_result(_result(sha="cd" * 32), machine="m1", axis="x")
        assert not again.created and again.entry_id == first.entry_id
        assert other.created
        assert cat.count() == 2
        assert cat.known_hashes(["ab" * 32, "ef" * 32]) == {"ab" * 32}


def test_failures_are_entries_with_their_error(catalog_url):
    with Catalog(catalog_url) as cat:
        cat.add_result(_result(), machine="m1", axis="x", measured_at="2026-01-01")
        cat.add_failure(inputs=[{"path": "bad.csv", "sha256": "99" * 32}], method="logdec",
                        error="FileFormatError: no position column", machine="m1", axis="y",
                        measured_at="2026-01-02")
        failed = cat.entries(status="failed")
        assert [e.error for e in failed] == ["FileFormatError: no position column"]
        assert failed[0].parameters == {} and failed[0].covariance is None
        assert len(cat.entries()) == 2
        assert cat.known_hashes(["99" * 32]) == {"99" * 32}
        frame = cat.to_frame()
    assert set(frame["status"]) == {"ok", "failed"}
    assert frame.loc[frame["status"] == "failed", "parameter"].isna().all()


def test_filters(catalog_url):
    with Catalog(catalog_url) as cat:
        for k, (machine, day) in enumerate([("m1", "01"), ("m1", "15"), ("m2", "10")]):
            cat.add_result(_result(sha=f"{k:02d}" * 32), machine=machine, axis="x",
                           measured_at=f"2026-03-{day}", machine_type="mill")
        assert [e.machine for e in cat.entries(machine="m1")] == ["m1", "m1"]
        assert len(cat.entries(since="2026-03-05", until="2026-03-12")) == 1
        assert cat.entries(machine_type="lathe") == []


def test_migrates_a_version_1_catalogue(catalog_url):
    engine = sa.create_engine(to_url(catalog_url))
    with engine.begin() as conn:
        S.schema_version.create(conn)
        conn.execute(S.schema_version.insert().values(version=1))
        S.MIGRATIONS[0](conn)
        conn.execute(sa.text(
            "INSERT INTO entries (entry_key, machine, axis, measured_at, added_at, method, "
            "status) VALUES ('k1', 'old', 'x', '2025-01-01 00:00:00', '2025-01-01 00:00:00', "
            "'logdec-lsq', 'ok')"))
    engine.dispose()
    with Catalog(catalog_url) as cat:
        assert cat.schema_version == S.SCHEMA_VERSION == 2
        (old,) = cat.entries()
        assert old.machine == "old" and old.machine_type is None
        cat.add_result(_result(), machine="new", axis="x", machine_type="mill")
        assert {e.machine: e.machine_type for e in cat.entries()} == {"old": None, "new": "mill"}


def test_newer_schema_is_refused(catalog_url):
    Catalog(catalog_url).close()
    engine = sa.create_engine(to_url(catalog_url))
    with engine.begin() as conn:
        conn.execute(S.schema_version.update().values(version=99))
    engine.dispose()
    with pytest.raises(ConfigError, match="schema version 99 is newer.*upgrade driveid"):
        Catalog(catalog_url)


@pytest.mark.parametrize("bad, match", [
    ({"schema": "other/1", "method": "x", "parameters": {}}, "result schema must be"),
    ({"schema": "driveid-result/99", "method": "x", "parameters": {}}, "newer driveid"),
    ({"schema": "driveid-result/1", "parameters": {}}, "needs 'method'"),
    ({"method": "x", "parameters": {"K": 3.0}}, "parameter 'K' must be"),
    ({"method": "x", "parameters": {"K": {"value": "a"}}}, "non-numeric"),
    ({"method": "x", "parameters": {}, "covariance": {"names": ["K"], "matrix": [[1, 2]]}},
     "covariance matrix must be 1×1"),
])
def test_bad_results_are_refused(tmp_path, bad, match):
    with Catalog(tmp_path / "c.sqlite") as cat, pytest.raises(FileFormatError, match=match):
        cat.add_result(bad, machine="m", axis="x")


def test_key_ignores_input_order_and_separates_methods():
    assert entry_key(["a", "b"], "logdec") == entry_key(["b", "a"], "logdec")
    assert entry_key(["a"], "logdec") != entry_key(["a"], "output-error")


def test_urls_and_times(tmp_path):
    assert to_url(None).startswith("sqlite:///") and to_url(None).endswith(
        "driveid-catalog.sqlite")
    assert to_url("postgres://u@h/d") == "postgresql+psycopg://u@h/d"
    with pytest.raises(ConfigError, match="must be a SQLite file.*got 'mysql://x'"):
        to_url("mysql://x")
    with pytest.raises(ConfigError, match="ISO 8601.*got 'March'"):
        parse_time("March")
    with pytest.raises(ConfigError, match="no catalogue at"):
        Catalog(tmp_path / "missing.sqlite", create=False)


def test_not_a_catalogue_is_refused(tmp_path):
    path = tmp_path / "other.sqlite"
    engine = sa.create_engine(f"sqlite:///{path}")
    with engine.begin() as conn:
        conn.execute(sa.text("CREATE TABLE entries (x INTEGER)"))
    engine.dispose()
    with pytest.raises(ConfigError, match="not a driveid catalogue"):
        Catalog(path)


def test_cli_add_list_export(tmp_path):
    runner = CliRunner()
    cat = str(tmp_path / "c.sqlite")
    result_file = tmp_path / "r.json"
    result_file.write_text(json.dumps(_result()))
    args = ["add", str(result_file), "--machine", "m1", "--axis", "x", "--time", "2026-03-01",
            "--catalog", cat]
    out = runner.invoke(catalog_group, args)
    assert out.exit_code == 0, out.output
    assert "added as entry 1" in out.output
    out = runner.invoke(catalog_group, args)
    assert "already catalogued as entry 1" in out.output
    with Catalog(cat) as c:
        c.add_failure(inputs=[{"path": "bad.csv", "sha256": "77" * 32}], method="logdec",
                      error="RecordError: too short", machine="m1", axis="y")
    out = runner.invoke(catalog_group, ["list", "--catalog", cat])
    assert out.exit_code == 0 and "RecordError: too short" in out.output
    assert "2 entries, 1 failed" in out.output
    out = runner.invoke(catalog_group, ["list", "--catalog", cat, "--json"])
    listed = json.loads(out.output)
    assert [e["status"] for e in listed] == ["ok", "failed"]
    assert listed[0]["parameters"]["K"]["value"] == 16.0
    csv_path, pq_path = tmp_path / "c.csv", tmp_path / "c.parquet"
    out = runner.invoke(catalog_group, ["export", "--csv", str(csv_path), "--catalog", cat])
    assert out.exit_code == 0, out.output
    frame = pd.read_csv(csv_path)
    assert len(frame) == 4  # 3 parameters of the ok entry + 1 row for the failure
    out = runner.invoke(catalog_group, ["export", "--parquet", str(pq_path), "--catalog", cat])
    assert out.exit_code == 0, out.output
    assert len(pd.read_parquet(pq_path)) == 4
    out = runner.invoke(catalog_group, ["export", "--csv", str(csv_path), "--catalog", cat])
    assert out.exit_code == 2 and "exists" in out.output


def test_cli_errors_are_one_line(tmp_path):
    runner = CliRunner()
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    out = runner.invoke(catalog_group, ["add", str(bad), "--machine", "m", "--axis", "x",
                                        "--catalog", str(tmp_path / "c.sqlite")])
    assert out.exit_code == 2 and out.output.startswith("error: ")
    assert "not valid JSON" in out.output
    out = runner.invoke(catalog_group, ["list", "--catalog", str(tmp_path / "none.sqlite")])
    assert out.exit_code == 2 and "no catalogue at" in out.output
    assert not (tmp_path / "none.sqlite").exists()


def test_add_many_is_one_transaction_without_duplicates(catalog_url):
    place = {"machine": "m1", "axis": "x", "measured_at": "2026-03-01", "machine_type": None}
    failure = {"inputs": [{"path": "bad.csv", "sha256": "55" * 32}], "method": "logdec",
               "error": "RecordError: too short", **place}
    with Catalog(catalog_url) as cat:
        first = cat.add_result(_result(), **place)
        outcomes = cat.add_many([{"result": _result(), **place},            # already there
                                 {"result": _result(sha="66" * 32), **place},
                                 {"result": _result(sha="66" * 32), **place},  # twice in one
                                 {"failure": failure}])
        assert [o.created for o in outcomes] == [False, True, False, True]
        assert outcomes[0].entry_id == first.entry_id
        assert outcomes[1].entry_id == outcomes[2].entry_id
        assert cat.count() == 3
