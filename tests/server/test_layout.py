"""server/'s modules depend on each other one way only. A module is a .c/.h pair named alike
(or a header alone, such as server.h); module A depends on B when A's .c or .h includes B.h.
The test reads every #include "..." of server/ and fails on any cycle in that graph, naming it.
So that the include graph is also the call graph, every function a header declares must be
defined in the .c of the same name: a header shared by two halves that call each other (as
httpreq.h once declared functions of both http.c and httpvolumes.c) fails that check. The
test also runs its cycle finder on small graphs with and without a cycle, so a finder that
found nothing could not pass."""
import os
import re
import sys
import unittest

SERVER = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "server")
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)
# A function declared at file scope: not static (inline helpers), typedef, macro or return.
DECLARATION = re.compile(r"^(?!\s*(?:static|typedef|#|return))[A-Za-z_][\w \t*]*?\b(sdfd_\w+)\s*\(",
                         re.M)


def without_comments(text):
    return re.sub(r"/\*.*?\*/", "", re.sub(r"//[^\n]*", "", text), flags=re.S)


def undefined_declarations(folder):
    """[(header, function)] for each function a header declares that the .c of the same name
    does not define."""
    missing = []
    for f in sorted(os.listdir(folder)):
        if not f.endswith(".h"):
            continue
        with open(os.path.join(folder, f), encoding="utf-8") as fh:
            names = set(DECLARATION.findall(without_comments(fh.read())))
        source = os.path.join(folder, f[:-2] + ".c")
        text = ""
        if os.path.exists(source):
            with open(source, encoding="utf-8") as fh:
                text = without_comments(fh.read())
        for name in sorted(names):
            if not re.search(r"\b%s\s*\([^;{]*\)\s*\{" % name, text):
                missing.append((f, name))
    return missing


def module_graph(folder):
    """{module: set of modules its files include}, for the headers of this folder only."""
    files = [f for f in os.listdir(folder) if f.endswith((".c", ".h"))]
    modules = {os.path.splitext(f)[0] for f in files}
    graph = {m: set() for m in modules}
    for f in files:
        with open(os.path.join(folder, f), encoding="utf-8") as fh:
            text = fh.read()
        here = os.path.splitext(f)[0]
        for header in INCLUDE.findall(text):
            other = os.path.splitext(os.path.basename(header))[0]
            if header.endswith(".h") and "/" not in header and other in modules and other != here:
                graph[here].add(other)
    return graph


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
    def test_finder(self):
        self.assertEqual(find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}), ["a", "b", "c", "a"])
        self.assertIsNone(find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}))

    def test_headers_declare_their_own_functions(self):
        self.assertEqual(undefined_declarations(SERVER), [])

    def test_declarations_are_read(self):
        graph_names = set()
        for f in os.listdir(SERVER):
            if f.endswith(".h"):
                with open(os.path.join(SERVER, f), encoding="utf-8") as fh:
                    graph_names |= set(DECLARATION.findall(without_comments(fh.read())))
        self.assertIn("sdfd_query_admit", graph_names)
        self.assertIn("sdfd_http_error", graph_names)
        self.assertNotIn("sdfd_buffer_reserve", graph_names)  # static inline in server.h

    def test_graph_is_read(self):
        graph = module_graph(SERVER)
        self.assertIn("server", graph["http"])  # http.h includes server.h
        self.assertIn("queries", graph["binrequests"])

    def test_server_modules_are_one_way(self):
        cycle = find_cycle(module_graph(SERVER))
        self.assertIsNone(cycle, "server/ modules include each other in a circle: " +
                          " -> ".join(cycle or []))


if __name__ == "__main__":
    sys.exit(unittest.main(verbosity=2))
