"""``handsplice splice``: output, report, progress, and one-line errors with exit status 2."""

from __future__ import annotations

import json

import pytest
from conftest import MOCAP

from engine.cli import main
from engine.io.bvh import read_bvh
from engine.model.roles import find_roles

BODY = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
HAND = MOCAP / "gestification/hello-world.bvh"


def test_splice_writes_bvh_report_and_progress(tmp_path, capsys, monkeypatch):
    import re
    import time

    import engine.cli.splice as cli_splice

    # a first run on a machine says its stages' times include compiling (stranger 8 read
    # "pass 1 done (64.89 s)" on a cold cache)
    monkeypatch.setattr(cli_splice, "kernels_cached", lambda: False)
    out, rep = tmp_path / "out.bvh", tmp_path / "r.json"
    t0 = time.perf_counter()
    code = main(
        [
            "splice",
            str(BODY),
            str(HAND),
            "-o",
            str(out),
            "--report",
            str(rep),
            "--match",
            "60:40:3",
            "--band",
            "0.4",
            "--refine-band",
            "0.15",
        ]
    )
    wall = time.perf_counter() - t0
    assert code == 0
    err = capsys.readouterr().err
    assert "pass 1" in err and "pass 2" in err and f"wrote {out}" in err
    assert err.startswith("splice: first run on this machine: compiling the kernels")
    # the time said is what the user waited for (it said 'spliced in 3.02 s' for a 14.8 s
    # run: the trust stage and the reading were not counted), and names what it covers
    said = re.search(r"(\d+\.\d+) s in all \(splice (\d+\.\d+) s; the rest: ", err)
    assert said, err
    in_all, splice_s = float(said.group(1)), float(said.group(2))
    stages = sum(float(t) for t in re.findall(r"^splice: .* done \((\d+\.\d+) s\)$", err, re.M))
    trust_s = float(re.search(r"^splice: trust done \((\d+\.\d+) s\)$", err, re.M).group(1))
    assert splice_s + trust_s - 0.02 <= in_all <= wall + 0.01
    assert stages - 0.05 <= in_all
    report = json.loads(rep.read_text())
    from engine.splice.report import unmatched_summary

    unmatched = unmatched_summary(report["unmatched_body"], 30.0)
    # (the sentence may go on to say an end was cut by the open-end limit)
    assert (f"\nsplice: {unmatched}" in err) == bool(unmatched)
    motion = read_bvh(out)
    assert motion.n_frames == read_bvh(BODY).n_frames
    assert find_roles(motion.skeleton).side("right").has_fingers
    report = json.loads(rep.read_text())
    assert len(report["map"]) == motion.n_frames
    assert report["parameters"]["points_given"] == [[60, 40, 3.0]]
    assert report["parameters"]["band"] == 0.4 and report["parameters"]["refine_band"] == 0.15
    # the matching point holds on the path: body 60 -> hand 40 +- 3 (hand-take frames; on
    # the alignment grid as the report gives it); the smoothed map stays within a blend of it
    [(x, y, tol)] = report["parameters"]["points"]
    cols = [j for i, j in report["pass2"]["path"] if i == x]
    assert x == 60 and cols and all(abs(j - y) <= tol for j in cols)
    assert abs(report["map"][60] - 40) <= 3 + 2
    # trust: one uncertainty per body frame, strokes with verdicts, the CLI's summary line
    assert len(report["uncertainty_ms"]) == motion.n_frames
    assert all(u >= 0 for u in report["uncertainty_ms"])
    # a pair the motion does not pin (typical uncertainty over 100 ms) is judged against
    # that typical level; strokes outside the overlap are not timed
    words = (
        ("ok", "check", "desync") if report["desync"]["pinned"] else ("typical", "check", "desync")
    )
    assert report["desync"]["pinned"] == (report["desync"]["typical_ms"] <= 100.0)
    assert all(
        s["verdict"] in (*words, "unmatched") and s["start"] <= s["end"] for s in report["strokes"]
    )
    assert report["desync"]["summary"] in err
    assert 1 <= len(report["suggested_points"]) <= 3


def test_quiet_prints_nothing(tmp_path, capsys):
    """No progress; only the reader's notes (the hand file's extra zero row), which are
    the file's, not the command's progress."""
    assert main(["splice", str(BODY), str(HAND), "-o", str(tmp_path / "o.bvh"), "--quiet"]) == 0
    notes = read_bvh(HAND).meta.notes
    assert notes and capsys.readouterr().err == "".join(f"handsplice: note: {n}\n" for n in notes)


def test_roles_file_maps_an_unusual_name(tmp_path):
    roles = tmp_path / "roles.json"
    roles.write_text(json.dumps({"body": {"right.wrist": "Hand_R"}}))
    assert (
        main(
            [
                "splice",
                str(BODY),
                str(HAND),
                "-o",
                str(tmp_path / "o.bvh"),
                "--quiet",
                "--roles",
                str(roles),
            ]
        )
        == 0
    )


@pytest.mark.parametrize(
    "args,message",
    [
        (["{body}", str(MOCAP / "lafan1/dance1_subject1.bvh")], "no finger joints"),
        (["{body}", str(MOCAP / "pyomeca/markers.trc")], "holds markers"),
        (["{body}", "{hand}", "--side", "left"], "no left hand"),
        (
            ["{body}", "{hand}", "--match", "12"],
            "error: --match 12: matching point 1: expected BODY:HAND or BODY:HAND:TOL",
        ),
        (
            ["{body}", "{hand}", "--match", "a:b"],
            "error: --match a:b: matching point 1: expected a whole body frame number >= 0, got 'a'",
        ),
        (
            ["{body}", "{hand}", "--match", "40:30", "--match", "5000:40"],
            "error: --match 5000:40: matching point 2 (body 5000, hand 40): outside the takes; "
            "expected body frames 0 to ",
        ),
        (
            ["{body}", "{hand}", "--match", "50:40", "--match", "40:60"],
            "error: --match 40:60: matching point 2 (body 40, hand 60): body frame 40 is not "
            "after matching point 1's body frame 50; body frames must increase",
        ),
        (["{body}", "{hand}", "--band", "-1"], "band: expected a fraction"),
        (["{body}", "{hand}", "--band", "0.01"], "band: expected a fraction"),
        (
            ["{body}", "{hand}", "--match", "40:30:1000"],
            "error: --match 40:30:1000: matching point 1 (body 40, hand 30): expected a "
            "tolerance from 0 to 500 frames, got 1000",
        ),
        (["{body}", "{hand}", "--preview", "x.txt"], "--preview"),
        (["{body}", "/nonexistent/take.bvh"], "take.bvh"),
        # a hand take given as the body (Leap: forearm, hand, fingers; ManipNet: no forearm)
        (["{hand}", "{hand}"], "no right shoulder or clavicle above the elbow"),
        ([str(MOCAP / "manipnet/mug1_rightHand.bvh"), "{hand}"], "looks like a hand take"),
        # the two swapped: the fingerless body as the hand (stranger 8 wanted the hint)
        (["{hand}", "{body}"], "has fingers: are body and hand swapped?"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, args, message):
    argv = (
        ["splice"]
        + [a.format(body=BODY, hand=HAND) for a in args]
        + ["-o", str(tmp_path / "o.bvh"), "--quiet"]
    )
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("handsplice: error:") and message in err[0]
    assert not (tmp_path / "o.bvh").exists()


def test_output_must_be_bvh(tmp_path, capsys):
    assert main(["splice", str(BODY), str(HAND), "-o", str(tmp_path / "o.fbx")]) == 2
    assert ".bvh" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv",
    [
        ["splice", str(BODY), str(HAND), "-o", "{missing}/o.bvh"],
        ["splice", str(BODY), str(HAND), "-o", "{tmp}/o.bvh", "--report", "{missing}/r.json"],
        ["splice", str(BODY), str(HAND), "-o", "{tmp}/o.bvh", "--preview", "{missing}/p.gif"],
        ["render", str(BODY), "-o", "{missing}/o.png"],
        ["synthesize", str(BODY), "-o", "{missing}/o.bvh"],
        ["analyze", str(BODY), "--csv", "{missing}/o.csv"],
    ],
)
def test_an_output_in_a_missing_folder_is_refused_at_once(tmp_path, capsys, argv):
    """A typo in an output's folder is refused in one line (exit 2) before any work; no
    folder is created and nothing is written."""
    missing = tmp_path / "no-such-folder"
    args = [a.format(missing=missing, tmp=tmp_path) for a in argv]
    with pytest.raises(SystemExit) as info:
        main(args)
    assert info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "no-such-folder does not exist" in err[0], err
    assert not missing.exists() and not (tmp_path / "o.bvh").exists()


def test_preview_renders_the_spliced_take(tmp_path):
    png = tmp_path / "preview.png"
    code = main(
        [
            "splice",
            str(BODY),
            str(HAND),
            "-o",
            str(tmp_path / "o.bvh"),
            "--quiet",
            "--preview",
            str(png),
        ]
    )
    assert code == 0 and png.stat().st_size > 1000


def test_session_file_from_the_app_gives_the_apps_map(tmp_path, sample_dir):
    """``--session`` reads the JSON the app downloads: same side, bands, tolerance, points
    (alignment-grid frames) and roles, hence the same frame map; flags override it."""
    import numpy as np

    from engine.io.session import read_session
    from webapp import config
    from webapp.state import Session

    cfg = config.AppConfig(sample_dir=sample_dir.resolve(), upload_dir=tmp_path / "up")
    app = Session(cfg)
    app.load_sample("bye-hello")
    app.set_roles({"body": {"right.wrist": "Hand_R"}})
    app.param.update(band=0.25, refine_band=0.08)
    app.add_point(40, 30, 2)
    app.add_point(80, 50)
    app.tolerance = 1
    assert app.error == "" and len(app.points) == 2
    session = tmp_path / "handsplice-session.json"
    session.write_text(app.to_json())  # what the app's "Session JSON" button downloads
    assert read_session(session).roles == {"body": {"right.wrist": "Hand_R"}}
    pair = cfg.sample("bye-hello")
    rep = tmp_path / "r.json"
    assert (
        main(
            [
                "splice",
                str(pair.body),
                str(pair.hand),
                "-o",
                str(tmp_path / "o.bvh"),
                "--session",
                str(session),
                "--report",
                str(rep),
                "--quiet",
            ]
        )
        == 0
    )
    report = json.loads(rep.read_text())
    app_map = np.asarray(app.solution.cache["engine"].map)
    assert np.allclose(report["map"], app_map, atol=1e-4)  # the report keeps 4 decimals
    params = report["parameters"]
    assert params["band"] == 0.25 and params["refine_band"] == 0.08
    assert params["points_given"] == [[40, 30, 2.0], [80, 50, 1.0]]
    # flags win over the file: --band, and --match replaces the file's points
    rep2 = tmp_path / "r2.json"
    assert (
        main(
            [
                "splice",
                str(pair.body),
                str(pair.hand),
                "-o",
                str(tmp_path / "o2.bvh"),
                "--session",
                str(session),
                "--report",
                str(rep2),
                "--quiet",
                "--band",
                "0.4",
                "--match",
                "60:40",
            ]
        )
        == 0
    )
    params = json.loads(rep2.read_text())["parameters"]
    assert params["band"] == 0.4 and params["refine_band"] == 0.08
    assert params["points_given"] == [[60, 40, 0.0]]


def test_session_file_of_other_takes_is_said_in_one_line(tmp_path, capsys):
    """A session the app made on another body take (its sha256 in the file) replayed on
    BODY: one warning line naming the file, the take and that its points were placed on
    that take; the splice is still written (stranger 14 F3). On its own takes: no word."""
    import hashlib

    digest = {f: hashlib.sha256(f.read_bytes()).hexdigest() for f in (BODY, HAND)}
    session = tmp_path / "handsplice-session.json"

    def replay(body_sha: str) -> list[str]:
        session.write_text(
            json.dumps(
                {
                    "format": "handsplice-session",
                    "version": 2,
                    "inputs": {
                        "body": {"sha256": body_sha, "name": "session1_body_wave.bvh"},
                        "hand": {"sha256": digest[HAND], "name": HAND.name},
                    },
                    "points": [{"body": 40, "hand": 7, "tolerance": None}],
                }
            )
        )
        out = tmp_path / "t.bvh"
        argv = ["splice", str(BODY), str(HAND), "-o", str(out), "--session", str(session)]
        assert main([*argv, "--quiet"]) == 0 and out.is_file()
        err = capsys.readouterr().err.strip().splitlines()
        return [line for line in err if not line.startswith("handsplice: note:")]

    assert replay(digest[BODY]) == []
    assert replay("0" * 64) == [
        "handsplice: warning: handsplice-session.json was made on body take "
        f"session1_body_wave.bvh, not {BODY.name}: its matching points were placed on that take"
    ]


def test_bad_session_file_is_one_line(tmp_path, capsys):
    bad = tmp_path / "s.json"
    bad.write_text('{"points": [{"body": 5}]}')
    assert (
        main(
            [
                "splice",
                str(BODY),
                str(HAND),
                "-o",
                str(tmp_path / "o.bvh"),
                "--quiet",
                "--session",
                str(bad),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "handsplice: error: s.json: matching point 1 (body 5): expected a hand frame, none was given"
    ]


@pytest.mark.parametrize(
    "argv",
    [
        ["splice", str(BODY), str(HAND), "-o", "/nonexistent/dir/o.bvh"],
        ["splice", str(BODY), str(HAND)],
        ["splice", "--band"],
        ["info", "--no-such-flag"],
        ["analyze", "--no-such-flag"],
        ["synthesize", "--no-such-flag"],
        ["render", "--no-such-flag"],
        ["batch", "--no-such-flag"],
        ["serve", "--no-such-flag"],
        ["no-such-command"],
    ],
)
def test_argument_errors_are_the_readmes_one_line_form(argv, capsys):
    """Every subcommand's argument errors: 'handsplice: error: ...' on one line, exit 2
    (argparse wrote 'handsplice splice: error: argument -o/--output: ...')."""
    with pytest.raises(SystemExit) as info:
        main(argv)
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("handsplice: error: "), err
    assert "argument " not in err and "usage:" not in err, err
    if "-o" in argv:
        assert err.startswith("handsplice: error: -o/--output: /nonexistent/dir/o.bvh: the folder")


def test_an_end_cut_by_max_unmatched_is_named_in_the_unmatched_sentence(tmp_path, capsys):
    """The demo pair leaves 30 and 23 body frames unmatched with the default limit; with
    --max-unmatched 0.5 (15 frames) both ends stop at the limit, and the sentence says the
    limit, not the data, cut them."""
    body = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
    hand = MOCAP / "gestification/fingers-ok.bvh"
    out = tmp_path / "o.bvh"
    argv = ["splice", str(body), str(hand), "-o", str(out), "--side", "right"]
    assert main(argv + ["--max-unmatched", "0.5"]) == 0
    err = capsys.readouterr().err
    line = next(x for x in err.splitlines() if "have no hand match" in x)
    assert line.startswith("splice: body frames 0-14, 172-186 (1.0 s) have no hand match"), line
    assert "15 frames (0.5 s) at an end is the open-end limit (--max-unmatched)" in line


#: a refused flag value and its message: the flag as typed (``engine.cli.flag_for``)
FLAG_REFUSALS = [
    (  # stranger R4-6: it named the engine's field max_unmatched_s
        ["splice", "{body}", "{hand}", "-o", "{tmp}/o.bvh", "--max-unmatched", "-1"],
        "--max-unmatched: expected a number of seconds from 0 to 3600, got -1",
    ),
    (  # argparse's "invalid float value" before
        ["splice", "{body}", "{hand}", "-o", "{tmp}/o.bvh", "--max-unmatched=abc"],
        "--max-unmatched: expected a number of seconds from 0 to 3600, got 'abc'",
    ),
    (  # a prefix argparse takes for the flag
        ["splice", "{body}", "{hand}", "-o", "{tmp}/o.bvh", "--max-unm", "1e9"],
        "--max-unmatched: expected a number of seconds from 0 to 3600, got 1e+09",
    ),
    (
        ["splice", "{body}", "{hand}", "-o", "{tmp}/o.bvh", "--band", "5"],
        "--band: expected a fraction of the body take from 0.02 to 1",
    ),
    (
        ["splice", "{body}", "{hand}", "-o", "{tmp}/o.bvh", "--refine-band", "0s"],
        "--refine-band: expected a fraction of the body take from 0.01 to 1",
    ),
    (
        ["render", "{body}", "-o", "{tmp}/o.png", "--size", "0x0"],
        "--size 0x0: width and height must lie in 16..4096",
    ),
    (  # "phase parameter hold_speed: ..." before
        ["analyze", "{body}", "--hold-speed", "-5"],
        "--hold-speed: expected a positive number (phase parameter), got -5.0",
    ),
    (  # "handedness threshold: ..." before
        ["analyze", "{body}", "--threshold", "-1"],
        "--threshold: expected a handedness threshold >= 0 (m/s), got -1.0",
    ),
    (
        ["batch", "{tmp}/pairs.csv", "-o", "{tmp}/out", "--pair-seconds", "-1"],
        "--pair-seconds: expected a number >= 0 (0: no limit), got -1.0",
    ),
    (
        ["batch", "{tmp}/pairs.csv", "-o", "{tmp}/out", "--pair-memory-mb", "nan"],
        "--pair-memory-mb: expected a number >= 0 (0: no limit), got nan",
    ),
    (  # accepted silently before (a Python index from the end)
        ["render", "{body}", "-o", "{tmp}/o.png", "--frame", "-1"],
        "--frame -1: expected a frame from 0 (the first) to the take's last",
    ),
    (
        ["render", "{body}", "-o", "{tmp}/o.gif", "--frames", "5:x"],
        "--frames '5:x': A and B must be integers",
    ),
    (  # "slice step cannot be zero" before
        ["render", "{body}", "-o", "{tmp}/o.glb", "--frames", "0:9:0"],
        "--frames '0:9:0': the step must be a whole number >= 1",
    ),
    (  # "flexion warp factor: ..." before
        ["synthesize", "{body}", "-o", "{tmp}/o.bvh", "--warp", "-1"],
        "--warp: expected a flexion scale factor >= 0 (1: as captured), got -1.0",
    ),
    (
        ["render", "{body}", "-o", "{tmp}/o.png", "--size=-5x10"],
        "--size '-5x10': expected WIDTHxHEIGHT from 16 to 4096, e.g. 640x480",
    ),
    (
        ["synthesize", "{body}", "-o", "{tmp}/o.bvh", "--poses", "fist@x"],
        "pose key 'fist@x': frame 'x' is not an integer",
    ),
]


@pytest.mark.parametrize("args, message", FLAG_REFUSALS)
def test_a_bad_flag_value_names_the_flag_typed(tmp_path, capsys, args, message):
    """A refused flag value is named by the flag the user typed (one rule,
    ``engine.cli.flag_for``), never by the engine's name of the value; one line, exit 2."""
    argv = [a.format(body=BODY, hand=HAND, tmp=tmp_path) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"handsplice: error: {message}") and err.count("\n") == 1, err
    assert "Traceback" not in err and "_s:" not in err and "pair_" not in err
    assert not (tmp_path / "o.bvh").exists() and not (tmp_path / "out").exists()


@pytest.mark.parametrize("args, message", FLAG_REFUSALS)
def test_a_bad_flag_value_is_refused_before_any_take_is_read(tmp_path, capsys, args, message):
    """Stranger R5-9: a mistyped flag value cost the wait for the takes to be read (15-20 s
    on long takes). With takes that do not exist, the flag's own message still comes: it is
    checked before any take is opened, in the same words."""
    body, hand = tmp_path / "absent_body.bvh", tmp_path / "absent_hand.bvh"
    argv = [a.format(body=body, hand=hand, tmp=tmp_path) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"handsplice: error: {message}") and err.count("\n") == 1, err


@pytest.mark.parametrize(
    "args, message",
    [
        (["--frame", "201"], "--frame 201: expected a frame from 0 to 200 (the take has 201"),
        (["--frames", "300:400"], "--frames '300:400': selects no frame of a take with 201"),
    ],
)
def test_a_frame_beyond_the_take_says_what_the_take_has(tmp_path, capsys, args, message):
    """A frame past the take's end is refused in one line that names the flag and the
    take's frames (201 here)."""
    take = MOCAP / "bandai-namco" / "dataset-2_wave-both-hands_normal_001.bvh"
    out = tmp_path / ("o.png" if args[0] == "--frame" else "o.gif")
    assert main(["render", str(take), "-o", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"handsplice: error: {message}") and err.count("\n") == 1, err
    assert not out.exists()


def test_a_value_starting_with_a_dash_is_told_how_to_be_given(capsys):
    """argparse takes ``-5x10`` for a flag ("--size: expected one argument"): the line says
    how to give such a value, which is then judged (``--size=-5x10`` above)."""
    with pytest.raises(SystemExit) as info:
        main(["render", str(BODY), "-o", "o.png", "--size", "-5x10"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert err == (
        "handsplice: error: --size: expected a value (one that starts with '-' goes as "
        "--size=VALUE)\n"
    )


def test_a_value_named_like_a_flag_not_given_keeps_its_name():
    """Only a flag given on the command line renames the message (a file's or another
    source's message keeps its words)."""
    from engine.cli import named_as_typed

    text = "band: expected a fraction"
    assert named_as_typed(text, ["splice", "b.bvh", "--band", "5"]) == "--band: expected a fraction"
    assert named_as_typed(text, ["splice", "b.bvh", "--session", "s.json"]) == text
    assert named_as_typed("walk.bvh line 3: bad", ["render", "--frame", "3"]) == (
        "walk.bvh line 3: bad"
    )


def test_the_kernel_cache_is_known_cold_or_warm(tmp_path, monkeypatch):
    from engine.base.jit import kernels_cached

    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    assert not kernels_cached()
    (tmp_path / "engine" / "dtw").mkdir(parents=True)
    (tmp_path / "engine" / "dtw" / "kernels.forward-12.py311.nbi").write_bytes(b"x")
    assert kernels_cached()


@pytest.mark.parametrize(
    "matches, first, last",
    [(["60:0"], 60, None), (["150:81:0"], None, 150), (["40:7:3", "150:79:3"], None, 147)],
)
def test_a_point_on_the_hand_takes_first_or_last_frame_pins_where_the_hand_starts_or_ends(
    tmp_path, matches, first, last
):
    """Stranger 14 F1: ``--match 60:0`` (the hand's first frame at body frame 60) started
    the hand at body frame 102, and a point on (or whose tolerance reached) the hand's
    last frame, 81, let it end at body frame 103: the open ends skipped the points' rows.
    The matched body frames now run from the point (or before) to the point (or after)."""
    rep = tmp_path / "r.json"
    args = ["splice", str(BODY), str(HAND), "-o", str(tmp_path / "o.bvh"), "--side", "right"]
    for m in matches:
        args += ["--match", m]
    assert main([*args, "--report", str(rep), "--quiet"]) == 0
    body0, body1 = json.loads(rep.read_text())["overlap"]["body"]
    if first is not None:
        assert body0 <= first, (body0, body1)
    if last is not None:
        assert body1 >= last, (body0, body1)
