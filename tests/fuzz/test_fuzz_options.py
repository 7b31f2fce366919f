"""Hostile numeric option values on every command: NaN, inf, negative, huge, not a number.

``--noise nan`` and ``--K nan`` were once taken as "none", ``--mass 1e308`` printed K = inf
with exit 0, ``--omega-c 1e9`` tried to allocate 32 TiB and ``--duration 1e9`` ran out of
memory: each must now be one ``error:`` line naming the option, exit 2, nothing written.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.fuzz.conftest import snapshot

# (command words, option, kind); kind: "pos" > 0, "nonneg" >= 0, "finite", "int"
_FD = ("simulate", "free-decay", "--out", "out.csv")
_LOG = ("identify", "logdec", "{record}")
_HIL = ("identify", "hilbert", "{record}")
_WAV = ("identify", "wavelet", "{record}")
_FMAP = ("identify", "friction-map", "{record}")
_IDIM = ("identify", "idim", "{record}")
_PHO = ("pho", "run", "--out", "campaign")
_PHA = ("pho", "analyse", ".")
OPTIONS = [
    (_FD, "--J", "pos"), (_FD, "--K", "nonneg"), (_FD, "--c-mean", "finite"),
    (_FD, "--c-delta", "finite"), (_FD, "--fk-mean", "finite"), (_FD, "--fk-delta", "finite"),
    (_FD, "--fs-mean", "finite"), (_FD, "--fs-delta", "finite"), (_FD, "--x0", "finite"),
    (_FD, "--duration", "pos"), (_FD, "--rate", "pos"), (_FD, "--noise", "nonneg"),
    (_FD, "--counts-per-rev", "pos"), (_FD, "--counts-per-metre", "pos"),
    (_LOG, "--mass", "pos"), (_LOG, "--K", "nonneg"), (_LOG, "--fs", "pos"),
    (_LOG, "--t-start", "finite"), (_LOG, "--t-end", "finite"),
    (_LOG, "--counts-per-rev", "pos"), (_LOG, "--counts-per-metre", "pos"),
    (_HIL, "--mass", "pos"), (_HIL, "--fs", "pos"), (_HIL, "--t-start", "finite"),
    (_HIL, "--counts-per-rev", "pos"),
    (_WAV, "--omega-c", "pos"), (_WAV, "--modes", "int"), (_WAV, "--fs", "pos"),
    (_WAV, "--t-end", "finite"),
    (_FMAP, "--rel-tol", "pos"), (_FMAP, "--min-samples", "int"),
    (_IDIM, "--cutoff-hz", "pos"), (_IDIM, "--decimate", "int"),
    (_PHO, "--D-start", "finite"), (_PHO, "--D-step", "finite"), (_PHO, "--x0", "pos"),
    (_PHO, "--duration", "pos"), (_PHO, "--fs", "pos"), (_PHO, "--noise", "nonneg"),
    (_PHO, "--abort-limit", "pos"), (_PHO, "--K", "nonneg"), (_PHO, "--n-D", "int"),
    (_PHO, "--min-peaks", "int"),
    (_PHA, "--delay", "nonneg"), (_PHA, "--K", "nonneg"),
]
_BAD = {
    "finite": ["nan", "inf", "-inf", "1e308", "abc"],
    "nonneg": ["nan", "inf", "-1", "1e308", "abc"],
    "pos": ["nan", "-inf", "0", "-1", "1e308", "abc"],
    "int": ["-5", "abc", "1.5", "99999999999"],
}
CASES = [pytest.param(words, option, value, id=f"{' '.join(words[:2])} {option} {value}")
         for words, option, kind in OPTIONS for value in _BAD[kind]]


@pytest.mark.parametrize("words, option, value", CASES)
def test_bad_numeric_option_is_one_error_line(run, tmp_path, good_record, words, option,
                                              value):
    args = [w.format(record=good_record) for w in words]
    before = snapshot(tmp_path)
    out = run(*args, option, value)
    out.assert_clean_error()
    assert option.lower() in out.stderr.lower(), out.describe()
    assert snapshot(tmp_path) == before  # nothing written


@pytest.mark.parametrize("args, match", [
    (("simulate", "free-decay", "--out", "o.csv", "--duration", "1e9"), "memory"),
    (("simulate", "free-decay", "--out", "o.csv", "--rate", "1e12"), "memory"),
    (("pho", "run", "--out", "c", "--duration", "1e9"), "memory"),
    (("pho", "run", "--out", "c", "--P-range", "1", "1", "6000"), "limit of 10000"),
    (("identify", "wavelet", "{record}", "--omega-c", "1e9"), "at most"),
    (("pho", "analyse", ".", "--delay", "1e6"), "at most"),
    # issue 28: 1.2e7 records (~700 GB) and dates past year 9999 ran silently
    (("fleet", "simulate", "f", "--axes", "1000000"), "limit of 100000"),
    (("fleet", "simulate", "f", "--axes", "2", "--months", "100000"), "year 9999"),
    (("simulate", "contour", "{contour}", "--out", "c.csv"), "--max-periods"),
])
def test_absurd_sizes_are_refused_before_allocating(run, tmp_path, good_record, args, match):
    contour = tmp_path / "axes.toml"  # the example circle under a 10 MHz controller
    example = Path(__file__).resolve().parents[2] / "examples/drive_configs/contour_xy.toml"
    contour.write_text(example.read_text()
                       .replace("rate = 2000.0 ", "rate = 1e7 "))
    before = snapshot(tmp_path)
    out = run(*[a.format(record=good_record, contour=contour) for a in args])
    out.assert_clean_error(match, progress_label="PHO runs")
    assert snapshot(tmp_path) == before
