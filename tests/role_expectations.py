"""Expected joint roles of every real capture, and hand-built rigs of other conventions.

Shared by tests/test_roles.py and tests/test_cli_info.py. ``expected_roles(path)``
gives, per side, the arm roles and finger chains a correct matcher must report
(joint names), or raises ``KeyError`` for a file nobody has described yet, so a
new capture added to ../shared/data/mocap fails loudly until described here.
"""

from __future__ import annotations

from pathlib import Path

from engine.model.motion import Skeleton

FINGERS = ("thumb", "index", "middle", "ring", "pinky")
NO_FINGERS = {f: [] for f in FINGERS}


def _arm(
    clavicle=None, shoulder=None, elbow=None, wrist=None, hand=None, hand_end=None, fingers=None
):
    return {
        "clavicle": clavicle,
        "shoulder": shoulder,
        "elbow": elbow,
        "wrist": wrist,
        "hand": hand if hand is not None else wrist,
        "hand_end": hand_end,
        "fingers": {**NO_FINGERS, **(fingers or {})},
    }


EMPTY = _arm()


def _smplx(side):
    return _arm(
        f"{side}_collar",
        f"{side}_shoulder",
        f"{side}_elbow",
        f"{side}_wrist",
        fingers={f: [f"{side}_{f}{k}" for k in (1, 2, 3)] for f in FINGERS},
    )


def _bandai(s):
    return _arm(f"Shoulder_{s}", f"UpperArm_{s}", f"LowerArm_{s}", f"Hand_{s}")


def _mixamo_like(side, fingers=None, hand_end=None):
    S = side.title()
    return _arm(
        f"{S}Shoulder", f"{S}Arm", f"{S}ForeArm", f"{S}Hand", hand_end=hand_end, fingers=fingers
    )


def _cmu(side):
    S, s = side.title(), side[0]
    return _arm(
        f"{S}Collar",
        f"{S}Shoulder",
        f"{S}Elbow",
        f"{S}Wrist",
        hand=f"{s}hand",
        hand_end=f"{s.upper()}Fingers",
        fingers={"thumb": [f"{s.upper()}Thumb"]},
    )


_LEAP = _arm(
    elbow="rForeArm",
    wrist="rHand",
    fingers={
        "thumb": ["rThumb1", "rThumb2", "rThumb3"],
        "index": ["rIndex1", "rIndex2", "rIndex3"],
        "middle": ["rMid1", "rMid2", "rMid3"],
        "ring": ["rRing1", "rRing2", "rRing3"],
        "pinky": ["rPinky1", "rPinky2", "rPinky3"],
    },
)

_MANIPNET = _arm(
    wrist="WRIST",
    fingers={
        "thumb": ["THUMB_CMC_FE", "THUMB_MCP_FE", "THUMB_IP_FE"],
        **{
            f: [f"{f.upper()}_MCP", f"{f.upper()}_PIP_FE", f"{f.upper()}_DIP_FE"]
            for f in ("index", "middle", "ring", "pinky")
        },
    },
)


def expected_roles(path: str | Path) -> dict[str, dict]:
    """``{"right": arm, "left": arm}`` for a real capture (see module docstring)."""
    path = Path(path)
    folder, name = path.parent.name, path.name
    if folder == "beat":
        return {"right": _smplx("right"), "left": _smplx("left")}
    if folder == "bandai-namco":
        return {"right": _bandai("R"), "left": _bandai("L")}
    if folder == "lafan1":
        return {"right": _mixamo_like("right"), "left": _mixamo_like("left")}
    if folder == "animated-drawings" and name.startswith("fair1_"):
        return {
            s: _mixamo_like(
                s, fingers={"thumb": [f"{s.title()}HandThumb1"]}, hand_end=f"{s.title()}HandEnd"
            )
            for s in ("right", "left")
        }
    if folder == "animated-drawings" and name.startswith("cmu1_"):
        return {"right": _cmu("right"), "left": _cmu("left")}
    if folder == "gestification":
        return {"right": _LEAP, "left": EMPTY}
    if folder == "manipnet":
        side = "right" if "right" in name.lower() else "left"
        return {side: _MANIPNET, ("left" if side == "right" else "right"): EMPTY}
    raise KeyError(f"no expected roles for {path}: describe it in tests/role_expectations.py")


# --------------------------------------------------------------------------- hand-built rigs


def rig(spec: list[tuple]) -> Skeleton:
    """Skeleton from ``[(name, parent name or None, (x, y, z) offset?), ...]``."""
    names = [s[0] for s in spec]
    parents = [names.index(s[1]) if s[1] else -1 for s in spec]
    offsets = [s[2] if len(s) > 2 else (1.0, 0.0, 0.0) for s in spec]
    return Skeleton(names, parents, offsets, [("Zrotation", "Xrotation", "Yrotation")] * len(names))


def _arm_spec(side: str, style: str, prefix: str = "") -> list[tuple]:
    S, s = side.title(), side[0].upper()
    out: list[tuple] = []
    if style == "mixamo":  # mixamorig:RightHandIndex1..4 (4 = tip)
        p = prefix
        out = [
            (f"{p}{S}Shoulder", f"{p}Spine2"),
            (f"{p}{S}Arm", f"{p}{S}Shoulder"),
            (f"{p}{S}ForeArm", f"{p}{S}Arm"),
            (f"{p}{S}Hand", f"{p}{S}ForeArm"),
        ]
        for f in ("Thumb", "Index", "Middle", "Ring", "Pinky"):
            parent = f"{p}{S}Hand"
            for k in range(1, 5):
                out.append((f"{p}{S}Hand{f}{k}", parent))
                parent = f"{p}{S}Hand{f}{k}"
    elif style == "humanik":  # MotionBuilder: roll bones, RightInHandIndex metacarpals
        out = [
            (f"{S}Shoulder", "Spine2"),
            (f"{S}Arm", f"{S}Shoulder"),
            (f"{S}ArmRoll", f"{S}Arm"),
            (f"{S}ForeArm", f"{S}Arm"),
            (f"{S}ForeArmRoll", f"{S}ForeArm"),
            (f"{S}Hand", f"{S}ForeArm"),
        ]
        for f in ("Thumb", "Index", "Middle", "Ring", "Pinky"):
            parent = f"{S}Hand"
            if f != "Thumb":
                out.append((f"{S}InHand{f}", parent))
                parent = f"{S}InHand{f}"
            for k in range(1, 5):
                out.append((f"{S}Hand{f}{k}", parent))
                parent = f"{S}Hand{f}{k}"
    elif style == "biped":  # 3ds Max: Bip01 R Finger0 / Finger01 / Finger02 / Finger0Nub
        b = "Bip01 "
        out = [
            (f"{b}{s} Clavicle", f"{b}Spine2"),
            (f"{b}{s} UpperArm", f"{b}{s} Clavicle"),
            (f"{b}{s} Forearm", f"{b}{s} UpperArm"),
            (f"{b}{s} ForeTwist", f"{b}{s} Forearm"),
            (f"{b}{s} Hand", f"{b}{s} Forearm"),
        ]
        for k in range(5):
            parent = f"{b}{s} Hand"
            for n in (f"Finger{k}", f"Finger{k}1", f"Finger{k}2", f"Finger{k}Nub"):
                out.append((f"{b}{s} {n}", parent))
                parent = f"{b}{s} {n}"
    elif style == "unreal":  # UE mannequin: upperarm_r, index_metacarpal_r, index_01_r
        x = side[0]
        out = [
            (f"clavicle_{x}", "spine_03"),
            (f"upperarm_{x}", f"clavicle_{x}"),
            (f"upperarm_twist_01_{x}", f"upperarm_{x}"),
            (f"lowerarm_{x}", f"upperarm_{x}"),
            (f"hand_{x}", f"lowerarm_{x}"),
        ]
        for f in FINGERS:
            parent = f"hand_{x}"
            if f != "thumb":
                out.append((f"{f}_metacarpal_{x}", parent))
                parent = f"{f}_metacarpal_{x}"
            for k in range(1, 4):
                out.append((f"{f}_0{k}_{x}", parent))
                parent = f"{f}_0{k}_{x}"
    elif style == "rigify":  # Blender Rigify deform bones: DEF-upper_arm.R, DEF-f_index.01.R
        out = [
            (f"DEF-shoulder.{s}", "DEF-spine.003"),
            (f"DEF-upper_arm.{s}", f"DEF-shoulder.{s}"),
            (f"DEF-forearm.{s}", f"DEF-upper_arm.{s}"),
            (f"DEF-hand.{s}", f"DEF-forearm.{s}"),
        ]
        for f in ("thumb", "f_index", "f_middle", "f_ring", "f_pinky"):
            parent = f"DEF-hand.{s}"
            for k in range(1, 4):
                out.append((f"DEF-{f}.0{k}.{s}", parent))
                parent = f"DEF-{f}.0{k}.{s}"
    return out


_TRUNKS = {
    "mixamo": lambda p: [
        (f"{p}Hips", None),
        (f"{p}Spine", f"{p}Hips"),
        (f"{p}Spine2", f"{p}Spine"),
    ],
    "humanik": lambda p: [("Hips", None), ("Spine", "Hips"), ("Spine2", "Spine")],
    "biped": lambda p: [
        ("Bip01", None),
        ("Bip01 Pelvis", "Bip01"),
        ("Bip01 Spine2", "Bip01 Pelvis"),
    ],
    "unreal": lambda p: [("root", None), ("pelvis", "root"), ("spine_03", "pelvis")],
    "rigify": lambda p: [("root", None), ("DEF-spine", "root"), ("DEF-spine.003", "DEF-spine")],
}


def body_rig(style: str, prefix: str = "") -> Skeleton:
    """A trunk with both arms and five-finger hands in a given naming convention."""
    return rig(
        _TRUNKS[style](prefix)
        + _arm_spec("right", style, prefix)
        + _arm_spec("left", style, prefix)
    )
