"""``handsplice batch MANIFEST.csv -o OUTDIR [--scheduler ADDRESS] [--workers N]``.

Splices every body/hand pair listed in a manifest CSV on dask.distributed (an
embedded local cluster of ``N`` worker processes by default, or an existing
scheduler), with a progress line per pair on stderr, and writes per pair the
spliced BVH, its report and a thumbnail; ``summary.csv`` grows as pairs finish, and
``index.html`` comes at the end. Each pair runs under a time and a memory limit
(``--pair-seconds``, ``--pair-memory-mb``); a pair beyond them is stopped and failed.
Re-running skips finished pairs. See :mod:`engine.jobs.batch` for the manifest format.

Exit status: 0 when every pair is done or skipped, 3 when the batch finished but
some pairs failed (listed in the summary; a row with a bad cell, such as a ``match`` out of
order, is such a failure, the other rows run), 2 for a file that is no manifest (not CSV, a
bad header, a row with more values than columns, a name used twice) or a bad option.
"""

from __future__ import annotations

import argparse
import os
import sys

from engine.base.limits import PAIR_MEMORY_MB, PAIR_SECONDS

EXIT_PAIRS_FAILED = 3


def add_parser(subparsers) -> None:
    p = subparsers.add_parser(
        "batch",
        help="splice many body/hand pairs listed in a CSV manifest (Dask)",
        description="Splice every pair of a manifest CSV (columns body, hand, side; optional "
        "band, refine_band, match, name; relative paths from the manifest's folder) "
        "on dask.distributed. Re-running skips finished pairs; a failing pair (or a "
        "row with a bad cell) is recorded and never stops the batch. Exit status 3 when "
        "some pairs failed.",
    )
    p.add_argument("manifest", help="the manifest CSV")
    p.add_argument(
        "-o", "--output", required=True, metavar="OUTDIR", help="output folder (created; resumable)"
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="an existing Dask scheduler, e.g. tcp://10.0.0.5:8786 (default: start a "
        "local cluster)",
    )
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        metavar="N",
        help="worker processes of the local cluster (default: min(4, CPU count))",
    )
    p.add_argument(
        "--thumbnails",
        choices=["render", "stick", "none"],
        default="render",
        help="thumbnail per pair: skinned render (stick figure without OpenGL), "
        "stick figure, or none (default: render)",
    )
    p.add_argument(
        "--pair-seconds",
        type=float,
        default=PAIR_SECONDS,
        metavar="S",
        help=f"stop a pair after S seconds and record it as failed (default "
        f"{PAIR_SECONDS:g}; 0: no limit)",
    )
    p.add_argument(
        "--pair-memory-mb",
        type=float,
        default=PAIR_MEMORY_MB,
        metavar="MB",
        help=f"stop a pair whose process holds more than MB megabytes (default "
        f"{PAIR_MEMORY_MB:g}; 0: no limit)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from engine.base.errors import ParameterError
    from engine.jobs.batch import run_batch

    workers = args.workers
    if workers is None:
        workers = max(1, min(4, os.cpu_count() or 1))
    if workers < 1:
        raise ParameterError(f"--workers: expected a whole number >= 1, got {workers}")
    if args.scheduler and args.workers is not None:
        raise ParameterError(
            "--workers applies to the local cluster; with --scheduler the "
            "cluster's own workers run the pairs"
        )
    result = run_batch(
        args.manifest,
        args.output,
        scheduler=args.scheduler,
        workers=workers,
        thumbnails=args.thumbnails,
        progress=None if args.quiet else sys.stderr,
        pair_seconds=args.pair_seconds,
        pair_memory_mb=args.pair_memory_mb,
    )
    failed = result.count("failed")
    if failed:
        print(
            f"handsplice batch: {failed} of {len(result.records)} pairs failed "
            f"(see {result.summary_csv})",
            file=sys.stderr,
        )
        return EXIT_PAIRS_FAILED
    return 0
