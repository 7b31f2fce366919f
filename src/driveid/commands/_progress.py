"""Progress on stderr for loops that take more than a few seconds (one helper, tqdm).

Quiet with ``--quiet`` or when stderr is not a terminal (scripts, CI, pipes), so that output
meant for other programs stays clean.
"""

from __future__ import annotations

import sys
from typing import Any

__all__ = ["progress_bar"]


def progress_bar(total: int, label: str, *, quiet: bool = False, unit: str = "it") -> Any:
    """Return a tqdm bar on stderr, disabled when quiet or not on a terminal.

    Parameters
    ----------
    total : int
        Number of steps [-].
    label : str
        What is counted, shown before the bar.
    quiet : bool
        The command's ``--quiet``.
    unit : str
        Name of one step.

    Returns
    -------
    tqdm.tqdm
        Use as a context manager; ``bar.update(1)`` per step, or pass
        ``lambda done, total: bar.update(1)`` to a ``progress=`` callback.
    """
    from tqdm import tqdm

    return tqdm(total=total, desc=label, unit=unit, file=sys.stderr, leave=False,
                disable=quiet or not sys.stderr.isatty())
