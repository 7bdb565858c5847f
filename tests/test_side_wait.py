"""A new pair opened over another one (stranger run 4: R4-7, R4-9), in the session itself.

* R4-7: with a pair whose hand is a left hand open, a hand take whose name says no side
  and whose joints are a right hand (gestification's ``rHand``) is refused for the side in
  force. The refusal names the person's file (never the server's ``<sha256>.bvh``), the
  open pair stays with its own names (a link or session file names the pair shown), and
  the new pair waits for the side: choosing it opens the new pair, not the old one again.
* R4-9: off the event loop a new pair is "opening" until its first path is in (the page's
  views of the previous pair stay inactive through the first alignment), as a link's is.

Real takes: Bandai-Namco's ``bye`` body, ManipNet's hand cut to 2 s and named as a left
hand, gestification's ``hello-world`` hand.
"""

from __future__ import annotations

import re

import pytest
from conftest import BODY_BVH, HAND_BVH, MOCAP, cropped_bvh, demo_config
from test_solves import FakeDoc

from webapp import uploads
from webapp.state import Session

MUG = MOCAP / "manipnet" / "mug1_leftHand.bvh"


@pytest.fixture(scope="module")
def cfg(sample_dir, tmp_path_factory):
    return demo_config(sample_dir, tmp_path_factory)


@pytest.fixture(scope="module")
def kept(cfg, tmp_path_factory):
    """Digests of the uploaded body, left hand (2 s) and right hand without a side name."""
    left = cropped_bvh(MUG, tmp_path_factory.mktemp("hand") / "mug_leftHand.bvh", 240)
    return {
        name: uploads.store(cfg, name, path.read_bytes())[0]
        for name, path in (
            (BODY_BVH.name, BODY_BVH),
            (left.name, left),
            (HAND_BVH.name, HAND_BVH),
        )
    }


def _load_left_pair(s: Session, kept: dict) -> None:
    left = "mug_leftHand.bvh"
    s.load_uploads(kept[BODY_BVH.name], kept[left], BODY_BVH.name, left, side="left")


def _open_left_pair(s: Session, kept: dict) -> None:
    _load_left_pair(s, kept)
    assert not s.error and s.side == "left" and s.solution is not None


def test_a_hand_with_only_the_other_side_waits_for_it_and_the_side_opens_it(cfg, kept):
    s = Session(cfg)
    _open_left_pair(s, kept)
    shown = s.to_query()
    assert shown["hname"] == "mug_leftHand.bvh"
    s.load_uploads(kept[BODY_BVH.name], kept[HAND_BVH.name], BODY_BVH.name, HAND_BVH.name)
    # the question names the person's file, not the file the server keeps it in
    assert "hello-world.bvh has no left hand" in s.error and "choose side right" in s.error
    assert not re.search(r"[0-9a-f]{64}", s.error), s.error
    assert s.waits_for_side and "hello-world.bvh" in s.waiting and "side" in s.refused_inputs
    # the pair shown stays, with its own names: its link is the one before
    assert s.to_query() == shown and s.hand_name == "mug_leftHand.bvh"
    # the side asked for opens the new pair (not the old one for the other side)
    s.side = "right"
    assert not s.error and not s.waits_for_side and not s.waiting
    assert (s.hand_sha256, s.hand_name, s.side) == (kept[HAND_BVH.name], HAND_BVH.name, "right")
    assert s.solution is not None and s.m_hand == s.prepared.m_hand
    query = s.to_query()
    assert (query["hand"], query["hname"], query["side"]) == (
        kept[HAND_BVH.name],
        HAND_BVH.name,
        "right",
    )


def test_other_takes_chosen_drop_the_waiting_pair(cfg, kept):
    s = Session(cfg)
    _open_left_pair(s, kept)
    s.load_uploads(kept[BODY_BVH.name], kept[HAND_BVH.name], BODY_BVH.name, HAND_BVH.name)
    assert s.waits_for_side
    s.load_sample(cfg.default_sample)
    assert not s.waits_for_side and not s.waiting and s.sample == cfg.default_sample
    side = "left" if s.side == "right" else "right"
    s.side = side  # an ordinary side change of the sample: no upload comes back
    assert s.sample == cfg.default_sample and s.hand_sha256 is None


def test_off_the_loop_a_new_pair_opens_until_its_first_path_is_in(cfg, kept):
    doc = FakeDoc()
    s = Session(cfg)
    s.compute_off_loop(doc)
    s.load_sample(cfg.default_sample)
    doc.pump(lambda: s.solution is not None and not s.busy)
    assert not s.opening
    seen = []  # (opening, has a solution) each time new takes are shown
    s.param.watch(lambda e: seen.append((s.opening, s.solution is not None)), ["inputs_revision"])
    _load_left_pair(s, kept)
    assert s.opening == f"{BODY_BVH.name} + mug_leftHand.bvh"
    assert s.to_query()["sample"] == cfg.default_sample  # a link names the pair shown
    doc.pump(lambda: not s.opening)
    # the takes were shown while the opening went on: their first alignment was part of it
    assert seen == [(f"{BODY_BVH.name} + mug_leftHand.bvh", False)]
    assert s.solution is not None and s.n == s.prepared.n and not s.error
    assert s.to_query()["hname"] == "mug_leftHand.bvh"
    doc.pump(lambda: not s.busy)


def test_a_new_pair_that_has_the_side_in_force_opens_on_it(cfg, kept):
    """Stranger 14 F2: a new pair asked for a side its hand lacks (a right hand, ``rHand``,
    whose file name says left) while the side in force is the one it has waited with the
    Side control already showing that side: choosing it could not be a change, so the page
    was stuck. It opens on the side in force at once, off the loop too."""
    for off_loop in (False, True):
        s, doc = Session(cfg), FakeDoc()
        if off_loop:
            s.compute_off_loop(doc)
        s.load_sample(cfg.default_sample)
        if off_loop:
            doc.pump(lambda s=s: s.solution is not None and not s.busy)
        assert s.side == "right" and s.solution is not None
        s.load_uploads(
            kept[BODY_BVH.name], kept[HAND_BVH.name], BODY_BVH.name, "x_left.bvh", side="left"
        )
        if off_loop:
            doc.pump(lambda s=s: not s.opening and not s.busy)
        assert not s.waits_for_side and not s.waiting, s.waiting
        assert (s.hand_sha256, s.hand_name, s.side) == (kept[HAND_BVH.name], "x_left.bvh", "right")
        assert s.solution is not None and s.m_hand == s.prepared.m_hand and not s.error
        # the other side, which it lacks, is refused; the pair stays on the side shown, and
        # the refusal asks for no side (the one it would ask for is the one in force)
        s.side = "left"
        if off_loop:
            doc.pump(lambda s=s: s.error and not s.busy)
        assert s.side == "right" and s.hand_name == "x_left.bvh" and not s.waits_for_side
        assert s.error == (
            "x_left.bvh has no left hand (hands found: right); it stays on the right side"
        )


def test_a_link_without_a_side_opens_a_left_named_right_hand_on_its_joints_side(cfg, kept):
    """Stranger 14 F2, a link's way in: without ``side`` the page takes the hand file's
    name's side, unless its joint names are the other hand's (the one rule,
    ``engine.model.roles.hand_file_side``): a right hand named ``..._left_...`` opens right."""
    s = Session(cfg)
    s.load_sample(cfg.default_sample)
    body, hand = kept[BODY_BVH.name], kept[HAND_BVH.name]
    s.open_link(
        {"body": body, "bname": BODY_BVH.name, "hand": hand, "hname": "pointing_left_hand.bvh"}
    )
    assert (s.hand_sha256, s.hand_name, s.side) == (hand, "pointing_left_hand.bvh", "right")
    assert s.solution is not None and not s.error, s.error
