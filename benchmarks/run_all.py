"""Run every ``benchmarks/bench_*.py`` in turn with this interpreter (``make bench``).

Usage::

    .venv/bin/python benchmarks/run_all.py            # all benchmarks, default settings
    .venv/bin/python benchmarks/run_all.py --quick    # arguments go to every benchmark

Each benchmark runs in its own process, from the repository root, and prints its own
tables. The exit status is 0 when all of them succeeded and 1 otherwise. A summary
lists the failures.
"""
from __future__ import annotations

import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def main(argv=None):
    args = sys.argv[1:] if argv is None else list(argv)
    scripts = sorted(HERE.glob("bench_*.py"))
    if not scripts:
        print(f"no bench_*.py in {HERE}", file=sys.stderr)
        return 1
    failed = []
    for script in scripts:
        name = script.relative_to(HERE.parent)
        print(f"\n##### {name} {' '.join(args)}".rstrip(), flush=True)
        t0 = time.perf_counter()
        code = subprocess.call([sys.executable, str(script), *args], cwd=HERE.parent)
        status = "ok" if code == 0 else f"FAILED (exit code {code})"
        print(f"##### {name}: {status} in {time.perf_counter() - t0:.1f} s", flush=True)
        if code != 0:
            failed.append(str(name))
    print(f"\n{len(scripts) - len(failed)} of {len(scripts)} benchmarks succeeded"
          + (": failed " + ", ".join(failed) if failed else ""))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
