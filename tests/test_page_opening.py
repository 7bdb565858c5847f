"""While a new pair opens (stranger2 item 1) the session takes no edits of the old one.

The views of the previous pair stay on screen, greyed (``webapp.views.veil``); an edit
reaching the session meanwhile is refused and said, undo does nothing, and the progress
line names the pair being opened. Real demo pair from ``sample_data``.
"""

from __future__ import annotations

import pytest

from webapp import config
from webapp.config import demo_sample_name
from webapp.state import Session
from webapp.views.progress import BusyLine


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory) -> config.AppConfig:
    return config.AppConfig(
        sample_dir=sample_dir.resolve(),
        upload_dir=tmp_path_factory.mktemp("uploads"),
        default_sample=demo_sample_name(sample_dir.resolve()),
    )


def test_edits_are_refused_while_a_new_pair_opens(cfg):
    s = Session(cfg)
    s.load_sample(cfg.default_sample)
    s.add_point(s.n // 2, s.m_hand // 2)
    assert len(s.points) == 1 and s.can_undo
    revision = s.revision
    s.begin_opening("body <b>.bvh + hand.bvh")
    line = BusyLine(s).pane.object
    assert "opening body &lt;b&gt;.bvh + hand.bvh" in line  # escaped, one line
    s.add_point(s.n // 3, s.m_hand // 3)
    assert len(s.points) == 1 and s.revision == revision
    assert "not taken" in s.error and "is opening" in s.error
    s.tolerance = 5.0
    assert s.tolerance != 5.0
    assert not s.undo() and len(s.points) == 1
    s.end_opening()
    s.add_point(s.n // 3, s.m_hand // 3)
    assert len(s.points) == 2 and s.revision > revision
    assert BusyLine(s).pane.object == ""
