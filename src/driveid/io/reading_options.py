"""Stored reading options, written back as the command-line options that give them.

A result keeps how its records were read (``inputs[k]["reading"]``); ``validate`` and the
HTML report show it in the words a user types again.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

__all__ = ["reading_as_cli"]


def reading_as_cli(reading: Mapping[str, Any]) -> str:
    """Return stored reading options as the command-line options that give them.

    Parameters
    ----------
    reading : mapping
        ``inputs[k]["reading"]`` of a result (see :meth:`RecordOptions.from_reading`).

    Returns
    -------
    str
        E.g. ``--position 'pos (3)' --unit x=m --max-jitter none``; empty for defaults.

    Examples
    --------
    >>> reading_as_cli({"columns": {"x": "q2"}, "units": {"x": "m"}, "max_jitter": None})
    '--position q2 --max-jitter none --unit x=m'
    """
    import shlex

    words: list[str] = []
    flags = {"t": "--time", "x": "--position", "v": "--velocity", "u": "--force"}
    for col, spec in dict(reading.get("columns") or {}).items():
        words += [flags.get(col, f"--{col}"), shlex.quote(str(spec))]
    if reading.get("fs") is not None:
        words += ["--fs", f"{reading['fs']:g}"]
    if "max_jitter" in reading:
        jitter = reading["max_jitter"]
        words += ["--max-jitter", "none" if jitter is None else f"{jitter:g}"]
    for key, flag in (("scale", "--scale"), ("units", "--unit")):
        for col, value in dict(reading.get(key) or {}).items():
            words += [flag, shlex.quote(f"{col}={value}")]
    for key, flag in (("counts_per_rev", "--counts-per-rev"),
                      ("counts_per_metre", "--counts-per-metre")):
        if reading.get(key) is not None:
            words += [flag, f"{reading[key]:g}"]
    for col, bits in dict(reading.get("sign_magnitude") or {}).items():
        words += ["--sign-magnitude", f"{col}:{bits}"]
    return " ".join(words)
