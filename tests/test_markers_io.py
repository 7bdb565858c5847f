"""C3D and TRC readers (MarkerSet) and load_take dispatch.

ezc3d is the independent reference for C3D: the real file and the Intel files
built here must read the same through both. Files in the other layouts (integer
data, MIPS big-endian, DEC VAX floats) are built by ``build_c3d`` below.
"""

from __future__ import annotations

import struct

import ezc3d
import numpy as np
import pytest
from conftest import MOCAP

from engine.base.errors import MotionFormatError
from engine.io import load_take, take_format
from engine.io.c3d import parse_c3d, read_c3d
from engine.io.trc import parse_trc, read_trc
from engine.model.motion import MarkerSet, Motion

C3D_FILE = MOCAP / "pyomeca/markers_analogs.c3d"
TRC_FILE = MOCAP / "pyomeca/markers.trc"


# --------------------------------------------------------------------------- real files


def test_c3d_real_file_matches_ezc3d():
    markers = read_c3d(C3D_FILE)
    ref = ezc3d.c3d(str(C3D_FILE))
    assert markers.n_frames == 580 and markers.fps == 100.0
    assert len(markers.labels) == 51
    assert markers.labels[:2] == ("boite:gauche_ext", "boite:gauche_int")
    assert markers.labels[-1] == "Daphnee:LATH"
    assert list(markers.labels) == ref["parameters"]["POINT"]["LABELS"]["value"]
    assert (markers.meta.units, markers.meta.up_axis, markers.meta.format) == ("mm", "z", "c3d")
    residual = np.transpose(ref["data"]["meta_points"]["residuals"][0])  # (F, M)
    gaps = np.isnan(markers.points).any(axis=2)
    assert gaps.sum() == 305 and np.array_equal(gaps, residual < 0)
    assert np.isnan(markers.points[gaps]).all()  # all three coordinates
    expected = np.transpose(ref["data"]["points"][:3], (2, 1, 0))
    np.testing.assert_array_equal(markers.points[~gaps], expected[~gaps])


def test_trc_real_file():
    markers = read_trc(TRC_FILE)
    assert markers.n_frames == 93  # the header says 652; the rows present win
    assert markers.fps == 100.0 and len(markers.labels) == 51
    assert markers.labels[:3] == ("ASISl", "ASISr", "PSISl")
    assert markers.labels[-1] == "boite_arriere_gauche"
    assert (markers.meta.units, markers.meta.up_axis, markers.meta.format) == ("mm", "y", "trc")
    np.testing.assert_array_equal(markers.points[0, 0], [733.7041, 80.9832, 191.8668])
    np.testing.assert_array_equal(markers.points[1, 1], [651.5213, 313.561, 179.0034])
    assert not np.isnan(markers.points).any()
    assert read_trc(TRC_FILE, up_axis="z").meta.up_axis == "z"
    with pytest.raises(ValueError, match="up_axis"):
        read_trc(TRC_FILE, up_axis="x")


def test_c3d_and_trc_of_the_same_set_share_labels():
    c3d = read_c3d(C3D_FILE).labels
    trc = read_trc(TRC_FILE).labels
    renamed = {label.replace("Daphnee:", "").replace("boite:", "boite_") for label in c3d}
    assert renamed == set(trc)


# --------------------------------------------------------------------------- C3D layouts


def _encode_float(values: np.ndarray, processor: str) -> bytes:
    v = np.asarray(values, dtype=np.float32)
    if processor == "mips":
        return v.astype(">f4").tobytes()
    if processor == "dec":  # VAX F-float: IEEE * 4 with the 16-bit halves swapped
        halves = (v * 4).astype("<f4").view("<u2").reshape(-1, 2)[:, ::-1]
        return np.ascontiguousarray(halves).tobytes()
    return v.astype("<f4").tobytes()


def build_c3d(
    points: np.ndarray,
    labels: list[str],
    rate: float = 50.0,
    scale: float = -0.1,
    processor: str = "intel",
    units: str = "mm",
    y_screen: str = "+Y",
    n_analog: int = 0,
    long_take: bool = False,
) -> bytes:
    """A minimal C3D file: POINT group (+ TRIAL for long takes), NaN points as residual -1."""
    F, M, _ = points.shape
    end = ">" if processor == "mips" else "<"
    code = {"intel": 84, "dec": 85, "mips": 86}[processor]

    def i16(x):
        return struct.pack(end + "h", x)

    def f32(x):
        return _encode_float(np.array([x]), processor)

    def chars(text, width=None):
        return text.ljust(width or len(text)).encode("ascii")

    groups = {"POINT": 1, "TRIAL": 2}
    params = [
        ("POINT", "USED", 2, (), i16(M)),
        ("POINT", "FRAMES", 2, (), i16(min(F, 32767))),
        ("POINT", "SCALE", 4, (), f32(scale)),
        ("POINT", "RATE", 4, (), f32(rate)),
        ("POINT", "UNITS", -1, (len(units),), chars(units)),
        ("POINT", "Y_SCREEN", -1, (2,), chars(y_screen)),
        ("POINT", "LABELS", -1, (8, M), b"".join(chars(lab, 8) for lab in labels)),
    ]
    if long_take:
        params += [
            ("TRIAL", "ACTUAL_START_FIELD", 2, (2,), i16(1) + i16(0)),
            ("TRIAL", "ACTUAL_END_FIELD", 2, (2,), struct.pack(end + "HH", F & 0xFFFF, F >> 16)),
        ]
    entries = []
    for name, gid in groups.items():
        entries.append(struct.pack("bb", len(name), -gid) + name.encode() + i16(3) + b"\x00")
    for group, name, ptype, dims, data in params:
        body = struct.pack("bB", ptype, len(dims)) + bytes(dims) + data + b"\x00"
        entries.append(
            struct.pack("bb", len(name), groups[group]) + name.encode() + i16(2 + len(body)) + body
        )
    last = entries[-1]
    n = last[0]
    entries[-1] = last[: 2 + n] + i16(0) + last[4 + n :]
    section = b"".join(entries)
    n_blocks = (4 + len(section)) // 512 + 1
    section = (bytes([1, 0x50, n_blocks, code]) + section).ljust(n_blocks * 512, b"\x00")
    data_start = 2 + n_blocks

    header = bytearray(512)
    header[0], header[1] = 2, 0x50
    header[2:12] = struct.pack(end + "5H", M, n_analog, 1, 0xFFFF if long_take else F, 10)
    header[12:16] = f32(scale)
    header[16:20] = struct.pack(end + "2H", data_start, 0)
    header[20:24] = f32(rate)

    gaps = np.isnan(points).any(axis=2)
    frame = np.zeros((F, M, 4))
    frame[:, :, :3] = np.where(gaps[..., None], 0.0, points)
    if scale < 0:
        frame[:, :, 3] = np.where(gaps, -1.0, 1.0)
        values = np.concatenate([frame.reshape(F, M * 4), np.zeros((F, n_analog))], axis=1)
        data = _encode_float(values.ravel(), processor)
    else:
        frame[:, :, :3] = np.round(frame[:, :, :3] / scale)
        frame[:, :, 3] = np.where(gaps, -1, 2)
        values = np.concatenate([frame.reshape(F, M * 4), np.zeros((F, n_analog))], axis=1)
        data = values.astype(end + "i2").tobytes()
    raw = bytes(header) + section + data
    return raw.ljust(-(-len(raw) // 512) * 512, b"\x00")


def _sample_points(rng, frames=12, markers=3):
    pts = rng.uniform(-900, 900, size=(frames, markers, 3))
    pts[2, 1] = np.nan
    pts[5:8, 0] = np.nan
    return pts


@pytest.mark.parametrize("processor", ["intel", "mips", "dec"])
@pytest.mark.parametrize("scale", [-0.1, 0.1])
def test_c3d_layouts(processor, scale, tmp_path):
    rng = np.random.default_rng(7)
    pts = _sample_points(rng)
    labels = ["WRIST", "STYLr", "LARMl"]
    raw = build_c3d(
        pts,
        labels,
        rate=120.0,
        scale=scale,
        processor=processor,
        units="mm",
        y_screen="+Z",
        n_analog=4,
    )
    markers = parse_c3d(raw, source="built.c3d")
    assert markers.labels == tuple(labels) and markers.fps == 120.0
    assert markers.meta.units == "mm" and markers.meta.up_axis == "z"
    assert np.array_equal(np.isnan(markers.points), np.isnan(pts))
    tol = 1e-3 if scale < 0 else abs(scale) / 2 + 1e-6  # float32 or one integer step
    np.testing.assert_allclose(markers.points[~np.isnan(pts)], pts[~np.isnan(pts)], atol=tol)
    if processor == "intel":  # the built file reads the same through ezc3d
        path = tmp_path / "built.c3d"  # (no analog samples: ezc3d takes their count from
        path.write_bytes(build_c3d(pts, labels, rate=120.0, scale=scale))  # ANALOG params)
        markers = read_c3d(path)
        ref = np.transpose(ezc3d.c3d(str(path))["data"]["points"][:3], (2, 1, 0))
        ok = ~np.isnan(pts)
        np.testing.assert_allclose(markers.points[ok], ref[ok], atol=1e-9)


def test_c3d_long_take_uses_trial_fields():
    pts = np.zeros((70000, 1, 3))
    pts[:, 0, 0] = np.arange(70000) % 1000
    markers = parse_c3d(build_c3d(pts, ["M"], long_take=True), source="long.c3d")
    assert markers.n_frames == 70000
    assert markers.points[69999, 0, 0] == pytest.approx(999)


def _flip(raw: bytes, at: int, value: int) -> bytes:
    return raw[:at] + bytes([value]) + raw[at + 1 :]


def _real() -> bytes:
    return C3D_FILE.read_bytes()


@pytest.mark.parametrize(
    "make,fragment",
    [
        (lambda: b"\x02\x50" + bytes(100), "shorter than the 512-byte header"),
        (lambda: bytes(range(256)) * 8, "header byte 2 is 0x01, expected 0x50"),
        (lambda: _real()[:100_000], "truncated C3D file (or damaged header): 580 frames need"),
        (lambda: _real()[:3000], "truncated C3D file: 3000 bytes, the parameter section needs"),
        (lambda: _flip(_real(), 512 + 3, 0), "processor type 0, expected 84"),
        (lambda: _flip(_real(), 898, 228), "damaged C3D parameter section at byte 897"),  # ezc3d
        (lambda: _flip(_real(), 16, 3), "data starts at block 3, inside the parameter section"),
        (lambda: _flip(_real(), 2, 50), "header says 50 points but POINT:USED is 51"),
    ],
)
def test_c3d_malformed(make, fragment):
    with pytest.raises(MotionFormatError) as err:
        parse_c3d(make(), source="/data/take.c3d")
    msg = str(err.value)
    assert msg.startswith("take.c3d: ") and fragment in msg and "\n" not in msg


def test_c3d_file_errors(tmp_path):
    with pytest.raises(FileNotFoundError):
        read_c3d(tmp_path / "none.c3d")
    garbage = tmp_path / "garbage.c3d"
    garbage.write_bytes(bytes(np.random.default_rng(3).integers(0, 256, 5000, dtype=np.uint8)))
    with pytest.raises(MotionFormatError, match="garbage.c3d: not a C3D file"):
        read_c3d(garbage)


# --------------------------------------------------------------------------- TRC


def _trc(rows: list[str], names=("WRIST", "ELB"), sep="\t", header=None, blank=True) -> str:
    head = header or [
        "PathFileType\t4\t(X/Y/Z)\tt.trc",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate",
        f"60\t60\t{len(rows)}\t{len(names)}\tm\t60",
    ]
    name_row = "Frame#\tTime\t" + "\t\t\t".join(names) + "\t\t"
    xyz = "\t\t" + "\t".join(f"X{i}\tY{i}\tZ{i}" for i in range(1, len(names) + 1))
    lines = head + [name_row, xyz] + ([""] if blank else []) + rows
    return "\n".join(line.replace("\t", sep) for line in lines) + "\n"


def test_trc_gaps_nan_text_crlf_and_commas():
    rows = [
        "1\t0.0\t1\t2\t3\t4\t5\t6",
        "2\t0.0167\t\t\t\t4.5\t5.5\t6.5",  # WRIST not seen
        "3\t0.0333\tNaN\tNaN\tNaN\t7\t8\t9\t\t",
    ]  # NaN text and trailing tabs
    for text in (
        _trc(rows),
        _trc(rows).replace("\n", "\r\n"),
        _trc(rows, sep=","),
        _trc(rows, blank=False),
    ):
        markers = parse_trc(text, source="t.trc")
        assert markers.labels == ("WRIST", "ELB") and markers.fps == 60.0
        assert markers.meta.units == "m" and markers.n_frames == 3
        assert np.isnan(markers.points[1:, 0]).all() and not np.isnan(markers.points[0]).any()
        np.testing.assert_array_equal(markers.points[2, 1], [7, 8, 9])


@pytest.mark.parametrize(
    "text,line,fragment",
    [
        (
            _trc(["1\t0\t1\t2\t3\t4\t5"]),
            7,
            "expected 8 values (Frame#, Time, 3 x 2 markers), found 7",
        ),
        (_trc(["1\t0\t1\t2\t3\t4\t5\t6", "2\t0.1\t1\t2"]), 8, "found 4 (file cut short?)"),
        (_trc(["1\t0\t1\t2\tabc\t4\t5\t6"]), 7, "WRIST Z: 'abc' is not a number"),
        (_trc(["1\t0\t1\t2\t3\t4\tinf\t6"]), 7, "ELB Y: 'inf' is not finite"),
        (_trc(["\t0\t1\t2\t3\t4\t5\t6"]), 7, "Frame# is empty"),
        (_trc([]), 6, "no data rows after the header"),
        ("hello\nworld\n", 2, "not a TRC file: 2 lines"),
        ("x\n" * 6, 1, "expected 'PathFileType'"),
        (
            _trc(
                ["1\t0\t1\t2\t3\t4\t5\t6"],
                header=["PathFileType\t4", "DataRate\tNumMarkers", "abc\t2"],
            ),
            3,
            "DataRate is 'abc'",
        ),
        (
            _trc(
                ["1\t0\t1\t2\t3\t4\t5\t6"],
                header=["PathFileType\t4", "DataRate\tNumMarkers", "60\t3"],
            ),
            4,
            "header says 3 markers",
        ),
        (
            _trc(
                ["1\t0\t1\t2\t3\t4\t5\t6"], header=["PathFileType\t4", "Units\tNumMarkers", "mm\t2"]
            ),
            2,
            "header has no DataRate or CameraRate",
        ),
    ],
)
def test_trc_malformed(text, line, fragment):
    with pytest.raises(MotionFormatError) as err:
        parse_trc(text, source="/x/walk.trc")
    msg = str(err.value)
    assert msg.startswith(f"walk.trc line {line}: ") and fragment in msg, msg


def test_trc_binary(tmp_path):
    path = tmp_path / "bin.trc"
    path.write_bytes(b"PathFileType\t4\n\x00\x01\x02garbage")
    with pytest.raises(MotionFormatError, match=r"bin.trc: binary data \(NUL byte at offset 15\)"):
        read_trc(path)
    path.write_bytes(bytes(range(128, 256)) * 20)
    with pytest.raises(MotionFormatError, match=r"bin.trc: binary data \(byte 0x80"):
        read_trc(path)


# --------------------------------------------------------------------------- load_take


def test_load_take_dispatch(tmp_path):
    assert isinstance(load_take(C3D_FILE), MarkerSet)
    assert isinstance(load_take(TRC_FILE), MarkerSet)
    take = load_take(MOCAP / "gestification/hello-world.bvh")
    assert isinstance(take, Motion) and take.meta.format == "bvh"
    upper = tmp_path / "HELLO.BVH"
    upper.write_bytes((MOCAP / "gestification/hello-world.bvh").read_bytes())
    assert isinstance(load_take(upper), Motion)
    assert take_format("x.Trc") == "trc"


def test_load_take_errors(tmp_path):
    with pytest.raises(
        MotionFormatError,
        match=r"walk.fbx: unknown file type \(.fbx\): "
        r"expected .bvh, .c3d or .trc",
    ):
        load_take(tmp_path / "walk.fbx")
    with pytest.raises(MotionFormatError, match="no extension"):
        load_take(tmp_path / "walk")
    with pytest.raises(FileNotFoundError) as err:
        load_take(tmp_path / "missing.bvh")
    assert err.value.filename == str(tmp_path / "missing.bvh")
    folder = tmp_path / "takes.bvh"
    folder.mkdir()
    with pytest.raises(MotionFormatError, match="takes.bvh: is a folder"):
        load_take(folder)
