"""What an edit in the app recomputes besides its solve (issue 13: edits cost what they
change). The preview after an edit keeps the mannequins of the pair's previous preview:
rebuilding the body's and the hand take's meshes (and the spliced take's, bound in an
unchanged first frame) took most of the server's CPU after each edit, beside the next
edit's solve (benchmarks/RESULTS.md, section app)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from engine.render.offscreen import Preview
from webapp import backend, config
from webapp.state import Session

DEMO = "wave-ok"


@pytest.fixture(scope="module")
def session(sample_dir, tmp_path_factory) -> Session:
    cfg = config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=tmp_path_factory.mktemp("uploads"),
        default_sample=DEMO,
    )
    s = Session(cfg)
    s.load_sample(DEMO)
    assert s.error == ""
    return s


def _same_mesh(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, f.name), getattr(b, f.name))
        for f in dataclasses.fields(a)
        if isinstance(getattr(a, f.name), np.ndarray)
    )


def test_an_edit_keeps_the_preview_meshes_it_does_not_change(session):
    prepared = session.prepared
    before = backend.preview_for(prepared, session.solution)
    body, hand = prepared.body, prepared.hand
    session.add_point(session.n // 2, session.hand_frame_for(session.n // 2) + 3, 1)
    after = backend.preview_for(prepared, session.solution)
    assert after is not before and [v.motion for v in after.views[:2]] == [body, hand]
    # the body and the hand take did not change: their meshes are not built again
    assert after.views[0].mesh is before.views[0].mesh
    assert after.views[1].mesh is before.views[1].mesh
    spliced = backend.splice(prepared, session.solution)
    assert after.views[2].motion is spliced
    # the spliced take changed, its first frame (the bind pose) did not: its mesh is kept,
    # and it is the mesh a fresh build gives
    assert backend._same_bind(before.views[2].motion, spliced)
    assert after.views[2].mesh is before.views[2].mesh
    fresh = Preview([spliced], size=(96, 36)).views[0].mesh
    assert _same_mesh(after.views[2].mesh, fresh)


def test_a_changed_first_frame_builds_its_mesh_again(session):
    spliced = backend.splice(session.prepared, session.solution)
    rotations = spliced.rotations.copy()
    rotations[0] = rotations[min(1, len(rotations) - 1)] + 0.01
    moved = dataclasses.replace(spliced, rotations=rotations)
    assert not backend._same_bind(spliced, moved)
    assert backend._same_bind(spliced, dataclasses.replace(spliced))
    last = backend.preview_for(session.prepared, session.solution)
    takes = [session.prepared.body, session.prepared.hand, moved]
    meshes = backend._kept_meshes(last, takes)
    assert meshes[:2] == [last.views[0].mesh, last.views[1].mesh] and meshes[2] is None
