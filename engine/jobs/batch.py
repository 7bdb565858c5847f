"""Batch splicing of many body/hand pairs on dask.distributed.

A *manifest* is a CSV file with a header row and one pair per row::

    body,hand,side,band,refine_band,match,name
    takes/walk01.bvh,hands/point.bvh,right,0.3,0.1,120:98:2;300:280,walk01-point
    takes/walk02.bvh,hands/count.bvh,both,,,,

Columns ``body``, ``hand`` and ``side`` (``right``, ``left``, ``both`` or ``auto``,
as ``handsplice splice --side``) are required; ``band`` (pass-1 band width: a
fraction of the body take or seconds like ``10s``), ``refine_band`` (pass-2 band,
the same forms), ``match`` (matching points ``BODY:HAND[:TOL]`` separated by ``;``
or spaces, frames 0-based in each file's own numbering, as ``handsplice splice
--match``) and ``name`` (the output file stem) are optional; an empty cell means
the default. Ranges and error text are :mod:`engine.dtw.constraints`' (as every front). Relative paths resolve against the manifest's folder.
Blank lines and lines starting with ``#`` are skipped. A file that is no manifest (not
CSV, a bad or missing header, a row with more values than columns, a name used twice, too
many rows) raises :class:`ManifestError` naming the CSV line and column, before anything
runs. A bad value in one row's cell (``side``, ``band``, ``refine_band``, ``match``, a
take's path, ``name``) fails that row only (:attr:`PairJob.refused`, the same one line):
it is recorded in the summary and the other rows run, as a pair that fails does.

Per pair ``NAME`` the output folder receives (every file written atomically)::

    NAME.bvh            the spliced take
    NAME.report.json    the splice report (map, paths, costs, parameters, timings)
    NAME.png            a thumbnail (engine.render; a stick-figure fallback without OpenGL)
    .handsplice-batch/NAME.json   the done marker: input hashes, options, outputs

and ``summary.csv`` (rewritten as pairs finish) and, at the end, ``index.html`` (one row
and thumbnail per pair).

Limits: each pair runs in a forked child process (``engine.jobs.sandbox``) that is stopped
after ``pair_seconds`` (default 900) or beyond ``pair_memory_mb`` MB resident (default
2048); the pair is then failed with that reason, its temporary files removed.

Resuming: a pair is *skipped* when its done marker exists, records the same
SHA-256 of both input files and the same options, and its outputs still exist.
Failed pairs leave no marker and are tried again on the next run.

Failures: a pair that raises (unreadable take, no wrist, infeasible matching
points, a worker that died) is recorded with a one-line error in the summary and
never stops the batch.

Scheduling: each pair is one dask task (``pure=False``, one thread per worker
process, as splicing is CPU-bound numpy/numba). By default an embedded
``LocalCluster(processes=True, n_workers=N, threads_per_worker=1)`` is started
and closed; ``scheduler="tcp://host:8786"`` uses an existing cluster instead (its
workers must have HandSplice installed and see the same file paths).
"""

from __future__ import annotations

import csv
import html
import io
import json
import math
import os
import platform
import re
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from engine import __version__
from engine.base.atomic import atomic_path, clean_stale, write_text, write_texts
from engine.base.digest import file_sha256
from engine.base.errors import HandSpliceError, ParameterError, first_line
from engine.base.json_text import parse_json
from engine.base.limits import MAX_MANIFEST_ROWS, PAIR_MEMORY_MB, PAIR_SECONDS
from engine.dtw import constraints as C

REQUIRED_COLUMNS = ("body", "hand", "side")
OPTIONAL_COLUMNS = ("band", "refine_band", "match", "name")
SIDES = ("right", "left", "both", "auto")
MARKER_DIR = ".handsplice-batch"
SUMMARY_COLUMNS = (
    "name",
    "line",
    "status",
    "body",
    "hand",
    "side",
    "band",
    "refine_band",
    "match",
    "body_frames",
    "spliced_frames",
    "fps",
    "seconds",
    "output",
    "report",
    "thumbnail",
    "thumbnail_kind",
    "worker",
    "error",
    "notes",
)
THUMB_SIZE = (192, 144)
_NAME_OK = re.compile(r"[^A-Za-z0-9_.+-]+")


class ManifestError(HandSpliceError, ValueError):
    """The manifest CSV is malformed; the message names the file, line and column
    (``m.csv line 3: band: ...``, or ``m.csv line 3, column match: ...`` with ``column``)."""

    def __init__(self, path: str | Path, line: int | None, message: str, column: str = ""):
        self.path = str(path)
        self.line = line
        where = Path(path).name + (f" line {line}" if line is not None else "")
        where += f", column {column}" if column else ""
        super().__init__(f"{where}: {message}")


# ---------------------------------------------------------------- manifest


@dataclass(frozen=True)
class PairJob:
    """One row of the manifest, validated; paths absolute.

    ``match`` holds ``(body_frame, hand_frame, tolerance or None)`` triples. ``refused``:
    the one line (``m.csv line 5, column match: ...``) of a row whose cell has a bad value;
    such a row is failed with it and never run, its other fields what could be read.
    """

    line: int
    name: str
    body: str
    hand: str
    side: str
    band: float | str | None = None  # a fraction, or seconds as text ("10s")
    refine_band: float | str | None = None
    match: tuple[tuple[int, int, float | None], ...] = ()
    refused: str = ""

    def options(self) -> dict:
        """The splice options of this pair (what the done marker compares)."""
        return {
            "side": self.side,
            "band": self.band,
            "refine_band": self.refine_band,
            "match": [list(p) for p in self.match],
        }

    def match_text(self) -> str:
        return ";".join(f"{b}:{h}" + ("" if t is None else f":{t:g}") for b, h, t in self.match)


def read_manifest(path: str | Path) -> list[PairJob]:
    """Parse and validate a manifest CSV (module docstring); raises ManifestError."""
    path = Path(path)
    try:
        raw = path.read_bytes()
    except IsADirectoryError:
        raise ManifestError(path, None, "is a folder, expected a CSV file") from None
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        raise ManifestError(path, line, "not UTF-8 text") from None
    if "\x00" in text:
        raise ManifestError(
            path,
            text.count("\n", 0, text.index("\x00")) + 1,
            "binary data (NUL byte), expected CSV text",
        )
    return parse_manifest(text, path)


def parse_manifest(text: str, path: str | Path) -> list[PairJob]:
    """Validate manifest ``text``; ``path`` names it in errors and anchors relative paths."""
    path = Path(path)
    base = path.resolve().parent
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    header: list[str] | None = None
    jobs: list[PairJob] = []
    names: dict[str, int] = {}
    try:
        for row in reader:
            line = reader.line_num
            if not any(c.strip() for c in row) or row[0].lstrip().startswith("#"):
                continue
            if header is None:
                header = _check_header([c.strip().lower() for c in row], path, line)
                continue
            if len(jobs) >= MAX_MANIFEST_ROWS:
                raise ManifestError(
                    path, line, f"more than {MAX_MANIFEST_ROWS:,} pairs; split the manifest"
                )
            if len(row) > len(header) and any(c.strip() for c in row[len(header) :]):
                raise ManifestError(path, line, f"{len(row)} values for {len(header)} columns")
            cells = {k: (row[i].strip() if i < len(row) else "") for i, k in enumerate(header)}
            job = _parse_row(cells, path, line, base)
            if job.name in names:
                if cells.get("name") == job.name:
                    raise ManifestError(
                        path, line, f"name: {job.name!r} is already used on line {names[job.name]}"
                    )
                job = PairJob(**{**asdict(job), "name": f"{job.name}-line{line}"})
            names[job.name] = line
            jobs.append(job)
    except csv.Error as exc:
        raise ManifestError(path, reader.line_num, f"not valid CSV ({exc})") from None
    if header is None:
        raise ManifestError(
            path,
            None,
            "empty manifest: expected a header row "
            f"({', '.join(REQUIRED_COLUMNS + OPTIONAL_COLUMNS)})",
        )
    if not jobs:
        raise ManifestError(path, None, "no pairs below the header row")
    return jobs


def _check_header(cols: list[str], path: Path, line: int) -> list[str]:
    known = REQUIRED_COLUMNS + OPTIONAL_COLUMNS
    for c in cols:
        if c and c not in known:
            raise ManifestError(
                path, line, f"unknown column {c[:40]!r} (known: {', '.join(known)})"
            )
    seen = set()
    for c in cols:
        if c in seen:
            raise ManifestError(path, line, f"column {c!r} appears twice")
        seen.add(c)
    missing = [c for c in REQUIRED_COLUMNS if c not in cols]
    if missing:
        raise ManifestError(
            path,
            line,
            f"missing column{'s' if len(missing) > 1 else ''} "
            f"{', '.join(missing)} (the header row needs body, "
            "hand, side)",
        )
    return cols


def _parse_row(cells: dict[str, str], path: Path, line: int, base: Path) -> PairJob:
    """One row's pair; a bad value in a cell gives a pair ``refused`` with its one line."""
    try:
        return _read_row(cells, path, line, base)
    except ManifestError as exc:
        return _refused_row(cells, line, base, str(exc))


def _refused_row(cells: dict[str, str], line: int, base: Path, reason: str) -> PairJob:
    """The pair of a row refused for ``reason``: what of it can be shown in the summary
    (the takes' paths, its side as written, its name or the automatic one)."""
    takes = {}
    for key in ("body", "hand"):
        value = cells.get(key, "")
        ok = value and "\x00" not in value and len(value) <= 4096
        takes[key] = str((base / Path(value).expanduser()).resolve()) if ok else value[:200]
    side = " ".join(cells.get("side", "").lower().split())[:40]
    name = cells.get("name", "")
    if not _name_ok(name):
        name = _auto_name(takes["body"] or "body", takes["hand"] or "hand", side or "side")
    return PairJob(
        line=line, name=name, body=takes["body"], hand=takes["hand"], side=side, refused=reason
    )


def _read_row(cells: dict[str, str], path: Path, line: int, base: Path) -> PairJob:
    def fail(column: str, message: str) -> ManifestError:
        return ManifestError(path, line, f"{column}: {message}")

    takes = {}
    for key in ("body", "hand"):
        value = cells.get(key, "")
        if not value:
            raise fail(key, "empty, expected a take file (.bvh, .c3d, .trc)")
        if "\x00" in value or len(value) > 4096:
            raise fail(key, "not a file path")
        takes[key] = str((base / Path(value).expanduser()).resolve())
    side = cells.get("side", "").lower()
    if side not in SIDES:
        raise fail(
            "side", f"expected right, left, both or auto, got {cells.get('side', '')[:40]!r}"
        )
    try:
        band = C.BAND.parse(cells.get("band", ""))
        refine = C.REFINE_BAND.parse(cells.get("refine_band", ""))
        match = tuple((p.body, p.hand, p.tolerance) for p in C.parse_points(cells.get("match", "")))
    except C.ConstraintError as exc:
        if exc.index is not None:  # "m.csv line 3, column match: matching point 2 (...): ..."
            raise ManifestError(path, line, str(exc), column="match") from None
        raise fail(exc.label, exc.detail) from None
    band = None if band is None else band.to_json()
    refine = None if refine is None else refine.to_json()
    name = cells.get("name", "")
    if name:
        if not _name_ok(name):
            raise fail(
                "name",
                f"{name[:40]!r}: use letters, digits and _ . + - only (it becomes a file name)",
            )
    else:
        name = _auto_name(takes["body"], takes["hand"], side)
    return PairJob(
        line=line,
        name=name,
        body=takes["body"],
        hand=takes["hand"],
        side=side,
        band=band,
        refine_band=refine,
        match=match,
    )


def _name_ok(name: str) -> bool:
    """Whether a ``name`` cell can be the pair's output file stem."""
    return bool(name) and not (_NAME_OK.search(name) or name.startswith(".") or len(name) > 120)


def _auto_name(body: str, hand: str, side: str) -> str:
    stem = f"{Path(body).stem}+{Path(hand).stem}-{side}"
    return _NAME_OK.sub("_", stem).strip("._")[:120] or "pair"


# ---------------------------------------------------------------- one pair (runs on a worker)


def input_key(job: PairJob) -> dict:
    """What a done marker must match: both inputs' SHA-256, the options, the engine version."""
    return {
        "body_sha256": file_sha256(job.body),
        "hand_sha256": file_sha256(job.hand),
        "options": job.options(),
        "engine": __version__,
    }


def outputs_of(job: PairJob, outdir: Path) -> dict[str, Path]:
    return {
        "output": outdir / f"{job.name}.bvh",
        "report": outdir / f"{job.name}.report.json",
        "thumbnail": outdir / f"{job.name}.png",
    }


def marker_path(job: PairJob, outdir: Path) -> Path:
    return outdir / MARKER_DIR / f"{job.name}.json"


def missing_input(job: PairJob) -> str | None:
    """``PATH: no such file`` for the first of the pair's takes that is not a file (the
    ``splice`` command's words), None when both are there."""
    for path in (job.body, job.hand):
        if not Path(path).is_file():
            return f"{path}: no such file"
    return None


def is_done(job: PairJob, outdir: Path) -> dict | None:
    """The done marker of ``job`` if it is current (same inputs and options, outputs present)."""
    path = marker_path(job, outdir)
    try:
        marker = parse_json(path.read_bytes(), finite=False)
        key = input_key(job)
    except (OSError, ValueError):  # JsonTextError is a ValueError
        return None
    if not isinstance(marker, dict) or marker.get("key") != key:
        return None
    outs = marker.get("outputs", {})
    if not all((outdir / rel).is_file() for rel in outs.values()):
        return None
    return marker


def run_pair(
    job: PairJob,
    outdir: str | Path,
    thumbnails: str = "render",
    splice: Callable | None = None,
    seconds: float | None = PAIR_SECONDS,
    memory_mb: float | None = PAIR_MEMORY_MB,
) -> dict:
    """Splice one pair and write its outputs; never raises (errors go into the record).

    The pair runs in a forked child process (``engine.jobs.sandbox``) stopped after
    ``seconds`` of wall time or beyond ``memory_mb`` MB of resident memory (``None`` or
    0: no limit); a stopped pair is recorded as failed and leaves no partial outputs.

    Returns the pair's summary record (``SUMMARY_COLUMNS``) with ``status`` ``"done"``
    or ``"failed"`` and, when failed, a one-line ``error``.
    """
    from engine.jobs.sandbox import ChildFailed, LimitExceeded, run_limited

    t0 = time.perf_counter()
    try:
        if seconds or memory_mb:
            record = run_limited(
                _run_pair_here,
                (job, outdir, thumbnails, splice),
                seconds=seconds,
                memory_mb=memory_mb,
            )
        else:
            record = _run_pair_here(job, outdir, thumbnails, splice)
    except (LimitExceeded, ChildFailed) as exc:
        record = _base_record(job)
        why = f"the pair {exc}" if isinstance(exc, LimitExceeded) else f"the pair's {exc}"
        record.update(status="failed", error=why[:500], seconds=f"{time.perf_counter() - t0:.2f}")
    if (
        memory_mb
        and record.get("status") == "failed"
        and str(record.get("error", "")).startswith("MemoryError")
    ):  # RLIMIT_DATA in the child
        record["error"] = (
            f"the pair used more than the memory limit of {memory_mb:g} MB ({record['error']})"
        )[:500]
    record["worker"] = f"{platform.node()}:{os.getpid()}"
    return record


def _run_pair_here(
    job: PairJob, outdir: str | Path, thumbnails: str = "render", splice: Callable | None = None
) -> dict:
    """``run_pair`` in this process, without limits."""
    outdir = Path(outdir)
    t0 = time.perf_counter()
    record = _base_record(job)
    try:
        key = input_key(job)  # hashed before reading: a file changed meanwhile reruns next time
        from engine.io import load_take

        body = load_take(job.body)
        hand = load_take(job.hand)
        notes = reader_notes(body, hand) + side_notes(job, hand)
        if notes:  # kept on a failed pair too: they may say why it failed
            record["notes"] = NOTE_SEPARATOR.join(notes)
        motion, report = (splice or splice_pair)(body, hand, job)
        outs = outputs_of(job, outdir)
        from engine.io.bvh import iter_bvh

        report = dict(report)
        report["output"] = outs["output"].name
        if notes:
            report["reader_notes"] = list(notes)
        report.setdefault(
            "batch",
            {
                "name": job.name,
                "line": job.line,
                "body": job.body,
                "hand": job.hand,
                **job.options(),
            },
        )
        # the spliced take and its report: both replaced, or neither
        write_texts(
            [
                (outs["output"], iter_bvh(motion)),
                (outs["report"], json.dumps(_jsonable(report)) + "\n"),
            ]
        )
        kind = "none"
        if thumbnails != "none":
            kind = write_thumbnail(motion, outs["thumbnail"], prefer=thumbnails)
        written = {k: p.name for k, p in outs.items() if k != "thumbnail" or kind != "none"}
        record.update(
            status="done",
            body_frames=body.n_frames,
            spliced_frames=motion.n_frames,
            fps=f"{motion.fps:g}",
            thumbnail_kind=kind,
            **written,
        )
        record["seconds"] = f"{time.perf_counter() - t0:.2f}"
        marker = {
            "key": key,
            "outputs": written,
            "record": record,
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S"),
        }
        write_text(marker_path(job, outdir), json.dumps(marker, indent=1) + "\n")
    except Exception as exc:  # one failing pair never stops the batch
        record.update(
            status="failed", error=one_line(exc), seconds=f"{time.perf_counter() - t0:.2f}"
        )
        if not isinstance(exc, HandSpliceError | ValueError | OSError | KeyError):
            record["error"] += " [" + _where(exc) + "]"
    return record


#: between a pair's reader notes in its one summary cell
NOTE_SEPARATOR = " | "


def side_notes(job: PairJob, hand) -> tuple[str, ...]:
    """The warning for a hand take whose names carry no side, spliced (side ``auto``) as
    the hand its geometry forms (``engine.model.hand_side.unnamed_side_warning``), or whose
    file name says the other side than its joint names (``engine.model.roles.hand_file_side``),
    as ``handsplice splice`` says them on stderr, carried as the reader notes are."""
    from engine.model.hand_side import unnamed_side_warning
    from engine.model.motion import Motion
    from engine.model.roles import hand_file_side

    if not isinstance(hand, Motion):
        return ()
    name = Path(job.hand).name
    named = hand_file_side(name, hand.skeleton)  # a name saying the other side: as splice
    if named.warning and job.side in (None, "auto", named.side):
        return (named.warning,)
    if job.side in ("right", "left"):
        return ()
    text = unnamed_side_warning(name, hand, None, "set its side column to {side}")
    return (text,) if text else ()


def reader_notes(*takes) -> tuple[str, ...]:
    """What the readers accepted but a user should know (``meta.notes``, e.g. ``"markers.trc:
    the header says 652 frames, 93 were read"``), each once, as ``handsplice splice`` prints
    them on stderr: the pair's report (``reader_notes``), its ``notes`` in summary.csv and
    index.html (escaped), and a ``note:`` line in the progress carry them."""
    out: list[str] = []
    for take in takes:
        for note in getattr(getattr(take, "meta", None), "notes", ()) or ():
            text = " ".join(str(note).split())[:500]
            if text and text not in out:
                out.append(text)
    return tuple(out)


def splice_pair(body, hand, job: PairJob):
    """The default splice of one pair: ``engine.splice.pipeline.splice`` with the job's options.

    Matching points are ``(body frame, hand frame[, tol])`` in frames of the original
    takes, as ``handsplice splice --match`` reads them. A marker body (C3D/TRC) gives the
    hand take retimed to it, as ``handsplice splice`` does. Returns ``(Motion, report dict)``
    with the report of :func:`engine.splice.report.build_report`.
    """
    from engine.splice.report import build_report
    from engine.splice.retime import splice_takes
    from engine.trust import assess_splice

    options = {"side": job.side}
    if job.band is not None:
        options["band"] = job.band
    if job.refine_band is not None:
        options["refine_band"] = job.refine_band
    points = [(b, h, 0.0 if t is None else t) for b, h, t in job.match]
    try:
        # a marker body (C3D/TRC) gives the hand take retimed to it, as handsplice splice
        result, _ = splice_takes(body, hand, points=points, hand_points=True, **options)
    except C.ConstraintError as exc:  # a point that does not fit these takes: its cell named
        if exc.index is None:
            raise
        raise ParameterError(f"line {job.line}, column match: {exc}") from None
    trust = assess_splice(result.features, result.alignment)
    return result.motion, build_report(
        result, job.body, job.hand, points_given=points, assessment=trust
    )


def one_line(exc: BaseException) -> str:
    """The error's first line, in the CLI's words: a file error is ``PATH: no such file``
    (no Python class name); other non-HandSplice errors keep their class name."""
    text = str(exc).strip()
    named_file = isinstance(exc, OSError) and getattr(exc, "filename", None)
    if named_file:
        text = f"{exc.filename}: {exc.strerror or text}"
    first = first_line(text)
    name = type(exc).__name__
    if not isinstance(exc, HandSpliceError) and not named_file:
        first = f"{name}: {first}" if first else name
    return first


def _where(exc: BaseException) -> str:
    frames = traceback.extract_tb(exc.__traceback__)
    if not frames:
        return type(exc).__name__
    f = frames[-1]
    return f"{Path(f.filename).name}:{f.lineno}"


def _base_record(job: PairJob) -> dict:
    rec = dict.fromkeys(SUMMARY_COLUMNS, "")
    rec.update(
        name=job.name,
        line=job.line,
        body=job.body,
        hand=job.hand,
        side=job.side,
        band="" if job.band is None else C.BAND.parse(job.band).text(),
        refine_band="" if job.refine_band is None else C.REFINE_BAND.parse(job.refine_band).text(),
        match=job.match_text(),
    )
    return rec


def _jsonable(x: Any) -> Any:
    """numpy arrays and scalars to lists and numbers (reports may carry them)."""
    import numpy as np

    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    if isinstance(x, str | int | float | bool | type(None)):
        return x
    return str(x)  # an engine object (e.g. a transfer plan): its description


# ---------------------------------------------------------------- thumbnails


def write_thumbnail(motion, path: Path, prefer: str = "render", frame: int | None = None) -> str:
    """Write a PNG thumbnail of ``motion`` (middle frame); returns ``"render"`` or ``"stick"``.

    ``prefer="render"`` uses the skinned mannequin of :mod:`engine.render` and falls back
    to a plain stick figure (PIL) where OpenGL is unavailable; ``"stick"`` draws the
    stick figure directly.
    """
    i = motion.n_frames // 2 if frame is None else frame
    if prefer == "render":
        try:
            from engine.render.offscreen import Preview
            from engine.render.video import write_image

            image = Preview(motion, size=THUMB_SIZE).frame(i, camera="three-quarter")
            with atomic_path(path) as tmp:
                write_image(image, tmp)
            return "render"
        except Exception:  # no OpenGL on this worker: the stick figure below
            pass
    with atomic_path(path) as tmp:
        stick_figure_png(motion, tmp, i)
    return "stick"


def stick_figure_png(motion, path: Path, frame: int, size: tuple[int, int] = THUMB_SIZE) -> None:
    """A front-view stick figure of one frame (no OpenGL): bones as lines, PIL PNG."""
    import numpy as np
    from PIL import Image, ImageDraw

    from engine.model.kinematics import forward_kinematics

    pos, _ = forward_kinematics(motion, frame, frame + 1)
    p = pos[0]
    up = 2 if motion.meta.up_axis == "z" else 1
    horiz = 0
    xy = np.stack([p[:, horiz], p[:, up]], axis=1)
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    span = float(max(hi[0] - lo[0], hi[1] - lo[1], 1e-9))
    w, h = size
    scale = 0.9 * min(w, h) / span
    centre = (lo + hi) / 2
    px = (xy - centre) * scale
    px[:, 0] += w / 2
    px[:, 1] = h / 2 - px[:, 1]
    img = Image.new("RGB", size, (245, 245, 247))
    draw = ImageDraw.Draw(img)
    for j, parent in enumerate(motion.skeleton.parents):
        if parent >= 0:
            draw.line([tuple(px[parent]), tuple(px[j])], fill=(40, 70, 140), width=2)
    img.save(path, format="PNG")


# ---------------------------------------------------------------- the batch


@dataclass
class BatchResult:
    records: list[dict] = field(default_factory=list)
    summary_csv: Path | None = None
    index_html: Path | None = None
    seconds: float = 0.0

    def count(self, status: str) -> int:
        return sum(1 for r in self.records if r["status"] == status)


def run_batch(
    manifest: str | Path,
    outdir: str | Path,
    scheduler: str | None = None,
    workers: int = 2,
    thumbnails: str = "render",
    progress=None,
    client=None,
    splice: Callable | None = None,
    pair_seconds: float | None = PAIR_SECONDS,
    pair_memory_mb: float | None = PAIR_MEMORY_MB,
) -> BatchResult:
    """Run every pair of ``manifest`` into ``outdir`` (module docstring).

    Parameters
    ----------
    scheduler : address of an existing dask scheduler (``tcp://host:8786``); None starts
        an embedded ``LocalCluster(processes=True, n_workers=workers, threads_per_worker=1)``
    workers : worker processes of the embedded cluster (>= 1)
    thumbnails : ``"render"`` (mannequin, stick fallback), ``"stick"`` or ``"none"``
    progress : a text stream for progress lines (e.g. ``sys.stderr``); None is silent
    client : an existing ``distributed.Client`` (tests); overrides ``scheduler``
    splice : ``f(body, hand, job) -> (Motion, report dict)`` instead of :func:`splice_pair`
        (must be picklable for the workers)
    pair_seconds, pair_memory_mb : limits of one pair (wall seconds, resident MB; None or
        0: none); a pair beyond them is stopped and recorded as failed

    ``summary.csv`` is rewritten as pairs finish (finished pairs, manifest order; at most
    once a second), and complete at the end with ``index.html``.
    """
    t0 = time.perf_counter()
    if thumbnails not in ("render", "stick", "none"):
        raise HandSpliceError(f"thumbnails: expected render, stick or none, got {thumbnails!r}")
    if client is None and scheduler is None and not (isinstance(workers, int) and workers >= 1):
        raise HandSpliceError(f"--workers: expected a whole number >= 1, got {workers!r}")
    for label, value in (("pair_seconds", pair_seconds), ("pair_memory_mb", pair_memory_mb)):
        if value is not None and not (
            isinstance(value, int | float) and math.isfinite(value) and value >= 0
        ):
            raise HandSpliceError(f"{label}: expected a number >= 0 (0: no limit), got {value!r}")
    jobs = read_manifest(manifest)
    outdir = Path(outdir).resolve()
    outdir.mkdir(parents=True, exist_ok=True)
    for folder in (outdir, outdir / MARKER_DIR):  # temporary files of a killed run
        clean_stale(folder)
    show = Progress(len(jobs), progress)

    records: dict[str, dict] = {}
    todo: list[PairJob] = []
    for job in jobs:
        # a bad cell, or a take that is not there: failed before any cluster starts, in the
        # words `splice` uses; the other pairs run (a failing pair never stops the batch)
        missing = job.refused or missing_input(job)
        if missing:
            rec = {**_base_record(job), "status": "failed", "error": missing, "seconds": "0.00"}
            records[job.name] = rec
            show.update(rec)
            continue
        marker = is_done(job, outdir)
        if marker is not None:
            rec = {
                **_base_record(job),
                **marker.get("record", {}),
                "status": "skipped",
                "line": job.line,
            }
            records[job.name] = rec
            show.update(rec)
        else:
            todo.append(job)

    summary = _SummaryWriter(jobs, records, outdir / "summary.csv")
    if todo:
        limits = (pair_seconds, pair_memory_mb)
        for rec in _run_on_dask(
            todo,
            outdir,
            thumbnails,
            scheduler,
            workers,
            client,
            show,
            splice,
            limits,
            on_record=summary.add,
        ):
            records[rec["name"]] = rec
    ordered = [records[j.name] for j in jobs]
    result = BatchResult(records=ordered, seconds=time.perf_counter() - t0)
    result.summary_csv = write_summary_csv(ordered, outdir / "summary.csv")
    result.index_html = write_index_html(
        ordered, outdir / "index.html", Path(manifest).name, result.seconds
    )
    show.finish(result)
    return result


class _SummaryWriter:
    """``summary.csv`` rewritten (atomically) as pairs finish: at most once per ``every_s``."""

    def __init__(
        self, jobs: list[PairJob], records: dict[str, dict], path: Path, every_s: float = 1.0
    ):
        self.jobs, self.records, self.path, self.every_s = jobs, records, path, every_s
        self.last = -math.inf

    def add(self, rec: dict) -> None:
        self.records[rec["name"]] = rec
        now = time.monotonic()
        if now - self.last >= self.every_s:
            self.last = now
            write_summary_csv(
                [self.records[j.name] for j in self.jobs if j.name in self.records], self.path
            )


def _run_on_dask(
    todo: list[PairJob],
    outdir: Path,
    thumbnails: str,
    scheduler: str | None,
    workers: int,
    client,
    show: Progress,
    splice: Callable | None,
    limits: tuple = (PAIR_SECONDS, PAIR_MEMORY_MB),
    on_record: Callable | None = None,
) -> list[dict]:
    from distributed import Client, as_completed

    own_cluster = own_client = None
    try:
        if client is None:
            if scheduler:
                client = own_client = Client(scheduler, timeout="30s")
            else:
                show.note(
                    f"starting a local Dask cluster: {workers} worker process"
                    f"{'es' if workers > 1 else ''}"
                )
                own_cluster = local_cluster(workers)
                client = own_client = Client(own_cluster)
        # at most one pair per worker thread is handed to the cluster at a time: a pair
        # never waits in a worker's queue, so a pair that kills its worker process (a
        # segfault, the OOM killer) takes no other pair down with it
        pending = list(reversed(todo))
        running: dict = {}
        done_iter = as_completed()
        batch_id = f"{os.getpid()}-{time.time_ns()}"

        def fill() -> None:
            while pending and len(running) < _capacity(client):
                job = pending.pop()
                fut = client.submit(
                    run_pair,
                    job,
                    str(outdir),
                    thumbnails,
                    splice,
                    *limits,
                    pure=False,
                    key=f"handsplice_pair-{batch_id}-{len(todo) - len(pending)}",
                )
                running[fut] = job
                done_iter.add(fut)

        fill()
        out = []
        for fut in done_iter:
            job = running.pop(fut)
            try:
                rec = fut.result()
            except Exception as exc:  # a worker died (KilledWorker), a cancelled task...
                why = one_line(exc)
                if type(exc).__name__ == "KilledWorker":
                    why = (
                        "its worker process died while splicing it (a crash or out of "
                        "memory), also when retried"
                    )
                rec = {
                    **_base_record(job),
                    "status": "failed",
                    "error": f"the task did not finish: {why}",
                }
            out.append(rec)
            show.update(rec)
            if on_record is not None:
                on_record(rec)
            fut.release()
            fill()
        return out
    finally:
        if own_client is not None:
            own_client.close()
        if own_cluster is not None:
            own_cluster.close()


def _capacity(client) -> int:
    """Worker threads of the cluster now (at least 1, so a batch waits for workers)."""
    try:
        workers = client.scheduler_info(n_workers=-1)["workers"].values()
    except TypeError:  # older distributed: no n_workers argument
        workers = client.scheduler_info()["workers"].values()
    return max(1, sum(int(w.get("nthreads", 1)) for w in workers))


#: scheduler settings of the embedded cluster (see :func:`local_cluster`)
LOCAL_SCHEDULER_CONFIG = {
    # one task per single-threaded worker at a time (the batch also submits no more
    # pairs than there are worker threads)
    "distributed.scheduler.worker-saturation": 1.0,
    # a pair whose worker died is tried once more (a transient loss), then recorded as
    # failed, instead of taking down four workers in a row
    "distributed.scheduler.allowed-failures": 1,
}


def local_cluster(workers: int, config: dict | None = None, **kwargs):
    """The embedded cluster: ``workers`` processes of one thread, no dashboard.

    The scheduler's HTTP endpoint listens on a free port (not 8787), so batches run
    side by side (or beside another Dask cluster) start without a port clash.
    ``config`` adds to :data:`LOCAL_SCHEDULER_CONFIG` (read when the scheduler starts).
    """
    import logging

    import dask
    from distributed import LocalCluster

    with dask.config.set({**LOCAL_SCHEDULER_CONFIG, **(config or {})}):
        return LocalCluster(
            n_workers=workers,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            scheduler_kwargs={"dashboard_address": ":0"},
            silence_logs=logging.ERROR,
            **kwargs,
        )


class Progress:
    """Progress lines on a stream: one per pair, a status line on a terminal."""

    def __init__(self, total: int, stream=None):
        self.total = total
        self.stream = stream
        self.done = 0
        self.counts = {"done": 0, "skipped": 0, "failed": 0}
        self.t0 = time.perf_counter()

    def note(self, text: str) -> None:
        if self.stream is not None:
            print(f"handsplice batch: {text}", file=self.stream, flush=True)

    def update(self, rec: dict) -> None:
        self.done += 1
        self.counts[rec["status"]] = self.counts.get(rec["status"], 0) + 1
        if self.stream is None:
            return
        elapsed = time.perf_counter() - self.t0
        ran = self.done - self.counts["skipped"]
        left = self.total - self.done
        eta = ""
        if ran and left:
            eta = f", ~{_clock(elapsed / max(ran, 1) * left)} left"
        what = rec["status"]
        if rec["status"] == "failed":
            what += f": {rec['error']}"
        elif rec.get("seconds"):
            what += f" ({rec['seconds']} s)"
        print(
            f"[{self.done}/{self.total}] {rec['name']}: {what}  ({_clock(elapsed)} elapsed{eta})",
            file=self.stream,
            flush=True,
        )
        for note in filter(None, str(rec.get("notes") or "").split(NOTE_SEPARATOR)):
            print(f"handsplice batch: note: {rec['name']}: {note}", file=self.stream, flush=True)

    def finish(self, result: BatchResult) -> None:
        self.note(
            f"{result.count('done')} done, {result.count('skipped')} skipped, "
            f"{result.count('failed')} failed in {_clock(result.seconds)}; "
            f"summary: {result.summary_csv}"
        )


def _clock(seconds: float) -> str:
    s = int(round(seconds))
    return (
        f"{s // 3600}:{s // 60 % 60:02d}:{s % 60:02d}" if s >= 3600 else f"{s // 60}:{s % 60:02d}"
    )


# ---------------------------------------------------------------- summary


def write_summary_csv(records: list[dict], path: Path) -> Path:
    buf = io.StringIO(newline="")
    writer = csv.DictWriter(
        buf, fieldnames=SUMMARY_COLUMNS, extrasaction="ignore", lineterminator="\n"
    )
    writer.writeheader()
    for rec in records:
        writer.writerow(rec)
    write_text(path, buf.getvalue())
    return path


_STATUS_COLOUR = {"done": "#2e7d32", "skipped": "#1565c0", "failed": "#c62828"}


def write_index_html(records: list[dict], path: Path, manifest_name: str, seconds: float) -> Path:
    """A static page: one row per pair with its thumbnail, status, links and error."""
    esc = html.escape
    rows = []
    for rec in records:
        thumb = rec.get("thumbnail") or ""
        img = (
            f'<img src="{esc(thumb)}" width="{THUMB_SIZE[0]}" height="{THUMB_SIZE[1]}" '
            f'alt="{esc(rec["name"])}">'
            if thumb
            else ""
        )
        links = " ".join(
            f'<a href="{esc(rec[k])}">{label}</a>'
            for k, label in (("output", "BVH"), ("report", "report"))
            if rec.get(k)
        )
        colour = _STATUS_COLOUR.get(rec["status"], "#333")
        detail = esc(rec.get("error") or "")
        if not detail and rec.get("spliced_frames"):
            detail = f"{esc(str(rec['spliced_frames']))} frames at {esc(str(rec['fps']))} fps"
            if rec.get("seconds"):
                detail += f", {esc(str(rec['seconds']))} s"
        if rec.get("notes"):  # the readers' notes name the user's files: escaped
            notes = str(rec["notes"]).split(NOTE_SEPARATOR)
            detail += "".join(f"<br><small>note: {esc(n)}</small>" for n in notes)
        rows.append(
            f"<tr><td>{img}</td><td><b>{esc(rec['name'])}</b><br><small>line {rec['line']}: "
            f"{esc(Path(rec['body']).name)} + {esc(Path(rec['hand']).name)}, "
            f"{esc(rec['side'])}</small></td>"
            f'<td style="color:{colour}"><b>{esc(rec["status"])}</b></td>'
            f"<td>{detail}</td><td>{links}</td></tr>"
        )
    counts = {s: sum(1 for r in records if r["status"] == s) for s in ("done", "skipped", "failed")}
    page = f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8"><title>HandSplice batch: {esc(manifest_name)}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; }}
table {{ border-collapse: collapse; }}
td {{ border-bottom: 1px solid #ddd; padding: 6px 10px; vertical-align: middle; }}
</style></head><body>
<h1>HandSplice batch: {esc(manifest_name)}</h1>
<p>{len(records)} pairs: {counts["done"]} done, {counts["skipped"]} skipped (done before),
{counts["failed"]} failed; {seconds:.1f} s. Table as CSV: <a href="summary.csv">summary.csv</a>.</p>
<table>
<tr><th>thumbnail</th><th>pair</th><th>status</th><th>result</th><th>files</th></tr>
{chr(10).join(rows)}
</table></body></html>
"""
    write_text(path, page)
    return path
