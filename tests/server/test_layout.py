"""server/'s folders and modules depend on each other one way only.

server/ holds main.c and four folders in the order of a request's flow, each using only the
folders before it: core (settings, logs, errors, metrics) <- state (what sdfd holds) <- ops
(the table of operations, admission, one handler per operation) <- transport (HTTP and
binary: parse and reply) <- main.c. A module is a .c/.h pair named alike (or a header alone,
such as state/server.h), named by its path ("transport/http"); module A depends on B when
A's .c or .h includes B.h, always by its folder-qualified path. The test reads every
#include "..." of server/ and fails on an include against the folders' order, on any cycle
in the module graph (naming it), on a module outside the folders, and on a quoted include it
cannot place. So that the include graph is also the call graph, every function a header
declares must be defined in the .c of the same name: a header shared by two halves that call
each other fails that check. The finders also run on small graphs with and without a fault,
so a finder that found nothing could not pass."""
import os
import re
import sys
import unittest

SERVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "server")
FOLDERS = ["core", "state", "ops", "transport"]  # each may include those before it
TOP = {"main"}  # server/main.c: may include every folder
EXTERNAL = {"proto.h", "sdf/sdf.h"}  # quoted includes from proto/ and lib/
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
# A function declared at file scope: not static (inline helpers), typedef, macro or return.
DECLARATION = re.compile(r"^(?!\s*(?:static|typedef|#|return))[A-Za-z_][\w \t*]*?\b(sdfd_\w+)\s*\(",
                         re.M)


def without_comments(text):
    return re.sub(r"/\*.*?\*/", "", re.sub(r"//[^\n]*", "", text), flags=re.S)


def sources(root):
    """{module: [files]} for every .c and .h under root; module = path without extension."""
    out = {}
    for folder, _, files in os.walk(root):
        for f in files:
            if f.endswith((".c", ".h")):
                rel = os.path.relpath(os.path.join(folder, f), root)
                out.setdefault(os.path.splitext(rel)[0].replace(os.sep, "/"), []).append(rel)
    return out


def read(root, rel):
    with open(os.path.join(root, rel), encoding="utf-8") as fh:
        return fh.read()


def undefined_declarations(root):
    """[(header, function)] for each function a header declares that the .c of the same name
    does not define."""
    missing = []
    for module, files in sorted(sources(root).items()):
        header = module + ".h"
        if header.replace("/", os.sep) not in files:
            continue
        names = set(DECLARATION.findall(without_comments(read(root, header))))
        source = module + ".c"
        text = without_comments(read(root, source)) if source in files else ""
        for name in sorted(names):
            if not re.search(r"\b%s\s*\([^;{]*\)\s*\{" % name, text):
                missing.append((header, name))
    return missing


def module_graph(root):
    """({module: set of modules it includes}, [(file, include) that name no module])."""
    mods = sources(root)
    graph = {m: set() for m in mods}
    unknown = []
    for module, files in mods.items():
        for f in files:
            for header in INCLUDE.findall(read(root, f)):
                other = os.path.splitext(header)[0]
                if header.endswith(".h") and other in mods:
                    if other != module:
                        graph[module].add(other)
                elif header not in EXTERNAL:
                    unknown.append((f, header))
    return graph, unknown


def folder_of(module):
    return module.split("/")[0] if "/" in module else None


def against_order(graph, folders=FOLDERS, top=TOP):
    """[(module, included)] for each include of a later folder than the includer's, and
    [module] for modules outside the folders (other than top)."""
    bad, outside = [], []
    for module in sorted(graph):
        if module in top:
            continue
        f = folder_of(module)
        if f not in folders:
            outside.append(module)
            continue
        for other in sorted(graph[module]):
            g = folder_of(other)
            if g not in folders or folders.index(g) > folders.index(f):
                bad.append((module, other))
    return bad, outside


def find_cycle(graph):
    """One cycle as a list of modules (first repeated at the end), or None."""
    state = {}  # 1: on the current path, 2: done
    path = []

    def visit(m):
        state[m] = 1
        path.append(m)
        for n in sorted(graph.get(m, ())):
            if state.get(n) == 1:
                return path[path.index(n):] + [n]
            if n not in state:
                found = visit(n)
                if found:
                    return found
        path.pop()
        state[m] = 2
        return None

    for m in sorted(graph):
        if m not in state:
            found = visit(m)
            if found:
                return found
    return None


class Layout(unittest.TestCase):
    def test_finders(self):
        self.assertEqual(find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}), ["a", "b", "c", "a"])
        self.assertIsNone(find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}))
        graph = {"state/x": {"ops/y"}, "ops/y": {"state/x", "core/z"}, "core/z": set(),
                 "main": {"ops/y"}, "w": set()}
        self.assertEqual(against_order(graph), ([("state/x", "ops/y")], ["w"]))

    def test_headers_declare_their_own_functions(self):
        self.assertEqual(undefined_declarations(SERVER), [])

    def test_declarations_are_read(self):
        names = set()
        for module, files in sources(SERVER).items():
            for f in files:
                if f.endswith(".h"):
                    names |= set(DECLARATION.findall(without_comments(read(SERVER, f))))
        self.assertIn("sdfd_query_admit", names)
        self.assertIn("sdfd_http_error", names)
        self.assertNotIn("sdfd_buffer_reserve", names)  # static inline in server.h

    def test_graph_is_read(self):
        graph, _ = module_graph(SERVER)
        self.assertIn("state/server", graph["transport/http"])  # http.h includes server.h
        self.assertIn("ops/queries", graph["transport/binrequests"])
        self.assertIn("ops/dispatch", graph["transport/http"])

    def test_includes_are_placed(self):
        _, unknown = module_graph(SERVER)
        self.assertEqual(unknown, [], "includes that name no module of server/ by its path")

    def test_folders_are_one_way(self):
        graph, _ = module_graph(SERVER)
        bad, outside = against_order(graph)
        self.assertEqual(outside, [], "modules outside server/'s folders")
        self.assertEqual(bad, [], "includes against the order " + " <- ".join(FOLDERS))

    def test_server_modules_are_one_way(self):
        graph, _ = module_graph(SERVER)
        cycle = find_cycle(graph)
        self.assertIsNone(cycle, "server/ modules include each other in a circle: " +
                          " -> ".join(cycle or []))


if __name__ == "__main__":
    sys.exit(unittest.main(verbosity=2))
