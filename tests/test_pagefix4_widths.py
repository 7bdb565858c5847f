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
