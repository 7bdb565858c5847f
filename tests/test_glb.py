"""Share in 3D: the spliced take as GLB (glTF 2.0, skinned mannequin with its animation).

Checked by independent readers: pygltflib (structure), the Khronos glTF validator
(tests/js, run with Playwright's bundled node) and three.js's GLTFLoader in Chromium;
the joint positions computed from the file's node animation (here by hand, and by
three.js) match the BVH's forward kinematics, and the file's skinning reproduces the
renderer's mannequin.
"""

from __future__ import annotations

import asyncio
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
from conftest import ROOT, SAMPLE_DATA, mocap_files, open_demo_session

from engine.cli import main
from engine.io.bvh import read_bvh
from engine.model import rotations as rot
from engine.model.kinematics import forward_kinematics

JS = ROOT / "tests" / "js"
BODY = SAMPLE_DATA / "bandai-namco" / "dataset-2_wave-right-hand_normal_001.bvh"  # cm, Y up
HAND = SAMPLE_DATA / "gestification" / "fingers-ok.bvh"
TOL_M = 1e-4  # 0.1 mm: float32 storage of metre-scale values


def _js_ready() -> None:
    if not (JS / "node_modules" / ".installed").exists():
        raise AssertionError(
            "tests/js/node_modules is missing: run `make js` (npm ci in "
            "tests/js; `make test` does it)"
        )


@pytest.fixture(scope="module")
def spliced(tmp_path_factory):
    """The demo pair spliced by the CLI, and its GLB written by `handsplice render`."""
    out = tmp_path_factory.mktemp("glb")
    bvh, glb = out / "spliced.bvh", out / "spliced.glb"
    assert main(["splice", str(BODY), str(HAND), "-o", str(bvh), "--side", "right"]) == 0
    assert main(["render", str(bvh), "-o", str(glb), "--quiet"]) == 0
    return read_bvh(bvh), glb


@pytest.fixture(scope="module")
def gltf(spliced):
    import pygltflib  # a test dependency (pyproject [test])

    doc = pygltflib.GLTF2().load_binary(str(spliced[1]))
    return doc, doc.binary_blob()


def accessor(doc, blob: bytes, index: int) -> np.ndarray:
    """An accessor's data as (count, components) numpy, read per the glTF spec."""
    acc = doc.accessors[index]
    view = doc.bufferViews[acc.bufferView]
    dtype = {5126: "<f4", 5125: "<u4", 5123: "<u2", 5121: "u1"}[acc.componentType]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc.type]
    assert view.byteStride in (None, 0, width * np.dtype(dtype).itemsize)
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    data = np.frombuffer(blob, dtype=dtype, count=acc.count * width, offset=start)
    return data.reshape(acc.count, width).astype(float)


def expected_positions(motion) -> np.ndarray:
    """(F, J, 3) metres, Y up: the BVH's FK in centimetres, times 0.01."""
    assert motion.meta.units == "cm" and motion.meta.up_axis == "y"
    return forward_kinematics(motion)[0] * 0.01


def animated_world(doc, blob: bytes, n_frames: int) -> tuple[np.ndarray, list[str]]:
    """(F, N, 4, 4) world matrices of every node at each keyframe, from the node TRS
    and the animation's channels (glTF: M = T * R * S, parent before child)."""
    n = len(doc.nodes)
    trans = np.array([node.translation or [0, 0, 0] for node in doc.nodes], float)
    quat = np.array([node.rotation or [0, 0, 0, 1] for node in doc.nodes], float)
    trans = np.repeat(trans[None], n_frames, axis=0)
    quat = np.repeat(quat[None], n_frames, axis=0)
    anim = doc.animations[0]
    for ch in anim.channels:
        sampler = anim.samplers[ch.sampler]
        values = accessor(doc, blob, sampler.output)
        assert sampler.interpolation == "LINEAR" and len(values) == n_frames
        if ch.target.path == "rotation":
            quat[:, ch.target.node] = values
        elif ch.target.path == "translation":
            trans[:, ch.target.node] = values
    local = np.tile(np.eye(4), (n_frames, n, 1, 1))
    wxyz = np.concatenate([quat[..., 3:], quat[..., :3]], axis=-1)
    local[..., :3, :3] = rot.to_matrix(wxyz)
    local[..., :3, 3] = trans
    parent = {c: p for p, node in enumerate(doc.nodes) for c in (node.children or [])}
    world = np.empty_like(local)
    done: set[int] = set()

    def visit(k: int) -> None:
        if k in done:
            return
        if k in parent:
            visit(parent[k])
            world[:, k] = world[:, parent[k]] @ local[:, k]
        else:
            world[:, k] = local[:, k]
        done.add(k)

    for k in range(n):
        visit(k)
    return world, [node.name for node in doc.nodes]


def test_glb_structure_read_by_pygltflib(spliced, gltf):
    motion, _ = spliced
    doc, blob = gltf
    skel = motion.skeleton
    assert doc.asset.version == "2.0" and len(doc.skins) == 1 and len(doc.animations) == 1
    skin = doc.skins[0]
    names = [doc.nodes[j].name for j in skin.joints]
    assert names == list(skel.names)  # every joint, in the file's order
    assert len(names) > 30 and any("Thumb" in n or "thumb" in n for n in names)  # fingers
    for j, p in enumerate(skel.parents):  # the hierarchy of the file
        if p >= 0:
            assert skin.joints[j] in doc.nodes[skin.joints[p]].children
    ibm = accessor(doc, blob, skin.inverseBindMatrices)
    assert ibm.shape == (skel.n_joints, 16)
    mesh_nodes = [k for k, node in enumerate(doc.nodes) if node.mesh is not None]
    assert len(mesh_nodes) == 1 and doc.nodes[mesh_nodes[0]].skin == 0
    assert mesh_nodes[0] in doc.scenes[doc.scene].nodes  # a skinned mesh at the scene root
    prim = doc.meshes[0].primitives[0]
    verts = accessor(doc, blob, prim.attributes.POSITION)
    joints = accessor(doc, blob, prim.attributes.JOINTS_0).astype(int)
    weights = accessor(doc, blob, prim.attributes.WEIGHTS_0)
    assert len(verts) > 1000 and joints.shape == weights.shape == (len(verts), 4)
    assert joints.max() < skel.n_joints and np.allclose(weights.sum(axis=1), 1.0, atol=1e-5)
    faces = accessor(doc, blob, prim.indices).astype(int)
    assert faces.max() < len(verts) and len(faces) % 3 == 0
    # the animation: one time per frame at the take's rate, a rotation channel per joint
    anim = doc.animations[0]
    paths: dict[str, set[int]] = {"rotation": set(), "translation": set()}
    for ch in anim.channels:
        paths[ch.target.path].add(ch.target.node)
    assert paths["rotation"] == set(skin.joints)
    moving = {
        j for j in range(skel.n_joints) if np.ptp(motion.translations[:, j], axis=0).max() > 1e-6
    }
    assert moving and {skin.joints[j] for j in moving} <= paths["translation"]  # hips' path
    times = accessor(doc, blob, anim.samplers[0].input)[:, 0]
    assert np.allclose(times, np.arange(motion.n_frames) / motion.fps, atol=1e-5)


def test_glb_joint_positions_match_bvh_fk(spliced, gltf):
    motion, _ = spliced
    doc, blob = gltf
    world, names = animated_world(doc, blob, motion.n_frames)
    joints = doc.skins[0].joints
    got = world[:, joints][..., :3, 3]
    want = expected_positions(motion)
    assert [names[j] for j in joints] == list(motion.skeleton.names)
    err = np.abs(got - want).max()
    assert err < TOL_M, f"joint positions differ from FK by {err * 1000:.3f} mm"
    # inverse bind matrices: the inverse of each joint's world matrix in the first frame
    ibm = accessor(doc, blob, doc.skins[0].inverseBindMatrices).reshape(-1, 4, 4)
    ibm = np.swapaxes(ibm, 1, 2)  # column-major
    assert np.allclose(world[0, joints] @ ibm, np.eye(4), atol=1e-4)


def test_glb_skinning_reproduces_the_renderers_mannequin(spliced, gltf):
    """glTF skinning (joint matrix = world x inverse bind) gives the renderer's mesh."""
    from engine.render.scene import TakeView

    motion, _ = spliced
    doc, blob = gltf
    world, _ = animated_world(doc, blob, motion.n_frames)
    prim = doc.meshes[0].primitives[0]
    verts = accessor(doc, blob, prim.attributes.POSITION)
    joints = accessor(doc, blob, prim.attributes.JOINTS_0).astype(int)
    weights = accessor(doc, blob, prim.attributes.WEIGHTS_0)
    ibm = np.swapaxes(accessor(doc, blob, doc.skins[0].inverseBindMatrices).reshape(-1, 4, 4), 1, 2)
    skin_joints = np.array(doc.skins[0].joints)
    view = TakeView.from_motion(motion)
    for frame in (0, motion.n_frames // 2, motion.n_frames - 1):
        mats = world[frame, skin_joints] @ ibm  # (J, 4, 4)
        blended = np.einsum("vk,vkij->vij", weights, mats[joints])
        posed = np.einsum("vij,vj->vi", blended[:, :3, :3], verts) + blended[:, :3, 3]
        want = view.vertices(frame)[0]
        assert posed.shape == want.shape
        assert np.abs(posed - want).max() < 5 * TOL_M


def test_glb_passes_the_khronos_validator(spliced):
    from playwright._impl._driver import compute_driver_executable

    _js_ready()
    node = compute_driver_executable()[0]
    proc = subprocess.run(
        [str(node), "validate-gltf.mjs", str(spliced[1])],
        cwd=JS,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr
    report = json.loads(proc.stdout)
    issues = report["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]
    info = report["info"]
    assert info["version"] == "2.0" and info["animationCount"] == 1 and info["hasSkins"]
    assert info["totalVertexCount"] > 1000 and info["drawCallCount"] == 1


def _one_per_family() -> list[Path]:
    """The first BVH of each capture family of the shared data (Y and Z up; m, cm, mm,
    dm, inches and unknown units; bodies with and without fingers, hands alone)."""
    first: dict[str, Path] = {}
    for path in mocap_files():
        first.setdefault(path.parent.name, path)
    z_up = SAMPLE_DATA / "animated-drawings" / "fair1_dab.bvh"  # Z up, inches
    return [*first.values(), z_up]


@pytest.mark.parametrize("path", _one_per_family(), ids=lambda p: f"{p.parent.name}-{p.stem}")
def test_glb_of_each_capture_family_validates_and_follows_fk(path, tmp_path):
    """Every family: no validator error or warning, joints where FK puts them (display
    space: the renderer's scale and up axis)."""
    import pygltflib

    from engine.mesh.anatomy import find_anatomy
    from engine.model.roles import side_from_name
    from engine.render.scene import display_transform

    _js_ready()
    from playwright._impl._driver import compute_driver_executable

    motion = read_bvh(path).frames(0, 90)
    out = tmp_path / "take.glb"
    assert main(["render", str(path), "-o", str(out), "--frames", "0:90", "--quiet"]) == 0
    proc = subprocess.run(
        [str(compute_driver_executable()[0]), "validate-gltf.mjs", str(out)],
        cwd=JS,
        capture_output=True,
        text=True,
        timeout=300,
    )
    issues = json.loads(proc.stdout)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]
    doc = pygltflib.GLTF2().load_binary(str(out))
    world, _ = animated_world(doc, doc.binary_blob(), motion.n_frames)
    pos, rots = forward_kinematics(motion)
    anatomy = find_anatomy(motion.skeleton, pos[0], rots[0], side_hint=side_from_name(path.name))
    scale, axes = display_transform(motion, anatomy)
    want = scale * pos @ axes.T
    size = np.linalg.norm(np.ptp(want[0], axis=0))
    assert 0.1 < size < 3.0  # metres: a hand or a person
    assert np.abs(world[:, doc.skins[0].joints][..., :3, 3] - want).max() < TOL_M


def _serve_js(page, glb: Path) -> str:
    """Route http://glb.test/ to tests/js (page, three.js) and the GLB; nothing else."""
    types = {".html": "text/html", ".js": "text/javascript", ".glb": "model/gltf-binary"}

    def handle(route):
        rel = route.request.url.removeprefix("http://glb.test/").split("?")[0]
        path = glb if rel == "take.glb" else (JS / rel).resolve()
        if not path.is_file() or not (path == glb or path.is_relative_to(JS)):
            return route.fulfill(status=404, body="")
        route.fulfill(
            status=200,
            body=path.read_bytes(),
            content_type=types.get(path.suffix, "application/octet-stream"),
        )

    page.route("http://glb.test/**", handle)
    return "http://glb.test/gltf-page.html"


@pytest.mark.browser
def test_glb_loads_in_threejs_and_animates_as_the_bvh(browser, spliced, tmp_path):
    _js_ready()
    motion, glb = spliced
    frames = [0, motion.n_frames // 3, motion.n_frames - 1]
    times = [f / motion.fps for f in frames]
    context = browser.new_context()
    try:
        page = context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(_serve_js(page, glb))
        page.wait_for_function("window.pageReady === true", timeout=60_000)
        result = page.evaluate(
            "([url, times]) => window.loadGlb(url, times)", ["http://glb.test/take.glb", times]
        )
    finally:
        context.close()
    assert not errors, errors
    assert result["skinned"] and result["animations"] == 1 and result["vertices"] > 1000
    assert result["bones"] == list(motion.skeleton.names)
    assert abs(result["duration"] - (motion.n_frames - 1) / motion.fps) < 1e-4
    assert sum(t.endswith(".quaternion") for t in result["tracks"]) == motion.skeleton.n_joints
    got = np.array(result["positions"])
    want = expected_positions(motion)[frames]
    err = np.abs(got - want).max()
    assert err < TOL_M, f"three.js joint positions differ from FK by {err * 1000:.3f} mm"


def test_glb_frame_range_and_refused_options(tmp_path, capsys):
    import pygltflib

    out = tmp_path / "cut.glb"
    assert main(["render", str(BODY), "-o", str(out), "--frames", "10:40", "--quiet"]) == 0
    doc = pygltflib.GLTF2().load_binary(str(out))
    times = accessor(doc, doc.binary_blob(), doc.animations[0].samplers[0].input)
    assert len(times) == 30 and times[0, 0] == 0.0
    world, _ = animated_world(doc, doc.binary_blob(), 30)
    want = expected_positions(read_bvh(BODY))[10:40]
    assert np.abs(world[:, doc.skins[0].joints][..., :3, 3] - want).max() < TOL_M
    bad = tmp_path / "bad.glb"
    for extra in (["--frame", "3"], ["--trails"], ["--frames", "0:40:2"], ["--frames", "90:10"]):
        assert main(["render", str(BODY), "-o", str(bad), *extra]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith("handsplice: error:"), err
    assert not bad.exists()


def test_app_glb_download_callback(tmp_path):
    """The sharing view's GLB button returns the session's spliced take as GLB bytes."""
    import pygltflib

    from webapp.views import sharing

    session = open_demo_session(tmp_path / "uploads")
    view = sharing.SharingView(session)
    data = asyncio.run(view._glb())  # made on a download thread, awaited here
    assert data is not None and view.glb.filename == f"{session.output_stem()}.glb"
    doc = pygltflib.GLTF2.load_from_bytes(data.path.read_bytes())  # the file the page fetches
    motion = session.spliced()
    assert [doc.nodes[j].name for j in doc.skins[0].joints] == list(motion.skeleton.names)
    world, _ = animated_world(doc, doc.binary_blob(), motion.n_frames)
    want = expected_positions(motion)
    assert np.abs(world[:, doc.skins[0].joints][..., :3, 3] - want).max() < TOL_M
    # the app's file carries the takes' credit (stranger 12 F7) and stays valid glTF
    assert "Bandai-Namco-Research-Motiondataset" in doc.asset.copyright
    from playwright._impl._driver import compute_driver_executable

    _js_ready()
    proc = subprocess.run(
        [str(compute_driver_executable()[0]), "validate-gltf.mjs", str(data.path)],
        cwd=JS,
        capture_output=True,
        text=True,
        timeout=300,
    )
    issues = json.loads(proc.stdout)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"][:10]
