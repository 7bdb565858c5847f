"""``handsplice info``: every real capture reports its roles; bad input exits 2 on one line."""

from __future__ import annotations

import json
import re
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import MOCAP, SAMPLE_DATA, mocap_files
from role_expectations import expected_roles

from engine.cli import main
from engine.io import load_take

ALL_FILES = sorted(mocap_files("**/*.bvh") + mocap_files("**/*.c3d") + mocap_files("**/*.trc"))
HANDSPLICE = Path(sys.executable).parent / "handsplice"  # the venv's console script


def _info(capsys, *argv):
    code = main(["info", *map(str, argv)])
    out, err = capsys.readouterr()
    return code, out, err


def test_all_formats_present():
    suffixes = {p.suffix for p in ALL_FILES}
    assert suffixes == {".bvh", ".c3d", ".trc"} and len(ALL_FILES) >= 29


@pytest.mark.parametrize("path", ALL_FILES, ids=lambda p: p.name)
def test_info_json_on_every_capture(path, capsys):
    code, out, err = _info(capsys, "--json", path)
    notes = load_take(path).meta.notes  # pyomeca's TRC: its header says 652 frames, 93 read
    assert code == 0 and err == "".join(f"handsplice: note: {n}\n" for n in notes)
    # the end-frame outlier rule (engine.model.edge_glitch) holds on the measured takes only
    from test_edge_glitch import GLITCHED

    outliers = [n for n in notes if "one-frame outlier pose" in n]
    assert bool(outliers) == (path.name in GLITCHED), outliers
    assert all(n.startswith(f"{path.name}: frame 0 is ") for n in outliers), outliers
    report = json.loads(out)
    assert report["file"] == str(path) and report["format"] == path.suffix[1:]
    assert report["frames"] > 0 and report["fps"] > 0
    assert report["duration_s"] == pytest.approx(report["frames"] / report["fps"], abs=1e-3)
    assert report["up_axis"] in ("y", "z")
    if path.suffix == ".bvh":
        assert report["joints"]["count"] == len(report["joints"]["names"])
        expected = expected_roles(path)
        for side, arm in expected.items():
            got = report["roles"][side]
            assert {k: got[k] for k in arm} == arm, (path.name, side)
        assert report["sides"] == [s for s in ("right", "left") if expected[s]["wrist"]]
        assert report["hand_sides"] == [
            s for s in ("right", "left") if any(expected[s]["fingers"].values())
        ]
    else:
        markers = report["markers"]
        assert markers["count"] == len(markers["labels"]) == 51
        assert set(markers["gaps"]) == set(markers["labels"])
        # pyomeca labels carry no side: the arm's markers are reported as unsided
        unsided = report["roles"]["unsided"]
        assert unsided["wrist_radial"].endswith("STYLr") and unsided["hand"].endswith("LATH")
        assert report["sides"] == []


def test_info_markers_gaps(capsys):
    _, out, _ = _info(capsys, "--json", MOCAP / "pyomeca/markers_analogs.c3d")
    report = json.loads(out)
    assert report["frames"] == 580 and report["units"] == "mm" and report["up_axis"] == "z"
    assert report["markers"]["gap_percent"] == pytest.approx(100 * 305 / (580 * 51), abs=0.01)
    assert report["markers"]["gaps"]["Daphnee:SCAP_CP"] == pytest.approx(15.86, abs=0.01)
    _, out, _ = _info(capsys, "--json", MOCAP / "pyomeca/markers.trc")
    report = json.loads(out)
    assert report["frames"] == 93 and report["markers"]["gap_percent"] == 0
    _, out, _ = _info(capsys, "--json", "--side", "right", MOCAP / "pyomeca/markers.trc")
    report = json.loads(out)
    assert report["sides"] == ["right"] and report["roles"]["right"]["elbow"] == "EPICl"


def test_info_text_is_aligned(capsys):
    code, out, _ = _info(capsys, MOCAP / "beat/1_wayne_0_1_1.bvh")
    assert code == 0
    lines = out.splitlines()
    assert lines[0].split() == ["file", "1_wayne_0_1_1.bvh"]
    column = len(lines[0]) - len("1_wayne_0_1_1.bvh")
    for line in lines:
        assert line[:column].strip() == "" or line[column - 2 : column] == "  ", line
        assert line[column] != " ", line
    text = {re.split(r"\s{2,}", line, maxsplit=1)[0]: line for line in lines if line[0] != " "}
    assert text["frames"].split()[-1] == "250" and text["fps"].split()[-1] == "30"
    assert "wrist=right_wrist" in out and "index[right_index1 right_index2 right_index3]" in out
    assert "units          m" in out


def test_info_side_and_roles_options(tmp_path, capsys):
    mug = MOCAP / "manipnet/mug1_rightHand.bvh"
    _, out, _ = _info(capsys, "--json", mug)
    assert json.loads(out)["roles"]["right"]["wrist"] == "WRIST"  # side from the file name
    _, out, _ = _info(capsys, "--json", "--side", "left", mug)
    report = json.loads(out)
    assert report["roles"]["left"]["wrist"] == "WRIST" and report["sides"] == ["left"]
    mapping = tmp_path / "map.json"
    mapping.write_text(json.dumps({"right.wrist": "LowerArm_R", "right.hand": "Hand_R"}))
    bandai = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
    _, out, _ = _info(capsys, "--json", "--roles", mapping, bandai)
    roles = json.loads(out)["roles"]
    assert roles["right"]["wrist"] == "LowerArm_R" and roles["right"]["hand"] == "Hand_R"
    assert roles["side_source"]["right"] == "override"


def test_sample_data_is_described(capsys):
    listing = json.loads((SAMPLE_DATA / "samples.json").read_text())
    demo = listing["demo"]
    for key in ("body", "hand"):
        code, out, _ = _info(capsys, "--json", SAMPLE_DATA / demo[key])
        report = json.loads(out)
        assert code == 0 and demo["side"] in report["sides"]
    hand = json.loads(_info(capsys, "--json", SAMPLE_DATA / demo["hand"])[1])
    assert demo["side"] in hand["hand_sides"]
    for sample in listing["samples"]:
        path = SAMPLE_DATA / sample["file"]
        assert path.is_file(), sample["file"]
        if sample.get("licence_file"):
            assert (SAMPLE_DATA / sample["licence_file"]).is_file()
    total = sum(p.stat().st_size for p in SAMPLE_DATA.rglob("*") if p.is_file())
    assert total < 10 * 1024 * 1024


def test_info_describes_a_glb_export(tmp_path, capsys):
    """Stranger 7: ``info`` refused the app's own GLB ("unknown file type (.glb)"). It
    describes one now: frames, rate, duration, the skin and animation, the skin's joints
    and their roles; the thumb chain lists every joint (ManipNet's THUMB_CMC_AA was
    left out of BVH and GLB listings alike)."""
    hand = SAMPLE_DATA / "manipnet/mug1_rightHand.bvh"
    glb = tmp_path / "mug1_rightHand.glb"
    assert main(["render", str(hand), "-o", str(glb), "--frames", "0:30", "--quiet"]) == 0
    capsys.readouterr()
    code, out, err = _info(capsys, glb)
    assert code == 0 and err == "", err
    text = " ".join(out.split())
    for line in (
        "format GLB (binary glTF 2.0)",
        "frames 30",
        "fps 120",
        "duration 0.250 s",
        "joints 17 (the skin's)",
        "animation take: ",
        "30 frames at 120 fps",
        "right fingers thumb[THUMB_CMC_FE THUMB_CMC_AA THUMB_MCP_FE THUMB_IP_FE]",
    ):
        assert line in text, (line, out)
    code, out, _ = _info(capsys, "--json", glb)
    report = json.loads(out)
    assert report["format"] == "glb" and report["hand_sides"] == ["right"]
    assert report["joints"]["names"] == list(load_take(hand).skeleton.names)
    assert report["skin"]["vertices"] > 1000 and report["animations"][0]["channels"] >= 17
    # the BVH's listing names the same chain
    code, out, _ = _info(capsys, hand)
    assert "thumb[THUMB_CMC_FE THUMB_CMC_AA THUMB_MCP_FE THUMB_IP_FE]" in out


# --------------------------------------------------------------------------- bad input


def _bandai_lines() -> list[str]:
    path = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
    return path.read_text().split("\n")


def _data_line(lines: list[str]) -> int:
    return next(i for i, line in enumerate(lines) if line.startswith("Frame Time")) + 1


def _make_bad_inputs(folder: Path) -> dict[str, tuple[Path, str]]:
    """name -> (file, text the one-line error must contain)."""
    lines = _bandai_lines()
    first = _data_line(lines)
    out = {}
    path = folder / "truncated.bvh"
    path.write_text("\n".join(lines[: first + 20]) + "\n" + lines[first + 20][:40])
    out["truncated BVH"] = (path, f"truncated.bvh line {first + 21}: ")
    bad = list(lines)
    bad[first + 5] = " ".join(bad[first + 5].split()[:-3])
    path = folder / "count.bvh"
    path.write_text("\n".join(bad))
    out["wrong value count"] = (path, f"count.bvh line {first + 6}: expected 132 values, found 129")
    bad = list(lines)
    values = bad[first + 2].split()
    values[10] = "NaN"
    bad[first + 2] = " ".join(values)
    path = folder / "nan.bvh"
    path.write_text("\n".join(bad))
    out["NaN text"] = (path, f"nan.bvh line {first + 3}: ")
    path = folder / "garbage.bvh"
    path.write_bytes(bytes(range(256)) * 16)
    out["binary garbage"] = (path, "garbage.bvh line 1: binary data")
    path = folder / "garbage.c3d"
    path.write_bytes(bytes(range(255, -1, -1)) * 16)
    out["binary garbage c3d"] = (path, "garbage.c3d: not a C3D file")
    path = folder / "bad.trc"
    path.write_text((MOCAP / "pyomeca/markers.trc").read_text().replace("733.7041", "7x3"))
    out["bad TRC value"] = (path, "bad.trc line 7: ASISl X: '7x3' is not a number")
    path = folder / "picture.glb"
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(64))
    out["not a GLB"] = (path, "picture.glb: not a GLB file (no binary glTF header)")
    text = b'{"nodes":[{"name":"a","children":7}],"skins":[{"joints":[0]}]}  '
    path = folder / "broken.glb"
    path.write_bytes(
        b"glTF" + struct.pack("<IIII", 2, 20 + len(text), len(text), 0x4E4F534A) + text
    )
    out["broken GLB"] = (path, "broken.glb: ")
    path = folder / "walk.fbx"
    path.write_text("FBX")
    out["unknown extension"] = (path, "walk.fbx: unknown file type (.fbx): expected .bvh, .c3d")
    out["missing file"] = (folder / "missing.bvh", "missing.bvh")
    path = folder / "empty.bvh"
    path.write_text("")
    out["empty BVH"] = (path, "empty.bvh: the file is empty")
    return out


BAD_CASES = [
    "truncated BVH",
    "wrong value count",
    "NaN text",
    "binary garbage",
    "binary garbage c3d",
    "bad TRC value",
    "unknown extension",
    "not a GLB",
    "broken GLB",
    "missing file",
    "empty BVH",
]


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_input_via_main(case, tmp_path, capsys):
    path, fragment = _make_bad_inputs(tmp_path)[case]
    code, out, err = _info(capsys, path)
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("handsplice: error: "), err
    assert fragment in err and "Traceback" not in err


@pytest.mark.parametrize("case", BAD_CASES)
def test_bad_input_via_console_script(case, tmp_path):
    path, fragment = _make_bad_inputs(tmp_path)[case]
    proc = subprocess.run(
        [str(HANDSPLICE), "info", "--json", str(path)], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("handsplice: error: ")
    assert fragment in proc.stderr and "Traceback" not in proc.stderr


def test_bad_roles_file(tmp_path, capsys):
    bandai = MOCAP / "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh"
    mapping = tmp_path / "roles.json"
    mapping.write_text('{"right.wrist": "Hand_R",\n "right.elbow": }')
    code, _, err = _info(capsys, "--roles", mapping, bandai)
    assert (
        code == 2
        and "roles.json: line 2, column 17: not valid JSON" in err
        and err.count("\n") == 1
    )
    mapping.write_text('{"right.wrist": "Hnad_R"}')
    code, _, err = _info(capsys, "--roles", mapping, bandai)
    assert code == 2 and "right.wrist: the skeleton has no joint named 'Hnad_R'" in err
    assert "Hand_R" in err
    code, _, err = _info(capsys, "--roles", tmp_path / "none.json", bandai)
    assert code == 2 and "none.json" in err
    code, _, err = _info(capsys, "--roles", mapping, MOCAP / "pyomeca/markers.trc")
    assert code == 2 and "--roles applies to skeletal takes" in err


def test_console_script_text_and_json():
    path = MOCAP / "gestification/hello-world.bvh"
    proc = subprocess.run(
        [str(HANDSPLICE), "info", str(path)], capture_output=True, text=True, timeout=120
    )
    note = "hello-world.bvh: the header says 82 frames, the file has 83 data rows"
    assert proc.returncode == 0 and proc.stderr.startswith(f"handsplice: note: {note}: the first")
    assert "right fingers" in proc.stdout and "rMid1 rMid2 rMid3" in proc.stdout
    proc = subprocess.run(
        [str(HANDSPLICE), "info", "--json", str(path)], capture_output=True, text=True, timeout=120
    )
    report = json.loads(proc.stdout)
    assert report["frames"] == 82 and report["roles"]["right"]["elbow"] == "rForeArm"
    assert report["notes"][0].split(": the first")[0] == note  # stranger 14 F4
