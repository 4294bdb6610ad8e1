#!/usr/bin/env python3
"""Runs a command on a pseudo-terminal and holds a key on it, as a person
holding the space bar does: once the command asks for the key, a space every
30 ms (a terminal's auto-repeat) for SECONDS, or until the command ends when
SECONDS is `all`. Prints what the command printed; exits with its status.

usage: hold_key.py SECONDS COMMAND [ARG...]
"""
import os
import pty
import select
import sys
import time


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    hold = None if sys.argv[1] == "all" else float(sys.argv[1])
    pid, fd = pty.fork()
    if pid == 0:
        os.execv(sys.argv[2], sys.argv[2:])
    out = b""
    pressed_at = None
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline:
        r, _, _ = select.select([fd], [], [], 0.03)
        if r:
            try:
                chunk = os.read(fd, 4096)
            except OSError:  # the command ended and closed the terminal
                break
            if not chunk:
                break
            out += chunk
        if pressed_at is None and b"hold a key" in out:
            pressed_at = time.monotonic()
        if pressed_at is not None and (hold is None or time.monotonic() - pressed_at < hold):
            try:
                os.write(fd, b" ")
            except OSError:
                break
    _, status = os.waitpid(pid, 0)
    sys.stdout.write(out.decode(errors="replace"))
    sys.exit(os.waitstatus_to_exitcode(status))


if __name__ == "__main__":
    main()
