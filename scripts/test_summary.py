#!/usr/bin/env python3
"""Counts test cases in JUnit XML results (gtest, rostest) and prints 'N passed, N failed'.

Each failed case is printed with the first lines of its failure message, so that a log that holds
only this summary (a CI run) still says what failed.

catkin_test_results counts a gtest file's <testsuites> and <testsuite> totals both, doubling the
figure; this counts <testcase> elements once. Exit status 1 on any failure or on no tests.
"""
import pathlib
import sys
import xml.etree.ElementTree as ET


def message(element, lines=6, width=200):
    """The first lines of a failure's message, indented, each cut to width characters."""
    text = (element.get("message") or element.text or "").strip()
    out = [line[:width] for line in text.splitlines() if line.strip()][:lines]
    return "".join("\n    " + line for line in out)


def main(folder):
    passed, failed, skipped, files = 0, [], 0, 0
    for path in sorted(pathlib.Path(folder).rglob("*.xml")):
        try:
            root = ET.parse(path).getroot()
        except ET.ParseError as e:
            failed.append(f"{path.name}: unreadable result file ({e})")
            continue
        files += 1
        cases = list(root.iter("testcase"))
        if not cases and int(root.get("errors", "0")) + int(root.get("failures", "0")) > 0:
            failed.append(f"{path.name}: the test did not run ({root.get('name')})")
        for case in cases:
            name = f"{case.get('classname')}.{case.get('name')}"
            problem = case.find("failure")
            if problem is None:
                problem = case.find("error")
            if problem is not None:
                failed.append(name + message(problem))
            elif case.find("skipped") is not None or case.get("status") == "notrun":
                skipped += 1
            else:
                passed += 1
    for name in failed:
        print(f"FAILED: {name}")
    print(f"{files} result files")
    print(f"{passed} passed, {len(failed)} failed" + (f", {skipped} skipped" if skipped else ""))
    return 0 if passed > 0 and not failed else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
