"""Campaign manifests: full round trip, the minimal hand-written form, clear errors."""

import json

import numpy as np
import pytest

from driveid.errors import FileFormatError, OverwriteError
from driveid.io.manifest import Manifest, ManifestRun, read_manifest, write_manifest


def _csv(path, *, header="t,x,u", amplitude=0.1):
    t = np.arange(200) * 1e-3
    x = amplitude * np.exp(-t) * np.cos(30 * t)
    np.savetxt(path, np.column_stack([t, x, -5 * x]), delimiter=",", header=header,
               comments="")
    return x


def _write(folder, data):
    path = folder / "campaign.json"
    path.write_text(json.dumps(data))
    return path


def test_full_manifest_round_trip(tmp_path):
    runs = (ManifestRun(index=1, file="a.csv", P=5.0, D=0.1, x0=1.0, n_peaks=9,
                        settled_at=1.25),
            ManifestRun(index=2, file="b.csv", P=5.0, D=0.1, x0=-1.0, accepted=False,
                        reason="aborted: too much", aborted=True))
    m = Manifest(runs=runs, delay_s=0.01377, K=0.0, units="rad", plant="testbed-a",
                 created="2026-11-23T11:00:00+00:00", protocol={"P_values": [5.0]},
                 complete=True)
    path = write_manifest(m, tmp_path)
    assert path.name == "manifest.json"
    back = read_manifest(tmp_path, check_files=False)
    assert back.runs == runs
    assert (back.delay_s, back.K, back.units, back.plant, back.created, back.complete) == (
        0.01377, 0.0, "rad", "testbed-a", "2026-11-23T11:00:00+00:00", True)
    assert back.protocol == {"P_values": [5.0]}
    assert back.accepted == runs[:1]
    with pytest.raises(OverwriteError, match="--out"):
        write_manifest(m, tmp_path)


def test_minimal_hand_written_manifest(tmp_path):
    x1 = _csv(tmp_path / "r1pos.csv")
    _csv(tmp_path / "r1neg.csv", amplitude=-0.1)
    (tmp_path / "sub").mkdir()
    x3 = _csv(tmp_path / "sub" / "r2pos.csv", amplitude=0.12)  # not a copy of r1pos
    path = _write(tmp_path, {"delay_s": 0.01377, "K": 0, "runs": [
        {"file": "r1pos.csv", "P": 1.5, "D": 0.03},
        {"file": "r1neg.csv", "P": 1.5, "D": 0.03, "accepted": False},
        {"file": "sub/r2pos.csv", "P": 2, "D": 0.03}]})
    m = read_manifest(path)
    assert (m.delay_s, m.K, m.units) == (0.01377, 0.0, "rad")
    records = m.load_records()
    assert len(records) == 2  # the rejected run is skipped
    np.testing.assert_allclose(records[0].x, x1, rtol=1e-15)
    np.testing.assert_allclose(records[1].x, x3, rtol=1e-15)
    assert [(r.meta["P"], r.meta["D"]) for r in records] == [(1.5, 0.03), (2.0, 0.03)]
    assert records[0].meta["delay"] == 0.01377 and records[0].units["x"] == "rad"
    assert len(m.load_records(accepted_only=False)) == 3
    # run from another working directory: paths stay relative to the manifest
    assert m.folder == tmp_path.resolve()


def test_translational_units_apply_to_plain_headers_and_conflicts_are_errors(tmp_path):
    _csv(tmp_path / "r.csv")
    m = read_manifest(_write(tmp_path, {"units": "m", "runs": [
        {"file": "r.csv", "P": 300, "D": 4.5}]}))
    rec = m.load_records()[0]
    assert (rec.units["x"], rec.units["u"]) == ("m", "N")
    assert m.delay_s is None and m.K is None
    _csv(tmp_path / "deg.csv", header="t [s],x [rad],u [N·m]")
    m = read_manifest(_write(tmp_path, {"units": "m", "runs": [
        {"file": "deg.csv", "P": 300, "D": 4.5}]}))
    with pytest.raises(FileFormatError, match="contradicts the manifest's units 'm'"):
        m.load_records()


@pytest.mark.parametrize("data, message", [
    ({"runs": [{"file": "r.csv", "P": 1, "D": 0.1}, {"file": "missing.csv", "P": 1, "D": 0}]},
     r"runs\[1\] names file 'missing.csv', which does not exist"),
    ({"runs": [{"file": "r.csv", "P": 1, "D": 0.1}, {"file": "r.csv", "D": 0.1}]},
     r"runs\[1\] has no 'P'; every run needs \"file\", \"P\" and \"D\""),
    ({"runs": [{"file": "r.csv", "P": "1.5", "D": 0.1}]},
     r"runs\[0\]\.P must be a finite number; got '1.5'"),
    ({"runs": [{"file": "r.csv", "P": 1, "D": 0.1, "gain": 2}]},
     r"runs\[0\] has unknown key\(s\) \['gain'\]"),
    ({"delay": 0.01, "runs": [{"file": "r.csv", "P": 1, "D": 0.1}]},
     r"unknown top-level key\(s\) \['delay'\].*\"delay_s\""),
    ({"runs": []}, r"\"runs\" must be a non-empty list"),
    ({"delay_s": -1, "runs": [{"file": "r.csv", "P": 1, "D": 0.1}]}, r"delay_s must be >= 0"),
    ({"units": "deg", "runs": [{"file": "r.csv", "P": 1, "D": 0.1}]}, r"\"units\" must be"),
    ({"runs": [{"file": "r.csv", "P": 1, "D": 0.1, "accepted": "yes"}]},
     r"runs\[0\]\.accepted must be true or false"),
])
def test_manifest_errors_name_the_key_and_the_fix(tmp_path, data, message):
    _csv(tmp_path / "r.csv")
    with pytest.raises(FileFormatError, match=message):
        read_manifest(_write(tmp_path, data))


def test_missing_manifest_and_invalid_json(tmp_path):
    with pytest.raises(FileNotFoundError, match="no campaign manifest"):
        read_manifest(tmp_path)
    (tmp_path / "manifest.json").write_text("{runs: [")
    with pytest.raises(FileFormatError, match="not valid JSON"):
        read_manifest(tmp_path)
