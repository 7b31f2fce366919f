"""Integer registers as drives log them: sign-magnitude decoding and its detection.

Some drives and bus loggers store a signed count as a magnitude with the top bit as the sign
(``0x8005`` is -5 in a 16-bit register), not in two's complement. Read as an unsigned
number, a position that crosses zero jumps from small values to just above ``2**(bits-1)``.
:func:`decode_sign_magnitude` decodes such a column (``--sign-magnitude x:16``);
:func:`sign_magnitude_suspect` flags a column that looks undecoded.
"""

from __future__ import annotations

import numpy as np

from driveid.errors import FileFormatError

__all__ = ["decode_sign_magnitude", "sign_magnitude_suspect"]


def decode_sign_magnitude(values: np.ndarray, bits: int) -> np.ndarray:
    """Decode integers stored as sign-magnitude registers (top bit the sign).

    Parameters
    ----------
    values : ndarray, shape (n,)
        Raw register values, integers in ``[0, 2**bits)`` [-].
    bits : int
        Register width [bits], 2 to 64.

    Returns
    -------
    ndarray, shape (n,)
        Signed values: ``v`` below ``2**(bits-1)``, ``-(v - 2**(bits-1))`` above [-].

    Raises
    ------
    FileFormatError
        If ``bits`` is out of range or a value is not an integer of the register.

    Examples
    --------
    >>> decode_sign_magnitude(np.array([5.0, 32773.0, 0.0]), 16).tolist()
    [5.0, -5.0, 0.0]
    """
    try:
        bits = int(bits)
    except (TypeError, ValueError):
        raise FileFormatError(f"a sign-magnitude register width is a number of bits; got "
                              f"{bits!r}") from None
    if not 2 <= bits <= 64:
        raise FileFormatError(f"a sign-magnitude register has 2 to 64 bits; got {bits}")
    values = np.asarray(values, dtype=float)
    finite = values[np.isfinite(values)]
    top = 2.0 ** bits
    if finite.size and (np.any(finite != np.round(finite)) or finite.min() < 0
                        or finite.max() >= top):
        raise FileFormatError(
            f"a {bits}-bit sign-magnitude register holds integers 0..{2**bits - 1}; got "
            f"values from {finite.min():g} to {finite.max():g}")
    half = 2.0 ** (bits - 1)
    return np.where(values >= half, -(values - half), values)


def sign_magnitude_suspect(values: np.ndarray) -> int | None:
    """Return the register width of a column that looks like undecoded sign-magnitude.

    Integers only, none negative, and two clusters: small values and values just above a
    power of two (the sign bit), with the band between them empty. An unsigned count that
    crosses the sign bit fills that band and is not flagged.

    Parameters
    ----------
    values : ndarray, shape (n,)
        A column as read [-].

    Returns
    -------
    int or None
        The width [bits] (8, 12, 16, 24 or 32), or None when the column does not look so.

    Examples
    --------
    >>> sign_magnitude_suspect(np.array([3.0, 1, 0, 32770, 32771, 2, 32769, 5]))
    16
    """
    if values.size < 8 or values.dtype.kind != "f":
        return None
    sample = values[:: max(1, values.size // 20000)]
    sample = sample[np.isfinite(sample)]
    if not sample.size or sample.min() < 0 or np.any(sample != np.round(sample)):
        return None
    for bits in (8, 12, 16, 24, 32):
        half = 2.0 ** (bits - 1)
        if not half <= sample.max() < 2 * half:
            continue
        high = sample[sample >= half] - half
        low = sample[sample < half]
        # an unsigned count that crosses the sign bit fills the band between the clusters
        if high.size and low.size and high.max() < half / 2 and low.max() < half / 2:
            return bits
    return None
