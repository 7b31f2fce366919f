"""Safe arithmetic expressions of a record's columns (IDIM regressors and known loads).

An expression such as ``"sin(x)"`` or ``"9.81*0.3*sin(x)"`` is parsed with :mod:`ast` and
evaluated by walking the tree against a whitelist: numbers, the names ``t x v a u`` (time
[s], filtered position, velocity, acceleration, force of the record), the constants ``pi``
and ``e``, ``+ - * / **`` and the numpy functions ``sin cos tan tanh sign abs exp sqrt
log``. Nothing is passed to :func:`eval`; any other node (attributes, subscripts, other
names, keywords) is refused with a :class:`~driveid.errors.ParameterError`.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Mapping

import numpy as np

from driveid.errors import ParameterError

__all__ = ["parse_expression", "evaluate_expression", "EXPRESSION_NAMES",
           "EXPRESSION_FUNCTIONS"]

#: Record quantities an expression may use.
EXPRESSION_NAMES = ("t", "x", "v", "a", "u")

#: Functions an expression may call (numpy, element-wise).
EXPRESSION_FUNCTIONS = {
    "sin": np.sin, "cos": np.cos, "tan": np.tan, "tanh": np.tanh, "sign": np.sign,
    "abs": np.abs, "exp": np.exp, "sqrt": np.sqrt, "log": np.log,
}

_CONSTANTS = {"pi": math.pi, "e": math.e}
_BINARY = {ast.Add: np.add, ast.Sub: np.subtract, ast.Mult: np.multiply,
           ast.Div: np.divide, ast.Pow: np.power}
_UNARY = {ast.USub: np.negative, ast.UAdd: np.positive}


def _refuse(text: str, what: str) -> ParameterError:
    return ParameterError(
        f"expression {text!r} may only use numbers, {', '.join(EXPRESSION_NAMES)}, pi, e, "
        f"+ - * / ** and {', '.join(EXPRESSION_FUNCTIONS)}(); got {what}")


def parse_expression(text: str) -> ast.Expression:
    """Parse and check an expression against the whitelist.

    Parameters
    ----------
    text : str
        Expression, e.g. ``"sin(x)"`` [-].

    Returns
    -------
    ast.Expression
        The checked tree (evaluate it with :func:`evaluate_expression`).

    Raises
    ------
    ParameterError
        If the text is not valid Python syntax or uses anything outside the whitelist.

    Examples
    --------
    >>> isinstance(parse_expression("9.81*sin(x)"), ast.Expression)
    True
    """
    if not isinstance(text, str) or not text.strip() or len(text) > 500:
        raise ParameterError(f"an expression must be a non-empty string of at most 500 "
                             f"characters; got {text!r}")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError:
        raise ParameterError(f"expression {text!r} is not valid syntax; write e.g. "
                             "'sin(x)' or '2*v**2'") from None
    for node in ast.walk(tree):
        if isinstance(node, (ast.Expression, ast.Load)) or type(node) in _BINARY \
                or type(node) in _UNARY:
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in _BINARY:
            continue
        if isinstance(node, ast.UnaryOp) and type(node.op) in _UNARY:
            continue
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            if isinstance(node.value, int) and abs(node.value) > 1e308:  # float() overflows
                raise ParameterError(
                    f"expression {text[:60]!r} holds a number beyond the floating-point range "
                    "(about 1.8e308); write it in units that keep it finite")
            continue
        if isinstance(node, ast.Name) and (node.id in EXPRESSION_NAMES
                                           or node.id in _CONSTANTS
                                           or node.id in EXPRESSION_FUNCTIONS):
            continue
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in EXPRESSION_FUNCTIONS and len(node.args) == 1 \
                and not node.keywords:
            continue
        raise _refuse(text, f"{type(node).__name__}"
                      + (f" {node.id!r}" if isinstance(node, ast.Name) else ""))
    return tree


def evaluate_expression(text: str, values: Mapping[str, np.ndarray]) -> np.ndarray:
    """Evaluate a whitelisted expression on arrays.

    Parameters
    ----------
    text : str
        Expression of ``t x v a u`` [-], see the module docstring.
    values : mapping of str to ndarray, shape (n,)
        The quantities by name [SI units]; a name the expression uses must be present.

    Returns
    -------
    ndarray, shape (n,)
        The expression's value per sample [unit implied by the expression].

    Raises
    ------
    ParameterError
        If the expression is refused, uses a quantity that is not available, or gives a
        non-finite value or one above 1e100 in magnitude.

    Examples
    --------
    >>> import numpy as np
    >>> evaluate_expression("2*sin(x)", {"x": np.array([0.0, np.pi / 2])}).tolist()
    [0.0, 2.0]
    """
    tree = parse_expression(text)
    n = max((np.size(v) for v in values.values()), default=1)

    def walk(node: ast.AST) -> np.ndarray:
        if isinstance(node, ast.Expression):
            return walk(node.body)
        if isinstance(node, ast.Constant):
            return np.full(n, float(node.value))
        if isinstance(node, ast.Name):
            if node.id in _CONSTANTS:
                return np.full(n, _CONSTANTS[node.id])
            if node.id not in values or values[node.id] is None:
                raise ParameterError(
                    f"expression {text!r} uses {node.id!r}, which this record does not "
                    f"have; use {sorted(k for k, v in values.items() if v is not None)}")
            return np.asarray(values[node.id], dtype=float)
        if isinstance(node, ast.BinOp):
            return _BINARY[type(node.op)](walk(node.left), walk(node.right))
        if isinstance(node, ast.UnaryOp):
            return _UNARY[type(node.op)](walk(node.operand))
        if isinstance(node, ast.Call):
            return EXPRESSION_FUNCTIONS[node.func.id](walk(node.args[0]))
        raise _refuse(text, type(node).__name__)  # pragma: no cover - parse refused it

    with np.errstate(all="ignore"):
        out = np.broadcast_to(walk(tree), (n,)).astype(float)
    if not np.all(np.isfinite(out)):
        raise ParameterError(f"expression {text!r} gives non-finite values on this record "
                             f"(e.g. sqrt or log of a negative number); got "
                             f"{int(np.count_nonzero(~np.isfinite(out)))} non-finite samples")
    peak = float(np.max(np.abs(out), initial=0.0))
    if peak > 1e100:  # issue 28: exp(1000*x) reached 1e304; the fit gave nan with exit 0
        raise ParameterError(
            f"expression {text!r} reaches {peak:.3g} on this record, above the 1e+100 that "
            "driveid computes with (its squares overflow); check the expression and the "
            "units of t x v a u (SI: m or rad, s, N or N·m)")
    return out
