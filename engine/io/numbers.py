"""How numbers are written in capture text files (BVH, TRC): one rule for every reader.

Python's ``float()`` and ``int()`` accept more than any exporter writes: ``"1_000"``,
Arabic-Indic or full-width digits (``"\\u0663"`` is 3.0), surrounding white space,
``"nan"`` and ``"infinity"``. A reader that used them would silently take a damaged
or hostile file. Here a number is ASCII: an optional sign, digits with an optional
decimal point, an optional exponent.
"""

from __future__ import annotations

import re

import numpy as np

from engine.base.jit import njit_cached

#: a decimal number: ``-12``, ``0.5``, ``.5``, ``5.``, ``1e-3``, ``+2.5E+04``
NUMBER_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
#: a whole number without sign: ``0``, ``250``
WHOLE_RE = re.compile(r"[0-9]+")
#: spellings of NaN and infinity (refused as "not finite" rather than "not a number")
NON_FINITE_RE = re.compile(r"[+-]?(?:nan|inf|infinity)", re.IGNORECASE)
#: any character that cannot be part of a number or the white space between numbers
NOT_NUMERIC_RE = re.compile(r"[^0-9eE+\-.\s]")


def is_number(text: str) -> bool:
    """True when ``text`` is a decimal number written in ASCII (see module docstring)."""
    return NUMBER_RE.fullmatch(text) is not None


def is_whole(text: str) -> bool:
    """True when ``text`` is a whole number of ASCII digits, no sign."""
    return WHOLE_RE.fullmatch(text) is not None


def is_non_finite(text: str) -> bool:
    """True for ``nan``, ``inf``, ``-Infinity`` and the like."""
    return NON_FINITE_RE.fullmatch(text) is not None


# ----------------------------------------------------------------- rows of numbers, fast
#: white space between numbers: the ASCII characters ``str.split()`` splits on
_SPACE = np.zeros(256, np.bool_)
_SPACE[[9, 10, 11, 12, 13, 28, 29, 30, 31, 32]] = True
#: exact powers of ten in float64 (10**22 is the largest exact one)
_POW10 = np.array([10.0**k for k in range(23)])


def parse_rows(text: str, n_rows: int, n_values: int) -> np.ndarray | None:
    """``(n_rows, n_values)`` float64 of ``text``: ``n_rows`` lines joined by ``"\\n"``, each
    of ``n_values`` numbers (:data:`NUMBER_RE`) between white space; None when the text is
    anything else (a character no number has, a malformed number, a wrong count on a line,
    text that is not ASCII): the caller then finds and names the fault its own way.

    Each value is the correctly rounded double of its text, as ``float()`` reads it: a
    number of at most 15 significant digits and a power of ten within 10**±22 is an exact
    integer times or divided by an exact power of ten (one rounding); ``float()`` reads any
    other. Several times faster than splitting the text and converting each value in Python
    (a 2-minute 120 fps take with fingers: 14,400 lines of 159 values)."""
    try:
        data = np.frombuffer(text.encode("ascii"), np.uint8)
    except UnicodeEncodeError:
        return None
    out = np.empty(n_rows * n_values, np.float64)
    slow = np.empty((n_rows * n_values, 3), np.int64)
    n_slow = _parse_rows(data, n_rows, n_values, _SPACE, _POW10, out, slow)
    if n_slow < 0:
        return None
    for index, start, stop in slow[:n_slow]:  # beyond the exact fast path: float() reads it
        out[index] = float(text[start:stop])
    return out.reshape(n_rows, n_values)


@njit_cached(fastmath=False)  # IEEE division and products: the one rounding must be exact
def _parse_rows(data, n_rows, n_values, space, pow10, out, slow):  # pragma: no cover - numba
    """Values of ``data`` into ``out``; the (index, start, stop) of tokens left to
    ``float()`` into ``slow``; returns their count, or -1 when the text is not clean."""
    n = data.size
    pos = 0
    k = 0  # values read
    n_slow = 0
    row = 0
    in_row = 0
    while True:
        while pos < n and space[data[pos]]:  # white space; a newline ends a row
            if data[pos] == 10:
                if in_row != n_values:
                    return -1
                row += 1
                in_row = 0
            pos += 1
        if pos >= n:
            break
        if in_row >= n_values or row >= n_rows:
            return -1
        start = pos
        negative = False
        c = data[pos]
        if c == 43 or c == 45:  # + -
            negative = c == 45
            pos += 1
        mantissa = 0
        digits = 0  # significant digits in the mantissa
        shift = 0  # power of ten of the mantissa's last digit
        seen = 0  # digits of any kind (a number needs one)
        exact = True
        while pos < n and 48 <= data[pos] <= 57:
            d = data[pos] - 48
            if digits > 0 or d != 0:
                if digits < 15:
                    mantissa = mantissa * 10 + d
                    digits += 1
                else:
                    exact = False
            seen += 1
            pos += 1
        if pos < n and data[pos] == 46:  # .
            pos += 1
            while pos < n and 48 <= data[pos] <= 57:
                d = data[pos] - 48
                if digits > 0 or d != 0:
                    if digits < 15:
                        mantissa = mantissa * 10 + d
                        digits += 1
                    else:
                        exact = False
                shift -= 1
                seen += 1
                pos += 1
        if seen == 0:
            return -1
        if pos < n and (data[pos] == 101 or data[pos] == 69):  # e E
            pos += 1
            exp_negative = False
            if pos < n and (data[pos] == 43 or data[pos] == 45):
                exp_negative = data[pos] == 45
                pos += 1
            exp = 0
            exp_digits = 0
            while pos < n and 48 <= data[pos] <= 57:
                if exp < 100000:
                    exp = exp * 10 + (data[pos] - 48)
                exp_digits += 1
                pos += 1
            if exp_digits == 0:
                return -1
            shift += -exp if exp_negative else exp
        if pos < n and not space[data[pos]]:  # a character no number has, or a second sign
            return -1
        if exact and -22 <= shift <= 22:
            value = float(mantissa)
            value = value * pow10[shift] if shift >= 0 else value / pow10[-shift]
            out[k] = -value if negative else value
        else:
            slow[n_slow, 0] = k
            slow[n_slow, 1] = start
            slow[n_slow, 2] = pos
            n_slow += 1
            out[k] = 0.0
        k += 1
        in_row += 1
    if in_row != n_values or row != n_rows - 1:
        return -1
    return n_slow
