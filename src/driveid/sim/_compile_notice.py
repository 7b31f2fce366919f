"""A one-time notice when numba compiles one of the simulation kernels.

The first simulation after an install (or after the kernels' source changed) compiles the
numba kernels (about 30 s for all of them), later ones load numba's on-disk cache. numba
broadcasts its ``"numba:compile"`` event only when it really compiles, not when it loads the
cache, so the notice is exact wherever the cache lives (beside the package,
``NUMBA_CACHE_DIR``, or a per-user directory when the package's folder is read-only). A
short drive run before the drive kernel is compiled runs it interpreted and compiles
nothing (:mod:`driveid.sim._first_run`): no notice then.

The notice is an INFO record of the ``driveid.compile`` logger: silent for library users
unless they enable logging; the command line prints it on an interactive terminal.
"""

from __future__ import annotations

import logging

from numba.core import event

__all__ = ["MESSAGE", "install"]

MESSAGE = ("compiling the simulation kernels, once, about 30 s (cached afterwards; "
           "'driveid warmup' does it ahead)")
_LOG = logging.getLogger("driveid.compile")


class _Notice(event.Listener):
    """Log :data:`MESSAGE` at the first compilation of a driveid kernel in this process."""

    def __init__(self) -> None:
        self.said = False

    def on_start(self, ev: event.Event) -> None:
        function = getattr(ev.data.get("dispatcher"), "py_func", None)
        if not self.said and getattr(function, "__module__", "").startswith("driveid."):
            self.said = True
            _LOG.info(MESSAGE)

    def on_end(self, ev: event.Event) -> None:
        pass


_listener: _Notice | None = None


def install() -> None:
    """Listen for numba compilations (idempotent; called by each kernel module)."""
    global _listener
    if _listener is None:
        _listener = _Notice()
        event.register("numba:compile", _listener)
