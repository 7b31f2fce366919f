"""The reading layer (issue 11): formats, header units, column choice, scales, provenance.

Truth: every fixture stores the same simulated decay; a reading is right when the SI values
equal the reference record (to the digits the fixture writes) and the units are converted by
the exact definitions (1 in = 0.0254 m, 1 lbf = 4.4482216152605 N, 1 rpm = π/30 rad/s).
"""

import hashlib
import json
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from tests.fixtures.formats import (
    FIXTURES,
    decay,
    write_clean_csv,
    write_json_inch_kip,
    write_mat_v5,
    write_mat_v73,
    write_tdms,
)

from driveid.errors import FileFormatError, RecordError, RecordWarning
from driveid.io import Record, read_record, read_table
from driveid.io.reading import parse_scale
from driveid.io.units import split_header, to_si


@pytest.mark.parametrize("header, name, unit", [
    ("x [deg]", "x", "deg"), ("x / deg", "x", "deg"), ("x (deg)", "x", "deg"),
    ("x in deg", "x", "deg"), ("Weg &b_A1 / rad", "Weg &b_A1", "rad"),
    ("Zeit t / s", "Zeit t", "s"), ("v / m/s", "v", "m/s"), ("speed(rpm)", "speed", "rpm"),
    ("Torque [N m]", "Torque", "N·m"), ("T [Nm]", "T", "N·m"), ("M [oz-in]", "M", "oz·in"),
    ("F [lbs]", "F", "lbf"), ("x [um]", "x", "µm"), ("n [1/min]", "n", "rpm"),
    ("pos [counts]", "pos", "counts"), ("x", "x", None), ('"time [s]"', "time", "s"),
])
def test_header_spellings(header, name, unit):
    assert split_header(header) == (name, unit)


@pytest.mark.parametrize("column, unit, si, factor", [
    ("x", "in", "m", 0.0254), ("x", "ft", "m", 0.3048), ("x", "µm", "m", 1e-6),
    ("x", "rev", "rad", 2 * math.pi), ("x", "deg", "rad", math.pi / 180),
    ("v", "rpm", "rad/s", math.pi / 30), ("v", "in/s", "m/s", 0.0254),
    ("v", "deg/s", "rad/s", math.pi / 180), ("v", "mm/s", "m/s", 1e-3),
    ("u", "kip", "N", 4448.2216152605), ("u", "lbf", "N", 4.4482216152605),
    ("u", "kN", "N", 1e3), ("u", "mN", "N", 1e-3), ("u", "N·mm", "N·m", 1e-3),
    # published: 1 ozf·in = 7.061552e-3 N·m, 1 lbf·in = 0.1129848 N·m (NIST SP 811)
    ("u", "oz·in", "N·m", 7.0615518e-3), ("u", "lbf·in", "N·m", 0.112984829),
    ("t", "ms", "s", 1e-3),
])
def test_unit_factors_are_the_definitions(column, unit, si, factor):
    got_si, got = to_si(column, unit)
    assert got_si == si and got == pytest.approx(factor, rel=1e-8)  # published digits


def test_unit_errors_name_the_fix():
    with pytest.raises(FileFormatError, match=r"known units for 'x': rad, mrad, deg"):
        to_si("x", "furlong")
    with pytest.raises(FileFormatError, match=r"--scale u=FACTOR"):
        to_si("u", "V")
    with pytest.raises(FileFormatError, match="--counts-per-rev"):
        to_si("x", "counts")
    assert to_si("x", "counts", counts_per_rev=4000) == ("rad", pytest.approx(2 * math.pi / 4000))
    assert to_si("v", "counts/s", counts_per_metre=1e5) == ("m/s", pytest.approx(1e-5))


def test_scale_expressions_are_parsed_safely():
    assert parse_scale("0.02/60") == 0.02 / 60
    assert parse_scale("-(1.5e3 + 500) * 2") == -4000.0
    assert parse_scale("gtau*2", {"gtau": 35.15}) == pytest.approx(70.3)
    for bad in ("__import__('os')", "2*pi", "1/0", "0", "2**10", "abs(-1)"):
        with pytest.raises(FileFormatError, match="scale"):
            parse_scale(bad)


@pytest.mark.parametrize("name", sorted(FIXTURES))
def test_every_fixture_reads_the_reference_decay(tmp_path, name):
    if name in ("parquet", "tdms"):  # optional extras [parquet], [tdms]
        pytest.importorskip({"parquet": "pyarrow", "tdms": "nptdms"}[name])
    writer, options, reference = FIXTURES[name]
    path = writer(tmp_path)
    columns = {}
    for opt, col in (("--time", "t"), ("--position", "x"), ("--force", "u")):
        if opt in options:
            columns[col] = options[options.index(opt) + 1]
    jitter = None if "none" in options else 0.01
    units = dict(options[k + 1].split("=", 1) for k, opt in enumerate(options)
                 if opt == "--unit")
    rec = read_record(path, columns=columns, max_jitter=jitter, units=units)
    ref = decay()
    if name == "cassy":
        # jittery time: compare against the cubic interpolant's values at those times
        from tests.fixtures.formats import jittery_decay

        t, x = jittery_decay()
        np.testing.assert_allclose(rec.t, t, atol=6e-8)  # 7 decimals written [s]
        np.testing.assert_allclose(rec.x, x, atol=6e-11)  # 10 decimals written [rad]
        return
    np.testing.assert_allclose(rec.t, ref.t, atol=1e-9)  # ≥ 6 decimals of ms or s
    # inches come back as the same numbers in metres; 12 significant digits written
    np.testing.assert_allclose(rec.x, ref.x, rtol=1e-10, atol=1e-12)
    assert rec.units["x"] == ("m" if reference == "clean_m" else "rad")
    assert rec.meta["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert rec.meta["rows"] == ref.n and rec.meta["window"] == [0.0, pytest.approx(ref.t[-1])]


def test_unit_conversion_of_force_and_velocity(tmp_path):
    ref = decay()
    rec = read_record(write_json_inch_kip(tmp_path), columns={"x": "data.disp",
                                                              "u": "data.load"})
    np.testing.assert_allclose(rec.u, ref.u, rtol=1e-12, atol=1e-15)  # kip -> N exact
    assert rec.meta["units_in_file"] == {"t": "s", "x": "in", "u": "kip"}
    assert dict(rec.units)["u"] == "N"


def test_matrix_columns_and_scalars_of_mat_files(tmp_path):
    for path in (write_mat_v5(tmp_path), write_mat_v73(tmp_path)):
        table = read_table(path)
        assert [f"data:{i}" for i in range(7)] == list(table.columns)
        rec = read_record(path, columns={"t": "data:0", "x": 1, "v": "data:2"})
        np.testing.assert_array_equal(rec.x, decay().x)


def test_mat_scalar_variable_as_scale(tmp_path):
    path = write_mat_v5(tmp_path)
    rec = read_record(path, columns={"t": "data:0", "x": "data:1", "u": "data:5"},
                      scale={"u": "gain"})
    assert np.all(rec.u == 2.0) and rec.meta["scale"] == {"u": 2.0}


def test_column_errors_list_the_columns(tmp_path):
    path = write_mat_v5(tmp_path)
    with pytest.raises(FileFormatError, match=r"no column 'data:9'.*\[6\] data:6"):
        read_record(path, columns={"t": "data:0", "x": "data:9"})
    with pytest.raises(FileFormatError, match="--position COL"):
        read_record(path)


def test_json_variants(tmp_path):
    ref = decay()
    rows = [{"t": a, "pos [mm]": 1e3 * b} for a, b in zip(ref.t, ref.x, strict=True)]
    (tmp_path / "rows.json").write_text(json.dumps(rows))
    rec = read_record(tmp_path / "rows.json")
    np.testing.assert_allclose(rec.x, ref.x, rtol=1e-12)
    assert rec.units["x"] == "m"
    matrix = {"columns": ["t", "x"], "samples": np.column_stack([ref.t, ref.x]).tolist()}
    (tmp_path / "matrix.json").write_text(json.dumps(matrix))
    rec = read_record(tmp_path / "matrix.json", columns={"t": "samples:0", "x": "samples:1"})
    np.testing.assert_array_equal(rec.x, ref.x)
    beside = {"time": {"values": ref.t.tolist(), "unit": "ms"},
              "angle": {"values": ref.x.tolist(), "unit": "deg"}}
    (tmp_path / "beside.json").write_text(json.dumps(beside))
    rec = read_record(tmp_path / "beside.json")
    assert rec.meta["units_in_file"] == {"t": "ms", "x": "deg"}
    np.testing.assert_allclose(rec.x, np.radians(ref.x), rtol=1e-12)


def test_no_time_column_uses_fs(tmp_path):
    ref = decay()
    np.savetxt(tmp_path / "x.csv", ref.x, header="x [rad]", comments="")
    with pytest.raises(FileFormatError, match=r"--fs HZ"):
        read_record(tmp_path / "x.csv")
    rec = read_record(tmp_path / "x.csv", fs=1000.0)
    np.testing.assert_allclose(rec.t, ref.t, atol=1e-12)
    assert rec.meta["fs_given"] == 1000.0
    rec = read_record(write_tdms(tmp_path))  # TDMS: the rate comes from wf_increment
    assert rec.fs == 1000.0


def test_window_and_its_errors(tmp_path):
    path = write_clean_csv(tmp_path)
    rec = read_record(path, window=(2.0, 5.0))
    assert rec.t[0] == pytest.approx(2.0) and rec.t[-1] == pytest.approx(5.0)
    assert rec.meta["window"] == [pytest.approx(2.0), pytest.approx(5.0)]
    with pytest.raises(FileFormatError, match=r"spans 0\.\.12 s"):
        read_record(path, window=(50.0, None))
    with pytest.raises(FileFormatError, match="before its end"):
        read_record(path, window=(5.0, 2.0))


def test_volts_need_a_scale_and_screw_needs_a_lead(tmp_path):
    ref = decay()
    data = np.column_stack([ref.t, ref.x * 1e3, ref.u / 200, ref.v * 30 / math.pi])
    np.savetxt(tmp_path / "v.csv", data, delimiter=",", comments="",
               header="t [s],x [mm],u [V],n [rpm]")
    with pytest.raises(FileFormatError, match="electrical unit"):
        read_record(tmp_path / "v.csv")
    with pytest.raises(FileFormatError, match=r"--scale v=0.02/60"):
        read_record(tmp_path / "v.csv", columns={"v": "n"}, scale={"u": 200})
    with pytest.raises(FileFormatError, match="--velocity none"):
        read_record(tmp_path / "v.csv", columns={"v": "n"}, scale={"u": 200})
    assert read_record(tmp_path / "v.csv", columns={"v": "none"}, scale={"u": 200}).v is None
    rec = read_record(tmp_path / "v.csv", columns={"v": "n"},
                      scale={"u": "200", "v": "0.02/60"})
    np.testing.assert_allclose(rec.u, ref.u, rtol=1e-9, atol=1e-15)  # %.18e written
    assert rec.units["u"] == "N" and rec.units["v"] == "m/s"  # SI, following x in m
    np.testing.assert_allclose(rec.v, ref.v * 30 / math.pi * 0.02 / 60, rtol=1e-9, atol=1e-15)


def test_counts_position(tmp_path):
    ref = decay()
    counts = np.round(ref.x / (2 * math.pi) * 4000)
    np.savetxt(tmp_path / "enc.csv", np.column_stack([ref.t, counts]), delimiter=";",
               header="Time / s;Encoder / counts", comments="")
    with pytest.raises(FileFormatError, match="--counts-per-rev"):
        read_record(tmp_path / "enc.csv", columns={"x": "Encoder"})
    rec = read_record(tmp_path / "enc.csv", columns={"x": "Encoder"}, counts_per_rev=4000)
    assert np.max(np.abs(rec.x - ref.x)) <= math.pi / 4000 + 1e-12  # half a count


def test_decimal_comma_whitespace_and_comments(tmp_path):
    ref = decay()
    lines = ["% exported by scope", "# comment", "t\tx"]
    lines += [f"{a:.6f}\t{b:.12f}".replace(".", ",") for a, b in zip(ref.t, ref.x,
                                                                     strict=True)]
    (tmp_path / "tab.dat").write_text("\n".join(lines))
    rec = read_record(tmp_path / "tab.dat")
    np.testing.assert_allclose(rec.x, ref.x, atol=1e-12)
    lines = ["time   position"] + [f"  {a:.6f}   {b:.12f}" for a, b in zip(ref.t, ref.x,
                                                                         strict=True)]
    (tmp_path / "ws.txt").write_text("\n".join(lines))
    np.testing.assert_allclose(read_record(tmp_path / "ws.txt").x, ref.x, atol=1e-12)


def test_unknown_format_and_garbage(tmp_path):
    (tmp_path / "a.xlsx").write_bytes(b"PK")
    with pytest.raises(FileFormatError, match=r"\.csv.*\.tdms"):
        read_record(tmp_path / "a.xlsx")
    (tmp_path / "b.csv").write_text("hello\nworld\n")
    with pytest.raises(FileFormatError, match="no block of numeric rows"):
        read_record(tmp_path / "b.csv")


def test_hdf5_and_npz_tables(tmp_path):
    import h5py

    ref = decay()
    with h5py.File(tmp_path / "run.h5", "w") as fh:
        fh["signals/time"] = ref.t
        fh["signals/angle"] = np.degrees(ref.x)
        fh["signals/angle"].attrs["unit"] = "deg"
    rec = read_record(tmp_path / "run.h5")
    np.testing.assert_allclose(rec.x, ref.x, rtol=1e-14)
    np.savez(tmp_path / "m.npz", data=np.column_stack([ref.t, ref.x]))
    rec = read_record(tmp_path / "m.npz", columns={"t": "data:0", "x": "data:1"})
    np.testing.assert_array_equal(rec.x, ref.x)


def test_record_from_dataframe_and_resampling():
    ref = decay()
    df = pd.DataFrame({"Zeit t / ms": 1e3 * ref.t, "Weg / mm": 1e3 * ref.x})
    rec = Record.from_dataframe(df, window=(1.0, 3.0))
    assert rec.units["x"] == "m" and rec.t[0] == pytest.approx(1.0)
    rng = np.random.default_rng(3)
    t = np.arange(200) * 1e-3 + rng.uniform(-2e-5, 2e-5, 200)
    jittery = Record(t=t, x=3.0 * t + 1.0, max_jitter=None)
    with pytest.warns(RecordWarning, match="resampled linearly"):
        uniform = jittery.resampled_uniform(purpose="the test")
    assert uniform.jitter() < 1e-9
    np.testing.assert_allclose(uniform.x, 3.0 * uniform.t + 1.0, rtol=1e-12)  # linear: exact
    assert uniform.resampled_uniform() is uniform
    with pytest.raises(RecordError, match="not uniform"):
        Record(t=t, x=t)


def test_units_row_timestamps_and_quoted_headers(tmp_path):
    ref = decay()
    rows = "\n".join(f"{a},{1e3 * b},0" for a, b in zip(ref.t, ref.x, strict=True))
    (tmp_path / "unitrow.csv").write_text("Time,Position,Force\ns,mm,N\n" + rows)
    rec = read_record(tmp_path / "unitrow.csv")
    assert rec.meta["units_in_file"] == {"t": "s", "x": "mm", "u": "N"}
    np.testing.assert_allclose(rec.x, ref.x, rtol=1e-12)
    stamps = pd.Timestamp("2024-05-01 12:00:00") + pd.to_timedelta(ref.t[:500], unit="s")
    lines = [f"{s.isoformat(sep=' ', timespec='milliseconds')},{1e3 * b}"
             for s, b in zip(stamps, ref.x[:500], strict=True)]
    (tmp_path / "stamps.csv").write_text('"Timestamp","Position, mm"\n' + "\n".join(lines))
    rec = read_record(tmp_path / "stamps.csv")
    np.testing.assert_allclose(rec.t, ref.t[:500], atol=1e-9)  # ms timestamps, exact
    assert rec.meta["columns_used"] == {"t": "Timestamp", "x": "Position"}
    assert rec.meta["units_in_file"]["x"] == "mm"


def test_simulink_struct_and_sparse_last_column(tmp_path):
    from scipy.io import savemat

    ref = decay()
    savemat(tmp_path / "sim.mat", {"simout": {"time": ref.t.reshape(-1, 1), "signals": {
        "values": np.column_stack([ref.x, 2 * ref.x]), "dimensions": 2}}})
    rec = read_record(tmp_path / "sim.mat", columns={"x": "simout.signals.values:0"})
    assert rec.meta["columns_used"]["t"] == "simout.time"  # found by its leaf name
    np.testing.assert_array_equal(rec.x, ref.x)
    lines = ["t,x,event"] + [f"{a:.17g},{b:.17g}," + ("1" if i % 7 == 0 else "")
                             for i, (a, b) in enumerate(zip(ref.t, ref.x, strict=True))]
    (tmp_path / "sparse.csv").write_text("\n".join(lines))
    table = read_table(tmp_path / "sparse.csv")
    assert list(table.columns) == ["t", "x", "event"]
    np.testing.assert_array_equal(read_record(tmp_path / "sparse.csv").x, ref.x)


@pytest.mark.parametrize("codec, bom", [("utf-16-le", b"\xff\xfe"), ("utf-16-be", b"\xfe\xff"),
                                        ("utf-16-le", b"")])
def test_excel_unicode_text_exports(tmp_path, codec, bom):
    # Excel's "Unicode text" is UTF-16 (a BOM, or none): read as cp1252 it had no numeric
    # block ("found no block of numeric rows")
    ref = decay()
    text = "Zeit [s];Position [°]\n" + "".join(
        f"{a:.6f};{b:.12f}\n".replace(".", ",") for a, b in zip(ref.t, ref.x, strict=True))
    (tmp_path / "u.csv").write_bytes(bom + text.encode(codec))
    rec = read_record(tmp_path / "u.csv")
    np.testing.assert_allclose(rec.x, np.radians(ref.x), atol=1e-12)


def test_time_zones_and_a_clock_set_back_an_hour(tmp_path):
    # ISO times with an offset, across the DST switch, read on one clock (UTC); a local
    # clock set back an hour is named as such (its advice was to sort the samples)
    stamps = [f"2024-03-31T01:59:59.{k:01d}00+01:00" for k in range(10)] + \
        [f"2024-03-31T03:00:00.{k:01d}00+02:00" for k in range(10)]
    (tmp_path / "z.csv").write_text("timestamp,x [rad]\n" + "".join(
        f"{s},{k}\n" for k, s in enumerate(stamps)))
    np.testing.assert_allclose(np.diff(read_table(tmp_path / "z.csv").columns["timestamp"]),
                               0.1, atol=1e-9)
    stamps = [f"2024-10-27 02:59:{50 + 0.5 * k:04.1f}" for k in range(20)] + \
        [f"2024-10-27 02:00:{0.5 * k:04.1f}" for k in range(20)]
    (tmp_path / "b.csv").write_text("timestamp,x [rad]\n" + "".join(
        f"{s},{k % 7}\n" for k, s in enumerate(stamps)))
    with pytest.raises(RecordError, match="daylight saving time ends"):
        read_record(tmp_path / "b.csv")


def test_a_units_row_with_an_unknown_unit_is_named(tmp_path):
    # taken as the header before: "no position column ... columns found: [1] parsec"
    ref = decay()
    (tmp_path / "u.csv").write_text("Time,Position,Torque\ns,parsec,N*m\n" + "".join(
        f"{a:.6f},{b:.12f},0\n" for a, b in zip(ref.t, ref.x, strict=True)))
    with pytest.raises(FileFormatError, match="'x' is in 'parsec', which driveid does not"):
        read_record(tmp_path / "u.csv")


def test_thousands_separators_quoted_and_german(tmp_path):
    # "572,845.832" (quoted, in a , file) and 572.845,832 (a ; file with decimal commas)
    # were "no block of numeric rows" / "expected 4 fields"; mdeg was an unknown unit
    ref = decay()
    mdeg = 1e3 * np.degrees(ref.x) + 5e5  # positions of 6 digits: every one grouped

    def grouped(v, thousands, decimal):
        whole, frac = f"{v:.3f}".split(".")
        sign, whole = ("-", whole[1:]) if whole.startswith("-") else ("", whole)
        parts = [whole[max(i - 3, 0):i] for i in range(len(whole), 0, -3)][::-1]
        return sign + thousands.join(parts) + decimal + frac

    (tmp_path / "en.csv").write_text("time [s],position [mdeg],torque [N*m]\n" + "".join(
        f'{a:.4f},"{grouped(b, ",", ".")}",0\n' for a, b in zip(ref.t, mdeg, strict=True)))
    (tmp_path / "de.csv").write_text("Zeit [s];Position [mdeg];Moment [N·m]\n" + "".join(
        f"{a:.4f};{grouped(b, '.', ',')};0\n".replace(f"{a:.4f}", f"{a:.4f}".replace(".", ","))
        for a, b in zip(ref.t, mdeg, strict=True)))
    for name in ("en.csv", "de.csv"):
        rec = read_record(tmp_path / name)
        # the file holds 3 decimals of a millidegree: 1e-3 mdeg = 1.7e-8 rad
        np.testing.assert_allclose(rec.x, np.radians((mdeg.round(3)) / 1e3), atol=1e-12)


def test_fortran_d_exponents_with_points_and_decimal_commas(tmp_path):
    # Fortran's list-directed output writes 1.000000000D-03; such a file was refused as
    # "no block of numeric rows" (fifth campaign, left open until 2026-11-28)
    ref = decay()

    def d(v, decimal="."):
        return f"{v:.12E}".replace("E", "D").replace(".", decimal)

    (tmp_path / "f.csv").write_text("t [s],x [rad]\n" + "".join(
        f"{d(a)},{d(b)}\n" for a, b in zip(ref.t, ref.x, strict=True)))
    (tmp_path / "de.csv").write_text("t [s];x [rad]\n" + "".join(
        f"{d(a, ',')};{d(b, ',')}\n" for a, b in zip(ref.t, ref.x, strict=True)))
    # lower-case d and a mixed column (plain numbers beside D exponents) read too
    (tmp_path / "mix.csv").write_text("t [s],x [rad]\n" + "".join(
        f"{float(a)!r},{d(b).lower() if k % 2 else repr(float(b))}\n"
        for k, (a, b) in enumerate(zip(ref.t, ref.x, strict=True))))
    for name in ("f.csv", "de.csv", "mix.csv"):
        rec = read_record(tmp_path / name)
        # 13 significant digits written: relative 5e-13 of values below 1.1 rad
        np.testing.assert_allclose(rec.x, ref.x, rtol=0, atol=1e-12)
        np.testing.assert_allclose(rec.t, ref.t, rtol=1e-12)


def test_clock_times_that_cross_midnight(tmp_path):
    # 23:59:59.5 -> 00:00:00.0 was read as time going back 86399.5 s (refused, with advice
    # to sort the samples, which would scramble the record)
    stamps = [f"23:59:{59 + 0.1 * k:06.3f}" if k < 10 else f"00:00:{0.1 * (k - 10):06.3f}"
              for k in range(30)]
    (tmp_path / "m.csv").write_text("time,x [rad]\n" + "".join(
        f"{s},{k}\n" for k, s in enumerate(stamps)))
    t = read_table(tmp_path / "m.csv").columns["time"]
    np.testing.assert_allclose(np.diff(t), 0.1, atol=1e-9)


def test_missing_value_cells_and_ragged_rows(tmp_path):
    ref = decay()
    rows = [f"{a:.17g},{b:.17g},0" for a, b in zip(ref.t, ref.x, strict=True)]
    # a logger's missing-value marks: the file still reads from its header, and the record's
    # finiteness check names them (before, the block search restarted below the last mark
    # and the file read as headerless: "no time column")
    marked = list(rows)
    for i, mark in ((3, "n/a"), (40, "-"), (41, "NaN"), (90, "#N/A")):
        marked[i] = f"{ref.t[i]:.17g},{mark},{mark if i == 41 else 0}"
    (tmp_path / "marks.csv").write_text("\n".join(["t [s],x [rad],u [N*m]", *marked]))
    table = read_table(tmp_path / "marks.csv")
    assert list(table.columns) == ["t", "x", "u"]
    assert np.isnan(table.columns["x"]).sum() == 4
    with pytest.raises(RecordError, match="'x' has 4 non-finite.*drop or interpolate"):
        read_record(tmp_path / "marks.csv")
    # a few rows with extra fields under a 3-name header: one line naming the first of them
    ragged = list(rows)
    for i in (7, 107):
        ragged[i] += ",9,9,9"
    (tmp_path / "ragged.csv").write_text("\n".join(["t [s],x [rad],u [N*m]", *ragged]))
    with pytest.raises(FileFormatError, match=r"names 3 columns but line 9 \(and 1 more"):
        read_table(tmp_path / "ragged.csv")


@settings(max_examples=100, deadline=None)
@given(st.text(max_size=40))
def test_scale_text_never_escapes_the_arithmetic(text):
    try:
        value = parse_scale(text)
    except FileFormatError:
        return
    assert math.isfinite(value) and value != 0


@settings(max_examples=15, deadline=None)
@given(sep=st.sampled_from([",", ";", "\t", " "]), decimal=st.sampled_from([".", ","]),
       preamble=st.lists(st.sampled_from(["Device: DAQ", "Operator;X", "", "# note",
                                          "Channels 2"]), max_size=4),
       unit=st.sampled_from(["mm", "deg", "rad", "in"]), bom=st.booleans(),
       crlf=st.booleans(), seed=st.integers(0, 2**16))
def test_any_delimited_export_reads_back(tmp_path_factory, sep, decimal, preamble, unit, bom,
                                         crlf, seed):
    if sep == "," and decimal == ",":
        return  # not a valid CSV without quoting; no export writes it
    rng = np.random.default_rng(seed)
    t = np.arange(50) * 1e-3
    x = rng.normal(size=50)
    header = sep.join(["time [s]", f"position [{unit}]"]) if sep != " " else \
        f"time_[s] pos[{unit}]".replace("time_[s]", "t[s]")
    rows = [sep.join(f"{v:.10g}".replace(".", decimal) for v in (a, b))
            for a, b in zip(t, x, strict=True)]
    text = ("\r\n" if crlf else "\n").join([*preamble, header, *rows])
    path = tmp_path_factory.mktemp("h") / "export.csv"
    path.write_bytes(("\ufeff" if bom else "").encode() + text.encode("utf-8"))
    rec = read_record(path)
    factor = to_si("x", unit)[1]
    np.testing.assert_allclose(rec.x, x * factor, rtol=1e-9)  # 10 significant digits written
    np.testing.assert_allclose(rec.t, t, atol=1e-12)


def test_metadata_pair_above_a_single_unnamed_column(tmp_path):
    # a hobby rig's export: a line of names and a line of values, then one column of angles
    # in degrees, no time column; the rate comes from the file's own 'sample_rate' entry
    angle = 45.0 * np.cos(2 * np.pi * 1.7 * np.arange(600) / 1000.0)
    lines = ["trigger_start_deg, sample_rate, duration_sec", "45, 1000, 0.6 "]
    lines += [f"{a:.2f}" for a in angle]
    path = tmp_path / "pendulum.txt"
    path.write_text("\n".join(lines) + "\n")
    from driveid.io import read_record

    rec = read_record(path, columns={"x": 0}, units={"x": "deg"})
    assert rec.n == 600 and rec.fs == pytest.approx(1000.0)
    assert rec.x[0] == pytest.approx(np.radians(45.0), abs=1e-4)  # 0.01 deg written
    assert rec.units["x"] == "rad" and "x" not in rec.meta["units_in_file"]  # from --unit


@pytest.mark.shared_data
def test_rotary_pendulum_records_read_and_fit(shared_data):
    from driveid.identify.free_decay.output_error import estimate_output_error
    from driveid.io import read_record

    folder = shared_data / "rotary_pendulum_free_swing"
    rec = read_record(folder / "pendulum_free_swing_data_03.txt", columns={"x": 0},
                      units={"x": "deg"})
    assert rec.n == 5000 and rec.fs == pytest.approx(1000.0)  # SOURCE.md: 1 kHz for 5 s
    est = estimate_output_error([rec])
    # released from 45 deg: a ~1.7 Hz pendulum (measured 10.57 rad/s); the sin(theta)
    # nonlinearity makes this an amplitude-averaged value, so only a plausible band is checked
    assert 10.0 < est.value("omega0") < 11.2
    assert est.value("theta_k_mean") > 0  # SOURCE.md: a clear Coulomb component
