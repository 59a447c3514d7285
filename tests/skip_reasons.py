#!/usr/bin/env python3
"""skip_reasons.py - why each skipped test was skipped: reads ctest's JUnit
file (ctest --output-junit FILE) and prints one line per skipped test with
the reason the test printed (its last output line that speaks of skipping,
else its last line), for the end of ./dev test.
  usage: tests/skip_reasons.py JUNIT.xml"""
import re
import sys
import xml.etree.ElementTree as ET


def reason(output):
    lines = [l.strip() for l in (output or "").splitlines() if l.strip()]
    said = [l for l in lines if re.search(r"\bskip", l, re.I)]
    line = (said or lines or ["(it printed nothing)"])[-1]
    return re.sub(r"^skipped:\s*", "", line)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: skip_reasons.py JUNIT.xml")
    try:
        cases = ET.parse(sys.argv[1]).getroot().iter("testcase")
    except (OSError, ET.ParseError) as e:
        sys.exit(f"skip_reasons.py: {sys.argv[1]}: {e}")
    skipped = [(c.get("name"), reason(c.findtext("system-out")))
               for c in cases if c.find("skipped") is not None]
    if skipped:
        print(f"{len(skipped)} tests skipped, each for what this machine lacks:")
        width = max(len(n) for n, _ in skipped)
        for name, why in skipped:
            print(f"  {name:<{width}}  {why}")


if __name__ == "__main__":
    main()
