"""Band widths in seconds: how far two performances drift apart, and what the default
time width (``engine.dtw.constraints``) covers and costs.

Drift model: the accuracy bench's time warp (``benchmarks.split.smooth_warp``: the hand
take's local rate ``exp(sigma * noise)``, 1 s correlation, ends matched), the model the
short-take accuracy figures are measured on. For takes of 6 s to 10 min and sigma 0.15
and 0.3, the largest distance (seconds) between the warp and the straight diagonal, over
20 random warps. Then the default pass-1 width for each duration, its vertical reach
(Λ, eq. 4) and its band cells beside the paper's 30 % band, at 120 fps.

    python -m benchmarks.bench_band_widths [--quick]
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.ndimage import gaussian_filter1d

from benchmarks._results import write_section
from benchmarks.split import smooth_warp
from engine.dtw import Band
from engine.dtw import constraints as C

DURATIONS = (6.0, 20.0, 120.0, 600.0)
SIGMAS = (0.15, 0.3)
FPS = 120.0


def warp(
    rng: np.random.Generator,
    duration: float,
    scale: float,
    sigma: float,
    corr_s: float = 1.0,
    dt: float = 0.01,
) -> tuple[np.ndarray, np.ndarray]:
    """``benchmarks.split.smooth_warp``'s model sampled every ``dt`` seconds instead of 1 ms
    (the same random process; 1 ms makes 10-minute warps take minutes each)."""
    th = np.linspace(0.0, duration * scale, int(duration * scale / dt) + 2)
    step = th[1] - th[0]
    pad = int(4 * corr_s / step)
    noise = gaussian_filter1d(rng.normal(size=th.size + 2 * pad), corr_s / step)[pad:-pad]
    rate = np.exp(sigma * noise / (noise.std() + 1e-12))
    t = np.concatenate([[0.0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * step)])
    return th, t * (duration / t[-1])


def drift(duration: float, sigma: float, seeds: int) -> np.ndarray:
    """Largest |warp - diagonal| (seconds) of ``seeds`` random warps."""
    out = []
    for seed in range(seeds):
        rng = np.random.default_rng(seed)
        scale = float(rng.uniform(0.85, 1.2))
        make = smooth_warp if duration <= 20 else warp  # the bench's own function where cheap
        th, t = make(rng, duration, scale, sigma)
        out.append(float(np.abs(t - th / scale).max()))
    return np.array(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="5 warps each, print only")
    args = ap.parse_args(argv)
    seeds = 5 if args.quick else 20
    lines = [
        "## Band widths in seconds (`benchmarks/bench_band_widths.py`)",
        "",
        "Drift between two performances under the accuracy bench's warp model (local "
        "rate exp(σ·noise), 1 s correlation): largest distance from the diagonal, "
        f"seconds, over {seeds} warps per cell (median / max). Then the default pass-1 "
        "width W1 of `engine.dtw.constraints` (the paper's 0.30 of the take, or "
        "1.5 s·√T when narrower, capped so that the band fits `engine.base.limits."
        "MAX_BAND_CELLS` less 10 %), its vertical reach Λ = W1·√2/2 (takes of equal length) "
        "and its band cells beside a 30 % band at 120 fps.",
        "",
        "| take | drift σ=0.15 | drift σ=0.3 | default W1 | Λ | Λ / worst drift | "
        "cells (default) | cells (30 %) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    ratios, capped = [], []
    for duration in DURATIONS:
        cells = []
        for sigma in SIGMAS:
            d = drift(duration, sigma, seeds)
            cells.append((float(np.median(d)), float(d.max())))
        n = int(duration * FPS)
        width = C.BAND.default_for(n, FPS)
        lam = C.half_width(width.frames(n, FPS), n, n) / FPS
        area = Band.from_constraints(n, n, width.fraction(n, FPS)).area
        area30 = Band.from_constraints(n, n, 0.30).area
        worst = max(c[1] for c in cells)
        if (
            C.BAND.long_take_seconds(duration) > C.BAND.cap_seconds(n, FPS)
            and width.unit == C.SECONDS
        ):
            capped.append((duration, lam / worst))
        else:
            ratios.append(lam / worst)
        lines.append(
            f"| {duration:g} s | {cells[0][0]:.2f} / {cells[0][1]:.2f} s | "
            f"{cells[1][0]:.2f} / {cells[1][1]:.2f} s | {width.text()} | {lam:.1f} s | "
            f"{lam / worst:.1f} | {area / 1e6:.1f} M | {area30 / 1e6:.1f} M |"
        )
    lines += [
        "",
        "Drift grows as √T (a random walk of the local rate), so the long-take "
        f"width grows as √T too and keeps Λ at least {min(ratios):.1f}× the worst drift "
        "seen; pass 2 (W2 = 2 s on long takes) corrects the pass-1 path locally and does "
        "not grow. Warps of 2 and 10 minutes are sampled every 10 ms (the same process "
        "as the bench's 1 ms `smooth_warp`, which is used up to 20 s).",
    ]
    for duration, ratio in capped:
        lines.append(
            f"At {duration:g} s the cell limit caps W1 (1.5 s·√T would be "
            f"{C.BAND.long_take_seconds(duration):g} s): Λ is {ratio:.1f}× the worst drift "
            "seen, the widest band the engine accepts at this length; takes that drift "
            "more must be spliced in parts (or the limit raised)."
        )
    text = "\n".join(lines)
    print(text)
    if not args.quick:
        write_section("band_widths", text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
