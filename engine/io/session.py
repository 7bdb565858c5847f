"""Session files: the takes, parameters and matching points of one splice, as JSON.

The browser app saves and restores exactly this data, and the CLI reads it, so a
session tuned in the app can be replayed with ``handsplice splice``. The loader
accepts any text and either returns a valid :class:`SessionSpec` or raises
:class:`SessionError` naming the field and what was expected, e.g.::

    demo.json: matching point 3 (body 80, hand 40): expected a tolerance from 0 to 500 frames, got -1

Schema (version 2)::

    {
      "format": "handsplice-session",
      "version": 2,
      "inputs": {"sample": "NAME"}                       # a bundled sample pair, or
              | {"body": TAKE, "hand": TAKE},            # TAKE = {"path": "walk.bvh"}
                                                         #      | {"sha256": HEX64, "name": "walk.bvh"}
      "side": "right" | "left" | "both",
      "band": 0.3,            # optional: pass-1 band width W1, fraction of the body take
                              # or "10s"; absent: the automatic default for the takes
                              # (what the app saves unless the user set a width)
      "refine_band": 0.1,     # optional: pass-2 band width W2 around the pass-1 path,
                              # the same forms and default
      "tolerance": 0,         # global matching-point tolerance T, frames
      "max_unmatched": 20,    # optional: open ends, seconds each take may stay unmatched
                              # at each end (--max-unmatched); absent: the default
      "points": [{"body": 120, "hand": 98, "tolerance": null}, ...],
                              # matching points (body frame, hand frame), 0-based; body
                              # frames increase, hand frames never decrease; each in its
                              # own file's numbering (as handsplice splice --match);
                              # tolerance in hand frames, null = the global one
      "roles": {"body": {"right.wrist": "RHand"},        # optional joint-role overrides per
                "hand": {"right.index1": "rIdx1"}},      # take (as handsplice splice --roles)
      "view": {"matrix": "pass1", "frame": 0,            # optional, app display only:
               "camera": "three-quarter",               # the preview's camera (front, side)
               "trails": false, "follow": true,         # hand trails; re-render after edits
               "pick": false}                           # a click on the matrix picks a frame
    }

A missing view field takes its default (``VIEW_DEFAULTS``: files and links made before
the camera, trails, follow and pick fields open as they did). Frames are each file's own: body frames of the body take, hand frames (and
tolerances) of the hand take at its own frame rate. Version 1 files (the app before
it showed one frame numbering) hold hand frames on the alignment grid (the hand take
resampled to the body's rate); they are still read, with ``hand_frames == "grid"``
telling the reader to convert (``engine.splice.pipeline.grid_points_to_hand``).
Ranges, defaults and the error text of bands, tolerances and points are
:mod:`engine.dtw.constraints`' (the same for every front).
"""

from __future__ import annotations

import difflib
import json
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from engine.base.atomic import write_text
from engine.base.errors import ParameterError
from engine.base.json_text import JsonTextError, parse_json
from engine.base.limits import MAX_SESSION_BYTES
from engine.dtw import constraints as C
from engine.dtw.constraints import MatchPoint, Width

FORMAT = "handsplice-session"
VERSION = 2
#: what the points' hand frames count, per file version
HAND_FRAMES = {1: "grid", 2: "file"}
SIDES = ("right", "left", "both")
#: the sides the app aligns (its Side control's values), so the sides a link may name
LINK_SIDES = ("right", "left")
MATRIX_VIEWS = ("pass1", "pass2", "cumulative1", "cumulative2")
#: the preview's cameras (engine.render.scene's; ``hands``: every panel close up on the hands,
#: as ``handsplice render --camera hands``); the app's GIF/MP4 use the preview's camera
PREVIEW_CAMERAS = ("three-quarter", "front", "side", "hands")
#: the app's view state a session file or link may carry, with its defaults (a field left
#: out, as in files and links made before it existed, takes its default)
VIEW_DEFAULTS = {"camera": "three-quarter", "trails": False, "follow": True, "pick": False}
VIEW_FIELDS = ("matrix", "frame", *VIEW_DEFAULTS)
#: the file's keys of the constraints whose key is not the constraint's field name (a
#: refusal names the key the file holds)
FILE_KEYS = {"max_unmatched_s": "max_unmatched"}
MAX_POINTS = C.MAX_POINTS
MAX_TEXT = MAX_SESSION_BYTES  # a session is small; refuse anything bigger (engine.base.limits)
_HEX64 = re.compile(r"^[0-9a-f]{64}$")


class SessionError(ParameterError):
    """A session file or dict is malformed; the message names the field. ``constraint`` is
    the :class:`~engine.dtw.constraints.ConstraintError` behind it, if any (its structured
    fields: value, expected, the refused point); the message then names what it refuses in
    its words (``demo.json: matching point 2 (body 80, hand 20): ...``), ``field`` stays
    the field's name for code (``points[1]``)."""

    def __init__(
        self,
        source: str | None,
        field_name: str,
        message: str,
        constraint: C.ConstraintError | None = None,
    ):
        self.source = source
        self.field = field_name
        self.detail = message
        self.constraint = constraint
        where = f"{source}: " if source else ""
        label = field_name if constraint is None else constraint.label
        super().__init__(f"{where}{label}: {message}" if label else f"{where}{message}")


@dataclass(frozen=True)
class TakeRef:
    """One input take: a ``path`` (CLI) or an uploaded file's ``sha256`` and original ``name``."""

    path: str | None = None
    sha256: str | None = None
    name: str | None = None

    def to_dict(self) -> dict:
        if self.sha256:
            return {"sha256": self.sha256, "name": self.name}
        return {"path": self.path}


@dataclass(frozen=True)
class SessionSpec:
    """Everything needed to reproduce a splice: inputs, parameters, matching points."""

    sample: str | None = None
    body: TakeRef | None = None
    hand: TakeRef | None = None
    #: None (a link with a bad or no ``side``): the side the app chooses for the takes
    side: str | None = "right"
    band: Width | None = None
    refine_band: Width | None = None
    tolerance: float = 0.0
    points: tuple[MatchPoint, ...] = ()
    roles: dict = field(default_factory=dict)
    view: dict = field(default_factory=dict)
    #: "file": hand frames of the hand file (version 2); "grid": alignment grid (version 1)
    hand_frames: str = "file"
    #: open ends: seconds each take may stay unmatched at each end (None: the default,
    #: ``constraints.UNMATCHED_DEFAULT``); the CLI's --max-unmatched
    max_unmatched_s: float | None = None

    def __post_init__(self):
        # one normal form, checked by engine.dtw.constraints (ConstraintError names the field)
        object.__setattr__(self, "band", C.BAND.parse(self.band))
        object.__setattr__(self, "refine_band", C.REFINE_BAND.parse(self.refine_band))
        object.__setattr__(self, "tolerance", C.parse_tolerance(self.tolerance))
        object.__setattr__(self, "points", C.parse_points(tuple(self.points)))
        object.__setattr__(self, "max_unmatched_s", C.parse_max_unmatched(self.max_unmatched_s))

    def constraint_points(self) -> list[tuple[int, int, float]]:
        """Matching points as ``[(body_frame, hand_frame, tolerance), ...]`` for the DTW band."""
        return [p.resolved(self.tolerance) for p in self.points]


# ---------------------------------------------------------------- dict <-> spec


def to_dict(spec: SessionSpec) -> dict:
    """The JSON-ready dict of ``spec`` (schema above)."""
    if spec.sample is not None:
        inputs: dict[str, Any] = {"sample": spec.sample}
    else:
        inputs = {}
        if spec.body is not None:
            inputs["body"] = spec.body.to_dict()
        if spec.hand is not None:
            inputs["hand"] = spec.hand.to_dict()
    out = {
        "format": FORMAT,
        "version": 1 if spec.hand_frames == "grid" else VERSION,
        "inputs": inputs,
        **({"side": spec.side} if spec.side is not None else {}),
        "tolerance": _num_out(spec.tolerance),
        "points": [
            {
                "body": p.body,
                "hand": p.hand,
                "tolerance": None if p.tolerance is None else _num_out(p.tolerance),
            }
            for p in spec.points
        ],
    }
    for key, width in (("band", spec.band), ("refine_band", spec.refine_band)):
        if width is not None:
            out[key] = width.to_json()
    if spec.max_unmatched_s is not None:
        out["max_unmatched"] = _num_out(spec.max_unmatched_s)
    if spec.roles:
        out["roles"] = spec.roles
    if spec.view:
        out["view"] = spec.view
    return out


def _num_out(x: float) -> float | int:
    return int(x) if float(x).is_integer() else float(x)


class _Reader:
    def __init__(self, source: str | None):
        self.source = source

    def fail(self, field_name: str, message: str) -> SessionError:
        return SessionError(self.source, field_name, message)

    def unknown(self, parent: str, key, known) -> SessionError:
        """The refusal of a key the file's object ``parent`` has no field for, with the
        field it may have meant, as a link's typo is said (``tolerence: unknown field (did
        you mean 'tolerance'? known: ...)``)."""
        return self.fail(
            f"{parent}.{str(key)[:40]}" if parent else str(key)[:40],
            f"unknown field ({did_you_mean(key, known)}known: {', '.join(known)})",
        )

    def integer(self, value, field_name: str) -> int:
        if (
            isinstance(value, bool)
            or not isinstance(value, int | float)
            or (isinstance(value, float) and not value.is_integer())
        ):
            raise self.fail(field_name, f"expected a whole frame number, got {_show(value)}")
        if not 0 <= value < 2**31:
            raise self.fail(field_name, f"expected a frame number >= 0, got {_show(value)}")
        return int(value)

    def string(self, value, field_name: str, max_len: int = 1000) -> str:
        if not isinstance(value, str) or not value or len(value) > max_len or "\x00" in value:
            raise self.fail(field_name, f"expected a non-empty text, got {_show(value)}")
        return value

    def take(self, value, field_name: str) -> TakeRef:
        if not isinstance(value, dict):
            raise self.fail(
                field_name, f'expected {{"path": ...}} or {{"sha256": ...}}, got {_show(value)}'
            )
        unknown = set(value) - {"path", "sha256", "name"}
        if unknown:
            raise self.unknown(field_name, sorted(unknown)[0], ("path", "sha256", "name"))
        if "sha256" in value:
            digest = value["sha256"]
            if not isinstance(digest, str) or not _HEX64.match(digest):
                raise self.fail(
                    f"{field_name}.sha256", f"expected 64 lowercase hex digits, got {_show(digest)}"
                )
            name = value.get("name")
            if name is not None:
                name = self.string(name, f"{field_name}.name", 255)
            return TakeRef(sha256=digest, name=name)
        if "path" in value:
            return TakeRef(path=self.string(value["path"], f"{field_name}.path", 4096))
        raise self.fail(field_name, 'expected a "path" or a "sha256"')


def did_you_mean(key, known) -> str:
    """``"did you mean 'tolerance'? "`` for a key close to one of ``known`` (difflib), else
    ``""``: the one wording of a typo'd key, in a session file and a link alike."""
    near = difflib.get_close_matches(str(key), list(known), n=1)
    return f"did you mean {near[0]!r}? " if near else ""


def _show(value) -> str:
    text = (
        json.dumps(value)
        if isinstance(value, str | int | float | bool | type(None))
        else type(value).__name__
    )
    return text if len(text) <= 40 else text[:37] + "..."


_TOP_FIELDS = {
    "format",
    "version",
    "inputs",
    "side",
    "band",
    "refine_band",
    "tolerance",
    "points",
    "roles",
    "view",
    "max_unmatched",
}


def from_dict(data: Any, source: str | None = None) -> SessionSpec:
    """Validate a session dict (e.g. parsed JSON) into a :class:`SessionSpec`.

    Missing fields take their defaults; unknown fields, wrong types and values out of
    range raise :class:`SessionError` naming the field.
    """
    r = _Reader(source)
    if not isinstance(data, dict):
        raise r.fail("", f"expected a JSON object at the top level, got {_show(data)}")
    unknown = set(data) - _TOP_FIELDS
    if unknown:
        raise r.unknown("", sorted(unknown)[0], sorted(_TOP_FIELDS))
    if data.get("format", FORMAT) != FORMAT:
        raise r.fail("format", f'expected "{FORMAT}", got {_show(data.get("format"))}')
    version = data.get("version", VERSION)
    # a list or an object is no version (and cannot be looked up: unhashable)
    if isinstance(version, bool) or not isinstance(version, int) or version not in HAND_FRAMES:
        raise r.fail(
            "version", f"expected {' or '.join(map(str, HAND_FRAMES))}, got {_show(version)}"
        )

    sample = body = hand = None
    inputs = data.get("inputs", {})
    if not isinstance(inputs, dict):
        raise r.fail("inputs", f"expected an object, got {_show(inputs)}")
    unknown = set(inputs) - {"sample", "body", "hand"}
    if unknown:
        raise r.unknown("inputs", sorted(unknown)[0], ("sample", "body", "hand"))
    if "sample" in inputs:
        if "body" in inputs or "hand" in inputs:
            raise r.fail("inputs", "expected either a sample or body and hand, not both")
        sample = r.string(inputs["sample"], "inputs.sample", 200)
    else:
        if "body" in inputs:
            body = r.take(inputs["body"], "inputs.body")
        if "hand" in inputs:
            hand = r.take(inputs["hand"], "inputs.hand")

    side = data.get("side", "right")
    if side not in SIDES:
        raise r.fail("side", f"expected one of {', '.join(SIDES)}, got {_show(side)}")
    try:
        band = C.BAND.parse(_json_number_or_text(data.get("band")))
        refine = C.REFINE_BAND.parse(_json_number_or_text(data.get("refine_band")))
        tolerance = C.parse_tolerance(_json_number(data.get("tolerance", 0)))
        raw_points = data.get("points", [])
        if not isinstance(raw_points, list):
            raise C.ConstraintError("points", f"expected a list, got {_show(raw_points)}")
        points = C.parse_points([_json_point(p) for p in raw_points])
        max_unmatched = C.parse_max_unmatched(_json_number(data.get("max_unmatched")))
    except C.ConstraintError as exc:  # named by the file's key (``max_unmatched``)
        named = exc.named(FILE_KEYS.get(exc.field, exc.field))
        raise SessionError(source, exc.field, exc.detail, named) from None

    roles = data.get("roles", {})
    if not isinstance(roles, dict):
        raise r.fail("roles", f"expected an object, got {_show(roles)}")
    clean_roles = {}
    for take, mapping in roles.items():
        if take not in ("body", "hand"):
            raise r.fail(f"roles.{take}", "unknown take (known: body, hand)")
        clean_roles[take] = _role_map(r, mapping, f"roles.{take}")

    view = data.get("view", {})
    if not isinstance(view, dict):
        raise r.fail("view", f"expected an object, got {_show(view)}")
    unknown = set(view) - set(VIEW_FIELDS)
    if unknown:
        raise r.unknown("view", sorted(unknown)[0], VIEW_FIELDS)
    for key, choices in (("matrix", MATRIX_VIEWS), ("camera", PREVIEW_CAMERAS)):
        if key in view and (not isinstance(view[key], str) or view[key] not in choices):
            raise r.fail(
                f"view.{key}", f"expected one of {', '.join(choices)}, got {_show(view[key])}"
            )
    if "frame" in view:
        r.integer(view["frame"], "view.frame")
    for key in ("trails", "follow", "pick"):
        if key in view and not isinstance(view[key], bool):
            raise r.fail(f"view.{key}", f"expected true or false, got {_show(view[key])}")

    spec = SessionSpec(
        sample=sample,
        body=body,
        hand=hand,
        side=side,
        band=band,
        refine_band=refine,
        tolerance=tolerance,
        points=tuple(points),
        roles={k: v for k, v in clean_roles.items() if v},
        view=view,
        hand_frames=HAND_FRAMES[version],
        max_unmatched_s=max_unmatched,
    )
    return validate(spec, source)


def _json_number(value):
    """JSON numbers only (a JSON string "0.3" is not a number here)."""
    if isinstance(value, str):
        return object()  # refused by constraints with the field's expected text
    return value


def _json_number_or_text(value):
    """A band width: a JSON number (fraction) or a text with a unit ("10s")."""
    if isinstance(value, str) and not value.strip().lower().endswith(("s", "sec", "seconds")):
        return object()
    return value


def _json_point(raw):
    """A JSON point object or list, with numbers only (no "B:H" text in a session file)."""
    if isinstance(raw, dict):
        return {
            k: _json_number(v) if k in ("body", "hand", "tolerance") else v for k, v in raw.items()
        }
    if isinstance(raw, list):
        return [_json_number(v) for v in raw]
    return object()


def _role_map(r: _Reader, mapping, field_name: str) -> dict:
    """``{"right.wrist": "Name" or None}`` checked by ``engine.model.roles.normalize_overrides``."""
    from engine.model.roles import normalize_overrides

    if not isinstance(mapping, dict):
        raise r.fail(
            field_name, f'expected an object {{"right.wrist": "NAME"}}, got {_show(mapping)}'
        )
    if len(mapping) > 200:
        raise r.fail(field_name, f"expected at most 200 overrides, got {len(mapping)}")
    try:
        flat = normalize_overrides(mapping, field_name)
    except ParameterError as exc:
        raise r.fail("", str(exc)) from None
    for key, joint in flat.items():
        if joint is not None:
            r.string(joint, f"{field_name}.{key}", 200)
    return flat


def validate(spec: SessionSpec, source: str | None = None) -> SessionSpec:
    """``spec`` (its fields are checked when it is made, by ``engine.dtw.constraints``)."""
    return spec


# ---------------------------------------------------------------- whose takes


def foreign_takes(
    spec: SessionSpec, body: str | Path, hand: str | Path, folder: str | Path = "."
) -> tuple[tuple[str, str, str], ...]:
    """The takes ``spec`` names that ``body`` and ``hand`` (files) are not: ``(role, the
    session's name for its take, the file's name)`` for each, body first; ``()`` when the session belongs
    to these takes. The one rule of "does this session belong to these takes":

    * a take stored by ``sha256`` (the app's files) is these bytes or not;
    * a take stored by ``path`` (relative to ``folder``, the session file's) is the same
      file, or one with the same bytes; a path that names no file is compared by file name;
    * a sample pair (``inputs.sample``) or a take the session does not name: nothing to
      compare, never said.
    """
    from engine.base.digest import file_sha256

    out = []
    for role, ref, path in (("body", spec.body, Path(body)), ("hand", spec.hand, Path(hand))):
        if ref is None or spec.sample is not None:
            continue
        if ref.sha256:
            if file_sha256(path) != ref.sha256:
                out.append((role, ref.name or ref.sha256[:12], path.name))
            continue
        named = Path(folder) / Path(ref.path).expanduser()
        if named.is_file():
            same = named.resolve() == path.resolve() or file_sha256(named) == file_sha256(path)
        else:
            same = named.name == path.name
        if not same:
            out.append((role, ref.path, path.name))
    return tuple(out)


def foreign_takes_warning(
    source: str, foreign: tuple[tuple[str, str, str], ...], points_used: bool
) -> str | None:
    """One line saying that the session file ``source`` was made on other takes (the
    :func:`foreign_takes` of its spec), None when it was not: ``s.json was made on body
    take wave.bvh, not call.bvh: its matching points were placed on that take``."""
    if not foreign:
        return None
    takes = " and ".join(f"{role} take {_one_line(name)}" for role, name, _ in foreign)
    given = " and ".join(_one_line(given) for _, _, given in foreign)
    which = "those takes" if len(foreign) > 1 else "that take"
    what = (
        f"its matching points were placed on {which}"
        if points_used
        else f"its settings were tuned on {which}"
    )
    return f"{source} was made on {takes}, not {given}: {what}"


def _one_line(name: str) -> str:
    """A file name from a file, on one line of at most 80 characters."""
    text = " ".join(str(name).split())
    return text if len(text) <= 80 else text[:77] + "..."


# ---------------------------------------------------------------- text and files


def parse_session(text: str | bytes, source: str | None = None) -> SessionSpec:
    """Parse session JSON text; ``source`` names it in error messages."""
    if isinstance(text, bytes):
        if len(text) > MAX_TEXT:
            raise SessionError(source, "", f"expected at most {MAX_TEXT} bytes, got {len(text)}")
        try:
            text = text.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise SessionError(source, "", f"not UTF-8 text (byte {exc.start})") from None
    if len(text) > MAX_TEXT:
        raise SessionError(source, "", f"expected at most {MAX_TEXT} characters, got {len(text)}")
    try:
        data = parse_json(text)
    except JsonTextError as exc:
        raise SessionError(source, "", exc.detail) from None
    return from_dict(data, source)


def format_session(spec: SessionSpec) -> str:
    """Session JSON text (indented, newline-terminated)."""
    return json.dumps(to_dict(spec), indent=2) + "\n"


def read_session(path: str | Path) -> SessionSpec:
    """Read and validate a session file. Relative take paths stay as written."""
    path = Path(path)
    return parse_session(path.read_bytes(), source=path.name)


def write_session(spec: SessionSpec, path: str | Path) -> None:
    """Write ``spec`` as JSON, atomically."""
    write_text(Path(path), format_session(validate(spec)))


# ---------------------------------------------------------------- URL query


def to_query(spec: SessionSpec) -> dict[str, str]:
    """Short URL query parameters restoring ``spec`` (for sharing a link to the app).

    ``sample=NAME`` or ``body=SHA256&hand=SHA256`` (with ``bname`` and ``hname``, the
    uploaded files' original names, where known), ``side``, ``band`` and ``refine`` (where
    set: absent, the automatic default), ``tol``,
    ``unmatched`` (the open-end limit, seconds, where set), ``pts=B:H[:T],...``, ``roles`` (JSON), ``view``, ``frame``, and ``frames=hand`` when the
    hand frames are the hand file's own (links made before have grid frames); the view
    state ``camera``, ``trails``, ``follow`` and ``pick`` (``1`` or ``0``) only where it is
    not the default (``VIEW_DEFAULTS``). Take paths (CLI sessions) are not put in URLs.
    """
    q: dict[str, str] = {}
    if spec.sample is not None:
        q["sample"] = spec.sample
    else:
        for key, take in (("body", spec.body), ("hand", spec.hand)):
            if take is not None and take.sha256:
                q[key] = take.sha256
                if take.name:
                    q[QUERY_NAMES[key]] = take.name
    if spec.side is not None:
        q["side"] = spec.side
    if spec.band is not None:
        q["band"] = spec.band.text()
    if spec.refine_band is not None:
        q["refine"] = spec.refine_band.text()
    q["tol"] = f"{spec.tolerance:g}"
    if spec.max_unmatched_s is not None:
        q["unmatched"] = f"{spec.max_unmatched_s:g}"
    if spec.points:
        q["pts"] = ",".join(p.text() for p in spec.points)
        if spec.hand_frames == "file":
            q["frames"] = "hand"
    if spec.roles:
        q["roles"] = json.dumps(spec.roles, separators=(",", ":"), sort_keys=True)
    if "matrix" in spec.view:
        q["view"] = spec.view["matrix"]
    if "frame" in spec.view:
        q["frame"] = str(spec.view["frame"])
    for key, default in VIEW_DEFAULTS.items():
        value = spec.view.get(key, default)
        if value != default:
            q[key] = str(int(value)) if isinstance(value, bool) else str(value)
    return q


#: the link keys of the uploaded takes' original names
QUERY_NAMES = {"body": "bname", "hand": "hname"}
#: every key a link may hold (:func:`to_query`); any other is said as a typo
QUERY_KEYS = (
    "sample",
    "body",
    "hand",
    *QUERY_NAMES.values(),
    "side",
    "band",
    "refine",
    "tol",
    "unmatched",
    "pts",
    "frames",
    "roles",
    "view",
    "frame",
    *VIEW_DEFAULTS,
)


def from_query(query: dict[str, str]) -> SessionSpec:
    """Inverse of :func:`to_query`; an unknown key or a bad value raises SessionError (the
    first one; :func:`read_query` keeps the good values of a link with bad ones)."""
    spec, problems = read_query(query)
    if problems:
        raise problems[0]
    return spec


def read_query(query: dict[str, str]) -> tuple[SessionSpec, tuple[SessionError, ...]]:
    """A link's good values and a refusal for each bad one.

    Each parameter is read alone with the session file's rules (:func:`from_dict`, the
    widths, tolerances and points of :mod:`engine.dtw.constraints`): a bad one (``band=99``,
    ``pts=abc:1``, an unknown ``view``) is left out, with its one-line :class:`SessionError`,
    and the rest (the takes above all) is kept. A bad file name (``bname``, ``hname``)
    loses only the name, not its take; a bad matching point only itself (the others are
    kept when their order holds); a key that is not a link's (``camra=hands``) is said,
    with the key it may have meant (stranger 11: a typo was dropped in silence).
    """
    source = "URL"
    q = {k: (v[0] if isinstance(v, list | tuple) and v else v) for k, v in query.items()}
    version = 2 if q.get("frames") == "hand" else 1
    problems: list[SessionError] = []

    def checked(part: dict, key: str | None = None) -> bool:
        """Whether ``part`` (a few top-level fields) passes the session rules alone; a
        refusal is named by the link's ``key`` where given (``body``, not the file's
        ``inputs.body.sha256``)."""
        try:
            from_dict({"version": version, **part}, source)
        except SessionError as exc:
            named = key is not None and exc.constraint is None
            problems.append(SessionError(source, key, exc.detail) if named else exc)
            return False
        return True

    def constraint(key: str, read):
        """``read()`` with engine.dtw.constraints' refusal kept as a problem (None then)."""
        try:
            return read()
        except C.ConstraintError as exc:  # named by the link's key (``refine``, ``unmatched``)
            problems.append(SessionError(source, exc.field, exc.detail, exc.named(key)))
        except SessionError as exc:
            problems.append(exc)
        return None

    data: dict[str, Any] = {"version": version}
    if q.get("sample"):
        if checked({"inputs": {"sample": q["sample"]}}):
            data["inputs"] = {"sample": q["sample"]}
    elif q.get("body") or q.get("hand"):
        inputs = {}
        for key in ("body", "hand"):
            if not q.get(key):
                continue
            take = {"sha256": str(q[key]).lower()}
            if not checked({"inputs": {key: take}}, key):  # said once (stranger 8: twice)
                continue
            name = q.get(QUERY_NAMES[key])
            if name and checked({"inputs": {key: {**take, "name": name}}}, QUERY_NAMES[key]):
                take["name"] = name
            inputs[key] = take
        if inputs:
            data["inputs"] = inputs
    if "side" in q:  # a side the app cannot align is left out: the app then chooses
        if q["side"] in LINK_SIDES:
            data["side"] = q["side"]
        else:
            problems.append(
                SessionError(
                    source,
                    "side",
                    f"expected {' or '.join(LINK_SIDES)}, got {_show(q['side'])}",
                )
            )
    for key, rule in (("band", C.BAND), ("refine", C.REFINE_BAND)):  # every front's parsers
        if key in q:
            width = constraint(key, lambda rule=rule, key=key: rule.parse(str(q[key])))
            if width is not None:
                data[rule.name] = width.to_json()
    if "tol" in q:
        tolerance = constraint("tol", lambda: C.parse_tolerance(str(q["tol"])))
        if tolerance is not None:
            data["tolerance"] = tolerance
    if q.get("unmatched"):
        limit = constraint("unmatched", lambda: C.parse_max_unmatched(str(q["unmatched"])))
        if limit is not None:
            data["max_unmatched"] = limit
    if q.get("pts"):
        items = C.split_points_text(str(q["pts"]))
        if len(items) > C.MAX_POINTS:  # refused whole, as every front does
            points = constraint("pts", lambda: C.parse_points(items))
        else:  # each point alone: a bad one is left out by itself, then one out of order
            read = (
                (k, constraint("pts", lambda k=k, p=p: C.parse_point(p, k)))
                for k, p in enumerate(items)
            )
            points, disorder = C.ordered_points((k, p) for k, p in read if p is not None)
            for exc in disorder:  # each refused alone, in the user's numbering
                problems.append(SessionError(source, exc.field, exc.detail, exc.named("pts")))
        if points:
            data["points"] = [[p.body, p.hand, p.tolerance] for p in points]
    if q.get("roles"):
        try:
            roles = parse_json(str(q["roles"]))
        except JsonTextError:
            problems.append(SessionError(source, "roles", "expected a JSON object"))
        else:
            if checked({"roles": roles}):
                data["roles"] = roles
    view: dict[str, Any] = {}
    if q.get("view"):
        view["matrix"] = q["view"]
    if q.get("frame"):
        frame = constraint("frame", lambda: _query_number(q["frame"], "frame", source))
        if frame is not None:
            view["frame"] = frame
    for key, default in VIEW_DEFAULTS.items():  # checked with the file's rules (from_dict)
        if key in q:
            flag = isinstance(default, bool)
            view[key] = _QUERY_FLAGS.get(str(q[key]).strip().lower(), q[key]) if flag else q[key]
    view = {k: v for k, v in view.items() if checked({"view": {k: v}})}
    if view:
        data["view"] = view
    for key in q:
        if key not in QUERY_KEYS:
            problems.append(
                SessionError(
                    source,
                    str(key)[:40],
                    f"not a link parameter ({did_you_mean(key, QUERY_KEYS)}known: "
                    f"{', '.join(QUERY_KEYS)})",
                )
            )
    spec = from_dict(data, source)
    if "side" not in data:  # none given, or a bad one: the app's choice (Session._side_for)
        spec = replace(spec, side=None)
    return spec, tuple(problems)


#: a link's on/off values (anything else reaches from_dict as text, which refuses it)
_QUERY_FLAGS = {"1": True, "0": False, "true": True, "false": False}


def _query_number(text, field_name: str, source: str) -> float | int:
    try:
        x = float(text)
    except (TypeError, ValueError):
        raise SessionError(
            source, field_name, f"expected a number, got {str(text)[:40]!r}"
        ) from None
    return int(x) if x.is_integer() and abs(x) < 2**53 else x
