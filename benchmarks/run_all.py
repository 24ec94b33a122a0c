"""``make bench``: run every benchmark script in this folder, summarise, and keep the results.

Each ``bench_*.py`` measures its figures beside a reference measured in the same run and
exits non-zero when it misses its target. Pass names to run only some:
``python benchmarks/run_all.py render analysis``. The run is written to
``benchmarks/results/DATE-TIME-make-bench.json`` (the machine, the command, the date and
each script's figures as it printed them with ``--json``); docs/reference/benchmarks.md
shows the latest run per machine kind (``make docs-reference``).
"""

from __future__ import annotations

import datetime
import json
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from benchmarks.machine import describe_machine  # noqa: E402


def figures(stdout: str) -> dict | list | None:
    """The JSON a script printed last (scripts may print progress lines before it)."""
    start = min((i for i in (stdout.find("{"), stdout.find("[")) if i >= 0), default=-1)
    try:
        return json.loads(stdout[start:]) if start >= 0 else None
    except json.JSONDecodeError:
        return None


def main(argv: list[str]) -> int:
    scripts = sorted(HERE.glob("bench_*.py"))
    if argv:
        scripts = [s for s in scripts if s.stem.removeprefix("bench_") in argv]
    started = datetime.datetime.now(datetime.timezone.utc)
    results = []
    for script in scripts:
        print(f"== {script.stem}", flush=True)
        start = time.perf_counter()
        done = subprocess.run([sys.executable, str(script), "--json"], stdout=subprocess.PIPE, text=True)
        print(done.stdout, end="", flush=True)
        results.append({"benchmark": script.stem, "exit_status": done.returncode,
                        "seconds": round(time.perf_counter() - start, 1), "figures": figures(done.stdout),
                        "target": "met" if done.returncode == 0 else "**missed**"})
    print("\n== summary")
    for result in results:
        print(f"{result['benchmark']:<20} {'met its targets' if result['exit_status'] == 0 else 'MISSED A TARGET'} "
              f"({result['seconds']:.0f} s)")
    machine = describe_machine()
    record = {"date": started.strftime("%Y-%m-%d"), "time": started.strftime("%H:%M UTC"),
              "machine": {"kind": f"{machine['cores']}-core {machine['cpu']}", **machine},
              "command": "make bench" + (f" ({' '.join(argv)})" if argv else ""),
              "reference": "each script's own, measured in the same run", "rows": results}
    out = HERE / "results" / f"{started.strftime('%Y-%m-%d-%H%M')}-make-bench.json"
    out.write_text(json.dumps(record, indent=2) + "\n")
    print(f"written to {out.relative_to(HERE.parent)}; make docs-reference updates docs/reference/benchmarks.md")
    return 0 if all(result["exit_status"] == 0 for result in results) else 1


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
