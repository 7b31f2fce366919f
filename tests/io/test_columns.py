"""Reading that never guesses silently (issue 26, item 2), on exports imitating real labs."""

import math
import re

import numpy as np
import pytest
from tests.fixtures.formats import (
    SIGN_MAGNITUDE_COUNTS,
    decay,
    write_ni_force_log,
    write_robot_log,
    write_servo_telemetry,
    write_sign_magnitude,
    write_tracker,
    write_unitless,
)

from driveid.errors import FileFormatError, RecordWarning
from driveid.io import read_record
from driveid.io.columns import parse_column_name
from driveid.io.reading import decode_sign_magnitude
from driveid.io.tables import read_table
from driveid.io.units import split_header


def _notes(rec):
    return " | ".join(rec.meta["notes"])


def test_a_number_in_parentheses_stays_part_of_the_name():
    assert split_header("pos (3)") == ("pos (3)", None)
    assert split_header("Force (channel 1)") == ("Force (channel 1)", None)
    assert split_header("pos (mm)") == ("pos", "mm")
    assert split_header("x [furlong]") == ("x", "furlong")  # unknown: reported, not dropped


def test_servo_telemetry_full_name_is_that_column_and_the_torque_follows(tmp_path):
    path = write_servo_telemetry(tmp_path)
    assert list(read_table(path).columns)[1:4] == ["pos (5)", "pos (3)", "pos (4)"]
    rec = read_record(path, columns={"x": "pos (3)"})
    ref = decay()
    # servo 3 holds the reference decay, written with 12 significant digits
    np.testing.assert_allclose(rec.x, ref.x, atol=1e-11)
    assert rec.meta["columns_used"] == {"x": "pos (3)", "u": "torque (3)", "t": "time"}
    assert "'torque (3)' as the force" in _notes(rec)
    # the base name fits three columns: refused, the candidates listed with their index
    with pytest.raises(FileFormatError, match=r"'pos' for the position .* fits 3 columns: "
                                              r"\[1\] 'pos \(5\)', \[2\] 'pos \(3\)'"):
        read_record(path, columns={"x": "pos"})
    # nothing asked: the position is ambiguous, refused with the candidates
    with pytest.raises(FileFormatError, match=r"3 columns could be the position: 'pos \(5\)', "
                                              r"'pos \(3\)', 'pos \(4\)'"):
        read_record(path)
    # the torque follows the servo number of the position
    rec = read_record(path, columns={"x": 2})  # by index: servo 3 again
    assert rec.u is not None and rec.meta["columns_used"]["u"] == "torque (3)"
    # an ambiguous optional column (two velocities of a Tracker table) is left out, said so
    tracker = tmp_path / "pendulum.txt"
    tracker.write_text("mass A\nt\tθ\tω\tv\n" + "\n".join(
        f"{k / 100}\t{k}\t1\t2" for k in range(20)))
    rec = read_record(tracker, columns={"x": "θ"})
    assert rec.v is None and "2 columns could be the velocity: 'ω', 'v'; none is used" \
        in _notes(rec)


def test_robot_log_conventions_joint_numbers_and_predictions(tmp_path):
    path = write_robot_log(tmp_path)
    rec = read_record(path, columns={"x": "q2"})
    ref = decay()
    np.testing.assert_allclose(rec.x, ref.x, atol=1e-11)  # 12 significant digits written
    np.testing.assert_allclose(rec.u, ref.u, atol=1e-11)
    # joint 2's velocity and measured torque, never the model's prediction or ddq2
    assert rec.meta["columns_used"] == {"x": "q2", "v": "dq2", "u": "tau2", "t": "time"}
    notes = _notes(rec)
    assert "'dq2' as the velocity" in notes and "'q2_tau_J_compensate' (model prediction)" \
        in notes
    with pytest.raises(FileFormatError, match=r"2 columns could be the position: 'q1', 'q2'"):
        read_record(path)
    assert parse_column_name("ddq2").quantity == "a"
    assert parse_column_name("q2_tau_J_compensate").role == "prediction"
    assert parse_column_name("q_d").role == "target"  # Franka: desired position
    assert parse_column_name("qd").quantity == "v"  # Corke: q-dot


def test_measured_wins_over_target_and_the_choice_is_shown(tmp_path):
    path = tmp_path / "servo.csv"
    t = np.arange(100) / 100
    rows = "\n".join(f"{a},{np.sin(a)},{np.cos(a)},{0.1 * a}" for a in t)
    path.write_text("t [s],pos_target [deg],pos_measured [deg],torque_cmd [N·m]\n" + rows)
    rec = read_record(path)
    assert rec.meta["columns_used"] == {"t": "t", "x": "pos_measured", "u": "torque_cmd"}
    notes = _notes(rec)
    assert "'pos_measured' as the position (measured; passed over: 'pos_target' " \
           "(target/commanded))" in notes
    assert "'torque_cmd' as the force (target/commanded)" in notes  # the drive's input


def test_a_unitless_column_gets_one_note_naming_the_unit_and_the_option(tmp_path):
    rec = read_record(write_unitless(tmp_path))
    notes = rec.meta["notes"]
    assert len(notes) == 3  # t, x, u: one each
    assert any("'x' states no unit: read as rad; give --unit x=m" in n for n in notes)
    assert any("'u' states no unit: read as N·m; give --unit u=N" in n for n in notes)
    # a stated unit needs no note
    stated = read_record(write_unitless(tmp_path), units={"t": "s", "x": "rad", "u": "N·m"})
    assert not stated.meta["notes"]


def test_tracker_export_in_metres_with_a_preamble(tmp_path):
    path = write_tracker(tmp_path)
    rec = read_record(path)
    assert rec.units["x"] == "rad" and "--unit x=m" in _notes(rec)  # said, not silent
    rec = read_record(path, units={"x": "m"})
    assert rec.units["x"] == "m" and rec.meta["columns_used"]["x"] == "x"
    np.testing.assert_allclose(rec.x, decay().x, atol=1e-11)


def test_every_column_and_unit_problem_in_one_message(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("t [s],x [furlong],u [V],v [rpm]\n" + "\n".join(
        f"{k / 100},{k},{k},{k}" for k in range(20)))
    with pytest.raises(FileFormatError) as info:
        read_record(path, columns={"t": "time"})
    message = str(info.value)
    # one round trip instead of three: the column, the position's and the force's unit
    assert message.startswith("bad.csv: 3 problems: (1) no column 'time' for the time")
    assert "furlong" in message and "electrical unit" in message and "--scale u=" in message
    assert message.count("\n") == 0


def test_ni_two_line_header_and_a_force_only_file(tmp_path):
    path = write_ni_force_log(tmp_path)
    table = read_table(path)
    assert list(table.columns) == ["Time", "Load cell"]
    assert table.units == {"Time": "s", "Load cell": "N"}
    assert table.notes.get("Title") == "Load cell log"
    with pytest.raises(FileFormatError, match="no position column.*driveid inspect FILE"):
        read_record(path)


def test_inspect_describes_force_only_and_speed_only_files(tmp_path):
    from click.testing import CliRunner

    from driveid.commands.inspect import inspect_command

    res = CliRunner().invoke(inspect_command, [str(write_ni_force_log(tmp_path)), "--json"])
    assert res.exit_code == 0, res.output
    import json

    info = json.loads(res.stdout)
    assert info["position"] is None and info["u"]["column"] == "Load cell"
    assert info["u"]["unit"] == "N" and info["fs"] == pytest.approx(1000.0)
    # amplitude 10 N of the slow load cycle, printed with 9 significant digits
    assert info["u"]["max"] == pytest.approx(10.0, rel=1e-6)
    speed = tmp_path / "speed.csv"
    speed.write_text("time [s],speed [rpm]\n" + "\n".join(f"{k / 100},60" for k in range(50)))
    res = CliRunner().invoke(inspect_command, [str(speed), "--json"])
    assert res.exit_code == 0, res.output
    info = json.loads(res.stdout)
    assert info["position"] == "integrated velocity"
    # 60 rpm = 2π rad/s for 0.49 s, integrated by trapezoids (exact for a constant)
    assert info["x"]["max"] == pytest.approx(2 * math.pi * 0.49, rel=1e-12)


def test_speed_only_record_for_commands_that_need_no_position(tmp_path):
    speed = tmp_path / "speed.csv"
    speed.write_text("time [s],speed [rad/s]\n" + "\n".join(f"{k / 100},{k / 10}"
                                                            for k in range(50)))
    with pytest.raises(FileFormatError, match="no position"):
        read_record(speed)
    rec = read_record(speed, position=False)
    assert rec.meta["derived"]["x"].startswith("velocity integrated")
    # x = ∫ v dt with v = 10 t: 5 t², exact for trapezoids of a linear velocity
    np.testing.assert_allclose(rec.x, 5 * rec.t**2, atol=1e-12)


def test_sign_magnitude_register_decoded_or_flagged(tmp_path):
    assert decode_sign_magnitude(np.array([3.0, 32771.0, 32768.0]), 16).tolist() == [3, -3, 0]
    with pytest.raises(FileFormatError, match="holds integers 0..65535"):
        decode_sign_magnitude(np.array([70000.0]), 16)
    path = write_sign_magnitude(tmp_path)
    with pytest.warns(RecordWarning) as caught:  # also: the jumps look like corrupted bursts
        read_record(path)
    assert any(re.search("16-bit sign-magnitude.*--sign-magnitude x:16", str(w.message))
               for w in caught)
    rec = read_record(path, sign_magnitude={"x": 16},
                      scale={"x": f"1/{SIGN_MAGNITUDE_COUNTS:g}"})
    # the register rounds to 1/10000 rad: the decoded position is within half a count
    np.testing.assert_allclose(rec.x, decay().x, atol=0.5 / SIGN_MAGNITUDE_COUNTS + 1e-12)
    assert rec.meta["reading"]["sign_magnitude"] == {"x": 16}


def test_reading_options_are_kept_for_reuse(tmp_path):
    from driveid.identify.core.estimate import inputs_of

    path = write_robot_log(tmp_path)
    rec = read_record(path, columns={"x": "q2"}, units={"x": "rad"}, max_jitter=None)
    assert rec.meta["reading"] == {"columns": {"x": "q2"}, "units": {"x": "rad"},
                                   "max_jitter": None}
    assert inputs_of([rec])[0]["reading"] == rec.meta["reading"]
    assert inputs_of([rec])[0]["notes"] == rec.meta["notes"]  # kept with the result
    assert "reading" not in read_record(write_unitless(tmp_path)).meta  # defaults: nothing


def test_a_written_record_does_not_carry_the_old_reading(tmp_path):
    from driveid.io import write_record

    rec = read_record(write_robot_log(tmp_path), columns={"x": "q2"})
    again = read_record(write_record(rec, tmp_path / "joint2.csv"))
    # units are in the header now: no note, and no reading options of the old file
    assert "reading" not in again.meta and again.meta["notes"] == []


def test_epos_export_nameless_time_by_its_unit_and_a_percent_torque(tmp_path):
    """Maxon EPOS Studio export: a nameless time column in ms, a unit row with '%'."""
    path = tmp_path / "epos.csv"
    rows = "\n".join(f"{40.0 * k:.3f};{100 + k % 3};{1.5 + 0.1 * (k % 2)}" for k in range(60))
    path.write_text("Date:;2020-07-09 22:31:10\nSampling period:;40.000\n"
                    ";Velocity actual value averaged;Torque actual value averaged\n"
                    "ms;rpm;%\n" + rows + "\n")
    table = read_table(path)
    assert table.units == {"0": "ms", "Velocity actual value averaged": "rpm",
                           "Torque actual value averaged": "%"}
    with pytest.raises(FileFormatError, match=r"in %, a fraction of a rated.*--scale u=RATED/100"):
        read_record(path, position=False)
    rec = read_record(path, position=False, scale={"u": "0.5/100"})
    assert rec.meta["columns_used"]["t"] == "0" and "(its unit ms)" in _notes(rec)
    assert rec.t[1] == pytest.approx(0.040)  # 40 ms, exactly converted
    assert rec.v[0] == pytest.approx(100 * math.pi / 30)  # 100 rpm in rad/s
