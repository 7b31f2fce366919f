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
# the simulators' results must not depend on the state of numba's cache: no interpreted
# first runs (driveid.sim._first_run; tests/sim/test_first_run.py turns them on)
os.environ.setdefault("DRIVEID_INTERPRET_STEPS", "0")

#: ../shared/data beside the repository, present on developer machines and in CI only.
SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def _kernel_cache_is_stale() -> bool:
    """Return False when every kernel module has a numba cache index newer than its source.

    Only numba's default cache (``__pycache__`` beside the sources) is looked at; with
    ``NUMBA_CACHE_DIR`` set the warm-up always runs (a cache load takes ~2 s).
    """
    if os.environ.get("NUMBA_CACHE_DIR"):
        return True
    import driveid.sim

    folder = Path(driveid.sim.__file__).parent
    for name in ("_kernels", "_free_decay_kernel", "_smooth_kernels", "lugre"):
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
    # the groups of `driveid warmup`, one process each (one per core)
    from driveid.commands.warmup import GROUPS

    code = "from driveid.commands.warmup import compile_kernels; compile_kernels({!r})"
    procs = [subprocess.Popen([sys.executable, "-c", code.format(g)], stdout=subprocess.DEVNULL,
                              stderr=subprocess.PIPE, text=True) for g in GROUPS]
    for group, proc in zip(GROUPS, procs, strict=True):
        _, err = proc.communicate()
        if reporter is None:
            continue
        if proc.returncode != 0:  # the tests will fail and say why
            reporter.write_line(f"kernel warm-up failed:\n{err[-2000:]}")
        reporter.write_line(f"kernel group {group!r} ready after "
                            f"{time.perf_counter() - start:.0f} s")


@pytest.fixture
def shared_data() -> Path:
    if not SHARED_DATA.is_dir():
        pytest.skip("../shared/data is not present (a user's fresh clone has none)")
    return SHARED_DATA


@pytest.fixture(autouse=True)
def _ctrl_c_handler_unchanged(request):
    """Restore Python's SIGINT handler after a test that changed it, and name that test.

    tests/fuzz/test_safe_write.py sends itself Ctrl-C and expects KeyboardInterrupt; on the
    CI run of 2026-11-28 (a338a13) it got none, as if an earlier test in the same worker had
    left another handler behind (not reproduced locally in four runs). The handler is put
    back, so that no later test depends on the order, and a warning in the summary names
    the test that changed it.
    """
    import signal
    import threading

    if threading.current_thread() is not threading.main_thread():
        yield
        return
    before = signal.getsignal(signal.SIGINT)
    yield
    after = signal.getsignal(signal.SIGINT)
    if after is not before and before is not None:
        import warnings

        signal.signal(signal.SIGINT, before)
        warnings.warn(f"{request.node.nodeid} left the SIGINT handler changed ({before!r} -> "
                      f"{after!r}); restored", stacklevel=1)
