"""The user's alignment constraints, in one place: band widths, matching points,
tolerances and ends, with their defaults, ranges, parsing and error text.

Every front (``handsplice splice`` flags, the batch manifest, the session file and
the app's link, the app's ``Session`` and its backend) calls this module and shows
its message; nothing else re-validates. A refusal is a :class:`ConstraintError`
(a ``ParameterError``) whose text is ``FIELD: what was expected, got VALUE``; a
front may put its source in front (``demo.json: band: ...``, ``manifest.csv line 3:
band: ...``).

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
    nothing; ``None`` = half of the shorter take).
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np

from engine.base.errors import ParameterError
from engine.base.limits import MAX_BAND_CELLS
from engine.base.tolerances import FRAME_EPS

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
    names it (``points[2].tolerance``), ``value`` is what was given, ``expected`` what was
    expected (None where the refusal is a conflict between points rather than a range);
    ``detail`` is the sentence after the field and ``str(err)`` is ``"field: detail"`` (or
    ``text``, check_points' ``points[k] = (x=.., y=.., tol=..) ...`` form).

    A refusal of one matching point also keeps its parts apart, so that a front can write
    the points its own way (:meth:`text_with`, the page's ``(body 60, hand 10)``):
    ``point`` is the refused point ``(body, hand)``, ``reason`` what is wrong with it, with
    ``{0}``, ``{1}`` ... where the points it conflicts with (``others``) are named."""

    def __init__(
        self,
        field: str,
        detail: str,
        text: str | None = None,
        *,
        value=None,
        expected: str | None = None,
        point: tuple[int, int] | None = None,
        reason: str | None = None,
        others: tuple = (),
    ):
        self.field = field
        self.detail = detail
        self.value = value
        self.expected = expected
        self.point = point
        self.reason = reason
        self.others = tuple(others)
        self._own_text = text is not None
        super().__init__(text or (f"{field}: {detail}" if field else detail))

    def reason_with(self, show_point) -> str | None:
        """``reason`` with the conflicting points written by ``show_point(body, hand,
        tolerance)``; None when the refusal is not about one point."""
        if self.point is None or self.reason is None:
            return None
        if not self.others:
            return self.reason
        return self.reason.format(*(show_point(*_triple(p)) for p in self.others))

    def text_with(self, show_point) -> str:
        """``str(self)`` with the matching points written by ``show_point(body, hand,
        tolerance)`` (the message every front shows, in a front's own point form); a
        message given as ``text`` stays as it is."""
        reason = self.reason_with(show_point)
        if reason is None or self._own_text:
            return str(self)
        body, hand = self.point
        tol = self.value.tolerance if isinstance(self.value, MatchPoint) else None
        return f"{self.field}: {show_point(body, hand, tol)} {reason}"


def _triple(point) -> tuple[int, int, float | None]:
    if isinstance(point, MatchPoint):
        return point.body, point.hand, point.tolerance
    return tuple(point) + (None,) * (3 - len(point))


def _engine_point(body: int, hand: int, tolerance: float | None = None) -> str:
    """A point in the engine's text form, ``B:H`` or ``B:H:T`` (``MatchPoint.text``)."""
    return MatchPoint(body, hand, tolerance).text()


def _point_refusal(field: str, point: MatchPoint, reason: str, *others) -> ConstraintError:
    """``field: B:H REASON`` with the points kept apart (``reason`` names ``others`` as
    ``{0}``, ``{1}`` ...)."""
    detail = f"{point.text()} " + reason.format(*(o.text() for o in others))
    return ConstraintError(
        field,
        detail,
        value=point,
        point=(point.body, point.hand),
        reason=reason,
        others=others,
    )


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


def _number(value, field: str, expected: str) -> float:
    """A finite float from a number or numeric text; ConstraintError otherwise."""
    if isinstance(value, bool) or value is None:
        raise ConstraintError(
            field, f"expected {expected}, got {_show(value)}", value=value, expected=expected
        )
    if isinstance(value, str):
        text = value.strip()
        if not re.fullmatch(r"[+-]?(\d+(\.\d*)?|\.\d+)([eE][+-]?\d+)?", text):
            raise ConstraintError(
                field, f"expected {expected}, got {_show(value)}", value=value, expected=expected
            )
        value = text
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):
        raise ConstraintError(
            field, f"expected {expected}, got {_show(value)}", value=value, expected=expected
        ) from None
    if not math.isfinite(x):
        raise ConstraintError(
            field, f"expected {expected}, got {_show(value)}", value=value, expected=expected
        )
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

    def parse(self, value, field: str | None = None) -> float:
        field = field or self.name
        x = _number(value, field, self.expected)
        if not self.lo <= x <= self.hi:
            raise ConstraintError(
                field, f"expected {self.expected}, got {x:g}", value=x, expected=self.expected
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
#: the open-end limit, seconds (None = half of the shorter take)
MAX_UNMATCHED = Range("max_unmatched_s", 0.0, 0.0, 3600.0, "seconds")


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


def parse_max_unmatched(value) -> float | None:
    """Seconds a take may begin or end with unmatched (open ends); None = the default."""
    if value is None or (isinstance(value, str) and not value.strip()):
        return None
    if isinstance(value, str):
        value = re.sub(r"\s*s\s*$", "", value.strip())
    return MAX_UNMATCHED.parse(value)


def max_unmatched_frames(max_unmatched_s: float | None, n: int, m: int, fps: float) -> int:
    """The open-end limit in frames of the alignment grid (body rate): the given seconds,
    or half of the shorter take."""
    if max_unmatched_s is None:
        return int(min(n, m) // 2)
    return int(min(round(parse_max_unmatched(max_unmatched_s) * float(fps)), max(n, m) - 1))


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


def parse_frame(value, field: str = "frame") -> int:
    """A frame number (0-based) from a whole number or its text (``"125"``, ``125.0``);
    a fraction (``12.5``: a slip while typing 125) is refused, never truncated or rounded.
    Every front reads a matching point's frames through here (the app's table too)."""
    x = _number(value, field, "a whole frame number >= 0")
    if x != round(x) or not 0 <= x < _FRAME_LIMIT:
        raise ConstraintError(
            field,
            f"expected a whole frame number >= 0, got {x:g}",
            value=value,
            expected="a whole frame number >= 0",
        )
    return int(x)


_frame = parse_frame


def parse_point(value, field: str = "points[0]") -> MatchPoint:
    """One matching point from ``"B:H[:T]"``, ``(B, H[, T])``, ``{"body", "hand",
    "tolerance"}`` or a MatchPoint."""
    if isinstance(value, MatchPoint):
        value = (value.body, value.hand, value.tolerance)
    if isinstance(value, str):
        parts = value.strip().split(":")
        if len(parts) not in (2, 3):
            raise _bad_form(field, value)
        value = parts
    if isinstance(value, dict):
        unknown = set(value) - {"body", "hand", "tolerance"}
        if unknown:
            raise ConstraintError(
                f"{field}.{sorted(unknown)[0]}", "unknown field (known: body, hand, tolerance)"
            )
        for key in ("body", "hand"):
            if key not in value:
                raise ConstraintError(f"{field}.{key}", "missing", expected="a frame number")
        value = (value["body"], value["hand"], value.get("tolerance"))
    if not isinstance(value, list | tuple | np.ndarray) or len(value) not in (2, 3):
        raise _bad_form(field, value)
    body = _frame(value[0], f"{field}.body")
    hand = _frame(value[1], f"{field}.hand")
    tol = value[2] if len(value) == 3 else None
    tol = None if tol is None else parse_tolerance(tol, f"{field}.tolerance")
    return MatchPoint(body, hand, tol)


def _bad_form(field: str, value) -> ConstraintError:
    return ConstraintError(
        field,
        f"expected {_POINT_EXPECTED}, got {_show(value)}",
        value=value,
        expected=_POINT_EXPECTED,
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
    points = tuple(parse_point(p, f"{field}[{k}]") for k, p in enumerate(items))
    for k in range(1, len(points)):
        a, b = points[k - 1], points[k]
        if b.body <= a.body:
            raise _point_refusal(
                f"{field}[{k}]", b, "is out of order: body frames must increase (after {0})", a
            )
        if b.hand < a.hand:
            raise _point_refusal(
                f"{field}[{k}]",
                b,
                f"crosses {{0}}: the hand frame goes back from {a.hand} to {b.hand} while the "
                "body frame advances, and a path cannot go back in time",
                a,
            )
    return points


def sort_points(points: Iterable) -> tuple[MatchPoint, ...]:
    """Points (any form :func:`parse_point` reads) in body-frame order, for a front where a
    person places them anywhere (the app's matrix); then :func:`parse_points`."""
    parsed = [parse_point(p, f"points[{k}]") for k, p in enumerate(points)]
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


def _point_text(k: int, x, y, tol, takes: bool = False) -> str:
    """``points[k] = (x=.., y=.., tol=..)`` on a matrix; in the takes' own frames (the
    fronts) ``points[k] = (body frame .., hand frame .., tolerance ..)``."""
    if takes:
        return f"points[{k}] = (body frame {x:g}, hand frame {y:g}, tolerance {tol:g})"
    return f"points[{k}] = (x={x:g}, y={y:g}, tol={tol:g})"


def _bad_point(
    k: int, value: tuple, where: str, detail: str, before: tuple | None = None, takes=False
) -> ConstraintError:
    """``points[k] = (x=.., y=.., tol=..) DETAIL`` (field ``points[k]``, ``value`` the point's
    ``(x, y, tol)``). A refusal of the point as placed (``where`` without a colon: outside the
    matrix, out of order, too far from its neighbour) keeps the point and the reason apart;
    ``before`` (the previous point's ``(x, y, tol)``) is the point it conflicts with, named
    ``{0}`` in ``detail`` so that a front can write it its own way."""
    x, y, _ = value
    placed = not where.endswith(":") and x >= 0 and y >= 0 and x == int(x) and y == int(y)
    others = () if before is None else (before,)
    shown = detail.format(_point_text(k - 1, *before, takes)) if before else detail
    return ConstraintError(
        f"points[{k}]",
        f"{where[len(f'points[{k}] = ') :]} {shown}",
        text=f"{where} {shown}",
        value=value,
        point=(int(x), int(y)) if placed else None,
        reason=(detail if before else shown) if placed else None,
        others=others if placed else (),
    )


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
    ``resolved()``). Besides :func:`parse_points`' order rules: every point inside the
    matrix, and no pair of points (or a point and a corner) that no path can join
    (``order=False`` checks single points only). Tolerances are whole frames (rounded
    down, with ``EPS`` slack).

    ``grid_scale``: alignment-grid columns per hand frame (body fps / hand fps) when the
    points are in the files' own frames (the fronts; the text then names body and hand
    frames, not the matrix's ``x``/``y``). Whether two points on
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
            raise ConstraintError(
                f"points[{k}]",
                f"expected (x, y) or (x, y, tol), got {p!r}",
                text=f"points[{k}] = {p!r}: expected (x, y) or (x, y, tol)",
                value=p,
                expected="(x, y) or (x, y, tol)",
            ) from None
        if len(vals) not in (2, 3):
            raise ConstraintError(
                f"points[{k}]",
                f"expected (x, y) or (x, y, tol), got {p!r}",
                text=f"points[{k}] = {p!r}: expected (x, y) or (x, y, tol)",
                value=p,
                expected="(x, y) or (x, y, tol)",
            )
        x, y = vals[0], vals[1]
        tol = vals[2] if len(vals) == 3 else 0.0
        where = _point_text(k, x, y, tol, takes)
        if not all(math.isfinite(v) for v in (x, y, tol)):
            raise _bad_point(k, (x, y, tol), where + ":", "values must be finite")
        if x != round(x) or y != round(y):
            raise _bad_point(
                k, (x, y, tol), where + ":", "body and hand frames must be whole numbers"
            )
        if tol < 0:
            raise _bad_point(k, (x, y, tol), where + ":", "tolerance must be >= 0 frames")
        if not (0 <= x <= n - 1 and 0 <= y <= m - 1):
            raise _bad_point(
                k,
                (x, y, tol),
                where,
                (
                    f"is outside the takes (body frames 0..{n - 1}, hand frames 0..{m - 1})"
                    if takes
                    else f"is outside the {n} x {m} matrix (x in 0..{n - 1}, y in 0..{m - 1})"
                ),
            )
        t = math.floor(tol + EPS)
        if xs and order:
            px, py, pt = xs[-1], ys[-1], raw_tols[-1]
            before = (px, py, pt)
            if x == px and y == py:
                raise _bad_point(k, (x, y, tol), where, "duplicates {0}", before, takes)
            if x == px:
                raise _bad_point(
                    k,
                    (x, y, tol),
                    where,
                    "is on the same body frame as {0}; give one "
                    "point per body frame (a larger tolerance covers "
                    "a range of hand frames)",
                    before,
                    takes,
                )
            if x < px:
                raise _bad_point(
                    k,
                    (x, y, tol),
                    where,
                    "is out of order: body frames must increase (after {0})",
                    before,
                    takes,
                )
            if y < py:
                raise _bad_point(
                    k,
                    (x, y, tol),
                    where,
                    "crosses {0}: the hand frame goes back from "
                    f"{py:g} to {y:g} while the body frame advances, "
                    "and a path cannot go back in time",
                    before,
                    takes,
                )
            if x == px + 1 and _grid_gap(y, tol, py, pt, scale) > 1:
                step = "one step" if scale == 1.0 else "one body frame's worth"
                raise _bad_point(
                    k,
                    (x, y, tol),
                    where,
                    "and {0} are on consecutive body frames, but "
                    f"their hand frames {py:g} and {y:g} are more than "
                    f"{step} apart after tolerances; increase a "
                    "tolerance or move a point",
                    before,
                    takes,
                )
        if order and not open_ends and x == 0 and y - t > 0:
            raise _bad_point(
                k,
                (x, y, tol),
                where + ":",
                f"every path starts at (0, 0), so on body frame 0 "
                f"it covers hand frame 0; the tolerance must be "
                f"at least {y:g}",
            )
        if order and not open_ends and x == n - 1 and y + t < m - 1:
            raise _bad_point(
                k,
                (x, y, tol),
                where + ":",
                f"every path ends at ({n - 1}, {m - 1}), so on "
                f"body frame {n - 1} it covers hand frame "
                f"{m - 1}; the tolerance must be at least "
                f"{m - 1 - y:g}",
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
