#!/usr/bin/python3
"""Counts test cases in the JUnit XML files under a directory; prints 'N passed, N failed' and exits 1 on failure.

A result file that is missing or unreadable counts as a failure, so a crashed test binary cannot pass silently.
"""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main(root):
    passed = failed = 0
    files = sorted(glob.glob(os.path.join(root, "**", "*.xml"), recursive=True))
    for path in files:
        try:
            tree = ET.parse(path)
        except ET.ParseError as e:
            print(f"unreadable result file {path}: {e}")
            failed += 1
            continue
        cases = tree.getroot().iter("testcase")
        n = 0
        for case in cases:
            n += 1
            if case.find("failure") is not None or case.find("error") is not None:
                failed += 1
                print(f"FAILED: {case.get('classname')}.{case.get('name')} ({os.path.basename(path)})")
            elif case.find("skipped") is None:
                passed += 1
        if n == 0:
            print(f"no test cases in {path}")
            failed += 1
    if not files:
        print(f"no test results under {root}")
        failed += 1
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1] if len(sys.argv) > 1 else "build/test_results"))
