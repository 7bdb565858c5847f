"""Run every benchmark (``make bench``): each ``benchmarks/bench_*.py`` in its own process.

::

    python -m benchmarks.run_all [--quick] [--only NAME ...]

Each benchmark writes its own section of ``benchmarks/RESULTS.md`` (``--quick``: the ones
that have a quick mode run it, which prints only). Prints one line per benchmark with its
exit status and wall time; exits non-zero if any failed.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def benchmarks() -> list[str]:
    """Module names of every benchmark, sorted."""
    return sorted(p.stem for p in HERE.glob("bench_*.py"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--quick", action="store_true", help="quick mode where a benchmark has one (prints only)"
    )
    ap.add_argument("--only", nargs="+", metavar="NAME", help="run only these (bench_dtw ...)")
    args = ap.parse_args(argv)
    names = benchmarks()
    if args.only:
        unknown = sorted(set(args.only) - set(names))
        if unknown:
            ap.error(f"unknown benchmark {', '.join(unknown)} (known: {', '.join(names)})")
        names = [n for n in names if n in args.only]
    failed = []
    for name in names:
        cmd = [sys.executable, "-m", f"benchmarks.{name}"]
        if args.quick and '"--quick"' in (HERE / f"{name}.py").read_text(encoding="utf-8"):
            cmd.append("--quick")
        print(f"== {name}: {' '.join(cmd[1:])}", flush=True)
        t0 = time.perf_counter()
        code = subprocess.call(cmd, cwd=HERE.parent)
        print(f"== {name}: exit {code}, {time.perf_counter() - t0:.1f} s", flush=True)
        if code != 0:
            failed.append(name)
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
