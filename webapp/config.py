"""Server-wide settings of the app: where samples and uploads live, size limits.

One ``AppConfig`` per server process (set by ``handsplice serve`` through
:func:`configure`); sessions read it, never change it. The server reads files
only from ``sample_dir`` and ``upload_dir``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from engine.base.json_text import JsonTextError, parse_json
from engine.base.limits import MAX_UPLOAD_BYTES

ROOT = Path(__file__).resolve().parents[1]
SAMPLE_DIR = ROOT / "sample_data"
DEFAULT_MAX_UPLOAD = MAX_UPLOAD_BYTES  # the default; ``handsplice serve --max-upload-mb`` sets it
#: upload folder quota: at most this many kept files and bytes (least recently used go first)
DEFAULT_UPLOAD_FILES = 200
DEFAULT_UPLOAD_TOTAL_BYTES = 4 * 1024**3
#: budget of one upload's check (the reader runs in a child process): seconds and bytes
DEFAULT_CHECK_SECONDS = 300.0
DEFAULT_CHECK_BYTES = 4 * 1024**3


@dataclass(frozen=True)
class SamplePair:
    """A bundled body/hand pair: ``body`` and ``hand`` are paths inside ``sample_dir``."""

    name: str
    body: Path
    hand: Path
    side: str = "right"
    description: str = ""
    extra: dict = field(default_factory=dict, compare=False, hash=False)


@dataclass(frozen=True)
class AppConfig:
    sample_dir: Path = SAMPLE_DIR
    upload_dir: Path = ROOT / "uploads"
    default_sample: str | None = None
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD
    max_upload_files: int = DEFAULT_UPLOAD_FILES
    max_upload_total_bytes: int = DEFAULT_UPLOAD_TOTAL_BYTES
    upload_check_seconds: float = DEFAULT_CHECK_SECONDS
    upload_check_bytes: int = DEFAULT_CHECK_BYTES
    #: the pair named on the command line (``handsplice serve BODY HAND``), read from disk
    local: SamplePair | None = None

    def samples(self) -> list[SamplePair]:
        return ([self.local] if self.local else []) + load_samples(self.sample_dir)

    def sample(self, name: str) -> SamplePair:
        for pair in self.samples():
            if pair.name == name:
                return pair
        known = ", ".join(p.name for p in self.samples()) or "none"
        raise KeyError(f"sample: no sample pair named {name!r} (known: {known})")


_CONFIG = AppConfig()


def get() -> AppConfig:
    return _CONFIG


def configure(
    default_sample: str | None = None,
    upload_dir: Path | None = None,
    max_upload_bytes: int = DEFAULT_MAX_UPLOAD,
    sample_dir: Path | None = None,
    **limits,
) -> AppConfig:
    """Set the server-wide configuration; ``default_sample`` None = the samples.json demo pair.

    ``limits``: ``local`` (the pair of ``serve BODY HAND``, opened first),
    ``max_upload_files``, ``max_upload_total_bytes`` (the upload quota),
    ``upload_check_seconds``, ``upload_check_bytes`` (the budget of one upload's check)."""
    global _CONFIG
    sample_dir = Path(sample_dir or SAMPLE_DIR).resolve()
    upload_dir = Path(upload_dir or Path.cwd() / "uploads").resolve()
    cfg = AppConfig(
        sample_dir=sample_dir,
        upload_dir=upload_dir,
        max_upload_bytes=int(max_upload_bytes),
        **limits,
    )
    names = [p.name for p in cfg.samples()]
    if default_sample is not None and default_sample not in names:
        raise ValueError(
            f"--sample: no sample pair named {default_sample!r} in "
            f"{sample_dir / 'samples.json'} (known: {', '.join(names) or 'none'})"
        )
    if default_sample is None:
        local = limits.get("local")
        default_sample = local.name if local is not None else demo_sample_name(sample_dir)
    _CONFIG = AppConfig(
        sample_dir=sample_dir,
        upload_dir=upload_dir,
        default_sample=default_sample,
        max_upload_bytes=int(max_upload_bytes),
        **limits,
    )
    return _CONFIG


def local_pair(body: Path, hand: Path, side: str = "right") -> SamplePair:
    """The pair of ``handsplice serve BODY HAND``: the user's own files, opened by path
    (the server runs on their machine). Listed first among the sample pairs, under the
    name ``BODY.name + HAND.name``."""
    body, hand = Path(body).resolve(), Path(hand).resolve()
    return SamplePair(
        name=f"{body.name} + {hand.name}",
        body=body,
        hand=hand,
        side=side,
        description="your takes, opened from disk",
        extra={"local": True},
    )


def _read_manifest(sample_dir: Path) -> dict | list | None:
    path = sample_dir / "samples.json"
    if not path.is_file():
        return None
    try:
        return parse_json(path.read_bytes(), finite=False)
    except (OSError, JsonTextError):
        return None


def _pairs_from_manifest(data) -> list[dict]:
    if isinstance(data, dict):
        for key in ("pairs", "samples"):
            if isinstance(data.get(key), list | dict):
                data = data[key]
                break
    if isinstance(data, dict):  # {name: {...}}
        return [dict(v, name=v.get("name", k)) for k, v in data.items() if isinstance(v, dict)]
    if isinstance(data, list):
        return [d for d in data if isinstance(d, dict)]
    return []


def _inside(base: Path, rel) -> Path | None:
    if not isinstance(rel, str) or not rel:
        return None
    path = (base / rel).resolve()
    return path if path.is_relative_to(base.resolve()) and path.is_file() else None


def load_samples(sample_dir: Path) -> list[SamplePair]:
    """Bundled pairs listed in ``sample_dir/samples.json`` whose files exist.

    Accepts ``{"pairs": [...]}``, ``{"samples": [...]}``, a list, or ``{name: {...}}``;
    each entry needs ``name``, ``body`` and ``hand`` (paths relative to ``sample_dir``).
    """
    pairs = []
    for entry in _pairs_from_manifest(_read_manifest(sample_dir)):
        body = _inside(sample_dir, entry.get("body") or entry.get("body_file"))
        hand = _inside(sample_dir, entry.get("hand") or entry.get("hand_file"))
        name = entry.get("name")
        if not (isinstance(name, str) and body and hand):
            continue
        side = entry.get("side", "right")
        pairs.append(
            SamplePair(
                name=name,
                body=body,
                hand=hand,
                side=side if side in ("left", "right") else "right",
                description=str(entry.get("description", "")),
                extra=entry,
            )
        )
    return pairs


def file_credits(sample_dir: Path) -> dict[str, dict]:
    """samples.json's per-file entries (description, source, licence) by relative path."""
    data = _read_manifest(sample_dir)
    files = data.get("samples", []) if isinstance(data, dict) else []
    return {e["file"]: e for e in files if isinstance(e, dict) and isinstance(e.get("file"), str)}


def sample_path(path: Path, sample_dir: Path) -> str | None:
    """``path``'s name in samples.json (relative to ``sample_dir``, POSIX), or None for a
    file outside the bundled samples. The one rule the credits and ``no_share`` read."""
    try:
        return Path(path).resolve().relative_to(Path(sample_dir).resolve()).as_posix()
    except ValueError:
        return None


def no_share(pair: SamplePair, sample_dir: Path) -> bool:
    """True when spliced results of ``pair`` must not be shared: ``"no_share": true`` on the
    pair in samples.json, or ``"no_derivatives": true`` on a take's own entry there (its
    licence forbids adapted material). The one rule behind the credits' and the downloads'
    warnings (stranger 8: a pair's description and its warning said different things)."""
    if pair.extra.get("no_share"):
        return True
    files = file_credits(sample_dir)
    for path in (pair.body, pair.hand):
        rel = sample_path(path, sample_dir)
        if rel is not None and files.get(rel, {}).get("no_derivatives") is True:
            return True
    return False


def demo_sample_name(sample_dir: Path) -> str | None:
    """The pair marked as demo in samples.json (``"demo": name``, ``"demo": {"name": name,
    ...}`` or a pair's ``"demo": true``), else the first."""
    data = _read_manifest(sample_dir)
    pairs = load_samples(sample_dir)
    demo = data.get("demo") if isinstance(data, dict) else None
    if isinstance(demo, dict):
        demo = demo.get("name")
    if isinstance(demo, str) and any(p.name == demo for p in pairs):
        return demo
    for p in pairs:
        if p.extra.get("demo") is True:
            return p.name
    return pairs[0].name if pairs else None
