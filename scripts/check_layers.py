#!/usr/bin/env python3
"""Checks the module layers of docs/architecture.md against the code.

The table under "## Modules and layers" gives every module (a folder, or
`folder/*` for each sub-folder) a layer. This check fails when
  - a source file of the product (every folder but tests/, bench/, build*/)
    belongs to no module of the table, or a folder with a CMakeLists.txt is
    missing from it;
  - a file includes a header of another module whose layer is not lower
    than its own (modules of one layer never include each other).
Tests and benchmarks may include anything. Usage:
  check_layers.py [--root DIR] [--doc FILE]   (default: the repository)
"""
import argparse
import os
import re
import sys

SOURCE = re.compile(r"\.(c|cc|cpp|h|hh|hpp)$")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
EXEMPT = ("tests/", "bench/", "build", ".git/", "cmake/", "scripts/", "configs/", "docs/")


def parse_table(doc):
    """{module folder or pattern: layer} from the layer table."""
    text = open(doc, encoding="utf-8").read()
    start = text.find("## Modules and layers")
    if start < 0:
        sys.exit(f"{doc}: no section \"## Modules and layers\"")
    layers = {}
    for line in text[start:].splitlines()[1:]:
        if line.startswith("## "):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) < 2 or not cells[0].isdigit():
            continue
        for module in re.findall(r"`([^`]+)`", cells[1]):
            layers[module.rstrip("/")] = int(cells[0])
    if not layers:
        sys.exit(f"{doc}: the layer table has no rows")
    return layers


def module_of(path, layers, root):
    """The module a repository path belongs to (longest match), or None."""
    best = None
    for module in layers:
        if module.endswith("/*"):
            base = module[:-2]
            if not path.startswith(base + "/"):
                continue
            sub = path[len(base) + 1:].split("/")[0]
            if not os.path.isdir(os.path.join(root, base, sub)):
                continue
            name = base + "/" + sub
        elif path == module or path.startswith(module + "/"):
            name = module
        else:
            continue
        if best is None or len(name) > len(best[0]):
            best = (name, layers[module])
    return best


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument("--root", default=os.path.dirname(here))
    ap.add_argument("--doc", default=None)
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    doc = args.doc or os.path.join(root, "docs", "architecture.md")
    layers = parse_table(doc)
    errors = []
    checked = 0
    for dirpath, dirnames, filenames in os.walk(root):
        rel_dir = os.path.relpath(dirpath, root).replace(os.sep, "/")
        rel_dir = "" if rel_dir == "." else rel_dir
        dirnames[:] = sorted(d for d in dirnames if not ((rel_dir + "/" + d if rel_dir else d) + "/").startswith(EXEMPT)
                             and not d.startswith("."))
        if rel_dir and "CMakeLists.txt" in filenames and module_of(rel_dir, layers, root) is None:
            errors.append(f"{rel_dir}/CMakeLists.txt: the folder is a module missing from the layer table of {doc}")
        for name in sorted(filenames):
            if not SOURCE.search(name):
                continue
            path = f"{rel_dir}/{name}" if rel_dir else name
            mine = module_of(path, layers, root)
            if mine is None:
                errors.append(f"{path}: belongs to no module of the layer table of {doc}")
                continue
            checked += 1
            with open(os.path.join(root, path), encoding="utf-8", errors="replace") as f:
                for number, line in enumerate(f, 1):
                    m = INCLUDE.match(line)
                    if not m or not os.path.exists(os.path.join(root, m.group(1))):
                        continue  # a system header, or one next to the file
                    theirs = module_of(m.group(1), layers, root)
                    if theirs is None or theirs[0] == mine[0]:
                        continue
                    if theirs[1] >= mine[1]:
                        errors.append(f"{path}:{number}: {mine[0]} (layer {mine[1]}) includes \"{m.group(1)}\" of "
                                      f"{theirs[0]} (layer {theirs[1]}): a module includes only lower layers")
    for e in errors:
        print(e)
    print(f"{checked} files of {len(layers)} modules checked, {len(errors)} problems")
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
