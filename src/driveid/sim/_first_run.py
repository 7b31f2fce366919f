"""Short runs before the drive kernel is compiled: the same kernel, interpreted (issue 28).

The event-located RK4 kernel (:func:`driveid.sim._kernels.drive_kernel`) takes about 20 s
of CPU to compile from an empty numba cache, and a first ``driveid simulate drive`` after an
install paid all of it for a run that the kernel's own Python functions finish in a quarter
of a second (5000 grid steps of one body, ~40-50 µs a body and step). So a run goes to:

* the compiled kernel whenever it is compiled in this process or numba's on-disk cache
  holds it for these argument types (loading the cache takes ~0.5 s);
* otherwise the kernel's functions interpreted, while the interpreted work of this process
  stays within :func:`interpret_budget` body-steps (default 100 000, about 5 s); beyond it
  the kernel compiles as before, so a fit that simulates hundreds of times compiles once,
  after at most the budget.

The interpreted kernel is :mod:`driveid.sim._kernels` itself: each numba function's
``py_func`` rebound to a copy of the module's namespace in which its callees are the
interpreted ones too (no second copy of the source to drift). Its results differ from the
compiled kernel's by round-off only: the compiled loop may replace a division by a
multiplication with the reciprocal (``fastmath={"arcp"}``); tests/sim/test_first_run.py
compares the two. Python raises on some arithmetic that numba carries through as inf or NaN
(``math.sin(inf)``, ``int(nan)``, a float division by zero): such a run falls back to the
compiled kernel. ``driveid warmup`` compiles regardless (:func:`compiled_only`).

``DRIVEID_INTERPRET_STEPS`` sets the budget (0: always compile, the behaviour before; the
test suite sets it so that its results do not depend on the state of the cache).
"""

from __future__ import annotations

import contextlib
import math
import os
import threading
import types
from collections.abc import Iterator

import numpy as np
from numba.core.dispatcher import Dispatcher

from driveid.errors import ConfigError
from driveid.sim import _kernels as _k

__all__ = ["BUDGET_ENV", "DEFAULT_BUDGET", "compiled_only", "interpret_budget",
           "is_compiled_or_cached", "run_drive_kernel"]

#: Environment variable holding the interpreted budget [body-steps].
BUDGET_ENV = "DRIVEID_INTERPRET_STEPS"
#: Interpreted body-steps per process by default: ~5 s at ~50 µs each on a loaded 2-core
#: machine, a quarter of the kernel's compile time; the default ``simulate drive`` of every
#: preset needs 5 000-30 000.
DEFAULT_BUDGET = 100_000

_lock = threading.Lock()
_spent = 0.0  # interpreted body-steps so far in this process
_compiled_only = 0  # depth of compiled_only() blocks
_interpreted: types.FunctionType | None = None


def interpret_budget() -> int:
    """Body-steps [-] this process may run interpreted while the kernel is not compiled.

    Returns
    -------
    int
        ``DRIVEID_INTERPRET_STEPS`` if set, else :data:`DEFAULT_BUDGET`; 0 compiles always.

    Raises
    ------
    ConfigError
        If ``DRIVEID_INTERPRET_STEPS`` is not a finite number >= 0 (``1e5`` is fine).
    """
    raw = os.environ.get(BUDGET_ENV, "").strip()
    if not raw:
        return DEFAULT_BUDGET
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not 0 <= value < math.inf:
        raise ConfigError(f"{BUDGET_ENV}={raw!r} must be a number of steps >= 0 (0: always "
                          f"compile); unset it for the default {DEFAULT_BUDGET}")
    return int(value)


@contextlib.contextmanager
def compiled_only() -> Iterator[None]:
    """Run every drive kernel call inside the block compiled (``driveid warmup``).

    Yields
    ------
    None
    """
    global _compiled_only
    with _lock:
        _compiled_only += 1
    try:
        yield
    finally:
        with _lock:
            _compiled_only -= 1


def is_compiled_or_cached(args: tuple) -> bool:
    """Return whether ``drive_kernel(*args)`` would run without compiling.

    Parameters
    ----------
    args : tuple
        The kernel's arguments (their numba types pick the specialisation).

    Returns
    -------
    bool
        True if that specialisation is compiled in this process or numba's on-disk cache
        holds a fresh entry for it (this machine, this source), or if numba's cache cannot be
        inspected (its private API moved: compile, as before); False otherwise.
    """
    kernel = _k.drive_kernel
    try:
        sig = tuple(kernel.typeof_pyval(a) for a in args)
        if sig in kernel.overloads:
            return True
        cache = kernel._cache
        key = cache._index_key(sig, kernel.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # numba's private cache API differs: compile, as before
        return True


def _interpreted_kernel() -> types.FunctionType:
    """:func:`driveid.sim._kernels.drive_kernel` with every numba function interpreted."""
    global _interpreted
    if _interpreted is None:
        namespace = dict(vars(_k))
        for name, obj in vars(_k).items():
            if isinstance(obj, Dispatcher):
                f = obj.py_func
                namespace[name] = types.FunctionType(f.__code__, namespace, f.__name__,
                                                     f.__defaults__, f.__closure__)
        _interpreted = namespace["drive_kernel"]
    return _interpreted


def _choose_interpreted(args: tuple, work: float) -> bool:
    global _spent
    if not isinstance(_k.drive_kernel, Dispatcher):  # NUMBA_DISABLE_JIT: Python already
        return False
    budget = interpret_budget()
    with _lock:
        if _compiled_only or _spent + work > budget or is_compiled_or_cached(args):
            return False
        _spent += work
    return True


def run_drive_kernel(args: tuple, work: float, *, interpreted: bool | None = None
                     ) -> tuple[tuple, bool]:
    """Run :func:`driveid.sim._kernels.drive_kernel` compiled, or interpreted on a cold cache.

    Parameters
    ----------
    args : tuple
        The kernel's arguments (see :func:`driveid.sim._kernels.drive_kernel`).
    work : float
        Grid steps times bodies of the run [-], charged to the interpreted budget.
    interpreted : bool, optional
        None chooses (see the module's docstring); True or False repeats an earlier choice
        (the energy pass of a run, the periods of a sampled controller take the engine of
        their first call, so that their trajectories agree bitwise).

    Returns
    -------
    outputs : tuple
        The kernel's outputs.
    interpreted : bool
        Whether the interpreted kernel produced them.
    """
    global _spent
    if interpreted is None:
        interpreted = _choose_interpreted(args, work)
    elif interpreted:
        with _lock:
            _spent += work
    if interpreted:
        try:
            with np.errstate(all="ignore"):  # numba's float semantics: inf and NaN, no warning
                return _interpreted_kernel()(*args), True
        except (ArithmeticError, ValueError):  # Python's math refuses what numba carries on
            pass
    return _k.drive_kernel(*args), False
