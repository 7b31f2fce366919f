"""Scale factors of the reading options: a number or a safe arithmetic expression.

``--scale u=200``, ``--scale v=0.02/60``, ``--scale u=gtau`` (a scalar variable of the
file): numbers, ``+ - * / ( )`` and the file's scalar names only, evaluated on the parsed
syntax tree (never ``eval``).
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Mapping

from driveid.errors import FileFormatError

__all__ = ["parse_scale"]

_OPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
        ast.Div: operator.truediv}


def parse_scale(text: str | float, scalars: Mapping[str, float] | None = None) -> float:
    """Return the value of a scale factor: a number or a safe arithmetic expression.

    Parameters
    ----------
    text : str or float
        ``"200"``, ``"0.02/60"``, ``"2*pi"`` is refused (no names except the file's scalar
        variables), ``"gtau"`` for a scalar variable of the file.
    scalars : mapping, optional
        Scalar variables of the file that may be named [their own units].

    Returns
    -------
    float
        The factor; finite and non-zero.

    Raises
    ------
    FileFormatError
        If the text is not numbers and ``+ - * / ( )`` (and scalar names of the file).

    Examples
    --------
    >>> parse_scale("0.02/60") == 0.02 / 60, parse_scale("-(1.5e3 + 500)")
    (True, -2000.0)
    """
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        value = float(text)
    else:
        scalars = dict(scalars or {})
        try:
            tree = ast.parse(str(text).strip(), mode="eval")
            value = float(_evaluate(tree.body, scalars))
        except (SyntaxError, ValueError, ZeroDivisionError, KeyError, TypeError,
                OverflowError) as exc:
            names = f"; scalar variables of the file: {sorted(scalars)}" if scalars else ""
            digits = "Exceeds the limit" in str(exc)  # Python's 4300-digit integer limit
            why = "division by zero" if isinstance(exc, ZeroDivisionError) else (
                "a number beyond the floating-point range (about 1.8e308)"
                if isinstance(exc, OverflowError) or digits else
                "a syntax error" if isinstance(exc, SyntaxError) else
                "a name that is no scalar variable of the file or an operation other than "
                "+ - * /")
            raise FileFormatError(
                f"scale {_short(text)} is not a number or an expression of numbers with + - * / "
                f"and parentheses, e.g. 0.02/60{names}; it has {why}") from None
    if not (math.isfinite(value) and value != 0.0):
        raise FileFormatError(f"a scale must be finite and non-zero; got {_short(text)}")
    return value


def _short(text: object) -> str:
    """Return the user's text for a message, cut to 60 characters (5000 digits were echoed)."""
    shown = repr(text)
    return shown if len(shown) <= 60 else f"{shown[:57]}...'"


def _evaluate(node: ast.AST, scalars: Mapping[str, float]) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and not \
            isinstance(node.value, bool):
        return float(node.value)
    if isinstance(node, ast.BinOp) and type(node.op) in _OPS:
        return _OPS[type(node.op)](_evaluate(node.left, scalars), _evaluate(node.right, scalars))
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _evaluate(node.operand, scalars)
        return -value if isinstance(node.op, ast.USub) else value
    if isinstance(node, ast.Name) and node.id in scalars:
        return float(scalars[node.id])
    raise ValueError(f"not allowed: {ast.dump(node)[:40]}")
