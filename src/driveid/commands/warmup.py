"""``driveid warmup``: compile the simulation kernels once, ahead of the first simulation.

The simulators' numba kernels are compiled on first use (about 30 s) and cached on disk
(numba's cache: beside the package, or ``NUMBA_CACHE_DIR``). On a terminal the command line
says so when it happens (:mod:`driveid.sim._compile_notice`); this command does it ahead.
Until the drive kernel is compiled, short drive runs are interpreted
(:mod:`driveid.sim._first_run`); this command compiles it regardless.
"""

from __future__ import annotations

import time

import click

from driveid.commands import clean_errors

__all__ = ["GROUPS", "compile_kernels", "warmup_command"]

#: Kernel groups of similar compile time, so two processes can compile them side by side
#: (the test suite does): the event-located RK4 drive (about 23 s from an empty cache); the
#: stiff (Radau) drive path, the LuGre oscillator and the exact free-decay batch (about 14 s).
GROUPS = ("drive", "smooth")


def compile_kernels(group: str | None = None) -> None:
    """Compile the kernels of one of :data:`GROUPS` (None: all), or load them from the cache.

    Parameters
    ----------
    group : {"drive", "smooth"}, optional
        The group; all of them when None.
    """
    from driveid.models.dynamic_friction import LuGreParams
    from driveid.sim import (
        BodyParams,
        DriveParams,
        simulate_drive,
        simulate_free_decay_batch,
        simulate_lugre_oscillator,
    )
    from driveid.sim._first_run import compiled_only
    from driveid.sim.presets import preset

    if group in (None, "drive"):
        with compiled_only():  # a run this short would otherwise be interpreted
            simulate_drive(preset("testbed"), duration=0.05)  # event-located RK4
    if group in (None, "smooth"):
        simulate_free_decay_batch(J=1.0, K=2.0, c_mean=0.1, fk_mean=0.01, x0=1.0,
                                  duration=0.05)
        lugre = LuGreParams(sigma0=1e5, sigma1=300.0, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,
                            check_passivity=False)
        simulate_drive(DriveParams(bodies=(BodyParams(J=1.0, K=2.0, lugre=lugre),)),
                       duration=0.05, x0=[0.1])  # stiff Radau path
        simulate_lugre_oscillator(lugre, m=1.0, k=2.0, belt_speed=0.1, duration=0.05)


@click.command("warmup")
@clean_errors
def warmup_command() -> None:
    """Compile and cache the simulation kernels now (about 30 s after an install)."""
    start = time.perf_counter()
    compile_kernels()
    click.echo(f"simulation kernels ready ({time.perf_counter() - start:.1f} s)")
