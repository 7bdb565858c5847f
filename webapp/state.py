"""One browser session's state: inputs, parameters, matching points, results.

:class:`Session` is a ``param.Parameterized`` object with no widgets: views read
it and write its parameters, tests drive it directly. Every computation is an
engine call made through :mod:`webapp.backend`; nothing here aligns or splices.

Edits of ``band``, ``refine_band``, ``tolerance`` and ``points`` recompute band and
path at once (the matrix is small enough, and the engine re-solves incrementally);
an edit the engine rejects (points that leave no feasible path, say) is undone on
the spot and ``error`` says why. Every accepted edit can be undone and redone.

In a server session (:meth:`Session.compute_off_loop`) opening takes and solving run on
a worker thread (:mod:`webapp.solves`): the edit's values are set at once, band and
path follow when solved (``busy`` says what is running), a newer edit supersedes an
older one, and a refused solve puts back the values of the path on screen.

The same data is the CLI's session JSON (:mod:`engine.io.session`) and a shareable
URL query (``?sample=demo&band=0.3&pts=120:98:2,...``).
"""

from __future__ import annotations

import re
import time
from contextlib import contextmanager
from dataclasses import dataclass, replace
from urllib.parse import urlencode

import numpy as np
import param

from engine.base.errors import HandSpliceError, SideError
from engine.dtw import constraints as C
from engine.io import session as session_io
from engine.io.session import MatchPoint, SessionSpec, TakeRef
from engine.model.roles import side_from_name
from webapp import backend, config, edit_words
from webapp.matrix_frames import view_frame
from webapp.solves import Job, SolveRunner

EDIT_PARAMS = (
    "band",
    "band_s",
    "refine_band",
    "refine_band_s",
    "tolerance",
    "points",
    "max_unmatched_s",
)
INPUT_PARAMS = ("sample", "body_sha256", "hand_sha256", "side", "roles")
#: the inputs of the pair shown (its takes as named, side, roles): what a link and a session
#: file name, also while other takes are being opened
SHOWN_INPUTS = ("sample", "body_sha256", "hand_sha256", "body_name", "hand_name", "side", "roles")
#: the page's view state kept in the session (file and link): preview camera, hand trails,
#: follow edits, pick mode
VIEW_STATE = tuple(session_io.VIEW_DEFAULTS)
MATRIX_LABELS = {
    "pass1": "Pass 1 local cost D1 (signs of velocity, acceleration)",
    "pass2": "Pass 2 local cost D2 (forearm/hand angle)",
    "cumulative1": "Pass 1 cumulative cost γ in the band",
    "cumulative2": "Pass 2 cumulative cost γ in the band",
}
#: the pass-2 view's title when the hand take has no forearm (engine.splice.spin)
PASS2_SPIN_LABEL = "Pass 2 local cost (how the hand turns: the hand take has no forearm)"
#: said under the W2 controls when pass 2 does not use them
PASS2_SPIN_NOTE = (
    "W2 is not used for this pair: the hand take has no forearm, so pass 2 compares how "
    "the hand turns, inside the whole pass-1 band."
)
UNDO_LIMIT = 200
#: changes of one slider that follow each other with less than this many idle seconds
#: between them (a drag, a run of arrow-key steps) are one undo step
#: a link's points without ``frames=hand``: read as links made before hand frames were the
#: hand file's own held them (the alignment grid's columns), which moves them on a hand
#: take at another rate; said at the page's top
GRID_FRAMES_NOTE = (
    "pts: this link has no frames=hand, so its hand frames are read as the alignment grid's "
    "(as links made before 2026-12 held them); add &frames=hand to a link whose hand frames "
    "are the hand file's own"
)
SLIDER_PARAMS = ("band", "refine_band", "tolerance")
SLIDER_RUN_S = 5.0


#: the band widths: (parameter of the fraction, its rule); ``NAME_s`` holds seconds
WIDTHS = (("band", C.BAND), ("refine_band", C.REFINE_BAND))


def _width_of(name: str) -> str | None:
    """The band width an edit parameter sets (``band_s`` -> ``band``), or None."""
    base = name.removesuffix("_s")
    return base if any(base == w for w, _ in WIDTHS) else None


@dataclass(frozen=True)
class Snapshot:
    """Values of the edit parameters before an edit (an undo step), and which band widths
    were then the automatic default (``Session.automatic``)."""

    values: dict
    automatic: frozenset = frozenset()


@dataclass(frozen=True)
class _Change:
    """A param-like event (name, old) for input changes made by the session itself."""

    name: str
    old: object


def _width_values(widths: dict, names) -> dict:
    """The parameter values that put ``widths[name]`` (a ``Width``) in force, for each of
    ``names``: ``NAME_s`` for seconds, else the fraction ``NAME`` (and ``NAME_s`` None)."""
    out: dict = {}
    for name in names:
        width = widths[name]
        if width.unit == C.SECONDS:
            out[f"{name}_s"] = width.value
        else:
            out.update({name: width.value, f"{name}_s": None})
    return out


def _same(a, b) -> bool:
    try:
        return bool(a == b)
    except (TypeError, ValueError):
        return False


class Session(param.Parameterized):
    """State of one browser session (or one test)."""

    # inputs
    sample = param.String(default=None, allow_None=True, doc="bundled sample pair name")
    body_sha256 = param.String(default=None, allow_None=True, doc="uploaded body take (hash)")
    hand_sha256 = param.String(default=None, allow_None=True, doc="uploaded hand take (hash)")
    body_name = param.String(default="", doc="uploaded body file's original name")
    hand_name = param.String(default="", doc="uploaded hand file's original name")
    side = param.Selector(default="right", objects=["right", "left"], doc="which arm to align")
    roles = param.Dict(
        default={},
        doc='joint-role overrides {"body": {"right.wrist": NAME}, '
        '"hand": {...}} for unusual joint names',
    )

    # parameters and constraints (undoable edits)
    # defaults and ranges: engine.dtw.constraints (the same for links, files and widgets)
    band = param.Number(
        default=C.BAND.default,
        bounds=(C.BAND.lo, C.BAND.hi),
        step=0.01,
        doc="pass-1 band width W1, fraction of the body take's length",
    )
    band_s = param.Number(
        default=None,
        allow_None=True,
        bounds=(C.BAND.lo_s, C.BAND.hi_s),
        step=0.5,
        doc="pass-1 band width W1 in seconds; wins over the "
        "fraction when set (long takes get one by default)",
    )
    refine_band = param.Number(
        default=C.REFINE_BAND.default,
        bounds=(C.REFINE_BAND.lo, C.REFINE_BAND.hi),
        step=0.01,
        doc="pass-2 band width W2 around the pass-1 path, fraction",
    )
    refine_band_s = param.Number(
        default=None,
        allow_None=True,
        bounds=(C.REFINE_BAND.lo_s, C.REFINE_BAND.hi_s),
        step=0.1,
        doc="pass-2 band width W2 in seconds; wins when set",
    )
    tolerance = param.Number(
        default=C.TOLERANCE.default,
        bounds=(C.TOLERANCE.lo, C.TOLERANCE.hi),
        step=1.0,
        doc="global matching-point tolerance T in hand frames",
    )
    max_unmatched_s = param.Number(
        default=None,
        allow_None=True,
        bounds=(C.MAX_UNMATCHED.lo, C.MAX_UNMATCHED.hi),
        doc="open ends: seconds each take may stay unmatched at each end (the CLI's "
        "--max-unmatched); None: the default, " + C.UNMATCHED_DEFAULT,
    )
    points = param.Parameter(
        default=(),
        doc="matching points: tuple of MatchPoint, body and "
        "hand frames each in its own file's numbering",
    )

    # display
    matrix = param.Selector(
        default="pass1", objects=list(MATRIX_LABELS), doc="which cost matrix the figure shows"
    )
    frame = param.Integer(default=0, bounds=(0, None), doc="body frame shown in the preview")
    # view state (saved in the session file and link; defaults: engine.io.session.VIEW_DEFAULTS)
    camera = param.Selector(
        default=session_io.VIEW_DEFAULTS["camera"],
        objects=list(session_io.PREVIEW_CAMERAS),
        doc="the preview's camera",
    )
    trails = param.Boolean(
        default=session_io.VIEW_DEFAULTS["trails"], doc="hand trails in the preview"
    )
    follow = param.Boolean(
        default=session_io.VIEW_DEFAULTS["follow"],
        doc="after every edit the preview renders again, at the body frame of the matching "
        "point the edit placed (else only when its frame changes)",
    )
    pick = param.Boolean(
        default=session_io.VIEW_DEFAULTS["pick"],
        doc="a click on the matrix picks the previewed frame (True) or adds a matching point",
    )

    # results (written by the session only)
    n = param.Integer(default=0, constant=True, doc="body frames (rows)")
    m = param.Integer(
        default=0,
        constant=True,
        doc="alignment-grid columns: the hand take "
        "at the body's rate (internal; people see hand-file frames)",
    )
    m_hand = param.Integer(default=0, constant=True, doc="frames of the hand file")
    fps = param.Number(default=30.0, constant=True, doc="body frame rate")
    hand_fps = param.Number(default=30.0, constant=True, doc="hand file's frame rate")
    solution = param.Parameter(default=None, doc="backend.Solution of the current state")
    trust = param.Parameter(
        default=None,
        doc="engine.splice.uncertainty.Assessment of "
        "``solution`` (None until computed: see ``update_trust``)",
    )
    compute_ms = param.Number(default=0.0, doc="wall time of the last recompute, ms")
    error = param.String(default="", doc="why the last edit or input was rejected")
    link_notice = param.String(
        default="",
        doc="what of the page's shared link could not be opened, and what is shown instead "
        "(the page's top says it until closed: :meth:`link_not_opened`)",
    )
    revision = param.Integer(default=0, doc="bumped after every recompute")
    busy = param.String(
        default="", doc="what runs off the event loop now (opening takes, aligning), or empty"
    )
    dragging = param.Boolean(
        default=False,
        doc="the page says a matching point is being dragged (its edit comes on release): "
        "the previous edit's preview and trust work give way (``edit_coming``)",
    )
    inputs_revision = param.Integer(default=0, doc="bumped after the takes change")
    opening = param.String(
        default="",
        doc="names of a new pair being opened (off the loop), or empty; meanwhile the "
        "page's views show the previous pair, greyed, and edits are not taken",
    )
    waiting = param.String(
        default="",
        doc="an uploaded take that waits for its partner ('body walk.bvh checked: waiting "
        "for a hand take') or a new pair that waits for the side its hand has, or empty; "
        "meanwhile the views show the pair open before",
    )
    can_undo = param.Boolean(default=False)
    can_redo = param.Boolean(default=False)
    history_note = param.String(
        default="",
        doc="what the last Undo or Redo did ('Undid: matching point 2 moved (body 471 → "
        "402)'), or empty once another edit or pair came",
    )

    def __init__(self, cfg: config.AppConfig | None = None, **params):
        self._cfg = cfg or config.get()
        self._undo: list[Snapshot] = []
        self._redo: list[Snapshot] = []
        self._applying = False
        self._slider_run: tuple[str, float] | None = None
        self._refused: tuple[str, C.ConstraintError | None, str] = ("", None, "")
        #: the front whose edit is being made (:meth:`edit_from`); its refusal is said there
        self._front = ""
        #: the inputs (``side``, ``roles``, ...) whose change ``error`` refuses, if any
        self.refused_inputs: tuple[str, ...] = ()
        self.prepared: backend.Prepared | None = None
        #: off-loop computing (None: at once, as in tests); see compute_off_loop
        self.runner: SolveRunner | None = None
        self._chain = None  # the last solution computed (its solvers serve the next edit)
        self._accepted: dict | None = None  # edit values of the solution shown
        self._accepted_undo = 0  # undo steps then
        self._carry_error = ""  # shown on after the next solve (a link that failed)
        self.opening_since = 0.0  # monotonic s when ``opening`` was set
        #: a new pair refused for its side while another pair is open: (its input values,
        #: the ``waiting`` text); the next side chosen opens it (:meth:`_side_chosen`)
        self._side_wait: tuple[dict, str] | None = None
        #: a new pair is being opened again on the side in force (:meth:`_open_failed`)
        self._side_reopened = False
        self._shown: dict | None = None  # SHOWN_INPUTS of the pair shown, once one is
        #: a shared link that could not open because its uploaded takes are not on this
        #: server (its spec): the page's upload of those files opens it (:meth:`load_uploads`)
        #: ``(spec, the refusals of its values left out)``
        self._link_waits: tuple[SessionSpec, str] | None = None
        #: the link that waited opened on the uploads last opened (the page says so)
        self.link_applied = False
        super().__init__(**params)
        #: the band widths ("band", "refine_band") whose width in force is the automatic
        #: default (``rule.default_for`` the open takes: 17.2 s on a long take), not one the
        #: user set: the next pair gets its own default, and the session file and link say
        #: "automatic" (they leave the width out) instead of a width (:meth:`chosen_widths`)
        self.automatic: frozenset[str] = frozenset(
            name
            for name, rule in WIDTHS
            if getattr(self, f"{name}_s") is None and getattr(self, name) == rule.default
        )
        self._accepted_automatic = self.automatic  # that of the solution shown

        # the alignment shown: a shared one no page shows lets go of its preview (backend)
        self._page_closed = False
        self.param.watch(self._tell_showing, "solution")
        self.param.watch(self._on_edit, list(EDIT_PARAMS))
        self.param.watch(self._on_inputs, list(INPUT_PARAMS))

    # ------------------------------------------------------------ refusals

    def refuse(
        self, exc: BaseException, text: str | None = None, inputs=(), front: str | None = None
    ) -> None:
        """Say why an edit or input was refused: ``error`` is ``text`` (default: the
        exception's one line) and :meth:`refusal` the constraint behind it, if any;
        ``front``: the front whose edit it was (default: the one making an edit now,
        :meth:`edit_from`), :attr:`refused_from`."""
        text = self._named_uploads(backend.one_line(exc)) if text is None else text
        cause = exc if isinstance(exc, C.ConstraintError) else getattr(exc, "constraint", None)
        self._refused = (text, cause, self._front if front is None else front)
        self.refused_inputs = tuple(inputs)
        self.error = text

    def refusal(self) -> C.ConstraintError | None:
        """The structured constraint refusal (field, value, expected, the refused point)
        behind the current ``error``; None when ``error`` is not a constraint's."""
        text, cause, _ = self._refused
        return cause if self.error and text == self.error else None

    @contextmanager
    def edit_from(self, front: str):
        """Edits made inside this block come from ``front`` (``"table"``: the points
        table): their refusal, at once or from their solve off the loop, has
        :attr:`refused_from` ``front``, so that one box says it, where it was typed."""
        outer, self._front = self._front, front
        try:
            yield
        finally:
            self._front = outer

    @property
    def refused_from(self) -> str:
        """The front (:meth:`edit_from`) whose edit the current ``error`` refuses; '' for
        any other (a click on the matrix, a slider, a link: the page's error line)."""
        text, _, front = self._refused
        return front if self.error and text == self.error else ""

    def begin_opening(self, name: str) -> None:
        """A new pair named ``name`` is being opened off the loop: the views of the open
        pair go inactive and edits are refused until :meth:`end_opening`."""
        if not self.opening:
            self.opening_since = time.monotonic()
        self.opening = name or "the new takes"

    def end_opening(self) -> None:
        self.opening = ""

    def _tell_showing(self, *_) -> None:
        """Tell the backend which alignment this page shows (:func:`backend.showing`): its
        solution, or none once the page closed. The one place the page's part of that rule
        lives: every new solution and the page's close come here."""
        backend.showing(self, None if self._page_closed else self.solution)

    @property
    def page_is_closed(self) -> bool:
        """True once the session's page (its tab) has closed: work for it is wasted."""
        return self._page_closed

    def page_closed(self) -> None:
        """The page closed (its tab is gone): it shows no alignment from now on, even when
        a solve started before lands later."""
        self._page_closed = True
        self._tell_showing()

    def compute_off_loop(self, doc) -> None:
        """Open takes and solve on a worker thread from now on, applying results in
        ``doc``'s next-tick callbacks (a Bokeh server session's document)."""
        self.runner = SolveRunner(doc, on_busy=lambda label: setattr(self, "busy", label))

    # ------------------------------------------------------------ inputs

    @property
    def config(self) -> config.AppConfig:
        return self._cfg

    @property
    def takes_key(self) -> tuple:
        """Which takes the inputs name: ``(sample, body sha256, hand sha256)`` (a view
        compares it to tell a new pair from a side or role change of the same one)."""
        return (self.sample, self.body_sha256, self.hand_sha256)

    def take_paths(self):
        """(body path, hand path) of the current inputs, or None when incomplete.

        Paths are only ever inside the sample folder or the upload folder.
        """
        if self.sample:
            pair = self._cfg.sample(self.sample)
            return pair.body, pair.hand
        if self.body_sha256 and self.hand_sha256:
            from webapp import uploads

            return uploads.files_for(
                self._cfg,
                ((self.body_sha256, self.body_name), (self.hand_sha256, self.hand_name)),
            )
        return None

    def load_sample(self, name: str, then=None) -> None:
        """Open a bundled pair (KeyError naming the known pairs when unknown).

        ``then(opened: bool)``: called once the takes are open (or refused); off the
        event loop that is later, before the alignment is solved."""
        pair = self._cfg.sample(name)
        self._set_inputs(
            then=then,
            new_pair=True,
            sample=name,
            body_sha256=None,
            hand_sha256=None,
            body_name="",
            hand_name="",
            side=pair.side,
        )

    def load_uploads(
        self,
        body_sha256: str,
        hand_sha256: str,
        body_name: str = "",
        hand_name: str = "",
        then=None,
        side: str | None = None,
        takes: tuple | None = None,
    ) -> None:
        """Open two uploaded takes by content hash (``then``: as for :meth:`load_sample`);
        ``side``: the side to align (the one in force when None); ``takes``: ``(body,
        hand)`` as the upload check read them (not read again).

        When the hand (or body) has no arm on that side while another pair is open, the
        new pair waits for the side: ``error`` says which side it has (naming the files as
        uploaded), ``waiting`` says that it waits, the open pair stays, and the next side
        chosen opens the new pair (any other takes chosen drop it).

        The takes of a shared link that could not open for want of them (:meth:`open_link`)
        open that link instead, its points, bands, side, roles and view with them
        (:meth:`apply_spec`; ``link_applied`` says so): :meth:`_open_waiting_link`."""
        self.link_applied = False
        if self.link_waits_for(body_sha256, hand_sha256):
            self._open_waiting_link(body_name, hand_name, then, side, takes)
            return
        self._set_inputs(
            then=then,
            new_pair=True,
            takes=takes,
            sample=None,
            body_sha256=body_sha256,
            hand_sha256=hand_sha256,
            body_name=body_name,
            hand_name=hand_name,
            **({"side": side} if side else {}),
        )

    @property
    def link_waiting(self) -> bool:
        """Whether a shared link waits for its takes (:meth:`_keep_waiting_link`); the
        page's address bar then keeps that link, so a reload does not lose it."""
        return self._link_waits is not None

    def link_waits_for(self, body_sha256: str | None, hand_sha256: str | None) -> bool:
        """Whether uploading these takes opens the shared link that waits for them."""
        if self._link_waits is None:
            return False
        link = self._link_waits[0]
        return (link.body.sha256, link.hand.sha256) == (body_sha256, hand_sha256)

    def _keep_waiting_link(self, spec: SessionSpec, left_out: str = "") -> None:
        """A shared link did not open: keep ``spec`` for an upload of its takes when it
        names uploaded takes of which this server lacks one or both (only then can an
        upload open it). It waits until those takes are uploaded (then it opens, or is
        dropped when it cannot open on them), or the page closes: an upload of other files
        first (a wrong file picked) does not lose it, and the notice at the page's top keeps
        saying that uploading the named files applies the link.
        ``left_out``: the link's bad values' refusals (said again once it opens)."""
        if spec.body is None or spec.hand is None:
            return
        from webapp import uploads

        try:
            uploads.files_for(self._cfg, ((t.sha256, t.name) for t in (spec.body, spec.hand)))
        except uploads.UploadError:
            self._link_waits = (spec, left_out)

    def _open_waiting_link(self, body_name, hand_name, then, side, takes) -> None:
        """The takes a waiting link names were uploaded: open the link on them, as a link
        opens (:meth:`apply_spec`; a point outside the takes is left out and said, the
        undo history starts anew), under the names they were uploaded with. The link's
        notice goes (a value or point left out says so there again); a link that still
        cannot open (its side or roles do not fit the takes) opens the uploads plainly, as
        :meth:`load_uploads` (``side``), and the notice says why."""
        link, left_out = self._link_waits
        spec = replace(
            link,
            body=replace(link.body, name=body_name or link.body.name),
            hand=replace(link.hand, name=hand_name or link.hand.name),
        )
        then = then or (lambda opened: None)
        self.link_notice = ""
        if left_out:
            self.link_not_opened(f"{left_out} (left out; the rest of the link opened)")

        def applied(opened: bool) -> None:
            if opened:
                self._link_waits, self.link_applied = None, True
            then(opened)

        def plainly(exc: BaseException) -> None:
            self._link_waits = None  # tried on its own takes: uploading them again is plain
            named = ((link.body.sha256, body_name), (link.hand.sha256, hand_name))
            self.link_not_opened(
                f"{self._named_uploads(backend.one_line(exc), named)} (your uploads opened "
                "without the link's values)"
            )
            self._set_inputs(
                then=then,
                new_pair=True,
                takes=takes,
                sample=None,
                body_sha256=link.body.sha256,
                hand_sha256=link.hand.sha256,
                body_name=body_name,
                hand_name=hand_name,
                **({"side": side} if side else {}),
            )

        try:
            self.apply_spec(spec, plainly, keep_takes=True, then=applied, takes=takes)
        except (HandSpliceError, ValueError, KeyError, OSError) as exc:  # without a runner
            plainly(exc)

    def rename_takes(self, body_name: str, hand_name: str) -> None:
        """The open uploaded takes were uploaded again under other names (the same content,
        so the same hashes): the newest names are theirs from now on, in every place that
        names them (credits, command line, link, session file, download names). Nothing is
        opened or solved again."""
        names = {"body_name": body_name, "hand_name": hand_name}
        shown = self._shown
        if shown is not None and (shown["body_sha256"], shown["hand_sha256"]) == (
            self.body_sha256,
            self.hand_sha256,
        ):
            self._shown = {**shown, **names}
        self.param.update(**names)

    def set_roles(self, roles: dict) -> bool:
        """Joint-role overrides per take (validated like the session file); False if rejected."""
        try:
            spec = session_io.from_dict({"roles": roles}, source="role overrides")
        except session_io.SessionError as exc:
            self.refuse(exc, str(exc))
            return False
        self.roles = spec.roles
        return not self.error

    def _set_inputs(self, then=None, new_pair: bool = False, takes=None, **values) -> None:
        """``new_pair``: other takes than the open ones (a sample or uploads): once they
        are open, the matching points go (they name frames of the old takes); a refused
        pair leaves the open pair, its names and its points as they were."""
        old = self._current(values)
        if new_pair:
            self._begin_new_pair(values)
        self._apply(values)
        self._on_inputs(
            *[_Change(k, old[k]) for k in values], then=then, new_pair=new_pair, takes=takes
        )

    def _begin_new_pair(self, values: dict) -> None:
        """Off the loop, a new pair's opening begins before its inputs are set, so the views
        never name the new takes over the previous pair's (they switch when it is shown)."""
        if self.runner is not None:
            names = (values.get("body_name"), values.get("hand_name"))
            self.begin_opening(values.get("sample") or " + ".join(n for n in names if n))

    def _side_chosen(self, events, new_pair: bool):
        """The inputs to open for ``events``: a side chosen while a new pair waits for its
        side opens that pair (``(events, True)`` with its inputs applied); any other input
        change drops the waiting pair."""
        if self._side_wait is None:
            return events, new_pair
        values = self._side_wait[0]
        self.drop_side_wait()
        if [e.name for e in events] != ["side"]:
            return events, new_pair
        old = self._current(values)
        self.error = ""  # its question is answered
        self._begin_new_pair(values)
        self._apply(values)
        return (*events, *[_Change(k, v) for k, v in old.items()]), True

    @property
    def waits_for_side(self) -> bool:
        """A new pair waits for the side its takes have (``waiting`` says which)."""
        return self._side_wait is not None

    def drop_side_wait(self) -> None:
        """Forget the new pair that waits for its side (other takes were chosen)."""
        wait, self._side_wait = self._side_wait, None
        if wait is not None and self.waiting == wait[1]:
            self.waiting = ""

    def _on_inputs(self, *events, then=None, new_pair: bool = False, takes=None) -> None:
        if self._applying:
            return
        events, new_pair = self._side_chosen(events, new_pair)
        if not (self.sample or (self.body_sha256 and self.hand_sha256)):
            if new_pair:
                self.end_opening()
            return
        t0 = time.perf_counter()
        # every input the change set (the files' names too): a refused pair puts them back
        old = {e.name: e.old for e in events}
        then = then or (lambda opened: None)
        try:
            paths = self.take_paths()
            side, roles = self.side, dict(self.roles)
            if self.runner is None:
                prepared = backend.prepare(paths[0], paths[1], side, roles, takes=takes)
        except (HandSpliceError, ValueError, KeyError, OSError) as exc:
            self._open_failed(exc, old, then, new_pair)
            return
        if self.runner is None:
            self._opened(prepared, t0, then, new_pair)
            return
        self.runner.submit(
            Job(
                "inputs",
                "reading the takes",
                lambda progress: backend.prepare(paths[0], paths[1], side, roles, takes=takes),
                done=lambda prepared: self._opened(prepared, t0, then, new_pair),
                failed=lambda exc: self._open_failed(exc, old, then, new_pair),
                dropped=lambda: self._open_dropped(then),
            )
        )

    def link_not_opened(self, text: str) -> None:
        """Add ``text`` (one line: what of the page's shared link was left out, and what
        the page shows instead) to :attr:`link_notice`, said at the page's top: a link's
        refusal under the matrix alone was read as the link's own pair (stranger 8)."""
        self.link_notice = "; ".join(t for t in (self.link_notice, text) if t)

    def keep_error(self, text: str, exc: BaseException | None = None) -> None:
        """Show ``text`` now and keep it shown after the next solve (a shared link that
        could not be restored, while the default pair opens off the loop); ``exc``: the
        refusal behind it (:meth:`refusal`)."""
        self._carry_error = text
        if exc is None:
            self.error = text
        else:
            self.refuse(exc, text)

    def _open_dropped(self, then) -> None:
        self._side_reopened = False
        if self.runner is None or not self.runner.inputs_pending():
            self.end_opening()
        then(False)

    def _open_failed(self, exc: BaseException, old: dict, then, new_pair: bool = False) -> None:
        """A new pair or input change could not open. The inputs go back to those shown
        (the views ignore them meanwhile: the opening ends after, so a page's uploads are
        never taken for other takes chosen). A new pair whose takes have only another side
        than the one asked for waits for it, when that side is not the one in force; when
        it is, choosing it could not be a change (a Side control already showing it), so the
        pair opens on it at once (stranger 14 F2)."""
        reopened, self._side_reopened = self._side_reopened, False
        message = self._named_uploads(backend.one_line(exc))
        # a new pair whose takes have only the other side waits for it (the open pair stays)
        wait = None
        if (
            new_pair
            and self.prepared is not None
            and isinstance(exc, SideError)
            and any(side != self.side for side in exc.found)
        ):
            wait = self._current(k for k in old if k != "side")
        if self.prepared is not None:  # keep what worked: inputs back to their old values
            self._apply(old)
        if wait and self.side in exc.found and not reopened:
            # the side in force is one the new pair has: it opens on it now
            self._side_wait, self._side_reopened = (wait, ""), True
            self._on_inputs(_Change("side", self.side), then=then)
            return
        self.end_opening()
        if not wait and "side" in old and isinstance(exc, SideError) and self.side in exc.found:
            # the pair stays on the side shown: no "choose side X" for the side in force
            message = re.sub(r"; choose side \w+ in the page$", "", message)
            message += f"; it stays on the {self.side} side"
        # the inputs whose change was refused (a side the takes lack): the page shows
        # the refusal next to their controls
        self.refuse(exc, message, inputs=("side",) if wait else tuple(old))
        if wait:
            names = " + ".join(
                n for n in (wait.get("body_name"), wait.get("hand_name")) if n
            ) or str(wait.get("sample") or "the new takes")
            self._side_wait = (wait, f"{names} waits for its side: {message}")
            self.waiting = self._side_wait[1]
        then(False)

    def _named_uploads(self, text: str, takes=None) -> str:
        """``text`` with the uploaded takes' kept file names (``<sha256>.bvh``, what the
        engine read) given as the person's own file names (``walk.bvh``); ``takes``:
        ``((sha256, name), ...)`` to name (default: the session's own two)."""
        if takes is None:
            takes = ((self.body_sha256, self.body_name), (self.hand_sha256, self.hand_name))
        for sha, name in takes:
            if sha and name:
                text = re.sub(rf"\b{sha}\.(bvh|c3d|trc)\b", lambda _m, n=name: n, text)
        return text

    def _opened(self, prepared, t0: float, then, new_pair: bool = False) -> None:
        """The takes are open: show them (matrix, axes), then solve. The matching points
        stay where they still fit (a side or role change), none after a new pair.

        The opening lasts until the first path is in (:meth:`_solved`, or refused), as a
        link's does: until then the views of the previous pair stay inactive (its preview
        and suggestions are not the new pair's) and the progress line counts the whole
        opening, the first alignment included (seconds on a marker take)."""
        self.prepared = prepared
        self._side_reopened = False
        self._shown = self._current(SHOWN_INPUTS)
        self._chain = None
        self.param.update(solution=None, trust=None, history_note="")
        self._undo.clear()
        self._redo.clear()
        self._set_sizes(prepared)
        self._applying = True
        try:
            kept = tuple(
                p for p in self.points if not new_pair and p.body < self.n and p.hand < self.m_hand
            )
            self.param.update(
                points=kept,
                frame=min(self.frame, max(self.n - 1, 0)),
                **self._long_take_widths(prepared),
            )
        finally:
            self._applying = False
        self._accepted, self._accepted_undo = self._current(EDIT_PARAMS), 0
        self._accepted_automatic = self.automatic
        self.inputs_revision += 1
        self._solve(t0=t0)
        if self.runner is None or not self.runner.solving():  # solved, shared or refused
            self.end_opening()
        self._update_history_flags()
        then(True)

    def _long_take_widths(self, prepared) -> dict:
        """The automatic widths (:attr:`automatic`) for ``prepared``'s takes (the
        constraints' rule: the paper's fraction, at most a few seconds); a width the user
        set stays."""
        return _width_values(
            {name: rule.default_for(prepared.n, prepared.features.fps) for name, rule in WIDTHS},
            self.automatic,
        )

    def widths(self) -> tuple[C.Width, C.Width]:
        """The pass-1 and pass-2 band widths in force (seconds when set, else fractions)."""
        band = C.Width(self.band_s, C.SECONDS) if self.band_s is not None else C.Width(self.band)
        refine = (
            C.Width(self.refine_band_s, C.SECONDS)
            if self.refine_band_s is not None
            else C.Width(self.refine_band)
        )
        return band, refine

    def chosen_widths(self) -> tuple[C.Width | None, C.Width | None]:
        """The band widths as the user chose them: :meth:`widths`, None for a width that is
        the automatic default (what the session file, the link and the command line
        store: "automatic", so that other takes get their own default)."""
        return tuple(
            None if name in self.automatic else width
            for (name, _), width in zip(WIDTHS, self.widths())
        )

    # ------------------------------------------------------------ edits

    def _on_edit(self, *events) -> None:
        if self._applying:
            return
        old = {e.name: e.old for e in events if not _same(e.old, e.new)}
        if not old:
            return  # nothing changed (e.g. the same points set again): no recompute, no undo
        if self.opening:  # the views show the previous pair: an edit there goes nowhere
            self._apply(old)
            self.error = (
                f"not taken: {self.opening} is opening (the views show the previous pair "
                "until it is shown)"
            )
            return
        started = time.monotonic()
        automatic = self.automatic
        # a width the user set is theirs from now on, whatever its value
        self.automatic = automatic - {_width_of(name) for name in old}
        if not self._solve():
            self.automatic = automatic  # first: the values' watchers read it
            self._apply(old)  # rejected: back to the values that worked
            return
        # the idle time since the last step of this slider was solved (not the time between
        # steps: steps queued behind a slow solve still belong to one run)
        run = self._slider_run
        name = next(iter(old)) if len(old) == 1 and next(iter(old)) in SLIDER_PARAMS else None
        if (
            name is not None
            and run is not None
            and run[0] == name
            and started - run[1] < SLIDER_RUN_S
            and self._undo
            and set(self._undo[-1].values) == {name}
        ):
            pass  # the same slider again: the run stays one undo step
        else:
            self._undo.append(Snapshot(old, automatic))
            del self._undo[:-UNDO_LIMIT]
        self._slider_run = None if name is None else (name, time.monotonic())
        self._redo.clear()
        self.history_note = ""  # an edit of its own: the last undo's words are old
        self._update_history_flags()

    def _apply(self, values: dict) -> None:
        self._applying = True
        try:
            self.param.update(**values)
        finally:
            self._applying = False

    def _current(self, names) -> dict:
        return {k: getattr(self, k) for k in names}

    def undo(self) -> bool:
        """Revert the last accepted edit; False when there is nothing to undo."""
        return self._step(self._undo, self._redo)

    def redo(self) -> bool:
        """Re-apply the last undone edit; False when there is nothing to redo."""
        return self._step(self._redo, self._undo)

    def _step(self, source: list[Snapshot], target: list[Snapshot]) -> bool:
        if not source or self.opening:
            return False
        snap = source.pop()
        self._slider_run = None
        now = self._current(EDIT_PARAMS)
        target.append(Snapshot(self._current(snap.values), self.automatic))
        self.automatic = snap.automatic  # first: the values' watchers read it
        self._apply(snap.values)
        # the edit undone went from the snapshot's values to those shown; a redone one back
        undo = source is self._undo
        edit = ({**now, **snap.values}, now) if undo else (now, {**now, **snap.values})
        self.history_note = f"{'Undid' if undo else 'Redid'}: {edit_words.describe(*edit)}"
        self._solve()
        self._update_history_flags()
        return True

    def _update_history_flags(self) -> None:
        self.param.update(can_undo=bool(self._undo), can_redo=bool(self._redo))

    def set_constraints(
        self,
        band=None,
        refine_band=None,
        tolerance=None,
        points=None,
        band_s=None,
        refine_band_s=None,
        max_unmatched_s=None,
    ) -> bool:
        """Band widths (a fraction, ``"10s"`` or a ``Width``), the global tolerance and the
        matching points as a person types them, checked by engine.dtw.constraints as every
        front is; one undoable edit. False (and ``error``, nothing changed) if refused.
        ``band_s``/``refine_band_s``: what was typed into a width's field in seconds (``2``,
        ``2s``; empty text: the fraction is in force again), refused in that field's words
        (``W1 in seconds: ...``); ``max_unmatched_s`` likewise, the open-end limit typed in
        seconds (empty text: the default limit)."""
        values: dict = {}
        try:
            for name, rule, value, seconds in (
                ("band", C.BAND, band, band_s),
                ("refine_band", C.REFINE_BAND, refine_band, refine_band_s),
            ):
                width = rule.parse(value)
                if width is not None and width.unit == C.SECONDS:
                    values[f"{name}_s"] = width.value
                elif width is not None:
                    values.update({name: width.value, f"{name}_s": None})
                if seconds is not None:
                    values[f"{name}_s"] = rule.parse_seconds(seconds)
            if max_unmatched_s is not None:
                values["max_unmatched_s"] = C.parse_max_unmatched(
                    max_unmatched_s, label=C.MAX_UNMATCHED_LABEL
                )
            if tolerance is not None:
                values["tolerance"] = C.parse_tolerance(tolerance)
            if points is not None:
                values["points"] = C.parse_points(points)
        except C.ConstraintError as exc:
            self.refuse(exc, str(exc))
            return False
        self.error = ""
        self.param.update(**values)
        return not self.error

    # matching-point edits (each one undoable)

    def set_points(self, points) -> None:
        """Replace all matching points: iterable of MatchPoint or (body, hand[, tol])."""
        self.points = self._normalise(points)

    def _frames(self, index: int, body, hand) -> tuple[int, int] | None:
        """``(body, hand)`` as whole frames (engine.dtw.constraints.parse_point_frame: 12.5 is
        refused, never truncated); None, with the refusal shown, otherwise."""
        try:
            return (
                C.parse_point_frame(body, index, "body", body, hand),
                C.parse_point_frame(hand, index, "hand", body, hand),
            )
        except C.ConstraintError as exc:
            self.refuse(exc, str(exc))
            return None

    def add_point(self, body: int, hand: int, tolerance: float | None = None) -> None:
        frames = self._frames(len(self.points), body, hand)
        if frames is not None:
            self.set_points([*self.points, MatchPoint(*frames, tolerance)])

    def move_point(self, index: int, body: int, hand: int) -> None:
        frames = self._frames(index, body, hand)
        if frames is None:
            return
        pts = list(self.points)
        pts[index] = MatchPoint(*frames, pts[index].tolerance)
        self.set_points(pts)

    def delete_point(self, index: int) -> None:
        pts = list(self.points)
        del pts[index]
        self.set_points(pts)

    def set_point_tolerance(self, index: int, tolerance: float | None) -> None:
        if tolerance is not None:
            try:
                p = self.points[index]
                tolerance = C.parse_point_tolerance(tolerance, index, p.body, p.hand)
            except C.ConstraintError as exc:
                self.refuse(exc, str(exc))
                return
        pts = list(self.points)
        pts[index] = MatchPoint(
            pts[index].body, pts[index].hand, None if tolerance is None else float(tolerance)
        )
        self.set_points(pts)

    def set_points_from_view(self, edited) -> bool:
        """Points as the matrix figure sends them ((x, y, tol) floats); False if rejected."""
        pts = []
        for x, y, tol in edited:
            if x is None or y is None or not (np.isfinite(x) and np.isfinite(y)):
                continue
            body, hand = view_frame(x, self.n), view_frame(y, self.m_hand)
            tol = None if tol is None or (isinstance(tol, float) and np.isnan(tol)) else float(tol)
            pts.append(MatchPoint(body, hand, tol))
        before = self.points
        self.set_points(pts)
        return self.points != before or tuple(sorted(pts, key=lambda p: p.body)) == before

    def apply_view_edits(self, edits) -> int:
        """Browser edits of the matching points, in the order they were made.

        ``edits``: iterable of ``(before, after)``, each a list of ``(x, y, tol)`` as the
        page held its points before and after one click, drag or delete. The page may be
        several edits ahead of the session (it does not wait for the server's answer), so
        each edit is applied as what it did (one point added, moved or deleted) to the
        points the session holds now, not as a whole list: an edit made in the page while
        the server was changing the points (undo, a table edit) keeps both. Each edit is
        solved and is one undo step; a refused edit sets ``error`` and the next ones go on.
        Returns how many edits changed the points.
        """
        changed = 0
        for before, after in edits:
            before, after = self._view_cells(before), self._view_cells(after)
            if before == after:
                continue
            pts = self._merged(list(self.points), before, after)
            if pts is None or tuple(self._normalise(pts)) == self.points:
                continue
            old = self.points
            self.set_points(pts)
            changed += self.points != old
        return changed

    def _view_cells(self, edited) -> list[tuple[int, int, float | None]]:
        """The page's ``(x, y, tol)`` floats as matrix cells (``view_frame``; NaN tol = None)."""
        cells = []
        for x, y, *rest in edited:
            if x is None or y is None or not (np.isfinite(x) and np.isfinite(y)):
                continue
            tol = rest[0] if rest else None
            tol = None if tol is None or not np.isfinite(tol) else float(tol)
            cells.append((view_frame(x, self.n), view_frame(y, self.m_hand), tol))
        return cells

    @staticmethod
    def _merged(points: list[MatchPoint], before: list, after: list) -> list | None:
        """``points`` with the one edit ``before -> after`` of the page applied (by index in
        the page's list: a click appends, a drag changes entries in place, Backspace removes)."""

        def find(cell):
            for k, p in enumerate(points):
                if (p.body, p.hand) == cell[:2]:
                    return k
            return None

        if len(after) == len(before) + 1 and after[: len(before)] == before:
            x, y, tol = after[-1]
            return [*points, MatchPoint(x, y, tol)]
        if len(after) == len(before):
            for old, new in zip(before, after):
                if old == new:
                    continue
                k = find(old)
                if k is None:  # the session dropped that point meanwhile: the drag places it
                    points.append(MatchPoint(new[0], new[1], new[2]))
                else:
                    points[k] = MatchPoint(new[0], new[1], points[k].tolerance)
            return points
        if len(after) < len(before):
            remaining = list(after)
            for cell in before:
                if cell in remaining:
                    remaining.remove(cell)
                    continue
                k = find(cell)
                if k is not None:
                    del points[k]
            return points
        return [MatchPoint(*c) for c in after]  # not one click, drag or delete: take it whole

    def _normalise(self, points) -> tuple[MatchPoint, ...]:
        """Points placed anywhere, in body-frame order; refused (``error``) when they break a
        constraint (engine.dtw.constraints): the points stay as they were."""
        try:
            return C.sort_points(points)
        except C.ConstraintError as exc:
            self.refuse(exc, str(exc))
            return self.points

    # ------------------------------------------------------------ compute

    def _check_points(self) -> None:
        """Refuse points outside the takes or out of order: the rule and its text are
        ``engine.dtw.constraints``' (``matching point 2 (body 80, hand 20): ...``, counted
        as the table lists the points)."""
        C.check_points(
            self.user_points(),
            self.n,
            self.m_hand,
            open_ends=C.DEFAULT_ENDS == "open",
            grid_scale=1.0 / self.hand_scale,
        )

    def _solve(self, t0: float | None = None) -> bool:
        """Recompute band and path for the current state; False (and ``error``) if rejected."""
        if self.prepared is None:
            return True
        t0 = time.perf_counter() if t0 is None else t0
        try:
            self._check_points()
            band, refine = self.widths()
            points = self.constraint_points()
            if self.runner is None:
                sol = (
                    backend.first_solution(self.prepared, band, refine, points, owner=id(self))
                    if self.solution is None and self.max_unmatched_s is None
                    else backend.solve(
                        self.prepared,
                        band=band,
                        refine_band=refine,
                        points=points,
                        previous=self.solution,
                        max_unmatched_s=self.max_unmatched_s,
                    )
                )
        except (HandSpliceError, ValueError) as exc:
            self.refuse(exc)
            return False
        if self.runner is None:
            self._solved(sol, t0)
            return True
        prepared, values, automatic = self.prepared, self._current(EDIT_PARAMS), self.automatic
        limit = self.max_unmatched_s
        # a pair's first alignment is every tab's (backend.first_solution): computed by the
        # server's warm-up or another tab, it is shown at once; it has the default open-end
        # limit
        shared = (
            None
            if self._chain is not None or limit is not None
            else backend.shared_ready(prepared, band, refine, points)
        )
        if shared is not None:
            self._chain = shared
            self._solved(shared, t0, values, automatic)
            return True

        def work(progress):  # on the worker: solves run one at a time per session
            if self._chain is None and limit is None:  # the first alignment: shared
                sol = backend.first_solution(
                    prepared, band, refine, points, progress=progress, owner=id(self)
                )
            else:
                sol = backend.solve(
                    prepared,
                    band=band,
                    refine_band=refine,
                    points=points,
                    previous=self._chain,
                    progress=progress,
                    max_unmatched_s=limit,
                )
            self._chain = sol
            return sol

        front = self._front  # the edit's, when its solve is refused later
        self.runner.submit(
            Job(
                "solve",
                "aligning",
                work,
                done=lambda sol: self._solved(sol, t0, values, automatic),
                failed=lambda exc: self._solve_failed(exc, front),
            )
        )
        return True  # refused later: _solve_failed

    def _solved(self, sol, t0: float, values: dict | None = None, automatic=None) -> None:
        error, self._carry_error = self._carry_error, ""
        self.param.update(
            solution=sol, trust=None, compute_ms=(time.perf_counter() - t0) * 1000.0, error=error
        )
        self.revision += 1
        self.end_opening()  # a new pair's first path: it is open
        self._accepted = self._current(EDIT_PARAMS) if values is None else values
        self._accepted_automatic = self.automatic if automatic is None else automatic
        self._accepted_undo = len(self._undo)

    def _solve_failed(self, exc: BaseException, front: str = "") -> None:
        """The newest solve was refused (off the loop): its reason is shown (as the refusal
        of ``front``'s edit) and the edit values go back to those of the path on screen (the
        undo steps since go too)."""
        self.end_opening()
        self.refuse(exc, front=front)
        if self._accepted is not None:
            self.automatic = self._accepted_automatic  # first: the values' watchers read it
            self._apply(self._accepted)
            del self._undo[self._accepted_undo :]
            self._slider_run = None
            self._update_history_flags()

    def edit_coming(self) -> bool:
        """True while an edit's solve runs or waits, or a drag of a matching point is under
        way in the page (its edit arrives on release): the previous edit's follow-up work
        (the preview's splice and views, the trust assessment) is given up or not started,
        so it never shares the cores with the edit's solve. Safe on a worker thread."""
        runner = self.runner
        return self.dragging or (runner is not None and runner.solving())

    def assess(self, cancelled=None):
        """Trust in the current solution (uncertainty per body frame, strokes, suggestions),
        or None without one. Pure: safe to call off the event loop (``update_trust``).
        ``cancelled``: a callable; once it returns True the assessment stops
        (``engine.base.errors.Cancelled``)."""
        prepared, solution = self.prepared, self.solution
        if prepared is None or solution is None:
            return None
        return backend.assess(prepared, solution, cancelled=cancelled)

    def update_trust(self, assessment=None, revision: int | None = None) -> bool:
        """Set ``trust`` for the current solution (computing it unless given); an assessment
        of an older ``revision`` is dropped (a newer edit has been solved since)."""
        if revision is not None and revision != self.revision:
            return False
        self.trust = self.assess() if assessment is None else assessment
        return True

    def user_points(self) -> list[tuple[int, int, float]]:
        """``[(body, hand, tol), ...]`` in each file's frames, the global tolerance filled in
        (what ``handsplice splice --match`` takes)."""
        return [p.resolved(self.tolerance) for p in self.points]

    def constraint_points(self) -> list[tuple[int, int, float]]:
        """The matching points on the alignment grid (what the solver takes)."""
        if self.prepared is None:
            return self.user_points()
        return backend.points_to_grid(self.prepared, self.user_points())

    def pass2_turns_hand(self) -> bool:
        """True when pass 2 compares how the hand turns (a hand take without a forearm,
        ``engine.splice.pipeline.uses_spin``) over the whole pass-1 band: W2 is unused."""
        if self.prepared is None:
            return False
        from engine.splice.pipeline import uses_spin

        return bool(uses_spin(self.prepared.features))

    def matrix_label(self) -> str:
        """The title of the matrix shown (``MATRIX_LABELS``; pass 2 says its metric)."""
        if self.matrix == "pass2" and self.pass2_turns_hand():
            return PASS2_SPIN_LABEL
        return MATRIX_LABELS[self.matrix]

    @property
    def hand_scale(self) -> float:
        """Hand-file frames per alignment-grid column (hand fps / body fps)."""
        return self.hand_fps / self.fps if self.fps else 1.0

    def recompute(self) -> bool:
        return self._solve()

    # ------------------------------------------------------------ derived views

    def aligned_here(self) -> bool:
        """True when the alignment shown was computed for this session; False when it is
        the pair's first alignment computed earlier for another tab or the server's
        warm-up (``backend.first_solution``), shown without solving again."""
        sol = self.solution
        if sol is None:
            return False
        return not sol.cache.get("shared") or sol.cache.get("solved_for") == id(self)

    def status_text(self) -> str:
        sol = self.solution
        if sol is None:
            if self.opening and not self.error:  # the first pair of this page, on its way
                return f"opening {self.opening}: no alignment yet"
            return self.error or "no takes loaded"
        from engine.splice.report import unmatched_summary

        cells = sol.pass1.band_cells
        share = 100.0 * cells / max(self.n * self.m, 1)
        text = (
            f"pass 1 cost {sol.pass1.cost:.4g} · pass 2 cost {sol.pass2.cost:.4g} · "
            f"solved in {self.compute_ms:,.0f} ms · band {cells:,} cells ({share:.0f} %) · "
            f"{len(self.points)} matching point{'s' if len(self.points) != 1 else ''}"
        )
        result = sol.cache.get("engine")
        limit = result.unmatched_limit(self.fps) if hasattr(result, "unmatched_limit") else None
        given = getattr(result, "max_unmatched_s", None) is not None
        unmatched = unmatched_summary(
            getattr(result, "unmatched_body", ()),
            self.fps,
            limit,
            given,
            front="page",
            retimed=self.prepared is not None and backend.marker_body(self.prepared),
        )
        return text + (f" · {unmatched}" if unmatched else "")

    def unmatched_limits_s(self) -> tuple[float, float] | None:
        """Seconds of the body and of the hand take that may stay unmatched at each end
        (``engine.dtw.constraints.unmatched_limits``: the limit set, or the default for
        these takes); None without takes."""
        if self.prepared is None or not self.fps:
            return None
        body, hand = C.unmatched_limits(self.n, self.m, self.fps, self.max_unmatched_s)
        return body / self.fps, hand / self.fps

    def unmatched_note(self) -> str:
        """What the open-end limit in force is for these takes, in words (under its field)."""
        limits = self.unmatched_limits_s()
        if limits is None:
            return ""
        body, hand = limits
        rule = (
            "the limit set above"
            if self.max_unmatched_s is not None
            else f"the default: {C.UNMATCHED_DEFAULT}"
        )
        return (
            f"In force: the body take may leave {body:.1f} s and the hand take {hand:.1f} s "
            f"unmatched at each end ({rule})."
        )

    def band_placement_note(self) -> str:
        """Why narrowing W1 barely narrows the band of takes of different lengths, or ""
        (``engine.splice.end_band``: with open ends pass 1's band also holds every place
        the shorter take can sit inside the longer one; their spread comes from the takes'
        lengths and the unmatched-end limit, W1 only widens each place). Said where that
        spread is at least W1 (then it, not W1, makes most of the band's width)."""
        if self.prepared is None or not self.fps:
            return ""
        from engine.splice.end_band import placement_offsets

        limits = C.unmatched_limits(self.n, self.m, self.fps, self.max_unmatched_s)
        offsets = placement_offsets(self.n, self.m, limits)
        if offsets is None:
            return ""
        spread = (offsets[1] - offsets[0]) / self.fps
        if spread < self.widths()[0].frames(self.n, self.fps) / self.fps:
            return ""
        shorter = "hand" if self.m < self.n else "body"
        return (
            f"With open ends the band also holds every place the shorter ({shorter}) take "
            f"can sit inside the longer one: {spread:.1f} s of start times, set by the takes' "
            f"lengths and the unmatched-end limit ({C.MAX_UNMATCHED_LABEL}, below), not by "
            "W1, which only widens each place. So narrowing W1 narrows the band little; "
            "a smaller unmatched-end limit or a matching point narrows it."
        )

    def hand_rate_note(self) -> str:
        """Why a point's hand frame and the preview's can differ by a frame or two, or "":
        a hand take faster than the body is aligned at the body's rate (its frames on the
        alignment grid, ``constraints.points_to_grid``), so a point's hand frame counts to
        the nearest grid column, and the preview names the hand frame of that column."""
        if not (self.prepared is not None and self.fps and self.hand_fps > self.fps * 1.001):
            return ""
        ratio = self.hand_fps / self.fps
        if ratio < 1.1:  # nearly one rate: its step said in frames read as noise (stranger 12:
            return (  # "1 frames per body frame ... up to 0.501" at 120 vs 119.875 fps)
                f"The hand take runs a little faster than the body ({self.hand_fps:g} vs "
                f"{self.fps:g} fps) and is aligned at the body's rate: the preview at a point's "
                "body frame may name a hand frame one off the table's."
            )
        return (
            f"The hand take has {ratio:.3g} frames per body frame ({self.hand_fps:g} vs "
            f"{self.fps:g} fps) and is aligned at the body's rate, in steps of {ratio:.3g} "
            "hand frames: a point's hand frame is aligned to the nearest step, so the preview "
            f"at its body frame may name a hand frame up to {ratio / 2:.3g} from the table's."
        )

    def axis_signals(self) -> tuple[np.ndarray, np.ndarray]:
        if self.prepared is None:
            return np.zeros(0), np.zeros(0)
        return self.prepared.body_signal, self.prepared.hand_signal

    def axis_phases(self):
        if self.prepared is None:
            return None, None
        return self.prepared.body_phases, self.prepared.hand_phases

    def hand_frame_for(self, body_frame: int) -> int:
        """The hand-file frame the current alignment matches to ``body_frame``."""
        if self.solution is None or self.prepared is None:
            return 0
        return backend.frame_triplet(self.prepared, self.solution, body_frame)[1]

    def frame_pair(self) -> tuple[int, int]:
        return self.frame, self.hand_frame_for(self.frame)

    def pick_cell(self, x: float, y: float) -> None:
        """A click on the matrix: show that body frame (and the hand frame the path gives it)."""
        if self.n:
            self.frame = view_frame(x, self.n)

    def cost_view(self, ranges, max_pixels: int):
        """The visible part of the shown matrix, or None (no takes, or a view that is refused,
        e.g. a cumulative view too large to hold: the reason goes to ``error``)."""
        if self.prepared is None:
            return None
        if self.matrix.startswith("cumulative") and self.runner is not None and self.runner.busy:
            return None  # its γ is being recomputed: drawn when the solve is shown
        try:
            return backend.cost_view(self.prepared, self.solution, self.matrix, ranges, max_pixels)
        except HandSpliceError as exc:
            self.refuse(exc)
            return None

    def spliced(self):
        """The spliced Motion for the current alignment (cached per revision)."""
        if self.prepared is None or self.solution is None:
            raise HandSpliceError("no takes loaded")
        return backend.splice(self.prepared, self.solution)

    def output_stem(self) -> str:
        """A file name stem for downloads: the sample name, or the body take's file name
        without its extension (an upload's, or ``serve BODY HAND``'s pair opened from disk:
        one rule for the user's own takes, ``<body>-spliced``)."""
        import re

        local = self._cfg.local if self.sample else None
        if local is not None and local.name == self.sample:
            stem = local.body.stem
        else:
            stem = self.sample or (self.body_name.rsplit(".", 1)[0] if self.body_name else "")
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", stem).strip("._") or "handsplice"
        return f"{stem}-spliced"

    # ------------------------------------------------------------ save / restore

    def to_spec(self) -> SessionSpec:
        """The session as a link or session file gives it: the takes of the pair shown (not
        those of a pair still opening), its parameters, points and view."""
        shown = self._shown or self._current(SHOWN_INPUTS)
        body = hand = None
        if not shown["sample"] and shown["body_sha256"]:
            body = TakeRef(sha256=shown["body_sha256"], name=shown["body_name"] or None)
        if not shown["sample"] and shown["hand_sha256"]:
            hand = TakeRef(sha256=shown["hand_sha256"], name=shown["hand_name"] or None)
        band, refine = self.chosen_widths()  # None: automatic (each pair's own default)
        return SessionSpec(
            sample=shown["sample"],
            body=body,
            hand=hand,
            side=shown["side"],
            hand_frames="file",
            band=band,
            refine_band=refine,
            tolerance=self.tolerance,
            points=self.points,
            max_unmatched_s=self.max_unmatched_s,
            roles=dict(shown["roles"]),
            view={"matrix": self.matrix, "frame": self.frame, **self._current(VIEW_STATE)},
        )

    def apply_spec(
        self, spec: SessionSpec, failed=None, keep_takes: bool = False, then=None, takes=None
    ) -> None:
        """Restore inputs, parameters and points (one recompute; clears undo history).

        Off the event loop (:meth:`compute_off_loop`) the work runs on the worker and a
        refusal goes to ``failed(exc)`` (default: ``error``) instead of raising.

        All or nothing: the takes are resolved and opened, the points checked and both
        passes solved before anything in the session changes, so a bad session file or
        link (unknown sample or upload, points outside the matrix, infeasible points)
        raises (SessionError, KeyError, HandSpliceError, ValueError, OSError) and leaves
        the working session exactly as it was. A spec without takes (a link such as
        ``?frame=75``, a session file of parameters only) applies to the takes already
        open, or to the default pair when none are (:meth:`_takes_for`). ``keep_takes`` (a
        shared link): points that do not fit the takes are left out, with their refusal in
        ``error``, and the rest opens. ``then(opened: bool)``: called once it is installed
        (not after a refusal: that goes to ``failed``); ``takes``: ``(body, hand)`` as an
        upload's check read them (:meth:`load_uploads`).
        """
        self.drop_side_wait()  # the takes chosen now are the link's or the file's
        spec = self._takes_for(spec)
        if self.runner is None:
            self._commit(self._stage(spec, keep_takes=keep_takes, takes=takes))
            if then is not None:
                then(True)
            return

        def done(staged):
            self._commit(staged)
            if then is not None:
                then(True)

        def refused(exc):
            self.end_opening()
            (failed or self.refuse)(exc)

        if spec.sample is not None or spec.body is not None:
            names = (spec.body.name, spec.hand.name) if spec.body is not None else ()
            self.begin_opening(spec.sample or " + ".join(n for n in names if n))
        self.runner.submit(
            Job(
                "inputs",
                "opening the session",
                lambda progress: self._stage(spec, progress, keep_takes, takes),
                done=done,
                failed=refused,
                dropped=lambda: self._open_dropped(then or (lambda opened: None)),
            )
        )

    def _takes_for(self, spec: SessionSpec) -> SessionSpec:
        """``spec`` with the takes it applies to: its own, else the takes already open, else
        the server's default pair (the one rule for every front: a link, a session file, a
        caller of :meth:`apply_spec`). Without any of them, :meth:`_stage` refuses."""
        if spec.sample is not None or spec.body is not None or spec.hand is not None:
            return spec
        if self.take_paths() is not None or not self._cfg.default_sample:
            return spec
        return replace(spec, sample=self._cfg.default_sample)

    def _side_for(self, spec: SessionSpec) -> str:
        """The side ``spec`` aligns: its own, else (a link whose ``side`` was bad or absent)
        the side the page chooses without one: a sample pair's own, an uploaded hand's from
        its file name (as an upload through the page does, ``views.inputs``), else the
        side in force (stranger 12: ``side=middle`` put a leftHand take on the right)."""
        if spec.side is not None:
            return spec.side
        if spec.sample is not None:
            return self._cfg.sample(spec.sample).side
        named = side_from_name(spec.hand.name) if spec.hand and spec.hand.name else None
        return named or self.side

    @staticmethod
    def _joints_side(spec: SessionSpec, side: str, hand_path, takes=None) -> str:
        """``side`` (:meth:`_side_for`'s), unless ``spec`` gives none and its hand file's
        name says a side its joint names contradict: then the joints' (the one rule,
        ``engine.model.roles.hand_file_side``; stranger 14 F2). ``takes``: as read."""
        if spec.side is not None or spec.hand is None or not side_from_name(spec.hand.name or ""):
            return side
        from engine.io import load_take
        from engine.model.motion import Motion
        from engine.model.roles import hand_file_side

        take = takes[1] if takes else load_take(hand_path)
        skeleton = take.skeleton if isinstance(take, Motion) else None
        return hand_file_side(spec.hand.name, skeleton).side or side

    def _stage(
        self, spec: SessionSpec, progress=None, keep_takes: bool = False, takes=None
    ) -> dict:
        """Everything ``spec`` needs, computed without touching the session (safe on a
        worker thread); ``takes``: as for :meth:`apply_spec`."""
        t0 = time.perf_counter()
        side = self._side_for(spec)
        if side not in session_io.LINK_SIDES:
            raise session_io.SessionError(None, "side", "the app aligns one side: right or left")
        for k, take in (("body", spec.body), ("hand", spec.hand)):
            if take is not None and not take.sha256:
                raise session_io.SessionError(
                    None,
                    f"inputs.{k}",
                    "the app opens bundled samples or uploaded files (sha256), not paths",
                )
        if (spec.body is None) != (spec.hand is None):
            missing = "hand" if spec.hand is None else "body"
            raise session_io.SessionError(
                None, f"inputs.{missing}", "missing (an uploaded pair needs both takes)"
            )
        if spec.sample is not None:
            pair = self._cfg.sample(spec.sample)  # KeyError naming the known pairs
            inputs = dict(
                sample=spec.sample, body_sha256=None, hand_sha256=None, body_name="", hand_name=""
            )
            paths = (pair.body, pair.hand)
        elif spec.body is not None:
            from webapp import uploads

            inputs = dict(
                sample=None,
                body_sha256=spec.body.sha256,
                hand_sha256=spec.hand.sha256,
                body_name=spec.body.name or "",
                hand_name=spec.hand.name or "",
            )
            paths = uploads.files_for(
                self._cfg, ((t.sha256, t.name) for t in (spec.body, spec.hand))
            )
        else:  # parameters only: applied to the takes already open (see _takes_for)
            inputs = self._current(
                ("sample", "body_sha256", "hand_sha256", "body_name", "hand_name")
            )
            paths = self.take_paths()
            if paths is None:
                raise session_io.SessionError(
                    None,
                    "inputs",
                    "expected a sample or uploaded body and hand takes (none are open and the "
                    "server has no default pair)",
                )
        side = self._joints_side(spec, side, paths[1], takes)
        roles = dict(spec.roles)
        prepared = backend.prepare(paths[0], paths[1], side, roles, takes=takes)
        points = tuple(spec.points)  # checked by engine.dtw.constraints when the spec was made
        if spec.hand_frames == "grid":  # an old file or link: hand frames on the grid
            points = C.sort_points(
                backend.grid_points_to_hand(
                    prepared, [(p.body, p.hand, p.tolerance) for p in points]
                )
            )
        refused: list[BaseException] = []  # what of a link is left out, each said
        try:
            C.check_points(
                [p.resolved(spec.tolerance) for p in points],
                prepared.n,
                prepared.m_hand,
                open_ends=C.DEFAULT_ENDS == "open",
                grid_scale=prepared.fps / prepared.hand_fps,
            )
        except C.ConstraintError as exc:
            if not keep_takes:
                raise
            refused.append(exc)  # the link's takes and other values open without them
            points = ()
        defaults = {
            name: rule.default_for(prepared.n, prepared.features.fps) for name, rule in WIDTHS
        }
        # automatic: a width the spec leaves out, or one that is these takes' default (files
        # and links written before held the automatic default as a number, 17.2 s)
        automatic = frozenset(
            name for name, _ in WIDTHS if getattr(spec, name) in (None, defaults[name])
        )
        band = spec.band or defaults["band"]
        refine = spec.refine_band or defaults["refine_band"]
        grid = backend.points_to_grid(prepared, [p.resolved(spec.tolerance) for p in points])
        # a link or file without points, at settings another tab (or the warm-up) aligned
        # the pair with, shows that alignment, as a tab opening the pair does
        # (backend.first_solution; one kept per pair and settings, so not per set of points)
        solution = (
            backend.first_solution(prepared, band, refine, grid, progress=progress, owner=id(self))
            if not grid and spec.max_unmatched_s is None
            else backend.solve(
                prepared,
                band=band,
                refine_band=refine,
                points=grid,
                progress=progress,
                max_unmatched_s=spec.max_unmatched_s,
            )
        )
        widths = _width_values({"band": band, "refine_band": refine}, dict(WIDTHS))
        frame, last = int(spec.view.get("frame", 0)), max(prepared.n - 1, 0)
        if frame > last and keep_takes:  # a link's: said, not silent (stranger 11:
            refused.append(  # frame=9999 became 186 unsaid)
                session_io.SessionError(
                    "URL",
                    "frame",
                    f"{frame} is past the body take's last frame, {last}: {last} is shown",
                )
            )
        values = dict(
            inputs,
            side=side,
            roles=roles,
            **widths,
            tolerance=spec.tolerance,
            points=points,
            max_unmatched_s=spec.max_unmatched_s,
            matrix=spec.view.get("matrix", self.matrix),
            frame=min(frame, last),
            **{k: spec.view.get(k, session_io.VIEW_DEFAULTS[k]) for k in VIEW_STATE},
        )
        return {
            "values": values,
            "prepared": prepared,
            "solution": solution,
            "compute_ms": (time.perf_counter() - t0) * 1000.0,
            "refused": refused,
            "automatic": automatic,
        }

    def _commit(self, staged: dict) -> None:
        """Install a staged state: results first, so watchers of the inputs see a consistent
        session (a frame of the new takes has a hand frame in the new solution)."""
        prepared = staged["prepared"]
        self.end_opening()
        self.prepared = prepared
        self._set_sizes(prepared)
        self.param.update(
            solution=staged["solution"],
            trust=None,
            compute_ms=staged["compute_ms"],
            history_note="",
        )
        self.automatic = staged["automatic"]  # first: the values' watchers read it
        self._apply(staged["values"])
        self._shown = self._current(SHOWN_INPUTS)
        self._undo.clear()
        self._redo.clear()
        self._chain = staged["solution"]
        self._accepted, self._accepted_undo = self._current(EDIT_PARAMS), 0
        self._accepted_automatic = self.automatic
        self.inputs_revision += 1
        self.error, self._carry_error = self._carry_error, ""
        if staged["refused"]:  # a link's points or frame left out: say each and why
            left_out = "; ".join(backend.one_line(exc) for exc in staged["refused"])
            text = f"shared link: {left_out}"
            self.refuse(staged["refused"][0], "; ".join(t for t in (self.error, text) if t))
            self.link_not_opened(f"{left_out} (left out; the rest of the link opened)")
        self.revision += 1
        self._update_history_flags()

    def _set_sizes(self, prepared) -> None:
        with param.edit_constant(self):
            self.param.update(
                n=prepared.n,
                m=prepared.m,
                m_hand=prepared.m_hand,
                fps=prepared.fps,
                hand_fps=prepared.hand_fps,
            )

    def to_json(self) -> str:
        return session_io.format_session(self.to_spec())

    def from_json(self, text: str | bytes, source: str | None = None, failed=None) -> None:
        self.apply_spec(session_io.parse_session(text, source), failed)

    def to_query(self) -> dict[str, str]:
        return session_io.to_query(self.to_spec())

    def share_url(self, base: str = "") -> str:
        return f"{base}?{urlencode(self.to_query(), safe=':,')}"

    def from_query(self, query: dict, failed=None) -> None:
        """Restore a link whole or not at all (a bad value raises SessionError)."""
        self.apply_spec(session_io.from_query(query), failed)

    def open_link(self, query: dict, failed=None) -> None:
        """Restore a shared link's good values (the takes above all) and leave out each bad
        one (``band=99``, ``pts=abc:1``): ``error`` says why in one line, shown on after the
        link's solve (:func:`engine.io.session.read_query`). What cannot be opened at all
        (unknown takes, points outside the matrix) goes to ``failed`` as in
        :meth:`apply_spec`; a link whose uploaded takes are not on this server then waits
        for them: uploading them through the page opens it (:meth:`load_uploads`)."""
        spec, problems = session_io.read_query(query)
        if problems:
            text = "; ".join(backend.one_line(p) for p in problems)
            self.keep_error(f"shared link: {text}", problems[0])
            self.link_not_opened(f"{text} (left out; the rest of the link opened)")
        if spec.points and spec.hand_frames == "grid":  # said, not silent (stranger 14 F5)
            self.link_not_opened(GRID_FRAMES_NOTE)

        left_out = "; ".join(backend.one_line(p) for p in problems)

        def refused(exc):
            self._keep_waiting_link(spec, left_out)
            (failed or self.refuse)(exc)

        try:
            self.apply_spec(spec, refused, keep_takes=True)
        except Exception:  # without a runner: raised to the caller, as before
            self._keep_waiting_link(spec, left_out)
            raise
