"""JSON text from outside (a session file, a link's query, a roles map, a GLB's JSON chunk,
an edit queue from the page) read into Python objects, every way it can be refused giving
one :class:`JsonTextError`.

``json.loads`` refuses text in three unlike ways: ``JSONDecodeError`` (bad syntax, with a
place), ``RecursionError`` (arrays or objects nested thousands deep) and a bare ``ValueError``
(an integer of more than ``sys.get_int_max_str_digits()`` digits, or a hook's refusal). A
caller that caught only the first let the others out as tracebacks (CI of stop 32: a link
whose ``roles`` was 5,000 digits), so each reader calls :func:`parse_json` and catches one
error.
"""

from __future__ import annotations

import json
from typing import Any


class JsonTextError(ValueError):
    """JSON text that cannot be read; ``detail`` is one line that starts with the place
    (``line L, column C``) when JSON gives one."""

    def __init__(self, detail: str, line: int | None = None, column: int | None = None):
        super().__init__(detail)
        self.detail = detail
        self.line = line
        self.column = column


def _reject_constant(name: str):
    raise JsonTextError(f"expected finite numbers, found {name}")


def parse_json(text: str | bytes, *, finite: bool = True) -> Any:
    """The object of JSON ``text``; with ``finite`` the constants NaN and (-)Infinity,
    which Python's json reads but JSON does not have, are refused.

    Raises :class:`JsonTextError` for every refusal, never ``RecursionError``."""
    if isinstance(text, bytes | bytearray):
        try:
            text = bytes(text).decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise JsonTextError(f"not UTF-8 text (byte {exc.start})") from None
    hooks = {"parse_constant": _reject_constant} if finite else {}
    try:
        return json.loads(text, **hooks)
    except json.JSONDecodeError as exc:
        # json's messages end in " at" where it gives the place ("Unterminated string
        # starting at"): the place is said first, whole (stranger 8 read a cut-off sentence)
        raise JsonTextError(
            f"line {exc.lineno}, column {exc.colno}: not valid JSON "
            f"({exc.msg.removesuffix(' at').lower()})",
            exc.lineno,
            exc.colno,
        ) from None
    except JsonTextError:
        raise
    except RecursionError:
        raise JsonTextError("JSON nested too deeply") from None
    except ValueError as exc:  # an integer past the int-to-str digit limit
        digits = "digits" in str(exc)
        raise JsonTextError(
            "a number with too many digits" if digits else f"not valid JSON ({exc})"
        ) from None
