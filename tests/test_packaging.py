"""The wheel a user installs: built from a copy of the sources as a fresh clone would be.

``pip wheel --no-deps --no-build-isolation`` (offline: the setuptools of this environment,
which must satisfy pyproject's ``build-system.requires``) into a temporary folder; the
checkout itself is not written to (no ``build/`` or ``*.egg-info`` left behind).
"""

import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

pytestmark = pytest.mark.slow


def _setuptools_version():
    try:
        import setuptools
    except ImportError:
        return None
    return tuple(int(p) for p in re.findall(r"\d+", setuptools.__version__)[:2])


@pytest.fixture(scope="module")
def wheel(tmp_path_factory):
    needed = re.search(r'"setuptools>=(\d+)"', (ROOT / "pyproject.toml").read_text())
    have = _setuptools_version()
    if needed and (have is None or have[0] < int(needed.group(1))):
        pytest.skip(f"building offline needs setuptools>={needed.group(1)} in this environment "
                    f"(pyproject build-system.requires); found {have}: "
                    f"pip install 'setuptools>={needed.group(1)}'")
    tmp = tmp_path_factory.mktemp("wheel")
    source = tmp / "src-copy"
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copy2(ROOT / name, source / name)
    shutil.copytree(ROOT / "src", source / "src",
                    ignore=shutil.ignore_patterns("__pycache__", "*.egg-info", "*.pyc"))
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
         "--no-index", "-v", "-w", str(tmp / "dist"), str(source)],
        capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    (path,) = (tmp / "dist").glob("driveid-*.whl")
    return {"path": path, "log": done.stdout + done.stderr,
            "names": zipfile.ZipFile(path).namelist()}


def test_no_setuptools_deprecation_warning(wheel):
    log = wheel["log"]
    assert "SetuptoolsDeprecationWarning" not in log, log[-3000:]
    assert not re.search(r"(?i)license.*deprecat|deprecat.*license", log), log[-3000:]


def test_wheel_carries_licence_template_and_type_marker(wheel):
    names = wheel["names"]
    assert any(re.fullmatch(r"driveid-[^/]+\.dist-info/licenses/LICENSE", n) for n in names)
    fix = ('pyproject.toml needs [tool.setuptools.package-data] '
           'driveid = ["py.typed", "report/templates/*.j2"]')
    assert "driveid/report/templates/report.html.j2" in names, fix
    assert "driveid/py.typed" in names, fix


def test_wheel_metadata_has_spdx_licence_expression(wheel):
    with zipfile.ZipFile(wheel["path"]) as whl:
        (meta,) = [n for n in whl.namelist() if n.endswith(".dist-info/METADATA")]
        text = whl.read(meta).decode()
    assert re.search(r"^License-Expression: MIT$", text, re.M)
    assert re.search(r"^License-File: LICENSE$", text, re.M)
