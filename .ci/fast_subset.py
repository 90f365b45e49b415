"""Print the test files for CI's second, re-shuffled pass: the fastest, within a time budget.

Reads the JUnit XML of the first pass (``pytest --junitxml``), sums each test file's time
(setup + call + teardown of all its tests, so module fixtures count once) and prints the files
from fastest up while their total stays within ``--budget`` seconds, one per line.

Usage: ``python .ci/fast_subset.py FIRST_PASS.xml [--budget SECONDS]``
"""

from __future__ import annotations

import argparse
import sys
import xml.etree.ElementTree as ElementTree
from collections import defaultdict
from pathlib import Path


def file_times(junit: Path) -> dict[str, float]:
    """Seconds per test file (``tests/test_x.py``) from a JUnit XML report."""
    times: dict[str, float] = defaultdict(float)
    for case in ElementTree.parse(junit).iter("testcase"):
        module = case.get("classname", "").split("::")[0]
        parts = module.split(".")
        # classname is "tests.test_x" or "tests.test_x.TestClass": keep up to the test_ module
        index = next((i for i, p in enumerate(parts) if p.startswith("test_")), len(parts) - 1)
        times["/".join(parts[: index + 1]) + ".py"] += float(case.get("time", 0.0))
    return dict(times)


def fastest_within(times: dict[str, float], budget: float) -> list[str]:
    """Files in ascending time whose running total stays ≤ ``budget`` seconds."""
    chosen, total = [], 0.0
    for name, seconds in sorted(times.items(), key=lambda item: (item[1], item[0])):
        if total + seconds > budget:
            break
        chosen.append(name)
        total += seconds
    return chosen


def main(argv: list[str] | None = None) -> int:
    """Print the chosen files; exit 1 when none could be chosen."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("junit", type=Path)
    parser.add_argument("--budget", type=float, default=60.0, help="seconds (default 60)")
    args = parser.parse_args(argv)
    times = file_times(args.junit)
    chosen = [name for name in fastest_within(times, args.budget) if Path(name).is_file()]
    print("\n".join(chosen))
    return 0 if chosen else 1


if __name__ == "__main__":
    sys.exit(main())
