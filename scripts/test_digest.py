#!/usr/bin/env python3
"""Prints, after a ctest run, every test that failed at least once: the lines
of its output that say why, and whether a second run passed.

scripts/test.sh runs ctest with `--repeat until-pass:2`, so a test that fails
once and then passes does not fail the run; this digest is where it stays
visible (and, being the last thing printed, it survives a log cut short in
the middle).

usage: test_digest.py BUILD/Testing/Temporary/LastTest.log
"""
import re
import sys

# Lines that say why a test failed, for the frameworks the project uses:
# GoogleTest, QtTest, the shell tests' own messages, ctest's timeouts.
WHY = re.compile(
    r"(FAIL!|Loc: \[|Failure$|\[  FAILED  \]|Expected|Which is|actual:|Value of:|"
    r"\bFAIL\b|FAILED|error:|Error:|ERROR|Timeout|timed out|Assertion|Aborted|Segmentation|"
    r"The difference between|evaluates to|which exceeds)")
MAX_LINES = 30


def runs(log_text):
    """(name, passed, output lines) for every run in ctest's LastTest.log."""
    for block in re.split(r"\n-{58}\n\n", log_text):
        name = re.search(r'^"(.+)" start time:', block, re.M)
        if not name:
            continue
        out = re.search(r"Output:\n-{58}\n(.*?)<end of output>", block, re.S)
        # "Test Failed." (exit status) or "Test Fail Reason:" (a FAIL_ or
        # missed PASS_REGULAR_EXPRESSION); anything else passed or was
        # skipped ("Test Passed.", "Test Pass Reason:").
        failed = re.search(r"\nTest Fail(ed\.|\s+Reason:)", block) is not None
        yield name.group(1), not failed, (out.group(1).splitlines() if out else [])


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    try:
        text = open(sys.argv[1], errors="replace").read()
    except OSError as e:
        sys.exit(f"test_digest: {sys.argv[1]}: {e.strerror}")
    history = {}
    for name, passed, lines in runs(text):
        history.setdefault(name, []).append((passed, lines))
    failed = {n: h for n, h in history.items() if not all(p for p, _ in h)}
    if not failed:
        return
    print("\n=== tests that failed at least once (scripts/test_digest.py) ===")
    for name, h in failed.items():
        verdict = "passed on its second run (flaky)" if h[-1][0] else "FAILED every run"
        print(f"--- {name}: {verdict}")
        for passed, lines in h:
            if passed:
                continue
            why = [l for l in lines if WHY.search(l)] or lines[-5:]
            for l in why[:MAX_LINES]:
                print(f"    {l}")
            if len(why) > MAX_LINES:
                print(f"    ... {len(why) - MAX_LINES} more")


if __name__ == "__main__":
    main()
