"""Large downloads travel over plain HTTP (``webapp.served_files``): the file the download
child writes is the command line's, the server streams it from its own folder under a
random token, the browser's file name is escaped in the header, and a token that is not
(or no longer) served answers 404 without touching any other path."""

from __future__ import annotations

import asyncio
import threading
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import tornado.web

from engine.io.bvh import read_bvh, write_bvh
from webapp import downloads, served_files

MOCAP = Path(__file__).resolve().parents[2] / "shared" / "data" / "mocap"
TAKE = MOCAP / "bandai-namco" / "dataset-1_bye_normal_001.bvh"


@pytest.fixture(scope="module")
def server():
    """A Tornado server with only the download route, on its own thread; yields
    ``(base url, store)``."""
    from webapp.launch import free_port

    store = served_files.FileStore(max_files=3)

    class Handler(served_files.FileHandler):
        pass

    Handler.store = store
    port = free_port()
    ready = threading.Event()
    box = {}

    def serve():
        loop = asyncio.new_event_loop()
        asyncio.set_event_loop(loop)
        app = tornado.web.Application([(served_files.ROUTE_PATTERN, Handler)])
        box["server"] = app.listen(port, address="127.0.0.1")
        box["loop"] = loop
        ready.set()
        loop.run_forever()

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    assert ready.wait(30)
    yield f"http://127.0.0.1:{port}/", store
    box["loop"].call_soon_threadsafe(box["loop"].stop)
    thread.join(10)
    store.close()


def _get(url: str):
    try:
        with urllib.request.urlopen(url, timeout=60) as reply:
            return reply.status, dict(reply.headers), reply.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


def test_the_served_bvh_is_the_clis_file_and_its_name_is_escaped(server, tmp_path):
    base, store = server
    motion = read_bvh(TAKE)
    name = 'my "take"\r\nSet-Cookie: x=1;é.bvh'  # quotes, a header break, not ASCII
    served = store.put(lambda p: downloads.write("bvh", motion, p), name, "bvh", owner="a")
    write_bvh(motion, tmp_path / "cli.bvh")  # what `handsplice splice -o` writes
    status, headers, body = _get(base + served.url)
    assert status == 200 and body == (tmp_path / "cli.bvh").read_bytes()
    assert served.size == len(body) == int(headers["Content-Length"])
    assert served.path.parent == store.folder and served.path.name == served.token
    cd = headers["Content-Disposition"]
    assert cd == (
        'attachment; filename="my _take_Set-Cookie_ x_1__.bvh"; '
        "filename*=UTF-8''my%20%22take%22Set-Cookie%3A%20x%3D1%3B%C3%A9.bvh"
    )
    assert "Set-Cookie" not in headers and headers["X-Content-Type-Options"] == "nosniff"
    # only the last path component names the file; no leading dots (a hidden file)
    assert served_files.disposition("..\\..\\a/..c;d.bvh") == (
        "attachment; filename=\"c_d.bvh\"; filename*=UTF-8''c%3Bd.bvh"
    )


def test_tokens_not_served_answer_404_and_replaced_files_are_removed(server):
    base, store = server
    first = store.put(lambda p: p.write_bytes(b"one"), "a.glb", "glb", owner="page")
    assert _get(base + first.url)[:3:2] == (200, b"one")
    second = store.put(lambda p: p.write_bytes(b"two"), "a.glb", "glb", owner="page")
    assert _get(base + first.url)[0] == 404 and not first.path.exists()  # replaced
    assert _get(base + second.url)[2] == b"two"
    other = store.put(lambda p: p.write_bytes(b"bvh"), "a.bvh", "bvh", owner="page")
    store.drop("page")  # the page closed
    assert _get(base + second.url)[0] == 404 and _get(base + other.url)[0] == 404
    assert not second.path.exists() and not other.path.exists()
    for url in ("hs-file/" + "A" * 43, "hs-file/..%2F..%2Fetc%2Fpasswd", "hs-file/"):
        assert _get(base + url)[0] == 404
    kept = [store.put(lambda p: p.write_bytes(b"x"), "f.bvh", "bvh") for _ in range(5)]
    assert [store.get(s.token) is not None for s in kept] == [False, False, True, True, True]


def test_a_failed_write_serves_nothing_and_leaves_no_file(server):
    _, store = server
    motion = read_bvh(TAKE)
    before = set(store.folder.iterdir())
    with pytest.raises(ValueError, match="download kind"):
        store.put(lambda p: downloads.write("fbx", motion, p), "x.fbx", "fbx")
    assert set(store.folder.iterdir()) == before
