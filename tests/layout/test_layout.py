#!/usr/bin/env python3
"""test_layout.py - the folders of lib/ depend on each other one way only, and Embree stays
inside lib/bvh/.

Reads every `#include "folder/file.h"` of lib/'s .c and .h files and draws an edge from the
including file's folder to the included one's (lib/include/ is the public header, below all).
Fails, naming the circle, when the folders' graph has one; fails when a file of lib/ outside
lib/bvh/ includes an <embree3/...> header, or includes a header that does (so Embree's types
cannot leak out through one), or when a C file beside lib/ (server/, tests/) includes one. The intended order is written at the top of lib/meson.build; this test
checks the property, not that list, so a new folder needs no edit here.

Usage: test_layout.py [LIB_DIR]   (default: lib/ beside tests/)
"""
import os
import re
import sys

QUOTED = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
EMBREE = re.compile(r'^\s*#\s*include\s+<embree3/[^>]+>', re.M)


def sources(lib):
    """Every .c and .h file under lib, as paths relative to it."""
    for root, _dirs, files in os.walk(lib):
        for name in sorted(files):
            if name.endswith(('.c', '.h')):
                yield os.path.relpath(os.path.join(root, name), lib)


def folder(rel):
    """A lib-relative path's folder: its first component ('include' for sdf/sdf.h)."""
    parts = rel.split(os.sep)
    if parts[0] == 'sdf':  # included as "sdf/sdf.h" through lib/include
        return 'include'
    return parts[0] if len(parts) > 1 else '.'


def read_includes(lib):
    """{file: (quoted includes resolved to lib-relative paths, includes embree3 directly)}."""
    out = {}
    for rel in sources(lib):
        with open(os.path.join(lib, rel), encoding='utf-8', errors='replace') as f:
            text = f.read()
        quoted = []
        for inc in QUOTED.findall(text):
            if os.path.exists(os.path.join(lib, inc)):
                quoted.append(inc)
            elif os.path.exists(os.path.join(lib, 'include', inc)):
                quoted.append(os.path.join('include', inc))
            elif os.path.exists(os.path.join(lib, os.path.dirname(rel), inc)):
                quoted.append(os.path.normpath(os.path.join(os.path.dirname(rel), inc)))
            else:
                raise SystemExit('%s: #include "%s" names no file under %s' % (rel, inc, lib))
        out[rel] = (quoted, bool(EMBREE.search(text)))
    return out


def folder_graph(includes):
    """{folder: {folder it includes from: an example 'file -> header'}}, self-edges left out."""
    graph = {}
    for rel, (quoted, _) in includes.items():
        a = folder(rel)
        graph.setdefault(a, {})
        for inc in quoted:
            b = folder(inc)
            graph.setdefault(b, {})
            if a != b:
                graph[a].setdefault(b, '%s -> %s' % (rel, inc))
    return graph


def find_cycle(graph):
    """One circle of the graph as a list of folders (first == last), or None."""
    state = {}
    stack = []

    def visit(node):
        state[node] = 'open'
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 'open':
                return stack[stack.index(nxt):] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 'done'
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def embree_leaks(includes):
    """Files outside bvh/ that include an embree3 header, directly or through lib's headers."""
    memo = {}

    def reaches_embree(rel, seen):
        if rel in memo:
            return memo[rel]
        quoted, direct = includes.get(rel, ([], False))
        via = None if not direct else [rel]
        for inc in quoted:
            if via or inc in seen:
                break
            sub = reaches_embree(inc, seen | {inc})
            if sub:
                via = [rel] + sub
        memo[rel] = via
        return via

    leaks = []
    for rel in sorted(includes):
        if folder(rel) == 'bvh':
            continue
        chain = reaches_embree(rel, {rel})
        if chain:
            leaks.append(' -> '.join(chain) + ' -> <embree3/...>')
    return leaks


def embree_outside_lib(lib):
    """C files of the project beside lib/ (server/, tests/, ...; build folders aside) that
    include an embree3 header."""
    root = os.path.dirname(os.path.abspath(lib))
    found = []
    for top in sorted(os.listdir(root)):
        path = os.path.join(root, top)
        if top == os.path.basename(os.path.abspath(lib)) or top.startswith(('.', 'build')) \
                or not os.path.isdir(path):
            continue
        for rel in sources(path):
            with open(os.path.join(path, rel), encoding='utf-8', errors='replace') as f:
                if EMBREE.search(f.read()):
                    found.append(os.path.join(top, rel) + ' -> <embree3/...>')
    return found


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    lib = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, '..', '..', 'lib')
    includes = read_includes(lib)
    failures = 0
    if len(includes) < 10:
        print('FAIL: only %d sources found under %s' % (len(includes), lib))
        return 1
    graph = folder_graph(includes)
    cycle = find_cycle(graph)
    if cycle:
        print('FAIL: lib/ folders include each other in a circle: ' + ' -> '.join(cycle))
        for a, b in zip(cycle, cycle[1:]):
            print('  %s -> %s: %s' % (a, b, graph[a][b]))
        failures += 1
    else:
        print('ok: %d folders, no circle' % len(graph))
    leaks = embree_leaks(includes) + embree_outside_lib(lib)
    for leak in leaks:
        print('FAIL: Embree outside lib/bvh: ' + leak)
    failures += bool(leaks)
    if not leaks:
        print('ok: <embree3/...> is included inside lib/bvh only')
    print('%d passed, %d failed' % (2 - failures, failures))
    return 1 if failures else 0


if __name__ == '__main__':
    sys.exit(main())
