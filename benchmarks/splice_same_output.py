"""Same splice as another commit, bit for bit, on real pairs (issue 13's speed work).

Run: ``.venv/bin/python -m benchmarks.splice_same_output [--ref REF] [--no-long]``

Splices real pairs from ``../shared/data/mocap`` (and the 2-minute 120 fps bench pair,
``long_pairs.pair_files(120)``) with default options, once with this checkout and once
with the engine as at ``REF`` (``git archive``, a fresh child process each), and
compares the pass-1 and pass-2 paths and costs, the merged map, the notes and the
spliced BVH text (``format_bvh``) byte for byte. Prints one line per pair; exit
status 1 when any differs. A speed change that must not move the alignment runs this.
"""

from __future__ import annotations

import argparse
import json

from benchmarks import long_pairs as LP
from benchmarks.split import MOCAP

#: (name, body, hand) under MOCAP: a self pair, a mirrored hand take (Unity axes), a
#: forearm-less hand take, a 120 fps body with a 30 fps hand take
PAIRS = [
    ("beat-self", "beat/1_wayne_0_1_1.bvh", "beat/1_wayne_0_1_1.bvh"),
    ("lafan-manipnet", "lafan1/multipleActions1_subject1.bvh", "manipnet/mug1_rightHand.bvh"),
    (
        "bandai-gestification",
        "bandai-namco/dataset-2_wave-right-hand_normal_001.bvh",
        "gestification/gesture-pointing.bvh",
    ),
    ("wave120-beat", "animated-drawings/fair1_wave_hello.bvh", "beat/1_wayne_0_1_1.bvh"),
]

CHILD = r"""
import hashlib, json, sys
import numpy as np
from engine.io.bvh import read_bvh, format_bvh
from engine.splice import pipeline as P
def digest(x):
    return hashlib.sha256(np.ascontiguousarray(x).tobytes()).hexdigest()
out = {}
pairs = json.loads(sys.argv[1])
for name, b, h in pairs:
    try:
        r = P.splice(read_bvh(b), read_bvh(h))
    except Exception as e:
        out[name] = {"error": f"{type(e).__name__}: {e}"}
        continue
    a = r.alignment
    out[name] = {"path1": digest(a.pass1.path), "path2": digest(a.pass2.path),
                 "map": digest(np.asarray(a.map)), "cost1": repr(float(a.pass1.cost)),
                 "cost2": repr(float(a.pass2.cost)), "notes": list(r.features.notes),
                 "bvh": hashlib.sha256(format_bvh(r.motion).encode()).hexdigest()}
print(json.dumps(out))
"""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ref", default="efbcb40", help="commit to compare with")
    ap.add_argument("--no-long", action="store_true", help="without the 2-minute pair")
    args = ap.parse_args(argv)
    pairs = [(n, str(MOCAP / b), str(MOCAP / h)) for n, b, h in PAIRS]
    if not args.no_long:
        body, hand, _ = LP.pair_files(120.0, 120.0)
        pairs.append(("long-2min-120fps", str(body), str(hand)))
    arg = json.dumps(pairs)
    before = LP.run_child(CHILD, arg, tree=LP.baseline_tree(args.ref))
    now = LP.run_child(CHILD, arg)
    differ = 0
    for name, *_ in pairs:
        b, n = before[name], now[name]
        diff = [k for k in sorted(set(b) | set(n)) if b.get(k) != n.get(k)]
        differ += bool(diff)
        what = "same" if not diff else "DIFFERENT: " + ", ".join(diff)
        print(f"{name}: {what} (bvh {n.get('bvh', n.get('error', ''))[:16]})")
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main())
