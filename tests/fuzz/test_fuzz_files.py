"""Hostile record files through every identify command: one error line or a right answer.

The files are made by the tests and small: non-UTF-8 bytes, truncated .npz/.mat, object
and string arrays, malformed ``# meta:`` lines, deep JSON, empty, header-only and one-row
files, NaN/inf samples, units that contradict their metadata.
"""

from __future__ import annotations

import io
import json

import numpy as np
import pytest

from tests.fuzz.conftest import snapshot

_T = np.arange(400) * 1e-3
_X = np.exp(-0.3 * _T) * np.cos(25 * _T)


def _csv(rows: int = 400, header: str = "t [s],x [rad],u [N·m]", meta: str | None = None
         ) -> bytes:
    lines = ["# driveid record"]
    if meta is not None:
        lines.append(f"# meta: {meta}")
    lines.append(header)
    lines += [f"{_T[i]:.17g},{_X[i]:.17g},0.0" for i in range(rows)]
    return ("\n".join(lines) + "\n").encode()


def _npz(**arrays) -> bytes:
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    return buf.getvalue()


def _mat(**arrays) -> bytes:
    from scipy.io import savemat

    buf = io.BytesIO()
    savemat(buf, arrays)
    return buf.getvalue()


def _nan_csv() -> bytes:
    text = _csv().decode().splitlines()
    text[10] = "0.007,nan,0.0"
    return ("\n".join(text) + "\n").encode()


def _inf_csv() -> bytes:
    text = _csv().decode().splitlines()
    text[12] = "0.009,inf,0.0"
    return ("\n".join(text) + "\n").encode()


# name -> (file name, content); every one must be refused with one clean line
HOSTILE = {
    "empty": ("a.csv", b""),
    "blank-lines": ("a.csv", b"\n\n\n"),
    "comments-only": ("a.csv", b"# driveid record\n# meta: {}\n"),
    "header-only": ("a.csv", b"t,x,u\n"),
    "one-row": ("a.csv", b"t,x,u\n0,1,0\n"),
    "two-rows": ("a.csv", b"t,x\n0,1\n0.001,0.9\n"),
    "non-utf8-header": ("a.csv", b"t,x\xff\xfe,u\n0,1,0\n"),
    "non-utf8-body": ("a.csv", _csv()[:200] + b"\xff\xfe\xfa" + _csv()[200:]),
    "latin1-units": ("a.csv", "t [s],x [°],u\n".encode("latin-1") + b"0,1,0\n0.001,1,0\n"),
    "binary-garbage": ("a.csv", bytes(range(256)) * 8),
    "nul-bytes": ("a.csv", b"t,x\n0,\x001\n"),
    "text-in-data": ("a.csv", b"t,x\n0,1\n0.001,one\n"),
    "ragged-rows": ("a.csv", b"t,x,u\n0,1,0\n0.001,1\n"),
    "duplicate-column": ("a.csv", b"t,x,x\n0,1,2\n"),
    "no-position": ("a.csv", b"t,y\n0,1\n0.001,2\n"),
    "bad-header-field": ("a.csv", b"t,x+y\n0,1\n"),
    "unknown-unit": ("a.csv", _csv(header="t [fortnight],x [rad],u [N·m]")),
    "meta-not-json": ("a.csv", _csv(meta="{not json")),
    "meta-array": ("a.csv", _csv(meta="[1, 2, 3]")),
    "meta-deep": ("a.csv", _csv(meta="[" * 100_000 + "]" * 100_000)),
    "meta-units-not-object": ("a.csv", _csv(meta='{"units": 5}')),
    "meta-nan": ("a.csv", _csv(meta='{"P": NaN}')),
    "nan-sample": ("a.csv", _nan_csv()),
    "inf-sample": ("a.csv", _inf_csv()),
    "time-backwards": ("a.csv", b"t,x\n" + b"".join(
        f"{0.001 * (100 - i)},{np.cos(i / 5)}\n".encode() for i in range(100))),
    "constant-time": ("a.csv", b"t,x\n" + b"0,1\n" * 100),
    "npz-truncated": ("a.npz", _npz(t=_T, x=_X)[:300]),
    "npz-empty": ("a.npz", b""),
    "npz-not-zip": ("a.npz", b"PK\x03\x04 this is not a zip"),
    "npz-object-array": ("a.npz", b"placeholder"),  # replaced below (needs pickle)
    "npz-string-array": ("a.npz", _npz(t=np.array(["a", "b", "c"]), x=np.array(["1", "2", "3"]))),
    "npz-2d-position": ("a.npz", _npz(t=_T, x=np.ones((400, 3)))),
    "npz-length-mismatch": ("a.npz", _npz(t=_T, x=_X[:-7])),
    "npz-bad-meta": ("a.npz", _npz(t=_T, x=_X, meta=np.array("{oops"))),
    "npz-no-time": ("a.npz", _npz(x=_X)),
    "mat-truncated": ("a.mat", _mat(t=_T, x=_X)[:200]),
    "mat-empty": ("a.mat", b""),
    "mat-garbage": ("a.mat", b"MATLAB 5.0 MAT-file" + b"\x00" * 50),
    "mat-string-vars": ("a.mat", _mat(t="hello", x="world")),
    "mat-bad-meta": ("a.mat", _mat(t=_T, x=_X, driveid_meta="{oops")),
    "unknown-suffix": ("a.xyz", _csv()),
}


def _object_npz() -> bytes:
    buf = io.BytesIO()
    np.savez(buf, t=np.array([0.0, 0.001, None], dtype=object), x=_X[:3].astype(object))
    return buf.getvalue()


HOSTILE["npz-object-array"] = ("a.npz", _object_npz())

COMMANDS = {
    "logdec": ("identify", "logdec"),
    "hilbert": ("identify", "hilbert"),
    "wavelet": ("identify", "wavelet"),
    "friction-map": ("identify", "friction-map"),
}
def _case(cmd: str, case: str):
    return pytest.param(cmd, case, id=f"{cmd}-{case}")


CASES = [_case(cmd, case) for case in HOSTILE for cmd in COMMANDS]


@pytest.mark.parametrize("command, case", CASES)
def test_hostile_record_is_one_error_line(run, tmp_path, command, case):
    name, content = HOSTILE[case]
    path = tmp_path / name
    path.write_bytes(content)
    before = snapshot(tmp_path)
    out = run(*COMMANDS[command], path)
    out.assert_clean_error()
    assert snapshot(tmp_path) == before
    # the message never echoes the file's content (only names, positions, rules)
    assert "\ufffd" not in out.stderr and "\\x" not in out.stderr


def test_header_units_contradicting_meta_units_is_an_error(run, tmp_path):
    """``t [ms]`` under a meta saying seconds once gave ω0 = 0.004 instead of 4, exit 0."""
    t_ms = _T * 1e3
    lines = ["# driveid record", json.dumps({"units": {"t": "s", "x": "rad"}}).join(
        ["# meta: ", ""]), "t [ms],x [rad]"]
    lines += [f"{t_ms[i]:.17g},{_X[i]:.17g}" for i in range(400)]
    path = tmp_path / "ms.csv"
    path.write_text("\n".join(lines) + "\n")
    out = run("identify", "logdec", path)
    out.assert_clean_error()
    assert "'ms'" in out.stderr and "'s'" in out.stderr


def test_the_same_file_twice_warns(run, good_record):
    out = run("identify", "logdec", good_record, good_record, "--mass", "1")
    out.assert_ok()
    assert any("more than once" in line for line in out.lines), out.describe()
