"""Conversion of numpy values and mappings to plain, standard JSON (NaN and inf become null)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

__all__ = ["to_jsonable"]


def to_jsonable(value: Any) -> Any:
    """Return ``value`` with arrays, numpy scalars and tuples made JSON-serialisable.

    Parameters
    ----------
    value : Any
        Nested mappings, sequences, arrays and scalars.

    Returns
    -------
    Any
        The same structure of dicts, lists, floats, ints and strings; non-finite floats
        become ``None`` so the result is standard JSON.

    Examples
    --------
    >>> to_jsonable({"a": np.array([1.0, np.nan]), "b": (np.int64(2),)})
    {'a': [1.0, None], 'b': [2]}
    """
    if isinstance(value, Mapping):
        return {str(k): to_jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [to_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return to_jsonable(value.tolist())
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
