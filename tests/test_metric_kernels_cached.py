"""The splice metrics' path, grid and row kernels (``metrics.path_values``, ``metrics.cost_grid``,
the registered metrics' ``row``: the uncertainty sweep's cost rows), and the path values of
the built-in cells (the hand-spin pass's ``euclidean_fixed``) are cached on disk: a fresh process (a batch worker's pair, a server, the CLI) loads their
machine code from ``NUMBA_CACHE_DIR`` and compiles nothing for them (it compiled them anew in
every process, seconds each, when they took the metric as an argument)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from engine.align import metrics as M
from engine.dtw import kernels as K
from engine.splice import pipeline as P

ROOT = Path(__file__).resolve().parents[1]

# in a fresh process: the splice metrics' path values and grid on rows of the demo-sized
# shape, with numba's compile events recorded; prints how many compiles there were
_CHILD = """
import numpy as np
from numba.core import event
from engine.align import metrics as M
from engine.dtw import kernels as K

rows = np.load({rows!r})
a, b = rows["pa"], rows["pb"]
c, d = rows["aa"], rows["ab"]
path = np.stack([np.arange(5), np.arange(5)], axis=1)
with event.install_recorder("numba:compile") as rec:
    M.path_values(M.splice_phase, a, b, path)
    M.cost_grid(M.splice_phase, a, b, np.arange(3), np.arange(4))
    M.path_values(M.splice_angle, c, d, path)
    M.cost_grid(M.splice_angle, c, d, np.arange(3), np.arange(4))
    M.path_values(K.euclidean, c, d, path)
    M.path_values(K.euclidean_fixed, c, d, path)
    M.path_values(K.sqeuclidean, c, d, path)
    M.register_metrics()
    K.get_metric("splice_phase").row(a, b, 1, 0, 3)
    K.get_metric("splice_angle").row(c, d, 1, 0, 3)
print(sum(1 for _, ev in rec.buffer if ev.is_start))
"""


def test_a_fresh_process_compiles_no_path_or_grid_kernel_of_the_splice_metrics(
    sample_dir, tmp_path
):
    from engine.io.bvh import read_bvh

    body = read_bvh(sample_dir / "bandai-namco" / "dataset-2_wave-both-hands_normal_001.bvh")
    hand = read_bvh(sample_dir / "gestification" / "hello-world.bvh")
    feats = P.prepare(body.frames(0, 40), hand.frames(0, 40))
    pa, pb = feats.pass1_rows
    aa, ab = P.align_passes(feats).pass2.rows  # pass 2's rows, as the splice builds them
    path = np.stack([np.arange(5), np.arange(5)], axis=1)
    # here first: the kernels are compiled (or loaded) and their cache written
    for metric, (a, b) in ((M.splice_phase, (pa, pb)), (M.splice_angle, (aa, ab))):
        values = M.path_values(metric, a, b, path)
        grid = M.cost_grid(metric, a, b, np.arange(3), np.arange(4))
        # the same numbers as the metric cell by cell
        assert np.array_equal(values, [metric(a[i], b[j]) for i, j in path])
        assert np.array_equal(grid, [[metric(a[i], b[j]) for j in range(4)] for i in range(3)])
        # the uncertainty sweep's cost row (columns 0..3 of row 1)
        M.register_metrics()
        row = K.get_metric(metric).row(a, b, 1, 0, 3)
        assert np.array_equal(row, [metric(a[1], b[j]) for j in range(4)])
    for cell in (K.euclidean, K.euclidean_fixed, K.sqeuclidean):
        assert np.array_equal(
            M.path_values(cell, aa, ab, path), [cell(aa[i], ab[j]) for i, j in path]
        )
    rows = tmp_path / "rows.npz"
    np.savez(rows, pa=pa, pb=pb, aa=aa, ab=ab)
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]),
    }
    done = subprocess.run(
        [sys.executable, "-c", _CHILD.format(rows=str(rows))],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert done.stdout.strip() == "0", (done.stdout, done.stderr[-3000:])
