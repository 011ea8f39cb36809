#!/usr/bin/env python3
"""The layer check: Terrace's module graph, derived from the `use` lines of src/, against the layer
list of doc/architecture.md.

usage: check_layers.py [REPO]            (default: the repository this script is in)

The layers are the rows of the table under "## Layers" in doc/architecture.md, lowest first; the
second column names the folder(s) of each row (`src/NAME`). A module may use modules of its own
layer and of the layers listed before it, never one listed after it. Also, the deck's type
`config_t` may be named only in the layers from `input` on (input, run, analysis, app): physics,
engine and I/O receive records of their own parameters.

Prints every wrong-way import (file, line, the module used and both layers) and every
`config_t` outside its layers, then a summary; exits 1 when there is any, 0 otherwise, 2 when the
layer table or the sources cannot be read.
"""
import os
import re
import sys

USE = re.compile(r"^\s*use\s*(?:,\s*(?:non_)?intrinsic\s*::)?\s*(\w+)", re.I)
MODULE = re.compile(r"^\s*module\s+(\w+)\s*(?:!.*)?$", re.I)
ROW = re.compile(r"^\|\s*([^|]+?)\s*\|\s*([^|]+?)\s*\|")
CONFIG_FROM = "input"          # the first layer that may name config_t


def layers(doc):
    """[(layer name, [folders])] in the order of the table, lowest first."""
    rows, inside = [], False
    with open(doc, encoding="utf-8") as f:
        for line in f:
            if line.startswith("## "):
                inside = line.strip() == "## Layers"
                continue
            m = ROW.match(line) if inside else None
            if not m or m.group(1) in ("layer",) or set(m.group(1)) <= set("-: "):
                continue
            folders = re.findall(r"`src/([\w/]+)`", m.group(2))
            if folders:
                rows.append((m.group(1).strip(), folders))
    return rows


def sources(src):
    for root, _, files in os.walk(src):
        for name in sorted(files):
            if name.endswith((".f90", ".F90", ".inc")):
                yield os.path.join(root, name)


def strip_comment(line):
    return line.split("!", 1)[0]


def main(argv):
    repo = os.path.abspath(argv[1]) if len(argv) > 1 else \
        os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    doc = os.path.join(repo, "doc", "architecture.md")
    src = os.path.join(repo, "src")
    try:
        table = layers(doc)
    except OSError as e:
        print(f"check_layers: cannot read {doc}: {e}")
        return 2
    if not table:
        print(f"check_layers: {doc}: no layer table under '## Layers'")
        return 2
    rank = {}
    for i, (_, folders) in enumerate(table):
        for folder in folders:
            rank[folder] = i
    names = [name for name, _ in table]
    config_rank = next((i for i, (n, _) in enumerate(table) if n == CONFIG_FROM), None)

    def folder_of(path):
        rel = os.path.relpath(path, src).split(os.sep)
        return rel[0]

    owner, uses, unknown = {}, [], []
    for path in sources(src):
        folder = folder_of(path)
        if folder not in rank:
            unknown.append(os.path.relpath(path, repo))
            continue
        with open(path, encoding="utf-8", errors="replace") as f:
            for n, line in enumerate(f, 1):
                code = strip_comment(line)
                m = MODULE.match(code)
                if m and m.group(1).lower() not in ("procedure",):
                    owner[m.group(1).lower()] = folder
                m = USE.match(code)
                if m:
                    uses.append((path, n, folder, m.group(1).lower()))
                if config_rank is not None and rank[folder] < config_rank and re.search(r"\bconfig_t\b", code, re.I):
                    uses.append((path, n, folder, "<config_t>"))
    bad = []
    for path, n, folder, mod in uses:
        rel = os.path.relpath(path, repo)
        if mod == "<config_t>":
            bad.append(f"{rel}:{n}: names config_t, the deck's type, in layer '{names[rank[folder]]}' "
                       f"(only '{CONFIG_FROM}' and the layers after it may; pass a record of parameters)")
            continue
        target = owner.get(mod)
        if target is None or rank[target] <= rank[folder]:
            continue
        bad.append(f"{rel}:{n}: uses {mod} (layer '{names[rank[target]]}', src/{target}) from layer "
                   f"'{names[rank[folder]]}' (src/{folder}), which is below it")
    for u in unknown:
        bad.append(f"{u}: its folder is in no row of the layer table of doc/architecture.md")
    for line in bad:
        print(line)
    modules = len(owner)
    edges = sum(1 for _, _, _, m in uses if m in owner)
    print(f"check_layers: {len(table)} layers, {modules} modules, {edges} imports; "
          f"{len(bad)} violation{'s' if len(bad) != 1 else ''}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
