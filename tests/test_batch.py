"""``handsplice batch``: manifest validation, and a real batch on a 2-worker local Dask
cluster (separate processes) with one broken pair, then a re-run that skips the
finished pairs. Inputs are short crops of real takes from ../shared/data/mocap."""

from __future__ import annotations

import csv
import json
import os
import re
from pathlib import Path

import pytest
from conftest import MOCAP

from engine.cli import main
from engine.io.bvh import read_bvh, write_bvh
from engine.jobs.batch import (
    MARKER_DIR,
    ManifestError,
    PairJob,
    is_done,
    parse_manifest,
    read_manifest,
    run_pair,
)

pytestmark = pytest.mark.timeout(300, method="thread")

# body takes (no fingers) x hand takes (Leap Motion right hands), as in sample_data
BODIES = [
    "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
    "bandai-namco/dataset-2_raise-up-right-hand_normal_001.bvh",
    "bandai-namco/dataset-1_bye_normal_001.bvh",
]
HANDS = [
    "gestification/hello-world.bvh",
    "gestification/gesture-pointing.bvh",
    "gestification/fingers-ok.bvh",
]
CROP_BODY, CROP_HAND = 50, 60  # frames: the whole batch stays well under a minute


def _crop(src: Path, dst: Path, frames: int) -> Path:
    m = read_bvh(src)
    write_bvh(m.frames(0, min(frames, m.n_frames)), dst)
    return dst


@pytest.fixture(scope="module")
def takes(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("takes")
    (folder / "bodies").mkdir()
    (folder / "hands").mkdir()
    for name in BODIES:
        _crop(MOCAP / name, folder / "bodies" / Path(name).name, CROP_BODY)
    for name in HANDS:
        _crop(MOCAP / name, folder / "hands" / Path(name).name, CROP_HAND)
    # the deliberately broken pair's body: a take cut off in the middle of a data row
    text = (folder / "bodies" / Path(BODIES[0]).name).read_text(encoding="utf-8")
    (folder / "bodies" / "broken.bvh").write_text(text[: len(text) * 2 // 3], encoding="utf-8")
    return folder


def _write_manifest(
    folder: Path, rows: list[str], header: str = "body,hand,side,band,match,name"
) -> Path:
    path = folder / "manifest.csv"
    path.write_text(header + "\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def _summary(outdir: Path) -> dict[str, dict]:
    with open(outdir / "summary.csv", newline="", encoding="utf-8") as fh:
        return {row["name"]: row for row in csv.DictReader(fh)}


# ---------------------------------------------------------------- the batch on Dask


def test_batch_on_two_worker_cluster_then_resume(takes, tmp_path, capsys):
    b = [f"bodies/{Path(n).name}" for n in BODIES]
    h = [f"hands/{Path(n).name}" for n in HANDS]
    rows = [
        f"{b[0]},{h[0]},right,,,wave-hello",
        f"{b[1]},{h[1]},right,0.3,,raise-pointing",
        f"{b[2]},{h[2]},right,0.4,,bye-ok",
        f"{b[0]},{h[1]},right,,,wave-pointing",
        f"{b[1]},{h[2]},right,,,raise-ok",
        f"{b[2]},{h[0]},right,,5:6:2;40:45,bye-hello-matched",
        f"bodies/broken.bvh,{h[0]},right,,,broken",
        # a bad cell fails its row only, the others run (stranger 14 F10: it stopped the batch)
        f"{b[0]},{h[0]},right,,80:20;60:30,bad-match",
    ]
    manifest = _write_manifest(takes, rows)  # relative paths: from the manifest's folder
    out = tmp_path / "out"

    status = main(["batch", str(manifest), "-o", str(out), "--workers", "2"])
    err = capsys.readouterr().err
    assert status == 3, err  # finished, two pairs failed
    summary = _summary(out)
    assert len(summary) == 8
    assert summary["broken"]["status"] == "failed"
    assert "broken.bvh" in summary["broken"]["error"] and "line" in summary["broken"]["error"]
    assert summary["bad-match"]["status"] == "failed"
    assert summary["bad-match"]["error"] == (
        "manifest.csv line 9, column match: matching point 2 (body 60, hand 30): body frame 60 "
        "is not after matching point 1's body frame 80; body frames must increase from one "
        "point to the next"
    )
    done = [n for n, r in summary.items() if r["status"] == "done"]
    assert len(done) == 6
    # progress on stderr: one line per pair, the failures named
    assert len(re.findall(r"^\[\d/8\] ", err, re.M)) == 8
    assert "broken: failed" in err and "bad-match: failed: manifest.csv line 9" in err
    # separate worker processes, none of them this test process
    workers = {summary[n]["worker"] for n in done}
    assert len(workers) == 2 and all(not w.endswith(f":{os.getpid()}") for w in workers)
    for name in done:
        row = summary[name]
        spliced = read_bvh(out / row["output"])
        assert spliced.n_frames == CROP_BODY == int(row["spliced_frames"])
        assert any("index" in j.lower() for j in spliced.skeleton.names)  # fingers arrived
        report = json.loads((out / row["report"]).read_text(encoding="utf-8"))
        assert len(report["map"]) == CROP_BODY and report["output"] == row["output"]
        assert report["pass1"]["band"]["cells"] > 0 and report["timings_s"]["total"] > 0
        png = (out / row["thumbnail"]).read_bytes()
        assert png.startswith(b"\x89PNG") and row["thumbnail_kind"] in ("render", "stick")
        assert (out / MARKER_DIR / f"{name}.json").is_file()
    assert summary["bye-hello-matched"]["match"] == "5:6:2;40:45"
    matched = json.loads((out / "bye-hello-matched.report.json").read_text(encoding="utf-8"))
    assert matched["parameters"]["points_given"] == [[5, 6, 2.0], [40, 45, 0.0]]
    grid = matched["parameters"]["points"][1]  # (40, 45) on the alignment grid, tolerance 0
    assert grid[0] == 40 and [40, grid[1]] in matched["pass2"]["path"]
    assert abs(matched["map"][40] - 45) < 2.0  # merged and smoothed: near the point
    page = (out / "index.html").read_text(encoding="utf-8")
    assert page.count("<img ") == 6 and "broken" in page and "failed" in page
    assert "bad-match" in page
    # no temporary files left behind by the atomic writes
    assert not [p for p in out.iterdir() if p.name.startswith(".") and p.name != MARKER_DIR]
    mtimes = {n: (out / summary[n]["output"]).stat().st_mtime_ns for n in done}

    # re-run: finished pairs are skipped (outputs untouched), the broken one is tried again
    status = main(["batch", str(manifest), "-o", str(out), "--workers", "2", "--quiet"])
    assert status == 3
    again = _summary(out)
    assert {n for n, r in again.items() if r["status"] == "skipped"} == set(done)
    assert again["broken"]["status"] == "failed" and again["bad-match"]["status"] == "failed"
    assert {n: (out / summary[n]["output"]).stat().st_mtime_ns for n in done} == mtimes

    # a changed input (same name) is no longer "done": its hash differs
    job = next(j for j in read_manifest(manifest) if j.name == "wave-hello")
    assert is_done(job, out) is not None
    hand = Path(job.hand)
    hand.write_text(hand.read_text(encoding="utf-8") + "\n", encoding="utf-8")
    assert is_done(job, out) is None
    # and a changed option too
    job2 = next(j for j in read_manifest(manifest) if j.name == "raise-pointing")
    assert is_done(job2, out) is not None
    assert is_done(PairJob(**{**job2.__dict__, "band": 0.5}), out) is None


def test_run_pair_records_errors_without_raising(takes, tmp_path):
    job = PairJob(
        line=2,
        name="nohand",
        body=str(takes / "bodies" / Path(BODIES[0]).name),
        hand=str(takes / "bodies" / Path(BODIES[1]).name),
        side="right",
    )
    rec = run_pair(job, tmp_path, thumbnails="none")  # a body as the hand: no fingers
    assert rec["status"] == "failed" and rec["error"] and "\n" not in rec["error"]
    assert not (tmp_path / MARKER_DIR / "nohand.json").exists()

    def explode(body, hand, job):
        raise ZeroDivisionError("a bug")

    rec = run_pair(
        PairJob(**{**job.__dict__, "hand": str(takes / "hands" / Path(HANDS[0]).name)}),
        tmp_path,
        thumbnails="none",
        splice=explode,
    )
    assert rec["status"] == "failed" and rec["error"].startswith("ZeroDivisionError: a bug [")


# ---------------------------------------------------------------- manifest errors


@pytest.mark.parametrize(
    "text, line, words",
    [
        ("body,hand\na.bvh,b.bvh\n", 1, "missing column side"),
        ("body,hand,sde\na.bvh,b.bvh,right\n", 1, "unknown column 'sde'"),
        ("body,hand,side,side\n", 1, "appears twice"),
        ("body,hand,side,name\na.bvh,b.bvh,right,x\nc.bvh,d.bvh,left,x\n", 3, "already used"),
        ("body,hand,side\na.bvh,b.bvh,right,extra\n", 2, "4 values for 3 columns"),
        ("body,hand,side\n", None, "no pairs"),
        ("", None, "empty manifest"),
        ('body,hand,side\n"a.bvh,b.bvh,right\n', None, "not valid CSV"),
    ],
)
def test_manifest_errors_name_the_line(tmp_path, text, line, words):
    with pytest.raises(ManifestError) as info:
        parse_manifest(text, tmp_path / "m.csv")
    msg = str(info.value)
    assert words in msg, msg
    assert "points[" not in msg and "match[" not in msg, msg
    if line is not None:  # a matching point's cell: the line and the column
        assert msg.startswith((f"m.csv line {line}: ", f"m.csv line {line}, column match: ")), msg


@pytest.mark.parametrize(
    "text, line, words",
    [
        (
            "body,hand,side\na.bvh,b.bvh,right\n\na.bvh,b.bvh,up\n",
            4,
            "side: expected right, left, both or auto",
        ),
        (
            "body,hand,side,band\na.bvh,b.bvh,right,1.5\n",
            2,
            "band: expected a fraction of the body take",
        ),
        ("body,hand,side,band\na.bvh,b.bvh,right,nan\n", 2, "band"),
        ("body,hand,side,refine_band\na.bvh,b.bvh,right,x\n", 2, "refine_band"),
        (
            "body,hand,side,match\na.bvh,b.bvh,right,12\n",
            2,
            "m.csv line 2, column match: matching point 1: expected BODY:HAND",
        ),
        (
            "body,hand,side,match\na.bvh,b.bvh,right,10:5;8:9\n",
            2,
            "m.csv line 2, column match: matching point 2 (body 8, hand 9): body frame 8 is "
            "not after matching point 1's body frame 10;",
        ),
        (
            "body,hand,side,match\na.bvh,b.bvh,right,1:x\n",
            2,
            "m.csv line 2, column match: matching point 1 (body 1): expected a whole hand "
            "frame number >= 0, got 'x'",
        ),
        (
            "body,hand,side,match\na.bvh,b.bvh,right,1:2:-3\n",
            2,
            "column match: matching point 1 (body 1, hand 2): expected a tolerance from 0 to "
            "500 frames, got -3",
        ),
        ("body,hand,side\n,b.bvh,right\n", 2, "body: empty"),
        ("body,hand,side,name\na.bvh,b.bvh,right,../../etc/x\n", 2, "name"),
    ],
)
def test_a_bad_cell_refuses_its_row_only(tmp_path, text, line, words):
    """A bad value in one row's cell is that row's failure, in the same one line (the file,
    its line and column); the file's other rows are read (stranger 14 F10)."""
    text += "c.bvh,d.bvh,left\n"
    jobs = parse_manifest(text, tmp_path / "m.csv")
    (job,) = [j for j in jobs if j.refused]
    good = jobs[-1]
    assert job.line == line and words in job.refused, job.refused
    assert job.refused.startswith((f"m.csv line {line}: ", f"m.csv line {line}, column match: "))
    assert "points[" not in job.refused and "match[" not in job.refused
    assert good.refused == "" and good.side == "left" and Path(good.body).name == "c.bvh"


def test_manifest_paths_defaults_and_names(tmp_path):
    (tmp_path / "sub").mkdir()
    text = (
        "# a comment line\nBody , Hand,Side,band,match\n"
        "takes/a.bvh,/abs/h.bvh,RIGHT,,\n"
        "takes/a.bvh,/abs/h.bvh,right,0.25,3:4:1 9:10\n"
    )
    jobs = parse_manifest(text, tmp_path / "sub" / "m.csv")
    assert jobs[0].body == str((tmp_path / "sub" / "takes" / "a.bvh").resolve())
    assert jobs[0].hand == "/abs/h.bvh" and jobs[0].side == "right"
    assert jobs[0].band is None and jobs[0].match == ()
    assert jobs[1].band == 0.25 and jobs[1].match == ((3, 4, 1.0), (9, 10, None))
    assert jobs[0].name == "a+h-right" and jobs[1].name == "a+h-right-line4"
    assert [j.line for j in jobs] == [3, 4]


def test_cli_manifest_error_is_one_line_exit_2(tmp_path, capsys):
    manifest = tmp_path / "pairs.csv"
    manifest.write_text("body,hand,side\na.bvh,b.bvh,right\na.bvh,b.bvh,left,x\n", encoding="utf-8")
    assert main(["batch", str(manifest), "-o", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == "handsplice: error: pairs.csv line 3: 4 values for 3 columns"
    assert not (tmp_path / "o").exists()  # nothing ran
    assert main(["batch", str(tmp_path / "none.csv"), "-o", str(tmp_path / "o")]) == 2
    assert "none.csv" in capsys.readouterr().err
    assert main(["batch", str(manifest), "-o", str(tmp_path / "o"), "--workers", "0"]) == 2


# ---------------------------------------------------------------- an existing cluster


@pytest.fixture()
def one_worker_cluster():
    from distributed import Client

    from engine.jobs.batch import local_cluster

    # a task whose worker dies is failed at once (no retry): a quicker test
    cluster = local_cluster(1, config={"distributed.scheduler.allowed-failures": 0})
    client = Client(cluster)
    try:
        yield cluster, client
    finally:
        client.close()
        cluster.close()


def test_scheduler_address_and_a_dying_worker(takes, tmp_path, capsys, one_worker_cluster):
    from engine.jobs.batch import run_batch, splice_pair

    cluster, client = one_worker_cluster
    b = [f"bodies/{Path(n).name}" for n in BODIES]
    h = [f"hands/{Path(n).name}" for n in HANDS]
    manifest = _write_manifest(
        takes,
        [
            f"{b[0]},{h[0]},right,,,first",
            f"{b[1]},{h[1]},right,,,dies",
            f"{b[2]},{h[2]},right,,,last",
        ],
    )
    out = tmp_path / "out"
    # the CLI with --scheduler: the cluster's own worker runs the pairs
    assert (
        main(
            [
                "batch",
                str(manifest),
                "-o",
                str(out),
                "--scheduler",
                cluster.scheduler_address,
                "--thumbnails",
                "stick",
                "--quiet",
            ]
        )
        == 0
    )
    assert {r["status"] for r in _summary(out).values()} == {"done"}
    assert (
        main(
            [
                "batch",
                str(manifest),
                "-o",
                str(out),
                "--scheduler",
                cluster.scheduler_address,
                "--workers",
                "2",
            ]
        )
        == 2
    )
    assert "--workers applies to the local cluster" in capsys.readouterr().err

    def splice_or_die(body, hand, job):
        if job.name == "dies":
            os._exit(3)  # the worker process itself goes away (a segfault, the OOM killer)
        return splice_pair(body, hand, job)

    out2 = tmp_path / "out2"
    result = run_batch(manifest, out2, client=client, thumbnails="none", splice=splice_or_die)
    status = {r["name"]: r for r in result.records}
    assert status["dies"]["status"] == "failed", status["dies"]
    # the pair's own process died (engine.jobs.sandbox); the worker lives on for the next pair
    assert "process died (exit status 3)" in status["dies"]["error"], status["dies"]
    assert status["first"]["status"] == status["last"]["status"] == "done"


def test_a_missing_take_fails_its_pair_before_any_cluster_starts(tmp_path):
    """A manifest naming a hand file that does not exist: the pair is failed with the
    splice command's one line ('PATH: no such file', no Python class name), and no worker
    cluster is started for it (the client is never touched)."""
    from engine.jobs.batch import run_batch

    missing = tmp_path / "missing.bvh"
    manifest = tmp_path / "m.csv"
    manifest.write_text(f"body,hand,side\n{MOCAP / BODIES[0]},{missing},right\n")

    class NoCluster:
        def __getattr__(self, name):
            raise AssertionError(f"the cluster was used ({name}) for a pair with no take")

    result = run_batch(manifest, tmp_path / "out", client=NoCluster(), thumbnails="none")
    (rec,) = result.records
    assert rec["status"] == "failed"
    assert rec["error"] == f"{missing}: no such file"
    rows = list(csv.DictReader((tmp_path / "out" / "summary.csv").open()))
    assert rows[0]["error"] == f"{missing}: no such file"
    # rows with a bad cell: failed alike, before any cluster, each with its one line; at the
    # CLI the batch finishes with exit status 3 (stranger 14 F10: exit 2, nothing run)
    manifest.write_text(
        "body,hand,side,match\n"
        f"{MOCAP / BODIES[0]},{MOCAP / HANDS[0]},sideways,\n"
        f"{MOCAP / BODIES[0]},{MOCAP / HANDS[0]},right,80:20;60:30\n"
    )
    result = run_batch(manifest, tmp_path / "out", client=NoCluster(), thumbnails="none")
    assert [r["status"] for r in result.records] == ["failed", "failed"]
    assert result.records[0]["error"] == (
        "m.csv line 2: side: expected right, left, both or auto, got 'sideways'"
    )
    assert result.records[1]["error"].startswith("m.csv line 3, column match: matching point 2")
    rows = list(csv.DictReader((tmp_path / "out" / "summary.csv").open()))
    assert [r["error"] for r in rows] == [r["error"] for r in result.records]
    assert [r["line"] for r in rows] == ["2", "3"]
    assert main(["batch", str(manifest), "-o", str(tmp_path / "cli"), "--quiet"]) == 3


# ---------------------------------------------------------------- reader notes


def test_reader_notes_reach_the_pair_record_summary_page_and_progress(takes, tmp_path):
    """pyomeca's TRC (its header says 652 frames, 93 rows follow) under a file name with
    markup: the reader's note (which ``splice`` prints on stderr) is in the failed pair's
    record, its summary.csv row, the progress lines and index.html, escaped there (a marker
    body splices: the pair gives the hand take retimed to it, as ``handsplice splice``)."""
    import io
    import shutil

    from engine.jobs.batch import Progress, write_index_html, write_summary_csv

    trc = tmp_path / "<b>cut&.trc"
    shutil.copyfile(MOCAP / "pyomeca" / "markers.trc", trc)
    job = PairJob(
        line=2,
        name="cut",
        body=str(trc),
        # fingers-ok: no note of its own (hello-world's first frame has one: test_edge_glitch)
        hand=str(takes / "hands" / Path(HANDS[2]).name),
        side="right",
    )
    rec = run_pair(job, tmp_path, thumbnails="none", seconds=None, memory_mb=None)
    note = "<b>cut&.trc: the header says 652 frames, 93 were read"
    assert rec["status"] == "done" and rec["notes"] == note, rec["error"]
    write_summary_csv([rec], tmp_path / "summary.csv")
    assert _summary(tmp_path)["cut"]["notes"] == note
    page = write_index_html([rec], tmp_path / "index.html", "m.csv", 1.0).read_text("utf-8")
    assert "note: &lt;b&gt;cut&amp;.trc: the header says 652 frames, 93 were read" in page
    assert "<b>cut&" not in page
    stream = io.StringIO()
    Progress(1, stream).update(rec)
    assert f"handsplice batch: note: cut: {note}\n" in stream.getvalue()


def test_a_done_pair_keeps_its_reader_notes_in_its_report(takes, tmp_path, monkeypatch):
    """A pair that splices: the notes of both takes (each once) are in its report's
    ``reader_notes`` and its record's ``notes``, and come back when the pair is skipped."""
    from dataclasses import replace

    import engine.io as io_pkg

    read = io_pkg.load_take

    def noting(path):  # a reader that notes something about every take it reads
        take = read(path)
        notes = ("a.bvh: 3 frames & more were cut", f"{Path(path).name}: read")
        return replace(take, meta=replace(take.meta, notes=notes))

    monkeypatch.setattr(io_pkg, "load_take", noting)
    job = PairJob(
        line=2,
        name="noted",
        body=str(takes / "bodies" / Path(BODIES[0]).name),
        hand=str(takes / "hands" / Path(HANDS[0]).name),
        side="right",
    )
    rec = run_pair(job, tmp_path, thumbnails="none", seconds=None, memory_mb=None)
    assert rec["status"] == "done", rec["error"]
    body_name, hand_name = Path(BODIES[0]).name, Path(HANDS[0]).name
    expected = ["a.bvh: 3 frames & more were cut", f"{body_name}: read", f"{hand_name}: read"]
    assert rec["notes"].split(" | ") == expected
    report = json.loads((tmp_path / rec["report"]).read_text("utf-8"))
    assert report["reader_notes"] == expected
    assert is_done(job, tmp_path)["record"]["notes"] == rec["notes"]


# ---------------------------------------------------------------- marker takes


def test_batch_splices_a_marker_body_as_splice_does_and_refuses_a_marker_hand_alike(
    takes, tmp_path, capsys
):
    """A TRC body with a BVH hand: ``handsplice batch`` writes what ``handsplice splice``
    writes (the hand take retimed to the body), byte for byte; a marker hand is refused by
    both with the same one-line reason."""
    trc = MOCAP / "pyomeca" / "markers.trc"
    hand = takes / "hands" / Path(HANDS[0]).name
    job = PairJob(line=2, name="trc", body=str(trc), hand=str(hand), side="right")
    rec = run_pair(job, tmp_path / "batch", thumbnails="stick", seconds=None, memory_mb=None)
    assert rec["status"] == "done", rec["error"]
    out = tmp_path / "cli.bvh"
    assert main(["splice", str(trc), str(hand), "-o", str(out), "--side", "right"]) == 0
    capsys.readouterr()
    batch_bvh = tmp_path / "batch" / rec["output"]
    assert batch_bvh.read_bytes() == out.read_bytes()
    assert read_bvh(batch_bvh).n_frames == rec["body_frames"] == 93  # one per body frame

    refused = PairJob(line=3, name="hands", body=str(hand), hand=str(trc), side="right")
    rec = run_pair(refused, tmp_path / "batch", thumbnails="none", seconds=None, memory_mb=None)
    assert rec["status"] == "failed"
    assert main(["splice", str(hand), str(trc), "-o", str(tmp_path / "x.bvh")]) == 2
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line == f"handsplice: error: {rec['error']}"
    assert "the hand take must be a skeletal take" in line
