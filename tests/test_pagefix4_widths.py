"""A new pair gets its own default band widths unless the user typed one (stranger R3-8).

The app's session without a browser: two uploaded long bodies (30 s and 40 s, a Bandai
take tiled back and forth) opened one after the other in one session. The long-take
default W1 is 1.5·√T seconds (``engine.dtw.constraints.BAND.default_for``): the second
pair must get its own, not keep the first pair's; a width the user typed stays.
"""

from __future__ import annotations

import io

import numpy as np
import pytest
from conftest import HAND_BVH, MOCAP, demo_config

from engine.dtw import constraints as C
from engine.io.bvh import format_bvh, read_bvh
from webapp import config, uploads
from webapp.state import Session

BODY = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"
DEMO = "wave-ok"


def _tiled_body(seconds: float) -> bytes:
    """The Bandai take played forth and back until it lasts ``seconds``."""
    from dataclasses import replace

    take = read_bvh(BODY)
    n = int(round(seconds * take.fps))
    cycle = np.concatenate([np.arange(take.n_frames), np.arange(take.n_frames)[::-1]])
    keep = np.resize(cycle, n)
    tiled = replace(take, rotations=take.rotations[keep], translations=take.translations[keep])
    out = io.StringIO()
    out.write(format_bvh(tiled))
    return out.getvalue().encode()


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory) -> config.AppConfig:
    return demo_config(sample_dir, tmp_path_factory, max_upload_bytes=16 * 1024 * 1024)


def _open(s: Session, cfg, body: bytes, name: str) -> None:
    body_digest, _ = uploads.store(cfg, name, body)
    hand_digest, _ = uploads.store(cfg, HAND_BVH.name, HAND_BVH.read_bytes())
    s.load_uploads(body_digest, hand_digest, name, HAND_BVH.name)
    assert s.error == "" and s.body_name == name


def _default_w1(s: Session) -> float:
    width = C.BAND.default_for(s.prepared.n, s.prepared.features.fps)
    assert width.unit == C.SECONDS  # a long take: the default is a time width
    return width.value


def test_an_uploaded_pair_gets_its_own_default_w1_not_the_previous_pairs(cfg):
    s = Session(cfg)
    _open(s, cfg, _tiled_body(30.0), "thirty.bvh")
    first = _default_w1(s)
    assert s.band_s == first
    _open(s, cfg, _tiled_body(40.0), "forty.bvh")
    second = _default_w1(s)
    assert second > first
    assert s.band_s == second, (s.band_s, first, second)  # was the first pair's 8.2 s
    # a short pair after it: the paper's fraction again, no time width left over
    s.load_sample(DEMO)
    assert s.error == "" and s.band_s is None and s.band == C.BAND.default


def test_a_typed_w1_stays_with_the_next_pair(cfg):
    s = Session(cfg)
    _open(s, cfg, _tiled_body(30.0), "thirty.bvh")
    s.band_s = 12.0
    assert s.error == "" and s.band_s == 12.0
    _open(s, cfg, _tiled_body(40.0), "forty.bvh")
    assert s.band_s == 12.0


# --- the automatic width is stored as automatic (stranger R4-8) -----------------------


def _query(s: Session) -> dict:
    from urllib.parse import parse_qsl, urlsplit

    return dict(parse_qsl(urlsplit(s.share_url("http://127.0.0.1:5006/")).query))


def test_the_automatic_w1_is_stored_as_automatic_in_the_file_link_and_command(cfg):
    """The long take's default W1 (a time width the rule chose) is saved as "automatic":
    the session file and the link leave it out, so opening them on this pair gives this
    pair's default and a pair opened after it gets its own (it used to be saved as
    ``band=8.2s`` and then kept, as a width the user had typed, on the next pair)."""
    import json

    from webapp import backend

    thirty, forty = _tiled_body(30.0), _tiled_body(40.0)
    s = Session(cfg)
    _open(s, cfg, thirty, "thirty.bvh")
    first = _default_w1(s)
    assert s.band_s == first
    saved = json.loads(s.to_json())
    assert "band" not in saved and "refine_band" not in saved, saved
    link = _query(s)
    assert "band" not in link and "refine" not in link, link
    assert s.chosen_widths() == (None, None)
    assert backend.cli_command("b.bvh", "h.bvh", "right", *s.chosen_widths(), []).find("--band") < 0
    for restore in (
        lambda other: other.from_query(link),
        lambda other: other.from_json(s.to_json(), source="s.json"),
    ):
        other = Session(cfg)
        restore(other)
        assert other.error == "" and other.band_s == first and other.chosen_widths() == (None, None)
        _open(other, cfg, forty, "forty.bvh")
        assert other.band_s == _default_w1(other) > first  # the new pair's own default


def test_a_typed_width_is_stored_and_kept_and_undo_makes_it_automatic_again(cfg):
    """A width typed in the page is the user's: saved, kept with the next pair, and the
    note under W1 no longer calls it the default; undo makes it the default again."""
    from webapp.views.controls import parameter_widgets

    s = Session(cfg)
    _open(s, cfg, _tiled_body(30.0), "thirty.bvh")
    (_, note, w1_s, *_), *_ = parameter_widgets(s)  # W1's slider, its note, its seconds
    first = s.band_s
    assert "the default for these takes" in note.object and w1_s.value == f"{first:g}"
    w1_s.value = "12"  # typed in the page
    assert s.error == "" and s.band_s == 12.0 and "default" not in note.object
    assert _query(s)["band"] == "12s" and "refine" not in _query(s)
    other = Session(cfg)
    other.from_query(_query(s))
    _open(other, cfg, _tiled_body(40.0), "forty.bvh")
    assert other.band_s == 12.0  # a width the user set goes on with the next pair
    assert s.undo() and s.band_s == first and "band" not in _query(s)
    assert "the default for these takes" in note.object
    assert s.redo() and _query(s)["band"] == "12s" and "default" not in note.object


def test_old_files_and_links_with_an_explicit_width_open_as_before(cfg):
    """A file or link written before holds the automatic default as a number
    (``band=8.2s``): it opens with that width, as before, and as the default it is (the
    next pair gets its own). A width that is not the takes' default (a fraction on a long
    take, ``12s``) opens as a width set: it stays with the next pair."""
    import json

    s = Session(cfg)
    _open(s, cfg, _tiled_body(30.0), "thirty.bvh")
    first = s.band_s
    old = json.loads(s.to_json())
    old["band"], old["refine_band"] = f"{first:g}s", 0.1  # the old app wrote band always
    other = Session(cfg)
    other.from_json(json.dumps(old), source="old.json")
    assert other.error == "" and (other.band_s, other.refine_band_s) == (first, None)
    assert (other.to_spec().band, other.to_spec().refine_band) == (None, C.Width(0.1))
    _open(other, cfg, _tiled_body(40.0), "forty.bvh")
    assert other.band_s == _default_w1(other) > first  # its own default, not 8.2 s
    assert (other.refine_band_s, other.refine_band) == (None, 0.1)  # the file's W2 stays
    link = Session(cfg)
    link.from_query({**_query(s), "band": "12s"})
    assert link.error == "" and link.band_s == 12.0 and _query(link)["band"] == "12s"
