"""Every way JSON text from outside can be refused comes out as one JsonTextError, and
each reader of such text turns it into its own one-line error (stop 32's CI: a link whose
``roles`` was 5,000 digits escaped as a ValueError traceback)."""

from __future__ import annotations

import pytest

from engine.base.errors import MotionFormatError, ParameterError
from engine.base.json_text import JsonTextError, parse_json
from engine.io.session import SessionError, from_query, parse_session
from engine.model.roles import load_role_overrides
from webapp.views.cost_matrix import _fresh_edits

HUGE_INT = "1" * 5000
DEEP = "[" * 100_000 + "]" * 100_000


@pytest.mark.parametrize(
    ("text", "said"),
    [
        (HUGE_INT, "too many digits"),
        ('{"a": ' + HUGE_INT + "}", "too many digits"),
        (DEEP, "nested too deeply"),
        ('{"a": NaN}', "expected finite numbers, found NaN"),
        ('{"a": -Infinity}', "expected finite numbers, found -Infinity"),
        ('{"a": 1,}', "line 1, column 9: not valid JSON"),
        (b"\xff{}", "not UTF-8 text (byte 0)"),
    ],
)
def test_each_refusal_is_one_json_text_error(text, said):
    with pytest.raises(JsonTextError) as info:
        parse_json(text)
    assert said in info.value.detail and "\n" not in info.value.detail


def test_good_text_and_a_bom_are_read():
    assert parse_json('{"a": [1, 2.5, null]}') == {"a": [1, 2.5, None]}
    assert parse_json(b'\xef\xbb\xbf{"a": 1}') == {"a": 1}
    assert parse_json('{"a": NaN}', finite=False)["a"] != 0


def test_a_link_whose_roles_is_a_huge_number_is_a_session_error():
    # the CI failure of stop 32, found by test_fuzz's link-query fuzzer
    with pytest.raises(SessionError, match="roles"):
        from_query({"roles": HUGE_INT})


def test_a_session_file_with_a_huge_number_is_one_line(tmp_path):
    with pytest.raises(SessionError) as info:
        parse_session('{"points": [[' + HUGE_INT + ", 1]]}", "s.json")
    assert "too many digits" in str(info.value) and "\n" not in str(info.value)


def test_a_roles_map_with_a_huge_number_is_a_parameter_error(tmp_path):
    path = tmp_path / "roles.json"
    path.write_text('{"right.wrist": ' + HUGE_INT + "}")
    with pytest.raises(ParameterError, match=r"roles\.json: a number with too many digits"):
        load_role_overrides(path)


def test_a_glb_whose_json_chunk_has_a_huge_number_is_a_format_error(tmp_path):
    import struct

    from engine.io.glb import read_glb_summary

    chunk = ('{"asset": {"version": ' + HUGE_INT + "}}").encode()
    chunk += b" " * (-len(chunk) % 4)
    body = struct.pack("<II", len(chunk), 0x4E4F534A) + chunk
    path = tmp_path / "x.glb"
    path.write_bytes(struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body)
    with pytest.raises(MotionFormatError, match="JSON chunk: a number with too many digits"):
        read_glb_summary(path)


@pytest.mark.parametrize(
    "queue",
    [HUGE_INT, DEEP, "{}", '[{"seq": "3"}]', '[{"seq": 1e400}]', "not json", None],
)
def test_the_page_edit_queue_refuses_what_the_page_never_sends(queue):
    assert _fresh_edits(queue, 0) == []


def test_the_page_edit_queue_keeps_newer_edits_in_order():
    text = '[{"seq": 3, "after": {}}, {"seq": 1}, {"seq": 2}, {"seq": true}]'
    assert [e["seq"] for e in _fresh_edits(text, 1)] == [2, 3]
