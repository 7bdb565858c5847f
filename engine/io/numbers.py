"""How numbers are written in capture text files (BVH, TRC): one rule for every reader.

Python's ``float()`` and ``int()`` accept more than any exporter writes: ``"1_000"``,
Arabic-Indic or full-width digits (``"\\u0663"`` is 3.0), surrounding white space,
``"nan"`` and ``"infinity"``. A reader that used them would silently take a damaged
or hostile file. Here a number is ASCII: an optional sign, digits with an optional
decimal point, an optional exponent.
"""

from __future__ import annotations

import re

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
