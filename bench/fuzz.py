"""A long fuzzing run of tests/test_fuzz.py: the same properties, many more seeded examples.

    python3 bench/fuzz.py --examples 5000

Prints hypothesis's statistics (examples run per test, outcomes, failures); exits with pytest's
status, so a finding fails the run. CI runs the same tests with its small default budget.
"""

import argparse
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--examples", type=int, default=2000, help="examples per property (default 2000)")
    p.add_argument("-k", default=None, help="only the properties matching this pytest -k expression")
    args = p.parse_args()
    env = dict(os.environ, UVBAKE_FUZZ_EXAMPLES=str(args.examples))
    cmd = [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", str(ROOT / "tests" / "test_fuzz.py"),
           "--hypothesis-show-statistics", "--durations=0"]
    if args.k:
        cmd += ["-k", args.k]
    return subprocess.call(cmd, cwd=ROOT, env=env)


if __name__ == "__main__":
    sys.exit(main())
