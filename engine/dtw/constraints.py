"""The user's alignment constraints, in one place: band widths, matching points,
tolerances and ends, with their defaults, ranges, parsing and error text.

Every front (``handsplice splice`` flags, the batch manifest, the session file and
the app's link, the app's ``Session`` and its backend) calls this module and shows
its message; nothing else re-validates or words a refusal. A refusal is a
:class:`ConstraintError` (a ``ParameterError``) whose text is ``LABEL: what is wrong,
what was expected``; ``LABEL`` is the field (``band: expected ..., got 5``) or, for a
matching point, the point as a user counts and reads it: ``matching point 2 (body 80,
hand 20): hand frame 20 is before matching point 1's hand frame 30; ...`` (1-based, in
the order the user gave the points; :func:`point_label`). A front puts only its source in front
(``demo.json: ...``, ``manifest.csv line 3, column match: ...``, ``--match 80:20: ...``).

Band widths (docs/method.md §4, Majkowska et al. eqs. 4-5)
    A width is a :class:`Width`: a fraction of the body take (the paper's ``W = w·n``
    frames) or a time in seconds (``"10s"``: ``W = 10 · fps`` frames). Text forms:
    ``0.3`` and ``10s``/``10 s``. Without a width the default is the paper's fraction
    for short takes and a time width for long ones, whichever is narrower
    (:meth:`WidthRule.default_for`): a 30 % band of a 2-minute take allows 36 s of
    drift, while two performances of one script drift by a few seconds
    (see ``DRIFT_NOTE``).

Matching points
    ``(body, hand[, tolerance])``: body frame ``body`` matches hand frame ``hand``
    (0-based) within ``tolerance`` hand frames (``None``: the global tolerance).
    Body frames increase strictly from one point to the next; hand frames never
    decrease (equal hand frames are a hold of the hand take). Text form
    ``B:H[:T]``; a list of them is separated by ``;``, ``,`` or spaces.
    :func:`check_points` adds the rules that need the matrix size ``n x m``.

Ends
    ``ends="fixed"`` (the path starts at (0, 0) and ends at (n-1, m-1)) or ``"open"``
    (either take may begin or finish with up to ``max_unmatched_s`` seconds that match
    nothing; ``None`` = :data:`UNMATCHED_DEFAULT`, per take: half of the shorter take,
    plus the length difference for the longer one, see :func:`unmatched_limits`).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from engine.base.errors import ParameterError
from engine.base.limits import MAX_BAND_CELLS
from engine.base.tolerances import FRAME_EPS, PASS1_RATE_CAP_HZ

# slack when rounding tolerances and band edges computed in floating point
EPS = FRAME_EPS

DRIFT_NOTE = (
    "Default time widths on long takes: pass 1 W1 = 1.5 s x sqrt(T / 1 s) for a body take "
    "of T seconds (16.4 s at 2 minutes, 36.7 s at 10), pass 2 W2 = 2 s; each applies when "
    "narrower than the paper's 0.30 / 0.10 of the take (from 25 s / 20 s of take on). "
    "Why: between two performances of one script the hand take's local rate wanders "
    "(the accuracy bench's model: rate exp(sigma * noise), sigma 0.15-0.3, 1 s "
    "correlation, which the short-take accuracy figures are measured on). That is a random "
    "walk, so the drift from the diagonal grows as sqrt(T): over 20 warps the worst "
    "drift was 0.85 s at 6 s, 2.45 s at 20 s, 7.7 s at 2 min and 21.2 s at 10 min "
    "(sigma 0.3; benchmarks/RESULTS.md, 'Band widths in seconds'). W1's vertical "
    "half-width (about W1 / sqrt 2 when both takes last about as long) is then 11.6 s at "
    "2 min and 26 s at 10 min, 1.5x and 1.2x the worst drift, with half the cells of a "
    "30 % band at 2 minutes and a fifth at 10. W1 is capped so that its band keeps within "
    "the engine's cell limit (engine.base.limits.MAX_BAND_CELLS, less 10 %): 14.7 s at 10 "
    "minutes and 120 fps (vertical half-width 10.4 s: 1.0x the worst drift at sigma 0.15, "
    "1.05x the median and 0.5x the worst at sigma 0.3), the widest band the engine accepts "
    "there; takes that drift more must be spliced in parts (or the limit raised). "
    "Pass 2 only corrects the pass-1 path "
    "locally, an error that does not grow with the take: the 2 s the paper's 0.10 gives a "
    "20 s take (radius about 0.7 s) is kept."
)


class ConstraintError(ParameterError):
    """A constraint a user can break is out of range, as structured fields: ``field``
    names it for code (``band``, ``points[2].tolerance``: 0-based), ``value`` is what was
    given, ``expected`` what was expected (None where the refusal is a conflict between
    points rather than a range); ``detail`` is the sentence after the label and
    ``str(err)`` is ``"label: detail"``, the one text every front shows.

    ``label`` is what a user reads: the field, or for a matching point
    ``matching point K (body B, hand H)`` (:func:`point_label`: K 1-based, in the order
    the points were given). A refusal of one matching point also keeps its parts:
    ``index`` (0-based) of the refused point, ``point`` its ``(body, hand)`` when placed
    (whole frames), ``others`` the points it conflicts with."""

    def __init__(
        self,
        field: str,
        detail: str,
        *,
        label: str | None = None,
        value=None,
        expected: str | None = None,
        index: int | None = None,
        point: tuple[int, int] | None = None,
        others: tuple = (),
    ):
        self.field = field
        self.label = field if label is None else label
        self.detail = detail
        self.value = value
        self.expected = expected
        self.index = index
        self.point = point
        self.others = tuple(others)
        super().__init__(f"{self.label}: {detail}" if self.label else detail)

    def named(self, label: str) -> ConstraintError:
        """This refusal labelled with a front's own name of the field (the session file's
        ``max_unmatched``, the link's ``unmatched``); a matching point's label (the point
        in the user's words) is kept."""
        if self.label != self.field:
            return self
        return ConstraintError(
            self.field,
            self.detail,
            label=label,
            value=self.value,
            expected=self.expected,
            index=self.index,
            point=self.point,
            others=self.others,
        )


_NUMBER_TEXT = re.compile(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?")


def _frame_shown(value) -> str | None:
    """A frame as given, for a point's label (``40``, ``12.5``); None if not a number."""
    if isinstance(value, bool) or value is None:
        return None
    if isinstance(value, str):
        text = value.strip()
        return text if _NUMBER_TEXT.fullmatch(text) and len(text) <= 20 else None
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return f"{float(value):g}"
    return None


def point_label(index: int, body=None, hand=None) -> str:
    """``matching point K (body B, hand H)``: how every front names the matching point
    at 0-based ``index`` (K = index + 1, in the order the user gave the points); a frame
    that is missing or not a number is left out (``matching point 1 (hand 30)``)."""
    parts = [
        f"{which} {shown}"
        for which, shown in (("body", _frame_shown(body)), ("hand", _frame_shown(hand)))
        if shown is not None
    ]
    return f"matching point {index + 1}" + (f" ({', '.join(parts)})" if parts else "")


def _show(value) -> str:
    """A short, quoted rendering of a user's value for error text."""
    if isinstance(value, str):
        text = repr(value)
    elif isinstance(value, bool) or value is None:
        text = repr(value)
    elif isinstance(value, int | float | np.number):
        text = f"{float(value):g}" if isinstance(value, float | np.floating) else str(value)
    else:
        text = type(value).__name__
    return text if len(text) <= 40 else text[:37] + "..."


def _number(value, field: str, expected: str, **where) -> float:
    """A finite float from a number or numeric text; ConstraintError otherwise (``where``:
    the refusal's ``label`` and ``index``, for a matching point's)."""

    def refused() -> ConstraintError:
        return ConstraintError(
            field,
            f"expected {expected}, got {_show(value)}",
            value=value,
            expected=expected,
            **where,
        )

    if isinstance(value, bool) or value is None:
        raise refused()
    if isinstance(value, str):
        if not _NUMBER_TEXT.fullmatch(value.strip()):
            raise refused()
        value = value.strip()
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise refused() from None
    if not math.isfinite(x):
        raise refused()
    return x


# ---------------------------------------------------------------------------------------
# band widths
# ---------------------------------------------------------------------------------------

FRACTION = "fraction"
SECONDS = "s"


@dataclass(frozen=True, eq=False)
class Width:
    """A band width: ``value`` as a fraction of the body take (``unit="fraction"``) or in
    seconds (``unit="s"``)."""

    value: float
    unit: str = FRACTION

    def frames(self, n: int, fps: float) -> float:
        """The width ``W`` in body frames for a body take of ``n`` frames at ``fps``."""
        return self.value * n if self.unit == FRACTION else self.value * float(fps)

    def fraction(self, n: int, fps: float) -> float:
        """The width as a fraction of ``n`` (what :class:`engine.dtw.Band` takes)."""
        return self.value if self.unit == FRACTION else self.value * float(fps) / max(n, 1)

    def text(self) -> str:
        """``"0.3"`` or ``"10s"`` (the form every front reads back)."""
        return f"{self.value:g}" if self.unit == FRACTION else f"{self.value:g}s"

    def to_json(self) -> float | str:
        """A fraction as a number, seconds as text (``"10s"``)."""
        return self.value if self.unit == FRACTION else self.text()

    def __str__(self) -> str:
        return self.text()

    def __eq__(self, other) -> bool:
        # a fraction equals the plain number it was given as (``spec.band == 0.3``)
        if isinstance(other, Width):
            return (self.value, self.unit) == (other.value, other.unit)
        if isinstance(other, int | float) and not isinstance(other, bool):
            return self.unit == FRACTION and self.value == other
        return NotImplemented

    def __hash__(self) -> int:
        return hash((self.value, self.unit))


@dataclass(frozen=True)
class WidthRule:
    """Default and range of one band width, in both units."""

    name: str
    what: str
    default: float  # fraction of the body take (the paper's value, short takes)
    lo: float
    hi: float
    default_s: float  # seconds (long takes); times sqrt(T / 1 s) when ``grows``
    lo_s: float
    hi_s: float
    grows: bool = False  # the long-take width grows as the square root of the take
    #: the default width is capped so that its band (both takes about as long) keeps
    #: within this many cells (None: no cap)
    max_cells: int | None = None
    symbol: str = ""  # the paper's name of the width: W1, W2

    @property
    def seconds_label(self) -> str:
        """The app's field for this width in seconds (``W1 in seconds``): a refusal of what
        was typed there names it (not ``band``, whose text speaks of fractions too)."""
        return f"{self.symbol or self.name} in seconds"

    @property
    def expected_seconds(self) -> str:
        return f"seconds from {self.lo_s:g} to {self.hi_s:g} (like 10 or 10s)"

    def parse_seconds(self, value) -> float | None:
        """A width typed into a field in seconds (``10``, ``10s``, ``10 s``); empty text or
        None -> None (the fraction is in force). ConstraintError with field ``NAME_s``,
        labelled :attr:`seconds_label`, showing the value as typed."""
        if value is None or (isinstance(value, str) and not value.strip()):
            return None
        text = value
        if isinstance(value, str):
            text = re.sub(r"\s*s(ec(onds?)?)?\s*$", "", value.strip(), flags=re.IGNORECASE)
        where = {"label": self.seconds_label, "value": value, "expected": self.expected_seconds}
        try:
            x = _number(text, f"{self.name}_s", self.expected_seconds)
        except ConstraintError:
            x = math.nan
        if not self.lo_s - EPS <= x <= self.hi_s + EPS:
            raise ConstraintError(
                f"{self.name}_s", f"expected {self.expected_seconds}, got {_show(value)}", **where
            )
        return float(x)

    @property
    def expected(self) -> str:
        return (
            f"a fraction of the body take from {self.lo:g} to {self.hi:g} or seconds "
            f"like 10s (from {self.lo_s:g} to {self.hi_s:g} s)"
        )

    @property
    def crossover_s(self) -> float:
        """Seconds of body take from which the time width is the narrower (the default)."""
        ratio = self.default_s / self.default
        return ratio * ratio if self.grows else ratio

    @property
    def default_text(self) -> str:
        """The default in words, as :meth:`default_for` applies it (help texts say this)."""
        time = f"{self.default_s:g} s x sqrt(T / 1 s)" if self.grows else f"{self.default_s:g} s"
        text = (
            f"default {self.default:g} of the body take, or {time} when narrower "
            f"(takes from {self.crossover_s:g} s on"
        )
        if self.grows:
            text += "; T: the body take in seconds"
        if self.max_cells is not None:
            text += f"; capped so the band keeps within {self.max_cells:,} cells"
        return text + ")"

    def parse(self, value) -> Width | None:
        """A :class:`Width` from a number (fraction), text (``"0.3"``, ``"10s"``) or a Width;
        ``None`` or empty text -> ``None`` (the default applies). ConstraintError if out
        of range."""
        if value is None or (isinstance(value, str) and not value.strip()):
            return None
        if isinstance(value, Width):
            value, unit = value.value, value.unit
        elif isinstance(value, str) and re.fullmatch(
            r"\s*[^\s]+?\s*s(ec(onds?)?)?\s*", value, flags=re.IGNORECASE
        ):
            value, unit = (
                re.sub(r"\s*s(ec(onds?)?)?\s*$", "", value.strip(), flags=re.IGNORECASE),
                SECONDS,
            )
        else:
            unit = FRACTION
        x = _number(value, self.name, self.expected)
        lo, hi = (self.lo, self.hi) if unit == FRACTION else (self.lo_s, self.hi_s)
        if not lo - EPS <= x <= hi + EPS:
            got = f"{x:g}" + ("s" if unit == SECONDS else "")
            raise ConstraintError(
                self.name, f"expected {self.expected}, got {got}", value=x, expected=self.expected
            )
        return Width(float(x), unit)

    def default_for(self, n: int, fps: float) -> Width:
        """The default width for a body take of ``n`` frames at ``fps``: the paper's
        fraction, or the time width when that is narrower (long takes), capped by
        :meth:`cap_seconds`."""
        seconds = self.long_take_seconds(n / float(fps))
        if self.max_cells is not None:
            seconds = min(seconds, self.cap_seconds(n, fps))
        if self.default * n > seconds * float(fps):
            return Width(seconds, SECONDS)
        return Width(self.default, FRACTION)

    def cap_seconds(self, n: int, fps: float) -> float:
        """The widest time width (0.1 s steps) whose band over ``n x n`` frames keeps within
        :attr:`max_cells` (a diagonal band of width ``W`` has about ``sqrt 2 · n · W · fps``
        cells), less 10 % for the band's rounding and open-ends corners."""
        if self.max_cells is None or n <= 0:
            return math.inf
        cap = 0.9 * self.max_cells / (math.sqrt(2.0) * n * float(fps))
        return max(self.lo_s, math.floor(cap * 10.0) / 10.0)

    def long_take_seconds(self, duration_s: float) -> float:
        """The time width (seconds, 0.1 s steps) for a take of ``duration_s`` seconds."""
        if not self.grows:
            return self.default_s
        return round(self.default_s * math.sqrt(max(duration_s, 0.0)), 1)

    def resolve(self, value, n: int, fps: float) -> float:
        """The width (given, or the default) as a fraction of ``n``, for the engine's own
        calls: a plain number is a fraction taken as it is (any finite value >= 0: the
        benchmarks and tests use bands outside the users' range); text and ``Width``
        values are parsed and checked as every front does."""
        if isinstance(value, int | float | np.number) and not isinstance(value, bool):
            if not (math.isfinite(value) and value >= 0):
                raise ConstraintError(
                    self.name,
                    f"expected {self.expected}, got {_show(value)}",
                    value=value,
                    expected=self.expected,
                )
            return float(value)
        width = self.parse(value)
        if width is None:
            width = self.default_for(n, fps)
        return width.fraction(n, fps)


BAND = WidthRule(
    "band",
    "pass-1 band width W1",
    default=0.30,
    lo=0.02,
    hi=1.0,
    default_s=1.5,
    lo_s=0.1,
    hi_s=3600.0,
    grows=True,
    max_cells=MAX_BAND_CELLS,
    symbol="W1",
)
REFINE_BAND = WidthRule(
    "refine_band",
    "pass-2 band width W2 around the pass-1 path",
    default=0.10,
    lo=0.01,
    hi=1.0,
    default_s=2.0,
    lo_s=0.05,
    hi_s=3600.0,
    symbol="W2",
)


def half_width(w_frames: float, dx: float, dy: float) -> float:
    """Vertical half-width ``Λ = W sqrt(dx² + dy²) / (2 dx)`` (frames) of a diagonal band of
    perpendicular width ``W`` frames over a segment ``dx`` rows by ``dy`` columns (eq. 4)."""
    return w_frames * math.hypot(dx, dy) / (2.0 * dx)


def refine_radius(n: int, m: int, refine_band: float) -> int:
    """Pass-2 band radius (frames, Chebyshev) for width ``refine_band * n`` around the path.

    A Chebyshev radius ``r`` around a path of slope ``m/n`` spans about ``r (1 + m/n)``
    columns either side, so ``r = Λ / (1 + m/n)`` with ``Λ`` of the whole take.
    """
    if not (np.isfinite(refine_band) and refine_band >= 0):
        raise ConstraintError(
            REFINE_BAND.name,
            f"expected {REFINE_BAND.expected}, got {_show(refine_band)}",
            value=refine_band,
            expected=REFINE_BAND.expected,
        )
    lam = half_width(refine_band * n, n, m)
    return max(1, int(round(lam / (1.0 + m / n))))


# ---------------------------------------------------------------------------------------
# tolerances
# ---------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Range:
    """Default and closed range of a number."""

    name: str
    default: float
    lo: float
    hi: float
    unit: str

    @property
    def expected(self) -> str:
        return f"a number of {self.unit} from {self.lo:g} to {self.hi:g}"

    def parse(self, value, field: str | None = None, expected: str | None = None, **where):
        """``value`` as a float in range; ConstraintError naming ``field`` (``where``: the
        refusal's ``label`` and ``index``) otherwise."""
        field = field or self.name
        expected = expected or self.expected
        x = _number(value, field, expected, **where)
        if not self.lo <= x <= self.hi:
            raise ConstraintError(
                field, f"expected {expected}, got {x:g}", value=x, expected=expected, **where
            )
        return x


#: matching-point tolerance T (global or per point), hand frames
TOLERANCE = Range("tolerance", 0.0, 0.0, 500.0, "frames")


def parse_tolerance(value, field: str = "tolerance") -> float:
    """The global tolerance (frames); ConstraintError naming ``field`` if out of range."""
    return TOLERANCE.parse(value, field)


# ---------------------------------------------------------------------------------------
# ends
# ---------------------------------------------------------------------------------------

ENDS = ("fixed", "open")
DEFAULT_ENDS = "open"  # open-end DTW (issue 12); engine.splice.pipeline.ENDS is this
#: the open-end limit, seconds (None = the default, :func:`unmatched_limits`)
MAX_UNMATCHED = Range("max_unmatched_s", 0.0, 0.0, 3600.0, "seconds")
#: the default open-end limit in words (the CLI's help, the unmatched sentence, the docs)
UNMATCHED_DEFAULT = "half the shorter take, plus the length difference for the longer one"


def parse_ends(value) -> str:
    """``"fixed"`` or ``"open"`` (``None`` -> the default)."""
    if value is None or value == "":
        return DEFAULT_ENDS
    text = value.strip().lower() if isinstance(value, str) else value
    if text not in ENDS:
        expected = " or ".join(ENDS)
        raise ConstraintError(
            "ends", f"expected {expected}, got {_show(value)}", value=value, expected=expected
        )
    return text


#: the app's field for the open-end limit (its refusal names it, as ``--max-unmatched``
#: names the flag's)
MAX_UNMATCHED_LABEL = "Unmatched ends at most (seconds)"


def parse_max_unmatched(value, label: str | None = None) -> float | None:
    """Seconds a take may begin or end with unmatched (open ends); None = the default.
    ``label``: the field the value was typed into, for the refusal (default: the rule's
    name, ``max_unmatched_s``)."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, str):
        value = re.sub(r"\s*s\s*$", "", value.strip())
    return MAX_UNMATCHED.parse(value, **({} if label is None else {"label": label}))


def unmatched_limits(
    n: int, m: int, fps: float, max_unmatched_s: float | None = None
) -> tuple[int, int]:
    """Frames of the body take (``n`` frames) and of the hand take (``m`` frames on the
    alignment grid, the body's rate ``fps``) that may stay unmatched at each end (open
    ends, ``engine.dtw.Ends``): ``max_unmatched_s`` seconds for both, or the default
    (:data:`UNMATCHED_DEFAULT`), per take

        limit = (its length - the other's length, if longer) + min(n, m) // 2

    Why: the shorter take may lie anywhere inside the longer one (a 33 s hand take
    recorded during a 2-minute body take), so each end of the longer take may stay
    unmatched for up to the length difference; on top of that the takes may overlap
    only in part, by as little as half the shorter take at either end. With equal
    lengths this is half the take, as before; with half the shorter take for both
    (the old rule) a 33 s hand had to span at least 2 min - 33 s of the body take.
    Each limit is below its take's length."""
    n, m = int(n), int(m)
    if max_unmatched_s is None:
        half = min(n, m) // 2
        body, hand = max(n - m, 0) + half, max(m - n, 0) + half
    else:
        body = hand = int(round(parse_max_unmatched(max_unmatched_s) * float(fps)))
    return max(min(body, n - 1), 0), max(min(hand, m - 1), 0)


# ---------------------------------------------------------------------------------------
# matching points
# ---------------------------------------------------------------------------------------

#: at most this many matching points (a session, a link, a manifest row)
MAX_POINTS = 10_000
_FRAME_LIMIT = 2**31


@dataclass(frozen=True)
class MatchPoint:
    """A user matching point: body frame ``body`` corresponds to hand frame ``hand``.

    ``tolerance`` in hand frames (>= 0), or None to use the global tolerance.
    """

    body: int
    hand: int
    tolerance: float | None = None

    def resolved(self, global_tolerance: float = 0.0) -> tuple[int, int, float]:
        """``(x, y, tol)`` as the DTW band expects it."""
        tol = global_tolerance if self.tolerance is None else self.tolerance
        return (self.body, self.hand, float(tol))

    def text(self) -> str:
        """``B:H`` or ``B:H:T`` (the form every front reads back)."""
        return f"{self.body}:{self.hand}" + (
            "" if self.tolerance is None else f":{self.tolerance:g}"
        )


_POINT_EXPECTED = "BODY:HAND or BODY:HAND:TOL (frames >= 0, tolerance in frames)"
_WHOLE_FRAME = "a whole {}frame number >= 0"


def _frame(value, field: str, expected: str, **where) -> int:
    """A frame number (0-based) from a whole number or its text (``"125"``, ``125.0``); a
    fraction (``12.5``: a slip while typing 125) is refused, never truncated or rounded."""
    x = _number(value, field, expected, **where)
    if x != round(x) or not 0 <= x < _FRAME_LIMIT:
        raise ConstraintError(
            field, f"expected {expected}, got {x:g}", value=value, expected=expected, **where
        )
    return int(x)


def parse_point_frame(value, index: int, which: str, body=None, hand=None) -> int:
    """The ``which`` (``"body"`` or ``"hand"``) frame of the matching point at 0-based
    ``index`` (:func:`_frame`: 12.5 is refused, never truncated); the refusal names the point
    (``matching point 3 (body 40, hand 12.5): expected a whole hand frame number >= 0, got
    12.5``; ``body``/``hand``: the point's frames as given, for its label). Every front
    reads a matching point's frames through here (the app's table too)."""
    return _frame(
        value,
        f"points[{index}].{which}",
        _WHOLE_FRAME.format(f"{which} "),
        label=point_label(index, body, hand),
        index=index,
    )


def parse_point_tolerance(value, index: int, body=None, hand=None) -> float:
    """The tolerance of the matching point at 0-based ``index`` (hand frames, the range of
    :data:`TOLERANCE`); the refusal names the point."""
    expected = f"a tolerance from {TOLERANCE.lo:g} to {TOLERANCE.hi:g} {TOLERANCE.unit}"
    return TOLERANCE.parse(
        value,
        f"points[{index}].tolerance",
        expected=expected,
        label=point_label(index, body, hand),
        index=index,
    )


def parse_point(value, index: int = 0, field: str = "points") -> MatchPoint:
    """One matching point (0-based ``index`` in the user's list, for its refusal) from
    ``"B:H[:T]"``, ``(B, H[, T])``, ``{"body", "hand", "tolerance"}`` or a MatchPoint."""
    name = f"{field}[{index}]"
    if isinstance(value, MatchPoint):
        value = (value.body, value.hand, value.tolerance)
    if isinstance(value, str):
        parts = value.strip().split(":")
        if len(parts) not in (2, 3):
            raise _bad_form(name, index, value)
        value = parts
    if isinstance(value, dict):
        label = point_label(index, value.get("body"), value.get("hand"))
        unknown = set(value) - {"body", "hand", "tolerance"}
        if unknown:
            raise ConstraintError(
                f"{name}.{sorted(unknown)[0]}",
                f"unknown field {_show(sorted(unknown)[0])} (known: body, hand, tolerance)",
                label=label,
                index=index,
            )
        for key in ("body", "hand"):
            if key not in value:
                raise ConstraintError(
                    f"{name}.{key}",
                    f"expected a {key} frame, none was given",
                    label=label,
                    expected=f"a {key} frame",
                    index=index,
                )
        value = (value["body"], value["hand"], value.get("tolerance"))
    if not isinstance(value, list | tuple | np.ndarray) or len(value) not in (2, 3):
        raise _bad_form(name, index, value)
    body = parse_point_frame(value[0], index, "body", value[0], value[1])
    hand = parse_point_frame(value[1], index, "hand", value[0], value[1])
    tol = value[2] if len(value) == 3 else None
    tol = None if tol is None else parse_point_tolerance(tol, index, body, hand)
    return MatchPoint(body, hand, tol)


def _bad_form(field: str, index: int, value) -> ConstraintError:
    return ConstraintError(
        field,
        f"expected {_POINT_EXPECTED}, got {_show(value)}",
        label=point_label(index),
        value=value,
        expected=_POINT_EXPECTED,
        index=index,
    )


def split_points_text(text: str) -> list[str]:
    """``"120:98:2;300:280"`` (``;``, ``,`` or spaces between points) -> items."""
    return [t for t in re.split(r"[;,\s]+", text or "") if t]


def parse_points(items, field: str = "points") -> tuple[MatchPoint, ...]:
    """Matching points from a list (of any form :func:`parse_point` reads) or a text list
    (``"B:H[:T];..."``), checked for order: body frames increase strictly, hand frames
    never decrease."""
    if items is None:
        return ()
    if isinstance(items, str):
        items = split_points_text(items)
    if not isinstance(items, list | tuple):
        expected = f"a list of {_POINT_EXPECTED}"
        raise ConstraintError(
            field, f"expected {expected}, got {_show(items)}", value=items, expected=expected
        )
    if len(items) > MAX_POINTS:
        raise ConstraintError(
            field,
            f"expected at most {MAX_POINTS} points, got {len(items)}",
            value=items,
            expected=f"at most {MAX_POINTS} points",
        )
    points = tuple(parse_point(p, k, field) for k, p in enumerate(items))
    for k in range(1, len(points)):
        a, b = points[k - 1], points[k]
        reason = _order_reason(k, b.body, b.hand, a.body, a.hand)
        if reason is not None:
            raise _point_refusal(k, (b.body, b.hand), reason, b, others=(a,), field=field)
    return points


def ordered_points(indexed, field: str = "points"):
    """``(kept, refusals)``: of ``indexed``, ``(index, MatchPoint)`` pairs in the user's
    order (``index`` 0-based in their list), the points kept in order and the refusal of
    each point left out because it cannot follow the last one kept (:func:`parse_points`'
    order rules and words). A front that leaves a bad point out alone (a link) uses it:
    one point out of order loses only itself (stranger 12: ``pts=649:1149,429:1799``
    said point 2 was left out and dropped point 1 too)."""
    kept: list[tuple[int, MatchPoint]] = []
    refusals: list[ConstraintError] = []
    for k, p in indexed:
        if kept:
            j, a = kept[-1]
            reason = _order_reason(k, p.body, p.hand, a.body, a.hand, prev=j)
            if reason is not None:
                refusals.append(_point_refusal(k, (p.body, p.hand), reason, p, (a,), field))
                continue
        kept.append((k, p))
    return tuple(p for _, p in kept), tuple(refusals)


def _order_reason(k: int, x, y, px, py, prev: int | None = None) -> str | None:
    """Why point ``k`` at ``(x, y)`` cannot follow point ``prev`` (0-based; default
    ``k - 1``) at ``(px, py)`` (the order rules every front shares), or None."""
    j = k - 1 if prev is None else prev
    before = point_label(j)
    if x == px and y == py:
        return f"the same frames as {point_label(j, px, py)}; give each point once"
    if x == px:
        return (
            f"on the same body frame as {point_label(j, px, py)}; expected one point per "
            "body frame (a larger tolerance covers a range of hand frames)"
        )
    if x < px:
        return (
            f"body frame {x:g} is not after {before}'s body frame {px:g}; body frames must "
            "increase from one point to the next"
        )
    if y < py:
        return (
            f"hand frame {y:g} is before {before}'s hand frame {py:g}; a path cannot go back "
            "in time, so hand frames must not decrease while body frames increase"
        )
    return None


def _point_refusal(
    k: int, at: tuple, detail: str, value, others: tuple = (), field: str = "points"
) -> ConstraintError:
    """The refusal of the matching point ``k`` (0-based) placed at ``at = (body, hand)``:
    ``matching point K (body B, hand H): DETAIL``."""
    x, y = at[0], at[1]
    placed = all(math.isfinite(float(v)) and float(v) == int(v) and v >= 0 for v in (x, y))
    return ConstraintError(
        f"{field}[{k}]",
        detail,
        label=point_label(k, x, y),
        value=value,
        index=k,
        point=(int(x), int(y)) if placed else None,
        others=others if placed else (),
    )


def sort_points(points: Iterable) -> tuple[MatchPoint, ...]:
    """Points (any form :func:`parse_point` reads) in body-frame order, for a front where a
    person places them anywhere (the app's matrix); then :func:`parse_points` (a refusal
    counts the points in that order, as the app's table lists them)."""
    parsed = [parse_point(p, k) for k, p in enumerate(points)]
    parsed.sort(key=lambda p: (p.body, p.hand))
    return parse_points(parsed)


def point_triples(points) -> list[tuple[int, int, float]]:
    """``[(body, hand, tol), ...]`` (a missing tolerance is 0) from ``(x, y[, tol])`` or
    MatchPoints, for the engine's own calls; the band checks them (:func:`check_points`)."""
    xs, ys, tols = check_points(points, _FRAME_LIMIT, _FRAME_LIMIT, order=False)
    raw = [p.resolved() if isinstance(p, MatchPoint) else tuple(p) for p in points or ()]
    return [
        (int(x), int(y), float(r[2]) if len(r) == 3 else 0.0)
        for x, y, r in zip(xs.tolist(), ys.tolist(), raw)
    ]


def check_points(
    points,
    n: int,
    m: int,
    order: bool = True,
    open_ends: bool = False,
    grid_scale: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validated ``(xs, ys, tols)`` int64 arrays of matching points in an ``n x m`` matrix.

    ``points``: ``(x, y)`` or ``(x, y, tol)`` per point (a MatchPoint gives
    ``resolved()``); ``x`` is a body frame, ``y`` a hand frame. Besides
    :func:`parse_points`' order rules: every point inside the matrix, and no pair of
    points (or a point and a corner) that no path can join (``order=False`` checks single
    points only). Tolerances are whole frames (rounded down, with ``EPS`` slack). A
    refusal names the point as every front does (:func:`point_label`).

    ``grid_scale``: alignment-grid columns per hand frame (body fps / hand fps) when the
    points are in the files' own frames (the fronts; the text then speaks of the takes,
    not of the matrix). Whether two points on
    consecutive body frames can be joined is then decided where the path runs, on the
    grid (:func:`points_to_grid`'s rounding), and said in the user's frames: a 120 fps
    hand may move 4 frames per 30 fps body frame, a 30 fps hand not even one per 120 fps
    body frame.
    """
    xs, ys, tols, raw_tols = [], [], [], []
    takes = grid_scale is not None
    scale = 1.0 if grid_scale is None else float(grid_scale)
    for k, p in enumerate(points or ()):
        if isinstance(p, MatchPoint):
            p = p.resolved()
        try:
            vals = [float(v) for v in p]
        except (TypeError, ValueError):
            vals = []
        if len(vals) not in (2, 3):
            raise ConstraintError(
                f"points[{k}]",
                f"expected (body, hand) or (body, hand, tolerance), got {repr(p)[:40]}",
                label=point_label(k),
                value=p,
                expected="(body, hand) or (body, hand, tolerance)",
                index=k,
            )
        x, y = vals[0], vals[1]
        tol = vals[2] if len(vals) == 3 else 0.0
        value = (x, y, tol)
        if not all(math.isfinite(v) for v in value):
            raise _point_refusal(
                k,
                (x, y),
                f"expected finite frames and tolerance, got tolerance {tol:g}"
                if math.isfinite(x) and math.isfinite(y)
                else "expected finite frames",
                value,
            )
        if x != round(x) or y != round(y):
            raise _point_refusal(k, (x, y), "expected whole body and hand frame numbers", value)
        if tol < 0:
            raise _point_refusal(
                k, (x, y), f"expected a tolerance of at least 0 frames, got {tol:g}", value
            )
        if not (0 <= x <= n - 1 and 0 <= y <= m - 1):
            where = "the takes" if takes else f"the {n} x {m} matrix"
            raise _point_refusal(
                k,
                (x, y),
                f"outside {where}; expected body frames 0 to {n - 1} and hand frames 0 to {m - 1}",
                value,
            )
        t = math.floor(tol + EPS)
        if xs and order:
            px, py, pt = xs[-1], ys[-1], raw_tols[-1]
            before = (px, py, pt)
            other = point_label(k - 1, px, py)
            reason = _order_reason(k, x, y, px, py)
            if reason is None and x == px + 1 and _grid_gap(y, tol, py, pt, scale) > 1:
                step = "one step" if scale == 1.0 else "one body frame's worth"
                reason = (
                    f"on the body frame after {other}, but their hand frames {py:g} and "
                    f"{y:g} are more than {step} apart after tolerances ({pt:g} and "
                    f"{tol:g}); increase a tolerance or move a point"
                )
            if reason is not None:
                raise _point_refusal(k, (x, y), reason, value, others=(before,))
        if order and not open_ends and x == 0 and y - t > 0:
            raise _point_refusal(
                k,
                (x, y),
                f"with fixed ends every path starts at (0, 0), so on body frame 0 it "
                f"covers hand frame 0; expected a tolerance of at least {y:g}",
                value,
            )
        if order and not open_ends and x == n - 1 and y + t < m - 1:
            raise _point_refusal(
                k,
                (x, y),
                f"with fixed ends every path ends at ({n - 1}, {m - 1}), so on body frame "
                f"{n - 1} it covers hand frame {m - 1}; expected a tolerance of at least "
                f"{m - 1 - y:g}",
                value,
            )
        xs.append(int(x))
        ys.append(int(y))
        tols.append(int(t))
        raw_tols.append(tol)
    return (np.array(xs, np.int64), np.array(ys, np.int64), np.array(tols, np.int64))


def _grid_column(y: float, scale: float) -> int:
    """A hand frame's alignment-grid column (:func:`points_to_grid`'s rounding)."""
    return int(round(float(y) * scale))


def _grid_tolerance(tol: float, scale: float) -> int:
    """A tolerance in hand frames -> whole grid columns, rounded up as
    :func:`points_to_grid` does (then down with ``EPS`` slack, as the band does)."""
    gt = float(math.ceil(float(tol) * scale - EPS)) if tol else 0.0
    return math.floor(gt + EPS)


def _grid_gap(y: float, tol: float, py: float, ptol: float, scale: float) -> int:
    """Grid columns between a point's lowest reach and the previous point's highest
    (1 = adjacent: one diagonal step joins them)."""
    if scale == 1.0:
        return int(y - math.floor(tol + EPS) - (py + math.floor(ptol + EPS)))
    lo = _grid_column(y, scale) - _grid_tolerance(tol, scale)
    return lo - (_grid_column(py, scale) + _grid_tolerance(ptol, scale))


def points_to_grid(
    points, body_fps: float, hand_fps: float, m: int
) -> list[tuple[int, int, float]]:
    """Points in frames of the hand file -> alignment-grid columns (the hand take
    resampled to the body's rate, ``m`` columns). Hand frames round to the nearest
    column; tolerances round up so a point never gets stricter."""
    scale = float(body_fps) / float(hand_fps)
    out = []
    for x, y, t in points:
        gy = min(int(round(float(y) * scale)), m - 1)
        gt = float(math.ceil(float(t) * scale - EPS)) if t else 0.0
        out.append((int(x), gy, gt))
    return out


def points_to_hand(
    points, body_fps: float, hand_fps: float, m_hand: int
) -> list[tuple[int, int, float]]:
    """Inverse of :func:`points_to_grid`: grid columns -> frames of the hand file (rounded).

    A tolerance becomes the band's whole grid frames times the rate ratio, rounded down
    to 1/1000 frame, so :func:`points_to_grid` gives the same band back (a shared
    ``--match`` line replays the app's tolerance exactly).
    """
    scale = float(hand_fps) / float(body_fps)
    out = []
    for x, y, t in points:
        hy = min(int(round(float(y) * scale)), m_hand - 1)
        whole = math.floor(float(t) + EPS) if t else 0
        out.append((int(x), hy, math.floor(whole * scale * 1000.0) / 1000.0))
    return out


# --------------------------------------------------------------------------------------------
# multi-resolution pass 1: the coarse grid (engine.splice.coarse)
# --------------------------------------------------------------------------------------------


def pass1_decimation(fps: float, cap_hz: float | None = None) -> int:
    """Body frames per coarse pass-1 frame: the smallest whole ``k`` with ``fps / k`` at
    most ``cap_hz`` (default ``tolerances.PASS1_RATE_CAP_HZ``); 1 for takes at or below
    the cap (pass 1 then runs at full rate, as before). 120 fps -> 4, 60 -> 2, 100 -> 4.
    A rate within 1 % of a multiple of the cap counts as that multiple (a BVH's frame time
    0.0333330 s is 30.0003 fps: 30 fps)."""
    cap = float(PASS1_RATE_CAP_HZ if cap_hz is None else cap_hz)
    fps = float(fps)
    if not (math.isfinite(fps) and fps > 0):
        return 1
    return max(1, int(math.ceil(fps / cap - 0.01)))


def coarse_index(frame, k: int) -> np.ndarray:
    """Coarse frame (row or column) nearest fine frame ``frame``: coarse frame ``r`` is
    fine frame ``r * k`` (``floor(frame / k + 1/2)``)."""
    return np.floor(np.asarray(frame, np.float64) / k + 0.5).astype(np.int64)


def coarse_points(points, k: int, n_c: int, m_c: int) -> list[tuple[int, int, float]]:
    """Matching points ``(x, y, tol)`` (grid frames) on the coarse ``n_c x m_c`` grid of
    decimation ``k``, each tolerance rounded outward: the coarse point's window of
    columns holds the coarse column of every allowed crossing ``y - tol .. y + tol``
    (:func:`coarse_index`), plus one coarse column on each side for the up to ``k / 2``
    fine rows between the point's row and its coarse row; on consecutive coarse rows the
    earlier window reaches up to the later one (a path can join them), and a point rounded
    onto the first (last) coarse row reaches the first (last) column (a fixed-end path
    covers the corner's columns there). A point with ``tol = 0`` is
    therefore a tolerance-1 point on the coarse grid; the exact full-rate pass holds it
    exactly. Points that fall on one coarse row become one point whose window holds
    theirs. ``k = 1`` returns the points unchanged."""
    pts = point_triples(points)
    if k <= 1:
        return pts
    rows: list[list[int]] = []  # [x_c, lo_c, hi_c, y_c]
    for x, y, tol in pts:
        t = math.floor(float(tol) + EPS)
        xc = int(min(max(coarse_index(x, k), 0), n_c - 1))
        lo = int(coarse_index(y - t, k)) - 1
        hi = int(coarse_index(y + t, k)) + 1
        yc = int(min(max(coarse_index(y, k), 0), m_c - 1))
        if rows and rows[-1][0] == xc:
            last = rows[-1]
            last[1], last[2] = min(last[1], lo), max(last[2], hi)
            last[3] = (last[3] + yc) // 2 if last[3] != yc else yc
        else:
            rows.append([xc, lo, hi, yc])
    for prev, cur in zip(rows, rows[1:]):
        if cur[0] == prev[0] + 1 and cur[1] > prev[2] + 1:  # consecutive rows: windows join
            prev[2] = cur[1] - 1
    out = []
    for xc, lo, hi, yc in rows:
        if xc == 0:  # the first / last coarse row: a fixed-end path covers the corner there
            lo = 0
        if xc == n_c - 1:
            hi = m_c - 1
        lo, hi = max(lo, 0), min(hi, m_c - 1)
        yc = min(max(yc, lo), hi)
        out.append((xc, yc, float(max(yc - lo, hi - yc))))
    return out
