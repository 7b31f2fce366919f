"""``driveid warmup``: compile the simulation kernels once, ahead of the first simulation.

The simulators' numba kernels are compiled on first use and cached on disk beside the package
(``sim/__pycache__``); the first simulation after an install otherwise stays silent for about
half a minute. Commands that simulate call :func:`announce_compilation` first.
"""

from __future__ import annotations

import time
from pathlib import Path

import click

from driveid.commands import clean_errors

__all__ = ["warmup_command", "kernels_need_compiling", "announce_compilation"]

_KERNEL_MODULES = ("_kernels", "_smooth_kernels", "lugre")


def kernels_need_compiling() -> bool:
    """Return True when a kernel module has no on-disk numba cache newer than its source.

    Returns
    -------
    bool
        True if the next simulation will compile (a fresh install, or edited kernels).
    """
    import driveid.sim

    folder = Path(driveid.sim.__file__).parent
    cache = folder / "__pycache__"
    for name in _KERNEL_MODULES:
        source = folder / f"{name}.py"
        if not source.exists():
            continue
        indexes = list(cache.glob(f"{name}.*.nbi")) if cache.is_dir() else []
        if not indexes or max(p.stat().st_mtime for p in indexes) < source.stat().st_mtime:
            return True
    return False


def announce_compilation() -> None:
    """Say on stderr, once, that the kernels are being compiled (about 30 s, cached)."""
    if kernels_need_compiling():
        click.echo("compiling simulation kernels, once, about 30 s (cached afterwards; "
                   "'driveid warmup' does it ahead)", err=True)


@click.command("warmup")
@clean_errors
def warmup_command() -> None:
    """Compile and cache the simulation kernels now (about 30 s after an install)."""
    from driveid.models.dynamic_friction import LuGreParams
    from driveid.sim import BodyParams, DriveParams, simulate_drive, simulate_lugre_oscillator
    from driveid.sim.presets import preset

    announce_compilation()
    start = time.perf_counter()
    lugre = LuGreParams(sigma0=1e5, sigma1=300.0, sigma2=0.4, fc=1.0, fs=1.5, vs=1e-3,
                        check_passivity=False)
    simulate_drive(preset("testbed"), duration=0.05)            # event-located RK4 kernels
    simulate_drive(DriveParams(bodies=(BodyParams(J=1.0, K=2.0, lugre=lugre),)),
                   duration=0.05, x0=[0.1])                      # stiff Radau path
    simulate_lugre_oscillator(lugre, m=1.0, k=2.0, belt_speed=0.1, duration=0.05)
    click.echo(f"simulation kernels ready ({time.perf_counter() - start:.1f} s)")
