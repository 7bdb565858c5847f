"""Image and video output: PNG frame, contact sheet, GIF, MP4 (all written atomically).

``write_image``, ``contact_sheet``, ``write_gif``, ``write_mp4`` take rendered
``(H, W, 3) uint8`` frames; ``render_to_file(preview, path, ...)`` renders a frame
range of a :class:`engine.render.offscreen.Preview` straight to ``.png`` (one
frame, or a contact sheet of a range), ``.gif`` or ``.mp4``, reporting progress
through ``progress(done, total)``. MP4 is H.264 (yuv420p) through imageio-ffmpeg's
bundled ffmpeg; odd frame sizes are padded by one pixel.
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable, Iterable, Sequence
from pathlib import Path

import numpy as np

from engine.base.atomic import atomic_path, write_bytes
from engine.base.errors import ParameterError

Progress = Callable[[int, int], None]
FORMATS = (".png", ".gif", ".mp4")


def _as_frame(image: np.ndarray, field: str = "image") -> np.ndarray:
    arr = np.asarray(image)
    if arr.ndim != 3 or arr.shape[2] not in (3, 4) or arr.dtype != np.uint8:
        raise ValueError(f"{field}: expected an (H, W, 3) uint8 image, got {arr.shape} {arr.dtype}")
    return arr[..., :3]


def write_image(image: np.ndarray, path: str | Path) -> Path:
    """Write ``image (H, W, 3) uint8`` as PNG (or any format Pillow knows by suffix)."""
    from PIL import Image

    path = Path(path)
    img = _as_frame(image)
    with atomic_path(path) as tmp:
        Image.fromarray(img).save(tmp, format=None if path.suffix else "PNG")
    return path


def to_png_bytes(image: np.ndarray) -> bytes:
    """PNG bytes of ``image (H, W, 3) uint8`` (for a web page or a download)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(_as_frame(image)).save(buf, format="PNG")
    return buf.getvalue()


def contact_sheet(
    images: Sequence[np.ndarray],
    columns: int | None = None,
    labels: Sequence[str] | None = None,
    gap: int = 4,
    background: int = 255,
) -> np.ndarray:
    """Tile images (each ``(H, W, 3) uint8``, sizes may differ) in rows of ``columns``.

    ``labels`` are written in each tile's top-left corner. Returns ``(H, W, 3) uint8``.
    """
    if not images:
        raise ValueError("contact_sheet: no images")
    tiles = [_as_frame(im, f"images[{k}]") for k, im in enumerate(images)]
    if labels is not None:
        from engine.render.offscreen import label_image

        if len(labels) != len(tiles):
            raise ValueError(f"contact_sheet: {len(labels)} labels for {len(tiles)} images")
        tiles = [label_image(t, lab) for t, lab in zip(tiles, labels, strict=True)]
    n = len(tiles)
    cols = columns or int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / cols))
    th = max(t.shape[0] for t in tiles)
    tw = max(t.shape[1] for t in tiles)
    sheet = np.full(
        (rows * th + (rows + 1) * gap, cols * tw + (cols + 1) * gap, 3), background, np.uint8
    )
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        y, x = gap + r * (th + gap), gap + c * (tw + gap)
        sheet[y : y + t.shape[0], x : x + t.shape[1]] = t
    return sheet


GIF_MIN_DELAY_CS = 2  # browsers play shorter GIF frame delays (0-1 cs) as 10 cs


def gif_schedule(n: int, fps: float) -> tuple[list[int], list[int]]:
    """Which of ``n`` frames at ``fps`` a GIF keeps, and each kept frame's delay in ms.

    GIF delays are whole centiseconds: frame k is shown from ``round(100 k / fps)`` cs
    (cumulative rounding), so the delays differ by at most 1 cs and the total is
    ``round(100 n / fps)`` cs exactly (a fixed rounded delay drifts: 30 ms frames at
    30 fps play 10 % fast). Above 50 fps a frame starting less than
    ``GIF_MIN_DELAY_CS`` after the last kept one is dropped. Returns
    ``(kept frame indices, delays in ms)``.
    """
    if not fps > 0:
        raise ParameterError(f"fps {fps}: must be positive")
    if n < 1:
        raise ValueError("gif_schedule: no frames")
    starts = [int(round(100.0 * k / fps)) for k in range(n)] + [int(round(100.0 * n / fps))]
    kept = [0]
    for k in range(1, n):
        if starts[k] - starts[kept[-1]] >= GIF_MIN_DELAY_CS:
            kept.append(k)
    while len(kept) > 1 and starts[n] - starts[kept[-1]] < GIF_MIN_DELAY_CS:
        kept.pop()  # the last kept frame too short: the one before lasts to the end
    ends = [starts[k] for k in kept[1:]] + [starts[n]]
    delays = [10 * (end - starts[k]) for k, end in zip(kept, ends)]
    delays[-1] = max(delays[-1], 10 * GIF_MIN_DELAY_CS)  # only a take shorter than 2 cs
    return kept, delays


def gif_frame(image: np.ndarray):
    """``image (H, W, 3) uint8`` as the palette image a GIF stores (a Pillow "P" image:
    its own 256 colours by median cut, exactly what Pillow's GIF writer makes of an RGB
    frame). Quantising each frame as it is rendered spreads the encoder's main cost
    over the render, so a progress bar at its end means the file is nearly written."""
    from PIL import Image

    return Image.fromarray(_as_frame(image)).convert("P", palette=Image.Palette.ADAPTIVE)


class GifFrames:
    """Frames quantised for a GIF (:func:`gif_frame`) on a worker thread, in order, while
    the caller renders the next one: Pillow's quantiser releases the interpreter lock, so
    on two cores the median cut (a third of a GIF's time at 640x480) runs beside
    the renderer instead of after it. Use as a context manager; :meth:`images` waits for
    the last ones."""

    def __init__(self):
        from concurrent.futures import ThreadPoolExecutor

        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="hs-gif")
        self._jobs: list = []

    def add(self, image: np.ndarray) -> None:
        """Queue ``image (H, W, 3) uint8`` (not modified afterwards by the caller)."""
        self._jobs.append(
            self._pool.submit(gif_frame, _as_frame(image, f"frame {len(self._jobs)}"))
        )

    def __len__(self) -> int:
        return len(self._jobs)

    def images(self) -> list:
        """The palette images, in the order added."""
        return [job.result() for job in self._jobs]

    def __enter__(self) -> GifFrames:
        return self

    def __exit__(self, *exc) -> None:
        self._pool.shutdown(wait=True, cancel_futures=True)


def gif_bytes(frames: Sequence, fps: float, comment: str | None = None) -> bytes:
    """A looping GIF of frames playing at exactly ``fps`` (see :func:`gif_schedule`);
    Pillow. Each frame is an ``(H, W, 3) uint8`` array or a :func:`gif_frame` already.
    ``comment``: written in the file's comment extension (UTF-8; Pillow reads it back as
    ``info["comment"]``), e.g. the credit of the takes shown; none when None or empty."""
    import io

    from PIL import Image

    kept, delays = gif_schedule(len(frames), fps)
    images = [
        frames[k]
        if isinstance(frames[k], Image.Image)
        else gif_frame(_as_frame(frames[k], f"frame {k}"))
        for k in kept
    ]
    buf = io.BytesIO()
    images[0].save(
        buf,
        format="GIF",
        save_all=True,
        append_images=images[1:],
        duration=delays,
        loop=0,
        optimize=False,
        disposal=1,
        **({"comment": str(comment).encode("utf-8")} if comment else {}),
    )
    return buf.getvalue()


def write_gif(
    frames: Iterable[np.ndarray],
    path: str | Path,
    fps: float,
    progress: Progress | None = None,
    total: int | None = None,
) -> Path:
    """Write frames as a looping GIF playing at exactly ``fps`` (:func:`gif_bytes`);
    each frame is quantised beside the rendering of the next (:class:`GifFrames`)."""
    if not fps > 0:
        raise ParameterError(f"fps {fps}: must be positive")
    with GifFrames() as collected:
        for k, frame in enumerate(frames):
            collected.add(frame)
            if progress:
                progress(k + 1, total or 0)
        if not len(collected):
            raise ValueError("write_gif: no frames")
        images = collected.images()
    path = Path(path)
    write_bytes(path, gif_bytes(images, fps))
    return path


def write_mp4(
    frames: Iterable[np.ndarray],
    path: str | Path,
    fps: float,
    progress: Progress | None = None,
    total: int | None = None,
    quality: float = 7.0,
    metadata: dict[str, str] | None = None,
) -> Path:
    """Write frames as H.264 MP4 at ``fps`` (imageio-ffmpeg). All frames one size.
    ``metadata``: the container's tags (``{"comment": ..., "copyright": ...}``: ffmpeg's
    ``-metadata KEY=VALUE``; a player's or ``ffprobe``'s file properties show them)."""
    import imageio_ffmpeg

    if not fps > 0:
        raise ParameterError(f"fps {fps}: must be positive")
    path = Path(path)
    writer = None
    size = None
    count = 0
    with atomic_path(path) as tmp:
        try:
            for k, frame in enumerate(frames):
                img = _as_frame(frame, f"frame {k}")
                if size is None:
                    size = img.shape[:2]
                    even = (size[0] + size[0] % 2, size[1] + size[1] % 2)
                    writer = imageio_ffmpeg.write_frames(
                        str(tmp),
                        (even[1], even[0]),
                        fps=float(fps),
                        codec="libx264",
                        quality=quality,
                        macro_block_size=1,
                        ffmpeg_log_level="error",
                        output_params=["-preset", "veryfast", "-movflags", "+faststart"]
                        + _metadata_params(metadata),
                    )
                    writer.send(None)
                elif img.shape[:2] != size:
                    raise ValueError(
                        f"write_mp4: frame {k} is {img.shape[1]}x{img.shape[0]}, "
                        f"the first was {size[1]}x{size[0]}"
                    )
                if even != size:
                    img = np.pad(
                        img, ((0, even[0] - size[0]), (0, even[1] - size[1]), (0, 0)), mode="edge"
                    )
                writer.send(np.ascontiguousarray(img))
                count += 1
                if progress:
                    progress(count, total or 0)
        finally:
            if writer is not None:
                writer.close()
        if count == 0:
            raise ValueError("write_mp4: no frames")
    return path


def _metadata_params(metadata: dict[str, str] | None) -> list[str]:
    """ffmpeg's ``-metadata KEY=VALUE`` arguments of ``metadata`` (empty values left out;
    the arguments go to ffmpeg as a list, never through a shell)."""
    params: list[str] = []
    for key, value in (metadata or {}).items():
        if value:
            params += ["-metadata", f"{key}={value}"]
    return params


def parse_frames(frames: str) -> slice:
    """The slice of a frames text ``A:B`` (Python slice, B exclusive, either may be empty;
    ``A:B:STEP``), checked before any take is read; which frames it selects needs the
    take (:func:`frame_range`)."""
    parts = str(frames).split(":")
    if len(parts) not in (2, 3):
        raise ParameterError(f"frames {frames!r}: expected A:B (e.g. 0:90)")
    try:
        vals = [int(p) if p.strip() else None for p in parts]
    except ValueError:
        raise ParameterError(f"frames {frames!r}: A and B must be integers") from None
    if len(vals) == 3 and vals[2] is not None and vals[2] <= 0:
        raise ParameterError(f"frames {frames!r}: the step must be a whole number >= 1")
    return slice(*vals)


def frame_range(n_frames: int, frames: str | tuple[int, int] | None = None) -> range:
    """Frames ``A:B`` (Python slice, B exclusive, either may be empty) of a take."""
    if frames is None:
        return range(n_frames)
    sl = parse_frames(frames) if isinstance(frames, str) else slice(*frames)
    out = range(n_frames)[sl]
    if len(out) == 0:
        raise ParameterError(
            f"frames {frames!r}: selects no frame of a take with {n_frames} frames"
        )
    return out


def check_frame(frame: int, n_frames: int | None = None) -> int:
    """``frame`` if it is a frame of a take of ``n_frames`` frames (0 the first); with
    ``n_frames`` None (the take not read yet) only a negative frame is refused. The one
    rule of a picked frame (the CLI's ``--frame``, :func:`render_to_file`)."""
    last = "the take's last" if n_frames is None else f"{n_frames - 1}"
    first = "0 (the first)" if n_frames is None else "0"
    has = "" if n_frames is None else f" (the take has {n_frames} frames)"
    if not (frame >= 0 and (n_frames is None or frame < n_frames)):
        raise ParameterError(f"frame {frame}: expected a frame from {first} to {last}{has}")
    return int(frame)


def render_to_file(
    preview,
    path: str | Path,
    frames: range | Sequence[int] | None = None,
    frame: int | None = None,
    fps: float | None = None,
    progress: Progress | None = None,
    sheet_frames: int = 12,
    **frame_kwargs,
) -> Path:
    """Render ``preview`` to ``path`` by its suffix.

    ``.png``: frame ``frame`` (default: the first of ``frames``, or 0), or with
    ``frames`` and no ``frame`` a contact sheet of up to ``sheet_frames`` frames
    spread over the range. ``.gif``/``.mp4``: every frame of ``frames`` (default all),
    stepped so the output plays at ``fps`` (default the take's rate, at most 30).
    ``frame_kwargs`` go to ``Preview.frame`` (view, camera, size, trails ...).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in FORMATS:
        raise ParameterError(f"{path.name}: output must end in {', '.join(FORMATS)}")
    n = preview.n_frames
    if suffix == ".png":
        if frame is not None or frames is None:
            f = check_frame(frame if frame is not None else 0, n)
            image = preview.frame(f, **frame_kwargs)
            if progress:
                progress(1, 1)
            return write_image(image, path)
        picks = list(frames)
        if len(picks) > sheet_frames:
            picks = [picks[int(round(k))] for k in np.linspace(0, len(picks) - 1, sheet_frames)]
        images = []
        for k, f in enumerate(picks):
            images.append(preview.frame(f, **frame_kwargs))
            if progress:
                progress(k + 1, len(picks))
        labels = [f"frame {f}" for f in picks]
        return write_image(contact_sheet(images, labels=labels), path)
    frames = list(range(n) if frames is None else frames)
    if not frames:
        raise ParameterError("frames: selects no frame")
    take_fps = preview.fps
    out_fps = float(fps) if fps is not None else min(take_fps, 30.0)
    if not out_fps > 0:
        raise ParameterError(f"fps {fps}: must be positive")
    step = max(1.0, take_fps / out_fps)
    picks = [frames[int(k)] for k in np.arange(0, len(frames), step)]
    out_fps = take_fps / step

    def generate():
        for f in picks:
            yield preview.frame(f, **frame_kwargs)

    writer = write_gif if suffix == ".gif" else write_mp4
    return writer(generate(), path, out_fps, progress=progress, total=len(picks))


def remaining_text(spent: float, done: int, total: int) -> str:
    """``"about 40 s left"`` from the seconds ``spent`` on ``done`` of ``total`` steps
    (an even pace), or ``""`` before the second step or once done."""
    if done < 2 or done >= total or spent <= 0:
        return ""
    left = spent / done * (total - done)
    return f"about {left:.0f} s left" if left < 120 else f"about {left / 60:.0f} min left"


def progress_printer(
    label: str = "rendering", stream=None, min_interval: float = 0.2, log_interval: float = 10.0
) -> Progress:
    """A ``progress(done, total)`` for ``stream`` (stderr): on a terminal a one-line bar
    redrawn at most every ``min_interval`` s; elsewhere (a log file, a pipe) a plain line
    at most every ``log_interval`` s and the last one, never carriage returns."""
    stream = stream or sys.stderr
    terminal = bool(getattr(stream, "isatty", lambda: False)())
    interval = min_interval if terminal else log_interval
    state = {"last": 0.0 if terminal else time.perf_counter(), "start": time.perf_counter()}

    def report(done: int, total: int) -> None:
        now = time.perf_counter()
        final = total and done >= total
        if not final and now - state["last"] < interval:
            return
        state["last"] = now
        spent = now - state["start"]
        if total:
            left = remaining_text(spent, done, total)
            counts = f"{done}/{total} {spent:.1f}s{left and ', ' + left}"
            if terminal:
                fill = int(30 * done / total)
                msg = f"\r{label} [{'#' * fill + '-' * (30 - fill)}] {counts}  "
            else:
                msg = f"{label}: {counts}"
        else:
            msg = f"{label} {done} frames {spent:.1f}s"
            msg = "\r" + msg if terminal else msg
        stream.write(msg + ("\n" if final or not terminal else ""))
        stream.flush()

    return report
