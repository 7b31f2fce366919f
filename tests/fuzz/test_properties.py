"""Property tests (hypothesis): readers, Record, manifests, JSON and TOML loading, option types.

Each property states the outcome class: a value is either accepted and round-trips, or it is
refused with a driveid error (a ValueError subclass) - never another exception.
"""

from __future__ import annotations

import json
import math
import tempfile
from pathlib import Path

import click
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from driveid.cli import _error_line
from driveid.commands._checks import BoundedInt, FiniteFloat, NonNegativeFloat, PositiveFloat
from driveid.errors import DriveIdError
from driveid.io import Record, read_record, write_record
from driveid.io.consistency import check_meta_units, duplicate_groups, load_json
from driveid.io.manifest import manifest_from_dict
from driveid.io.safe_write import atomic_write_bytes

# derandomized: the suite is a regression gate, the same examples every run
FAST = settings(max_examples=40, deadline=None, derandomize=True,
                suppress_health_check=[HealthCheck.function_scoped_fixture,
                                       HealthCheck.too_slow])
floats_any = st.floats(allow_nan=True, allow_infinity=True)


@FAST
@given(st.lists(floats_any, min_size=0, max_size=40),
       st.lists(floats_any, min_size=0, max_size=40))
def test_record_accepts_or_refuses_cleanly(t, x):
    n = min(len(t), len(x))
    try:
        rec = Record(t=np.array(t[:n]), x=np.array(x[:n]))
    except DriveIdError as exc:
        assert isinstance(exc, ValueError)
        return
    assert np.all(np.isfinite(rec.t)) and np.all(np.diff(rec.t) > 0)


@FAST
@given(st.binary(max_size=600), st.sampled_from([".csv", ".npz", ".mat"]))
def test_readers_refuse_random_bytes_cleanly(data, suffix):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"r{suffix}"
        path.write_bytes(data)
        try:
            read_record(path)
        except Exception as exc:  # noqa: BLE001 - classified below
            # the CLI boundary must turn it into one error line with exit 2, not "bug"
            assert _error_line(exc)[1] == 2, repr(exc)


_cell = st.one_of(st.floats(allow_nan=True, allow_infinity=True).map(repr),
                  st.text(alphabet="0123456789.-e+,;x ", max_size=8))


@FAST
@given(st.lists(st.lists(_cell, min_size=1, max_size=4), min_size=0, max_size=12),
       st.sampled_from(["t,x", "t [s],x [rad]", "t;x;u", "time,position,force", "x"]))
def test_csv_reader_on_random_tables(rows, header):
    text = header + "\n" + "\n".join(",".join(r) for r in rows) + "\n"
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "r.csv"
        path.write_text(text)
        try:
            rec = read_record(path)
        except (DriveIdError, OSError):
            return
        assert rec.n >= 2 and np.all(np.isfinite(rec.x))


@FAST
@given(st.integers(min_value=8, max_value=60), st.floats(0.1, 50), st.floats(1e-3, 10),
       st.sampled_from([".csv", ".npz", ".mat"]))
def test_write_then_read_round_trips(n, omega, amp, suffix):
    t = np.arange(n) * 1e-3
    rec = Record(t=t, x=amp * np.cos(omega * t), meta={"P": 1.5, "note": "ü"})
    with tempfile.TemporaryDirectory() as d:
        path = write_record(rec, Path(d) / f"r{suffix}")
        back = read_record(path)
        assert sorted(p.name for p in Path(d).iterdir()) == [path.name]  # no temporaries
    np.testing.assert_array_equal(back.x, rec.x)
    np.testing.assert_array_equal(back.t, rec.t)


_json = st.recursive(
    st.none() | st.booleans() | st.floats(allow_nan=False) | st.text(max_size=5),
    lambda children: st.lists(children, max_size=3)
    | st.dictionaries(st.text(max_size=5), children, max_size=3), max_leaves=15)


@FAST
@given(_json)
def test_manifest_from_any_json_value(data):
    try:
        manifest_from_dict(data, source="m.json")
    except DriveIdError:
        pass


_run = st.fixed_dictionaries(
    {"file": st.text(min_size=1, max_size=8), "P": floats_any, "D": floats_any},
    optional={"x0": floats_any, "accepted": st.booleans() | st.integers(),
              "index": st.integers() | st.text(max_size=2), "n_peaks": st.integers()})


@FAST
@given(st.lists(_run, max_size=4), st.one_of(st.none(), floats_any),
       st.sampled_from(["rad", "m", "deg", 3]))
def test_manifest_runs(runs, delay, units):
    data = {"runs": runs, "delay_s": delay, "units": units}
    try:
        m = manifest_from_dict(data)
    except DriveIdError:
        return
    assert all(math.isfinite(r.P) and math.isfinite(r.D) for r in m.runs)
    assert m.delay_s is None or (math.isfinite(m.delay_s) and m.delay_s >= 0)


@FAST
@given(st.integers(0, 200), st.sampled_from(["[", "{\"a\":"]))
def test_load_json_depth(depth, opener):
    closer = "]" if opener == "[" else "}"
    text = opener * depth + "0" + closer * depth
    try:
        load_json(text, "x.json", max_depth=64)
    except DriveIdError as exc:
        assert depth > 64 and "levels deep" in str(exc)
    else:
        assert depth <= 64


@FAST
@given(st.text(max_size=200))
def test_toml_loader_refuses_cleanly(text):
    from driveid.sim.config import load_drive_config

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "c.toml"
        path.write_text(text)
        try:
            load_drive_config(path)
        except (DriveIdError, OSError):
            pass


@FAST
@given(st.sampled_from(["t", "x", "u", "v"]),
       st.sampled_from(["s", "ms", "rad", "deg", "m", "mm", "N", "N·m", "Nm", "rpm", "?"]),
       st.sampled_from(["s", "ms", "rad", "deg", "m", "mm", "N", "N·m", "Nm", "rpm", "?"]))
def test_meta_units_agree_only_when_the_si_conversion_agrees(col, head, meta):
    from driveid.io.files import UNIT_CONVERSIONS

    table = UNIT_CONVERSIONS[col]
    same = head == meta or (head in table and table.get(head) == table.get(meta))
    try:
        check_meta_units({col: head}, {col: meta}, "a.csv")
    except DriveIdError:
        assert not same
    else:
        assert same


@FAST
@given(st.one_of(floats_any.map(repr), st.text(max_size=6), floats_any))
def test_option_types_accept_only_finite_checked_numbers(value):
    for kind, rule in ((FiniteFloat(), lambda v: True), (PositiveFloat(), lambda v: v > 0),
                       (NonNegativeFloat(), lambda v: v >= 0)):
        try:
            got = kind.convert(value, None, None)
        except click.BadParameter:
            continue
        assert math.isfinite(got) and abs(got) <= 1e100 and rule(got)


@FAST
@given(st.one_of(st.integers(), st.text(max_size=6)))
def test_bounded_int(value):
    try:
        got = BoundedInt(100, min=1).convert(value, None, None)
    except click.BadParameter:
        return
    assert 1 <= got <= 100


@FAST
@given(st.lists(st.integers(0, 3), min_size=1, max_size=6))
def test_duplicate_groups_find_exactly_the_repeats(picks):
    base = [Record(t=np.arange(8.0), x=np.arange(8.0) * (k + 1)) for k in range(4)]
    records = [base[k] for k in picks]
    groups = duplicate_groups(records)
    expected = {tuple(i for i, p in enumerate(picks) if p == k) for k in set(picks)}
    assert {tuple(g) for g in groups} == {g for g in expected if len(g) > 1}


@FAST
@given(st.binary(max_size=300), st.booleans())
def test_atomic_write_leaves_exactly_the_file(data, twice):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "f.bin"
        atomic_write_bytes(path, data)
        if twice:
            atomic_write_bytes(path, data[::-1], overwrite=True)
        assert [p.name for p in Path(d).iterdir()] == ["f.bin"]
        assert path.read_bytes() == (data[::-1] if twice else data)


def test_json_nan_is_refused():
    with pytest.raises(DriveIdError, match="NaN"):
        load_json('{"P": NaN}', "m.json")
    assert load_json(json.dumps({"P": 1.5}), "m.json") == {"P": 1.5}
