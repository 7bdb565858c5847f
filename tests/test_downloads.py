"""The app's BVH and GLB downloads are encoded in a child process (``webapp.downloads``):
the bytes are the command line's, an encoder's error comes back as its one line, and the
work is done by another process (the server's interpreter is free meanwhile)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from engine.export.glb import glb_bytes
from engine.io.bvh import format_bvh, read_bvh, write_bvh
from webapp import backend, downloads

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
TAKE = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"


@pytest.fixture(scope="module")
def motion():
    return read_bvh(TAKE)


def test_bvh_bytes_are_the_writers_bytes(motion, tmp_path):
    data = backend.bvh_bytes(motion)
    write_bvh(motion, tmp_path / "cli.bvh")  # what `handsplice splice -o` writes
    assert data == (tmp_path / "cli.bvh").read_bytes()
    assert data == format_bvh(motion).encode("utf-8")
    assert data.startswith(b"HIERARCHY") and f"Frames: {motion.n_frames}".encode() in data


def test_glb_bytes_are_the_exporters_bytes(motion):
    data = backend.glb_bytes(motion)
    assert data[:4] == b"glTF"
    assert data == glb_bytes(motion)


def test_an_encoders_error_comes_back_as_its_one_line(motion):
    # a joint without rotation channels that rotates: BVH cannot hold it
    sk = motion.skeleton
    j = next(j for j, c in enumerate(sk.channels) if sk.parents[j] >= 0)
    channels = list(sk.channels)
    channels[j] = ()
    bad = replace(motion, skeleton=replace(sk, channels=tuple(channels)))
    rotations = bad.rotations.copy()
    rotations[:, j] = [np.cos(0.3), np.sin(0.3), 0.0, 0.0]
    bad = replace(bad, rotations=rotations)
    with pytest.raises(ValueError) as in_process:
        format_bvh(bad)
    with pytest.raises(ValueError) as in_child:
        backend.bvh_bytes(bad)
    assert str(in_child.value) == str(in_process.value).splitlines()[0]
    assert "no channels" in str(in_child.value)
    with pytest.raises(ValueError, match="download kind"):
        downloads.encode("fbx", motion)


def test_the_encoder_runs_in_another_process(motion, monkeypatch):
    """The server's own encoders are never called: the child (forked from the forkserver,
    which imported them afresh) makes the bytes, while this interpreter only waits on a
    pipe (which is why another tab's click is answered meanwhile; benchmarks/bench_app_long
    --downloads measures it)."""
    import engine.export.glb
    import engine.io.bvh

    def not_here(*args, **kwargs):
        raise AssertionError("encoded in the server's own process")

    monkeypatch.setattr(engine.io.bvh, "format_bvh", not_here)
    monkeypatch.setattr(engine.export.glb, "glb_bytes", not_here)
    assert backend.bvh_bytes(motion) == format_bvh(motion).encode("utf-8")
    assert backend.glb_bytes(motion) == glb_bytes(motion)
