"""Size limits on outside input, in one place, checked before anything is allocated.

Readers and the server refuse input beyond these with a one-line message
(``MotionFormatError`` / ``UploadError`` / ``SessionError`` / ``ParameterError``)
instead of trying to hold it in memory or computing with it. The numbers are far
above any real capture (the longest shared take is 4,587 frames; a 2-minute 120 fps
take is 14,400; the largest skeleton, BEAT's, has 75 joints and is 12 deep; real
frame rates lie in 24-480) and far below what would exhaust memory on a small
server: a capture file under 1 MB is either refused or read, analysed, spliced and
rendered within 1 GB (``benchmarks/bench_fuzz.py`` measures it).

What costs memory is not the size of a file but what it makes us hold:

* poses: ``frames x joints`` (7 floats each, twice more for forward kinematics).
  A joint without channels costs nothing in the file but the same in memory, so
  ``Frames: 2000000`` over a skeleton with ``CHANNELS 0`` is a 1 kB file asking for
  gigabytes. Poses are bounded by ``MAX_POSE_CELLS``, or by half the file's bytes for
  larger files (every joint that carries data costs at least 2 bytes a frame, ``"0 "``).
* the alignment grid: the hand take resampled to the body's rate
  (``(frames - 1) * body_fps / hand_fps + 1``); a take with ``Frame Time: 300`` next
  to a 30 fps body is 9,000 times longer on the grid. Bounded by ``MAX_GRID_FRAMES``.
* DTW band cells (``MAX_BAND_CELLS``, one byte each in a one-shot solve).

``check_take``, ``check_rate``, ``check_grid`` and ``check_band`` are the checks;
every reader and the splice pipeline call them.
"""

from __future__ import annotations

from engine.base.errors import MotionFormatError, ParameterError

#: joints in one skeleton (BVH).
MAX_JOINTS = 1_000
#: nesting depth of a skeleton (joints on the longest root-to-leaf chain; real ones: <= 30).
MAX_DEPTH = 100
#: frames (data rows) in one take, any format: 4.6 hours at 120 fps.
MAX_FRAMES = 2_000_000
#: markers in one marker set (C3D, TRC).
MAX_MARKERS = 10_000
#: frame rate range, frames per second (a BVH ``Frame Time`` outside 0.1 ms .. 1 s is refused).
MIN_FPS = 1.0
MAX_FPS = 10_000.0
#: length of one take in seconds (frames / fps): 6 hours.
MAX_DURATION_S = 6 * 3600.0
#: frames x joints (or markers) held as poses for a file under ``2 * MAX_POSE_CELLS`` bytes;
#: about 110 MB of local poses, under 1 GB through the whole splice.
MAX_POSE_CELLS = 2_000_000
#: frames x channels (data values) of one take: 800 MB of float64.
MAX_VALUES = 100_000_000
#: frames of a take resampled to another rate (the alignment grid): 69 minutes at 120 fps.
MAX_GRID_FRAMES = 500_000
#: cells of one DTW band (one byte each in a one-shot solve, ~18 kept incrementally).
MAX_BAND_CELLS = 200_000_000
#: magnitude of any offset, position or angle value in a capture file (file units or
#: degrees); larger values overflow forward kinematics and are never real.
MAX_ABS_VALUE = 1e9
#: bytes of one uploaded capture file (the web app; sent in chunks): a 10-minute
#: 120 fps BVH with fingers is about 250 MB, a 2-minute one about 50 MB.
MAX_UPLOAD_BYTES = 200 * 1024 * 1024
#: bytes of one session JSON file.
MAX_SESSION_BYTES = 4 * 1024 * 1024
#: bytes of one JSON file of joint-role overrides (``--roles``).
MAX_ROLES_BYTES = 1024 * 1024
#: bytes of one ELAN annotation file (a take's phases: a few kB).
MAX_EAF_BYTES = 16 * 1024 * 1024
#: bytes of a GLB's JSON chunk read by ``handsplice info`` (HandSplice's: tens of kB).
MAX_GLB_JSON_BYTES = 64 * 1024 * 1024
#: rows of a batch manifest.
MAX_MANIFEST_ROWS = 100_000
#: default limits of one batch pair (``handsplice batch --pair-seconds/--pair-memory-mb``):
#: wall time in seconds and resident memory in MB of the process splicing it.
PAIR_SECONDS = 900.0
PAIR_MEMORY_MB = 2048.0


def check_rate(
    fps: float, source: str | None, line: int | None = None, field: str = "frame rate"
) -> float:
    """``fps`` if it lies in ``MIN_FPS..MAX_FPS``, else ``MotionFormatError`` naming ``field``."""
    fps = float(fps)
    if not (MIN_FPS <= fps <= MAX_FPS):  # also NaN
        raise MotionFormatError(
            source,
            f"{field} gives {fps:.6g} frames per second; expected {MIN_FPS:g} to {MAX_FPS:g}",
            line=line,
        )
    return fps


def pose_budget(source_bytes: int = 0) -> int:
    """Most ``frames x joints`` a file of ``source_bytes`` bytes may ask for."""
    return max(MAX_POSE_CELLS, int(source_bytes) // 2)


def check_take(
    source: str | None,
    frames: int,
    fps: float,
    joints: int,
    values: int = 0,
    source_bytes: int = 0,
    line: int | None = None,
    what: str = "joints",
) -> None:
    """Refuse a take whose header asks for more than the limits, before reading its data.

    Parameters
    ----------
    source : file name for the message
    frames, fps : the take's frame count and rate (frames per second)
    joints : joints of the skeleton (or markers of a marker set: ``what="markers"``)
    values : data values per frame (BVH channels; 3 per marker)
    source_bytes : size of the file (larger files may hold more poses, see ``pose_budget``)
    line : the line the frame count was read from

    Raises ``MotionFormatError`` ("walk.bvh line 300: 2,000,000 frames x 1,000 joints ...").
    """
    check_rate(fps, source, line)
    if frames > MAX_FRAMES:
        raise MotionFormatError(
            source,
            f"{frames:,} frames is more than {MAX_FRAMES:,}; refusing an absurd take",
            line=line,
        )
    if frames / fps > MAX_DURATION_S:
        raise MotionFormatError(
            source,
            f"{frames:,} frames at {fps:.6g} fps last {frames / fps / 3600:.3g} hours, "
            f"more than {MAX_DURATION_S / 3600:g}; refusing an absurd take",
            line=line,
        )
    if frames * values > MAX_VALUES:
        raise MotionFormatError(
            source,
            f"{frames:,} frames x {values:,} values is more than {MAX_VALUES:,} values; "
            "refusing an absurd take",
            line=line,
        )
    budget = pose_budget(source_bytes)
    if frames * joints > budget:
        raise MotionFormatError(
            source,
            f"{frames:,} frames x {joints:,} {what} is more than {budget:,} poses for a "
            f"file of {source_bytes:,} bytes; refusing an absurd take",
            line=line,
        )


def resampled_length(frames: int, fps: float, target_fps: float) -> int:
    """Frames of a ``frames``-long take at ``fps`` resampled to ``target_fps`` (same span)."""
    if frames <= 0:
        return 0
    return max(1, int(round((frames - 1) * float(target_fps) / float(fps))) + 1)


def check_grid(name: str, frames: int, fps: float, target_fps: float) -> int:
    """Length of ``name`` resampled to ``target_fps``, or ``ParameterError`` beyond the limit."""
    n = resampled_length(frames, fps, target_fps)
    if n > MAX_GRID_FRAMES:
        raise ParameterError(
            f"{name}: {frames:,} frames at {fps:.6g} fps resampled to {target_fps:.6g} fps make "
            f"{n:,} frames, more than {MAX_GRID_FRAMES:,}; refusing (check the files' frame "
            "times)"
        )
    return n


def check_band(what: str, cells: int) -> None:
    """``ParameterError`` when a DTW band of ``cells`` cells is beyond ``MAX_BAND_CELLS``."""
    if cells > MAX_BAND_CELLS:
        raise ParameterError(
            f"{what}: the band has {cells:,} cells, more than {MAX_BAND_CELLS:,}; narrow the "
            "band or splice shorter takes"
        )
