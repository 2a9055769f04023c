#!/usr/bin/python3
"""Issue 42: docs/architecture.md draws the build. The build writes its project targets, their
folders and their direct links (BUILD/layout/targets.txt, at configure time); the doc's mermaid
graph must hold exactly the transitive reduction of those links (every arrow the build draws
that no longer path implies), and its table every target with its folder.

    graph_test.py BUILD/layout/targets.txt docs/architecture.md
"""
import re
import sys


def read_build(path):
    folders, edges = {}, set()
    for line in open(path, encoding="utf-8"):
        kind, *rest = line.split()
        if kind == "target":
            folders[rest[0]] = rest[1]
        elif kind == "link":
            edges.add((rest[0], rest[1]))
    return folders, edges


def reduction(edges):
    """The arrows no longer path implies."""
    out = {}
    for a, b in edges:
        out.setdefault(a, set()).add(b)

    def reach(start, skip):
        seen, stack = set(), [n for n in out.get(start, ()) if (start, n) != skip]
        while stack:
            n = stack.pop()
            if n not in seen:
                seen.add(n)
                stack.extend(out.get(n, ()))
        return seen

    return {(a, b) for a, b in edges if b not in reach(a, (a, b))}


def read_doc(path):
    text = open(path, encoding="utf-8").read()
    block = re.search(r"```mermaid\n(.*?)```", text, re.S)
    if not block:
        sys.exit(f"FAIL: {path} has no mermaid graph")
    edges = set(re.findall(r"^\s*(\w+)\s*-->\s*(\w+)\s*$", block.group(1), re.M))
    table = dict(re.findall(r"^\|\s*`(\w+)`\s*\|\s*`([\w/]+)/?`\s*\|", text, re.M))
    return edges, table


def main():
    folders, build_edges = read_build(sys.argv[1])
    doc_edges, table = read_doc(sys.argv[2])
    want = reduction(build_edges)
    problems = []
    for a, b in sorted(want - doc_edges):
        problems.append(f"the build links {a} -> {b}; the drawing lacks '{a} --> {b}'")
    for a, b in sorted(doc_edges - want):
        why = "a longer path implies it" if (a, b) in build_edges else "the build has no such link"
        problems.append(f"the drawing has '{a} --> {b}': {why}")
    for t, folder in sorted(folders.items()):
        if t not in table:
            problems.append(f"the table lacks target {t} ({folder})")
        elif table[t].rstrip("/") != folder:
            problems.append(f"the table puts {t} in {table[t]}; the build in {folder}")
    for t in sorted(set(table) - set(folders)):
        problems.append(f"the table names {t}, which the build does not have")
    for p in problems:
        print("FAIL:", p)
    if problems:
        return 1
    print(f"ok: docs/architecture.md draws the build's {len(folders)} targets and {len(want)} arrows")
    return 0


if __name__ == "__main__":
    sys.exit(main())
