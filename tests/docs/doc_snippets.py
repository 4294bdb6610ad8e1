#!/usr/bin/env python3
"""Runs the code blocks of README.md and docs/*.md, so that a documented
command or snippet that stops working fails a test.

Every fenced block is classified by an annotation on the line above it
(an HTML comment, invisible when the page is rendered), or by its language
for ```ini, ```sh and ```hal blocks; an unclassified block is a failure.
The annotations are documented in docs/architecture.md, "Documentation
tests":

  <!-- doc-test: skip REASON -->            not run; the reason is required
  <!-- doc-test: ini [options] -->          INI: merged into configs/sim
  <!-- doc-test: hal [options] -->          HAL commands: run on configs/sim
  <!-- doc-test: excerpt file=PATH -->      lines of PATH, in order
  <!-- doc-test: output cmd="COMMAND" -->   lines COMMAND prints, in order
  <!-- doc-test: folders -->                a listing of the repository's folders
  <!-- doc-test: sh [timeout=S] -->         shell commands, run on a copy of configs/sim

usage: doc_snippets.py --source DIR --bin DIR (--static | --commands) [FILE...]
  --static    every block is classified; ini, hal, excerpt, output and folders
              blocks checked (INI and HAL through `cncd --check --strict`)
  --commands  sh blocks run, each in a fresh sandbox with its own instance
"""

import argparse
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field

FENCE = re.compile(r"^(\s*)(```+|~~~+)\s*([A-Za-z0-9_+-]*)\s*$")  # also inside list items
ANNOTATION = re.compile(r"^\s*<!--\s*doc-test:\s*(.*?)\s*-->\s*$")
DEFAULT_KIND = {"ini": "ini", "sh": "sh", "hal": "hal"}
KINDS = {"skip", "ini", "hal", "excerpt", "output", "folders", "sh"}


@dataclass
class Block:
    path: str  # relative to the source folder
    line: int  # the opening fence
    lang: str
    text: list
    kind: str = ""
    options: dict = field(default_factory=dict)
    reason: str = ""

    def where(self):
        return f"{self.path}:{self.line}"


class Failure(Exception):
    pass


def parse_markdown(source, rel):
    lines = open(os.path.join(source, rel), encoding="utf-8").read().split("\n")
    blocks, problems = [], []
    i = 0
    pending = None  # (line number, annotation text)
    while i < len(lines):
        m = ANNOTATION.match(lines[i])
        if m:
            if pending:
                problems.append(f"{rel}:{pending[0]}: doc-test annotation not followed by a code block")
            pending = (i + 1, m.group(1))
            i += 1
            continue
        f = FENCE.match(lines[i])
        if not f:
            if pending and lines[i].strip():
                problems.append(f"{rel}:{pending[0]}: doc-test annotation not followed by a code block")
                pending = None
            i += 1
            continue
        indent, fence, lang = f.group(1), f.group(2), f.group(3)
        start = i + 1
        body = []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            line = lines[i]
            body.append(line[len(indent):] if line.startswith(indent) else line.lstrip())
            i += 1
        i += 1
        b = Block(rel, start, lang, body)
        head = pending[1].split(None, 1) if pending else []
        pending = None
        if head:
            b.kind = head[0]
            rest = head[1] if len(head) > 1 else ""
            if b.kind == "skip":
                b.reason = rest.strip()
            else:
                try:
                    words = shlex.split(rest)
                except ValueError as e:
                    problems.append(f"{b.where()}: doc-test options: {e}")
                    words = []
                for w in words:
                    if "=" not in w:
                        problems.append(f"{b.where()}: doc-test option \"{w}\": expected NAME=VALUE")
                        continue
                    k, v = w.split("=", 1)
                    b.options.setdefault(k, []).append(v)
        else:
            b.kind = DEFAULT_KIND.get(lang, "")
        if not b.kind:
            problems.append(
                f"{b.where()}: code block without a doc-test annotation (```{lang}); say what it is, e.g. "
                "<!-- doc-test: skip example output --> (docs/architecture.md, \"Documentation tests\")")
        elif b.kind not in KINDS:
            problems.append(f"{b.where()}: unknown doc-test kind \"{b.kind}\"; known: {', '.join(sorted(KINDS))}")
        elif b.kind == "skip" and not b.reason:
            problems.append(f"{b.where()}: doc-test skip needs a reason")
        blocks.append(b)
    if pending:
        problems.append(f"{rel}:{pending[0]}: doc-test annotation not followed by a code block")
    return blocks, problems


def option(b, name, default=None):
    v = b.options.get(name)
    return v[-1] if v else default


# --- INI merging: a fragment's keys replace the base's (first occurrence),
# new keys join their section, new sections go to the end. A line "..."
# stands for what the page left out.

SECTION = re.compile(r"^\s*\[([^\]]+)\]")
KEYLINE = re.compile(r"^\s*([A-Za-z_][A-Za-z0-9_]*)\s*=(.*)$")


def fragment_entries(lines, where):
    out, section = [], None
    for n, raw in enumerate(lines, 1):
        s = raw.strip()
        if not s or s[0] in "#;" or s == "...":
            continue
        m = SECTION.match(s)
        if m:
            section = m.group(1)
            out.append((section, None, None))
            continue
        m = KEYLINE.match(s)
        if not m or section is None:
            # Left for the INI reader to refuse with its own message.
            out.append((section or "", None, raw))
            continue
        out.append((section, m.group(1), m.group(2).strip()))
    return out


def merge_ini(base_text, entries, append_keys=()):
    lines = base_text.split("\n")

    def section_range(name):
        start = None
        for i, l in enumerate(lines):
            m = SECTION.match(l)
            if m and start is None and m.group(1) == name:
                start = i
            elif m and start is not None:
                return start, i
        return (start, len(lines)) if start is not None else (None, None)

    for section, key, value in entries:
        if key is None and value is not None:
            lines.append(value)  # a line the reader should refuse
            continue
        start, end = section_range(section)
        if start is None:
            if lines and lines[-1].strip():
                lines.append("")
            lines.append(f"[{section}]")
            start, end = len(lines) - 1, len(lines)
        if key is None:
            continue
        last_key = start
        for i in range(start + 1, end):
            m = KEYLINE.match(lines[i])
            if not m:
                continue
            last_key = i
            if m.group(1) == key and key not in append_keys:
                lines[i] = f"{key} = {value}"
                break
        else:
            lines.insert(last_key + 1, f"{key} = {value}")
    return "\n".join(lines)


def parse_set(b, text):
    m = re.match(r"^\[([A-Za-z0-9_]+)\]([A-Za-z0-9_]+)=(.*)$", text)
    if not m:
        raise Failure(f"{b.where()}: doc-test set=\"{text}\": expected set=\"[SECTION]KEY=value\"")
    return (m.group(1), m.group(2), m.group(3))


class Sandbox:
    """A copy of configs/sim (as configs/sim), build/bin (and build/python) linked, in a fresh folder."""

    def __init__(self, source, bindir):
        self.source = source
        self.bindir = bindir
        self.root = tempfile.mkdtemp(prefix="cnc-doc-")
        shutil.copytree(os.path.join(source, "configs"), os.path.join(self.root, "configs"))
        os.makedirs(os.path.join(self.root, "build"))
        os.symlink(bindir, os.path.join(self.root, "build", "bin"))
        # The Python module (docs/connectivity.md), when this build has it.
        python = os.path.join(os.path.dirname(bindir), "python")
        if os.path.isdir(python):
            os.symlink(python, os.path.join(self.root, "build", "python"))
        self.sim = os.path.join(self.root, "configs", "sim")

    def add_files(self, b):
        for spec in b.options.get("file", []):
            dest, _, src = spec.partition(":")
            if not src:
                raise Failure(f"{b.where()}: doc-test file=\"{spec}\": expected file=DEST:SOURCE")
            target = os.path.join(self.sim, dest)
            os.makedirs(os.path.dirname(target), exist_ok=True)
            shutil.copy(os.path.join(self.source, src), target)

    def close(self):
        shutil.rmtree(self.root, ignore_errors=True)


def run_check(b, bindir, ini):
    cmd = [os.path.join(bindir, "cncd"), "--check", "--strict", ini]
    env = dict(os.environ, CNC_NO_REALTIME="1")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env)
    if r.returncode != 0:
        raise Failure(f"{b.where()}: cncd --check --strict refused it (status {r.returncode}):\n{r.stderr.strip()}")


def blocks_by_id(blocks):
    return {option(b, "id"): b for b in blocks if option(b, "id")}


def check_ini(b, args, ids):
    box = Sandbox(args.source, args.bin)
    try:
        box.add_files(b)
        ini = os.path.join(box.sim, "sim.ini")
        entries = fragment_entries(b.text, b.where())
        entries += [parse_set(b, s) for s in b.options.get("set", [])]
        if option(b, "base", "sim") == "none":
            text = merge_ini("", entries)
            ini = os.path.join(box.sim, "doc.ini")
        else:
            text = merge_ini(open(ini).read(), entries)
        open(ini, "w").write(text)
        run_check(b, args.bin, ini)
    finally:
        box.close()


def check_hal(b, args, ids):
    box = Sandbox(args.source, args.bin)
    try:
        box.add_files(b)
        hal_text = "\n".join(b.text) + "\n"
        extra = []
        for ref in b.options.get("ini", []):
            if ref not in ids:
                raise Failure(f"{b.where()}: doc-test ini={ref}: no block with id={ref} on this page")
            extra += fragment_entries(ids[ref].text, ids[ref].where())
        extra += [parse_set(b, s) for s in b.options.get("set", [])]
        if option(b, "base", "sim") == "none":
            open(os.path.join(box.sim, "doc.hal"), "w").write(hal_text)
            ini = os.path.join(box.sim, "doc.ini")
            text = merge_ini("[EMC]\nMACHINE = documentation snippet\n[HAL]\nHALFILE = doc.hal\n", extra)
        else:
            ini = os.path.join(box.sim, "sim.ini")
            replace = option(b, "replace")
            if replace:
                hal = os.path.join(box.sim, "sim.hal")
                lines = open(hal).read().split("\n")
                hits = [i for i, l in enumerate(lines) if l.strip() == replace]
                if not hits:
                    raise Failure(f"{b.where()}: doc-test replace=\"{replace}\": no such line in configs/sim/sim.hal")
                lines[hits[0]:hits[0] + 1] = b.text
                open(hal, "w").write("\n".join(lines))
            else:
                open(os.path.join(box.sim, "doc.hal"), "w").write(hal_text)
                extra.append(("HAL", "HALFILE", "doc.hal"))
            text = merge_ini(open(ini).read(), extra, append_keys=("HALFILE",))
        open(ini, "w").write(text)
        run_check(b, args.bin, ini)
    finally:
        box.close()


def normalise(line):
    return " ".join(line.split())


def check_excerpt(b, args, ids):
    path = option(b, "file")
    if not path:
        raise Failure(f"{b.where()}: doc-test excerpt needs file=PATH")
    full = os.path.join(args.source, path)
    if not os.path.isfile(full):
        raise Failure(f"{b.where()}: doc-test excerpt: {path} does not exist")
    have = [normalise(l) for l in open(full).read().split("\n")]
    pos, gap = 0, True  # the first line may be anywhere
    for want in b.text:
        if want.strip() == "...":
            gap = True
            continue
        w = normalise(want)
        if gap:
            found = next((i for i in range(pos, len(have)) if have[i] == w), None)
        else:
            found = pos if pos < len(have) and have[pos] == w else None
        if found is None:
            raise Failure(f"{b.where()}: \"{want.strip()}\" is not {'in' if gap else 'the next line of'} {path}"
                          + ("" if gap else " (a line \"...\" stands for lines left out)"))
        pos, gap = found + 1, False


def check_output(b, args, ids):
    cmd = option(b, "cmd")
    if not cmd:
        raise Failure(f"{b.where()}: doc-test output needs cmd=\"COMMAND\"")
    box = Sandbox(args.source, args.bin)
    try:
        env = dict(os.environ, CNC_NO_REALTIME="1", QT_QPA_PLATFORM="offscreen")
        r = subprocess.run(["bash", "-c", cmd], cwd=box.root, env=env, timeout=60, stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, text=True)
    finally:
        box.close()
    have = [normalise(l) for l in r.stdout.split("\n")]
    pos = 0
    for want in b.text:
        w = normalise(want)
        if not w:
            continue
        found = next((i for i in range(pos, len(have)) if have[i] == w), None)
        if found is None:
            raise Failure(f"{b.where()}: \"{want.strip()}\" is not in what \"{cmd}\" prints "
                          f"(in order):\n{tail(r.stdout)}")
        pos = found + 1


def check_folders(b, args, ids):
    for line in b.text:
        words = line.split()
        if words and words[0].endswith("/") and not os.path.isdir(os.path.join(args.source, words[0])):
            raise Failure(f"{b.where()}: {words[0]} is not a folder of the repository")


# --- shell blocks

def command_lines(b):
    out, cur = [], ""
    for raw in b.text:
        line = raw.rstrip()
        if line.endswith("\\"):
            cur += line[:-1] + " "
            continue
        cur += line
        if cur.strip() and not cur.strip().startswith("#"):
            out.append(cur.strip())
        cur = ""
    return out


def split_comment(cmd):
    """The command and its trailing comment (a '#' after a blank)."""
    m = re.search(r"\s#\s", cmd + " ")
    return (cmd[:m.start()].rstrip(), cmd[m.end():].strip()) if m else (cmd, "")


def tail(text, n=30):
    return "\n".join(text.strip().split("\n")[-n:])


def run_sh(b, args, ids, index):
    box = Sandbox(args.source, args.bin)
    # The programs on PATH as when installed (docs/install.md), and the
    # sandbox as the home folder: cnc-config copies into ~/cnc/configs.
    env = dict(os.environ, CNC_NO_REALTIME="1", CNC_INSTANCE=f"doc{os.getpid()}x{index}",
               QT_QPA_PLATFORM="offscreen", HOME=box.root,
               PATH=os.path.join(box.root, "build", "bin") + os.pathsep + os.environ.get("PATH", ""))
    background = []  # (command, Popen, log path)
    timeout = float(option(b, "timeout", "120"))
    try:
        for n, line in enumerate(command_lines(b)):
            cmd, comment = split_comment(line)
            log = os.path.join(box.root, f"cmd{n}.log")
            if cmd.endswith("&"):
                p = subprocess.Popen(["bash", "-c", cmd[:-1]], cwd=box.root, env=env, start_new_session=True,
                                     stdout=open(log, "w"), stderr=subprocess.STDOUT)
                background.append((cmd, p, log))
                continue
            if "Ctrl-C" in comment:
                # Runs until interrupted: it must be running after 2 s and
                # end on SIGINT, as it does for the user.
                p = subprocess.Popen(["bash", "-c", cmd], cwd=box.root, env=env, start_new_session=True,
                                     stdout=open(log, "w"), stderr=subprocess.STDOUT)
                time.sleep(2)
                if p.poll() is not None:
                    raise Failure(f"{b.where()}: \"{cmd}\" ended (status {p.returncode}) instead of running "
                                  f"until Ctrl-C:\n{tail(open(log).read())}")
                os.killpg(p.pid, signal.SIGINT)
                try:
                    p.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    raise Failure(f"{b.where()}: \"{cmd}\" did not end on Ctrl-C (SIGINT)")
                continue
            try:
                r = subprocess.run(["bash", "-c", cmd], cwd=box.root, env=env, timeout=timeout,
                                   stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
            except subprocess.TimeoutExpired:
                raise Failure(f"{b.where()}: \"{cmd}\" still running after {timeout:.0f} s")
            if r.returncode != 0:
                raise Failure(f"{b.where()}: \"{cmd}\" failed (status {r.returncode}):\n{tail(r.stdout)}")
        # What the block started and stopped (`cnc shutdown`) must have
        # ended cleanly; what it left running is stopped below.
        stops = any(re.search(r"\bshutdown\b", l) for l in command_lines(b))
        for cmd, p, log in background if stops else []:
            try:
                rc = p.wait(15)
            except subprocess.TimeoutExpired:
                continue  # still running: stopped below
            if rc != 0:
                raise Failure(f"{b.where()}: \"{cmd}\" exited with status {rc}:\n{tail(open(log).read())}")
    except Failure as f:
        logs = "".join(f"\n--- {c}\n{tail(open(l).read())}" for c, p, l in background)
        raise Failure(str(f) + logs)
    finally:
        for cmd, p, log in background:
            if p.poll() is None:
                os.killpg(p.pid, signal.SIGTERM)
                try:
                    p.wait(15)
                except subprocess.TimeoutExpired:
                    os.killpg(p.pid, signal.SIGKILL)
                    p.wait()
        box.close()


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", required=True)
    ap.add_argument("--bin", required=True)
    mode = ap.add_mutually_exclusive_group(required=True)
    mode.add_argument("--static", action="store_true")
    mode.add_argument("--commands", action="store_true")
    ap.add_argument("files", nargs="*", help="pages relative to --source (default: README.md and docs/*.md)")
    args = ap.parse_args()
    args.source = os.path.abspath(args.source)
    args.bin = os.path.abspath(args.bin)
    files = args.files or ["README.md"] + sorted(
        os.path.join("docs", f) for f in os.listdir(os.path.join(args.source, "docs")) if f.endswith(".md"))
    failures, counts = [], {}
    index = 0
    for rel in files:
        blocks, problems = parse_markdown(args.source, rel)
        failures += problems
        ids = blocks_by_id(blocks)
        for b in blocks:
            if not b.kind or b.kind not in KINDS:
                continue
            if args.static == (b.kind == "sh"):
                continue
            counts[b.kind] = counts.get(b.kind, 0) + 1
            if b.kind == "skip":
                continue
            index += 1
            t0 = time.monotonic()
            try:
                {"ini": check_ini, "hal": check_hal, "excerpt": check_excerpt, "output": check_output,
                 "folders": check_folders,
                 "sh": lambda b, a, i: run_sh(b, a, i, index)}[b.kind](b, args, ids)
                print(f"ok    {b.where()} {b.kind} ({time.monotonic() - t0:.1f} s)", flush=True)
            except Failure as f:
                print(f"FAIL  {b.where()} {b.kind}", flush=True)
                failures.append(str(f))
    print("blocks: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    for f in failures:
        print("\n" + f)
    if failures:
        print(f"\n{len(failures)} problem(s) in the documentation's code blocks")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
