"""Write one benchmark's section of benchmarks/RESULTS.md (atomically).

Each benchmark owns the text between ``<!-- BEGIN name -->`` and
``<!-- END name -->``; other sections are left as they are.
"""

from __future__ import annotations

import platform
import re
import time
from pathlib import Path

from engine.base.atomic import write_text

RESULTS = Path(__file__).with_name("RESULTS.md")
HEADER = "# Benchmark results\n\nEach section is rewritten by the script named in it.\n"


def machine() -> str:
    """The machine and how busy it was (1-minute load average: timings on a shared 2-core
    machine are only comparable at a similar load; ratios measured side by side are)."""
    import os

    try:
        load = f", load {os.getloadavg()[0]:.1f}"
    except OSError:  # no load average on this platform
        load = ""
    return f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}{load}"


def write_section(name: str, markdown: str) -> None:
    """Replace (or append) section ``name`` of RESULTS.md with ``markdown``."""
    text = RESULTS.read_text(encoding="utf-8") if RESULTS.exists() else HEADER
    stamp = time.strftime("%Y-%m-%d %H:%M")
    block = (
        f"<!-- BEGIN {name} -->\n{markdown.rstrip()}\n\n"
        f"_Recorded {stamp} on {machine()}._\n<!-- END {name} -->"
    )
    pattern = re.compile(
        rf"<!-- BEGIN {re.escape(name)} -->.*?<!-- END {re.escape(name)} -->", re.S
    )
    if pattern.search(text):
        text = pattern.sub(lambda _: block, text)
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    write_text(RESULTS, text)
