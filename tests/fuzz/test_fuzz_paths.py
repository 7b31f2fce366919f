"""Files: symbolic links at every output, hostile campaign manifests, nothing read or written
outside the folders the user named, and no file content in messages."""

from __future__ import annotations

import json
import os
import shutil
from pathlib import Path

import pytest

from tests.fuzz.conftest import snapshot

SECRET = "SECRET-CONTENT-MUST-NOT-LEAK"


@pytest.fixture(scope="session")
def campaign_template(tmp_path_factory) -> Path:
    """A small valid campaign (2 P x 1 D x ±x0 = 4 runs of 1.5 s)."""
    from driveid.experiment import SimulatedPlant, run_pho_campaign

    folder = tmp_path_factory.mktemp("tpl") / "c"
    run_pho_campaign(SimulatedPlant("testbed-a", counts_per_rev=4000, seed=3),
                     P_values=[2.0, 3.0], D_values=[0.03], x0=1.0, duration=1.5,
                     out_dir=folder)
    return folder


@pytest.fixture
def campaign(tmp_path, campaign_template) -> Path:
    folder = tmp_path / "c"
    shutil.copytree(campaign_template, folder)
    return folder


@pytest.fixture
def outside(tmp_path) -> Path:
    """A folder beside the campaign holding a record-like file with a secret."""
    folder = tmp_path / "elsewhere"
    folder.mkdir()
    (folder / "x.csv").write_text(f"t,x\n{SECRET},1\n")
    return folder


def _edit(campaign: Path, change) -> None:
    path = campaign / "manifest.json"
    data = json.loads(path.read_text())
    change(data)
    path.write_text(json.dumps(data))


def _set_file(i, value):
    return lambda d: d["runs"][i].__setitem__("file", value)


def _scale(i, key, factor):
    return lambda d: d["runs"][i].__setitem__(key, d["runs"][i][key] * factor)


HOSTILE_MANIFESTS = {
    "dotdot": (_set_file(0, "../elsewhere/x.csv"), "'..'"),
    "dotdot-deep": (_set_file(1, "../../../../../../../../etc/passwd"), "'..'"),
    "absolute": (None, "absolute path"),  # filled in the test (needs tmp_path)
    "P-x1.5": (_scale(0, "P", 1.5), "manifest says P"),
    "D-x2": (_scale(2, "D", 2.0), "manifest says D"),
    "x0-flipped": (_scale(1, "x0", -1.0), "manifest says x0"),
    "runs-not-list": (lambda d: d.__setitem__("runs", {"a": 1}), "runs"),
    "runs-empty": (lambda d: d.__setitem__("runs", []), "runs"),
    "unknown-key": (lambda d: d.__setitem__("delay", 0.01), "unknown top-level"),
    "P-string": (lambda d: d["runs"][0].__setitem__("P", "2"), "finite number"),
    "file-number": (_set_file(0, 5), "file name"),
    "file-empty": (_set_file(0, ""), "file name"),
    "missing-file": (_set_file(0, "nope.csv"), "does not exist"),
    "delay-negative": (lambda d: d.__setitem__("delay_s", -1.0), "delay_s"),
    "units-bad": (lambda d: d.__setitem__("units", "deg"), "units"),
    "complete-string": (lambda d: d.__setitem__("complete", "yes"), "complete"),
    "format-bad": (lambda d: d.__setitem__("format", "other"), "format"),
}


@pytest.mark.parametrize("case", sorted(HOSTILE_MANIFESTS))
def test_hostile_manifest_is_one_error_line(run, tmp_path, campaign, outside, case):
    change, match = HOSTILE_MANIFESTS[case]
    if case == "absolute":
        change = _set_file(0, str(outside / "x.csv"))
    _edit(campaign, change)
    before = snapshot(tmp_path)
    out = run("pho", "analyse", campaign)
    out.assert_clean_error(match)
    assert SECRET not in out.stderr + out.stdout
    assert snapshot(tmp_path) == before


@pytest.mark.parametrize("how", ["file-link", "folder-link"])
def test_symlinked_record_pointing_outside_is_refused(run, campaign, outside, how):
    data = json.loads((campaign / "manifest.json").read_text())
    if how == "file-link":
        name = data["runs"][0]["file"]
        (campaign / name).unlink()
        (campaign / name).symlink_to(outside / "x.csv")
    else:
        (campaign / "sub").symlink_to(outside)
        _edit(campaign, _set_file(0, "sub/x.csv"))
    out = run("pho", "analyse", campaign)
    out.assert_clean_error("symbolic link")
    assert SECRET not in out.stderr + out.stdout


@pytest.mark.parametrize("content", [
    b"[" * 100_000 + b"]" * 100_000,
    b'{"runs": ' + b"[" * 5000 + b"]" * 5000 + b"}",
    b"\xff\xfe{\x00}",
    b"",
    b'{"runs": [{"file": "a.csv", "P": NaN, "D": 1}]}',
    b'{"runs": [{"file": "a.csv", "P": Infinity, "D": 1}]}',
    b"null",
    b'"a string"',
], ids=["deep-array", "deep-runs", "utf16", "empty", "nan", "infinity", "null", "string"])
def test_unreadable_manifest_is_one_error_line(run, campaign, content):
    (campaign / "manifest.json").write_bytes(content)
    run("pho", "analyse", campaign).assert_clean_error()


def test_duplicated_runs_and_incomplete_campaign_warn(run, campaign):
    def change(d):
        d["runs"] = d["runs"] + d["runs"][:1]
        d["complete"] = False
    _edit(campaign, change)
    out = run("pho", "analyse", campaign)
    out.assert_ok_or_clean_error()
    text = out.stderr
    assert "warning:" in text and "more than once" in text and "incomplete" in text, \
        out.describe()


def test_allow_outside_reads_a_trusted_outside_record(tmp_path, campaign):
    from driveid.errors import FileFormatError
    from driveid.io.manifest import read_manifest

    data = json.loads((campaign / "manifest.json").read_text())
    moved = tmp_path / "moved.csv"
    shutil.move(campaign / data["runs"][0]["file"], moved)
    data["runs"][0]["file"] = str(moved)
    (campaign / "manifest.json").write_text(json.dumps(data))
    with pytest.raises(FileFormatError, match="allow_outside=True"):
        read_manifest(campaign)
    records = read_manifest(campaign, allow_outside=True).load_records()
    assert len(records) == 4


# ---- outputs: links at --out / --figure, folders, refusals -------------------------------

_WRITERS = {
    "free-decay-out": lambda p, rec: ("simulate", "free-decay", "--out", p, "--duration", "2"),
    "logdec-figure": lambda p, rec: ("identify", "logdec", rec, "--mass", "1", "--figure", p),
}


@pytest.mark.parametrize("writer", sorted(_WRITERS))
@pytest.mark.parametrize("link", ["dangling", "to-file"])
def test_link_at_output_is_never_followed(run, tmp_path, good_record, writer, link):
    target = tmp_path / "target.png"
    if link == "to-file":
        target.write_text(SECRET)
    dest = tmp_path / ("out.csv" if writer == "free-decay-out" else "fig.png")
    dest.symlink_to(target)
    args = _WRITERS[writer](dest, good_record)
    out = run(*args)
    out.assert_clean_error("symbolic link")
    assert not target.exists() if link == "dangling" else target.read_text() == SECRET
    # with --overwrite the link itself is replaced, never its target
    out = run(*args, "--overwrite")
    out.assert_ok()
    assert dest.is_file() and not dest.is_symlink()
    assert not target.exists() if link == "dangling" else target.read_text() == SECRET


@pytest.mark.parametrize("args, match", [
    (("simulate", "free-decay", "--out", "folder"), "folder"),
    (("simulate", "free-decay", "--out", "x.txt"), "suffix"),
    (("identify", "logdec", "{rec}", "--mass", "1", "--figure", "f.xyz"), "suffix"),
    (("identify", "logdec", "{rec}", "--mass", "1", "--figure", "folder"), ""),
    (("identify", "logdec", "{rec}", "--mass", "1", "--figure", "existing.png"), "exists"),
    (("simulate", "free-decay", "--out", "existing.csv"), "exists"),
])
def test_bad_output_names_are_one_error_line(run, tmp_path, good_record, args, match):
    (tmp_path / "folder").mkdir()
    (tmp_path / "existing.png").write_text(SECRET)
    (tmp_path / "existing.csv").write_text(SECRET)
    before = snapshot(tmp_path)
    out = run(*[a.format(rec=good_record) for a in args])
    out.assert_clean_error(match or None)
    assert snapshot(tmp_path) == before


def test_pho_run_refuses_a_symlinked_out_folder(run, tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (tmp_path / "link").symlink_to(real)
    out = run("pho", "run", "--out", "link", "--P", "2", "--n-D", "1", "--duration", "1")
    out.assert_clean_error("symbolic link", progress_label="PHO runs")
    assert list(real.iterdir()) == []


def test_pho_run_never_writes_through_a_planted_manifest_tmp_link(run, tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text(SECRET)
    folder = tmp_path / "c"
    folder.mkdir()
    (folder / "manifest.json.tmp").symlink_to(victim)
    out = run("pho", "run", "--out", folder, "--P", "2,3", "--D-start", "0.03", "--D-step",
              "0.01", "--n-D", "1", "--duration", "1")
    assert out.code == 0, out.describe()
    assert victim.read_text() == SECRET
    assert json.loads((folder / "manifest.json").read_text())["complete"] is True
    assert not [p for p in folder.iterdir() if ".part" in p.name]


def test_second_pho_run_into_the_same_folder_names_resume(run, campaign):
    out = run("pho", "run", "--out", campaign, "--P", "2", "--n-D", "1", "--duration", "1")
    out.assert_clean_error("--resume", progress_label="PHO runs")
    assert "--force" not in out.stderr


def test_nothing_is_read_outside_the_named_paths(run, tmp_path, campaign, outside):
    _edit(campaign, _set_file(0, "../elsewhere/x.csv"))
    os.chmod(outside / "x.csv", 0o000)  # reading it would fail differently
    try:
        out = run("pho", "analyse", campaign)
    finally:
        os.chmod(outside / "x.csv", 0o644)
    out.assert_clean_error("'..'")
