"""Shared fixtures: the optional ../shared/data folder and a headless matplotlib.

With pytest-xdist (``make test`` runs ``pytest -n auto``) the controller compiles the numba
simulation kernels once, before the workers start, when their on-disk cache is missing or
stale: otherwise each worker compiles the same kernels at the same time on a cold cache.
"""

import os
import subprocess
import sys
import time
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

#: ../shared/data beside the repository, present on developer machines and in CI only.
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"

#: Two groups of kernels compiled side by side, one per core: the event-located RK4 drive
#: kernel; the stiff (Radau), LuGre and free-decay batch kernels (similar compile times).
_WARM_UP = (
    "from driveid.sim import simulate_drive\n"
    "from driveid.sim.presets import preset\n"
    "simulate_drive(preset('testbed'), duration=0.05)\n",
    "from driveid.models.dynamic_friction import LuGreParams\n"
    "from driveid.sim import (BodyParams, DriveParams, simulate_drive,\n"
    "    simulate_free_decay_batch, simulate_lugre_oscillator)\n"
    "lugre = LuGreParams(sigma0=1e5, sigma1=300.0, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,\n"
    "                    check_passivity=False)\n"
    "simulate_drive(DriveParams(bodies=(BodyParams(J=1.0, K=2.0, lugre=lugre),)),\n"
    "               duration=0.05, x0=[0.1])\n"
    "simulate_lugre_oscillator(lugre, m=1.0, k=2.0, belt_speed=0.1, duration=0.05)\n"
    "simulate_free_decay_batch(J=1.0, K=4.0, fk_mean=0.1, x0=[1.0, 2.0], duration=1.0)\n",
)


def _kernel_cache_is_stale() -> bool:
    """Return False when every kernel module has a numba cache index newer than its source.

    Only numba's default cache (``__pycache__`` beside the sources) is looked at; with
    ``NUMBA_CACHE_DIR`` set the warm-up always runs (a cache load takes ~2 s).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    import driveid.sim

    folder = Path(driveid.sim.__file__).parent
    for name in ("_kernels", "_smooth_kernels", "lugre"):
        indexes = list((folder / "__pycache__").glob(f"{name}.*.nbi"))
        if not indexes or max(p.stat().st_mtime for p in indexes) < (
                folder / f"{name}.py").stat().st_mtime:
            return True
    return False


def pytest_sessionstart(session):
    config = session.config
    # only the xdist controller (serial runs and workers compile on first use), and only for
    # the whole suite: a selection may need no kernel at all
    if config.pluginmanager.getplugin("dsession") is None:
        return
    if config.args_source is not pytest.Config.ArgsSource.TESTPATHS:
        return
    if not _kernel_cache_is_stale():
        return
    reporter = config.pluginmanager.getplugin("terminalreporter")
    if reporter is not None:
        reporter.write_line("compiling the simulation kernels before starting the workers")
    start = time.perf_counter()
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for code in _WARM_UP]
    for group, proc in enumerate(procs, 1):
        _, err = proc.communicate()
        if reporter is None:
            continue
        if proc.returncode != 0:  # the tests will fail and say why
            reporter.write_line(f"kernel warm-up failed:\n{err[-2000:]}")
        reporter.write_line(f"kernel group {group} ready after "
                            f"{time.perf_counter() - start:.0f} s")


@pytest.fixture
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is not present (a user's fresh clone has none)")
    return SHARED_DATA
