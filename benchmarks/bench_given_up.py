"""Memory under an edit's solve while the previous edit's given-up work is still referenced
(issue 13, mem29).

Run: ``python -m benchmarks.bench_given_up [--seconds 600] [--rounds 2]``

The app runs a preview's splice and a trust assessment on worker pools and gives them up
(``engine.base.errors.Cancelled``) when a newer edit comes; the page keeps the worker's
future until the newer edit's path is drawn. In one process (the server's backend calls,
no Panel or browser; ``benchmarks.long_pairs.pair_files``): prepare the pair and its first
alignment, then per round and case an edit's solve, that edit's preview (or trust) given
up late on a one-thread pool with its future kept, and the next edit's solve; prints the
resident memory before that solve and its peak (sampled every 10 ms). *before* submits
the work itself (as main did), *now* through ``run_cancellable`` (as the page does now),
alternating. Writes nothing to RESULTS.md.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import gc
import os
import sys
import threading
import time

#: the given-up work: (name, checks of ``cancelled`` before it says True; None: two blocks
#: before the preview's splice ends — it asks once per ``TRANSFER_CHUNK`` frames)
CASES = (("preview, given up two blocks before its end", None), ("trust, given up at check 60", 60))


def rss_mb() -> int:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") >> 20


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=600.0, help="pair length (120 fps)")
    parser.add_argument("--rounds", type=int, default=2)
    args = parser.parse_args(argv)

    from benchmarks.long_pairs import pair_files
    from engine.base.errors import Cancelled, run_cancellable
    from engine.dtw import constraints as C
    from webapp import backend
    from webapp.heap import give_back_large_blocks
    from webapp.views import preview

    give_back_large_blocks()  # as ``handsplice serve`` does
    peak = [0]

    def sample():
        while True:
            peak[0] = max(peak[0], rss_mb())
            time.sleep(0.01)

    threading.Thread(target=sample, daemon=True).start()
    body, hand, _ = pair_files(args.seconds)
    prep = backend.prepare(body, hand, "right")
    n, m = prep.features.n, prep.m_hand
    band, refine = C.BAND.default_for(n, prep.fps), C.REFINE_BAND.default_for(n, prep.fps)
    first = backend.first_solution(prep, band, refine, [])
    j0 = int(round(float(first.cache["engine"].map[n // 2])))
    print(f"prepared and first alignment: {rss_mb()} MB", flush=True)
    pool = concurrent.futures.ThreadPoolExecutor(1)
    k = 0
    from engine.splice.transfer import TRANSFER_CHUNK

    for case, checks in CASES:
        checks = -(-n // TRANSFER_CHUNK) - 2 if checks is None else checks
        for _ in range(args.rounds):
            for variant in ("before", "now"):
                k += 1
                edit = backend.solve(
                    prep, band, refine, [(n // 2, min(j0 + 10 * k, m - 1), 0.0)], previous=first
                )
                calls = [0]

                def stale(calls=calls, checks=checks) -> bool:
                    calls[0] += 1
                    return calls[0] > checks

                if case.startswith("preview"):
                    fn = preview._render_images
                    job = (prep, edit, 0, "front", False, (64, 64), (64, 64), stale)
                else:
                    fn, job = backend.assess, (prep, edit, stale)
                future = (
                    pool.submit(run_cancellable, fn, *job)
                    if variant == "now"
                    else pool.submit(fn, *job)
                )
                try:
                    future.result()
                except Cancelled:
                    pass
                before = peak[0] = rss_mb()
                point = [(n // 2, min(j0 + 10 * k + 5, m - 1), 0.0)]
                backend.solve(prep, band, refine, point, previous=edit)
                print(
                    f"{case}: {variant}: {before} MB before the next solve, peak {peak[0]} MB"
                    f" (load {os.getloadavg()[0]:.1f})",
                    flush=True,
                )
                del future, edit
                gc.collect()
    return 0


if __name__ == "__main__":
    sys.exit(main())
