"""``make bench``: run every benchmark script in this folder and summarise.

Each ``bench_*.py`` prints its own figures beside a reference measured in the same run
and exits non-zero when it misses its target. Pass names to run only some:
``python benchmarks/run_all.py render analysis``.
"""

from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv: list[str]) -> int:
    scripts = sorted(HERE.glob("bench_*.py"))
    if argv:
        scripts = [s for s in scripts if s.stem.removeprefix("bench_") in argv]
    results = []
    for script in scripts:
        print(f"== {script.stem}", flush=True)
        start = time.perf_counter()
        code = subprocess.call([sys.executable, str(script)])
        results.append((script.stem, code, time.perf_counter() - start))
    print("\n== summary")
    for name, code, seconds in results:
        print(f"{name:<20} {'met its targets' if code == 0 else 'MISSED A TARGET'} ({seconds:.0f} s)")
    return 0 if all(code == 0 for _, code, _ in results) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
