"""docs/openapi.yaml against the server's own route table (`sdfd --describe-routes`) and against
what a running sdfd serves as GET /openapi.json.

The table has one row per method and route: {"method", "path", "label", "auth", "body",
"args", "frame", ...}; HEAD is implied wherever GET is and is not listed, and the binary
protocol's own operations (HELLO, AUTH) have no path. The document has the same operations
plus a HEAD beside every GET (with GET's URL arguments), each path's `x-sdfd-label`, each
operation's `x-sdfd-frame`, a request body where the table says `body`, and a security that
says its auth: none `[]`, write `[{bearerToken: []}]`, query `[{}, {bearerToken: []}]` (the
token only with --auth-queries). Any difference in routes, methods, URL argument names,
labels, auth, bodies or frames fails, with every difference listed. The comparison itself is tested on mutated tables, so that a
difference of each kind is shown to be caught.

Environment (meson sets it): SDFD, the daemon. Standard library + python3-yaml."""
import json
import os
import subprocess
import sys
import unittest
import urllib.request

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "server"))
from harness import SDFD, Server  # noqa: E402

DOCUMENT = os.path.join(HERE, "..", "..", "docs", "openapi.yaml")
METHODS = ("get", "put", "post", "delete", "options", "head", "patch", "trace")
AUTH_OF_SECURITY = {"[]": "none", '[{"bearerToken": []}]': "write",
                    '[{}, {"bearerToken": []}]': "query"}


def load_document():
    with open(DOCUMENT, encoding="utf-8") as f:
        return yaml.safe_load(f)


def describe_routes():
    """The table sdfd prints with --describe-routes."""
    out = subprocess.run([SDFD, "--describe-routes"], capture_output=True, timeout=60)
    if out.returncode != 0:
        raise AssertionError(f"{SDFD} --describe-routes exited {out.returncode}: "
                             f"{out.stderr.decode(errors='replace')[:500]}")
    return json.loads(out.stdout)


def resolve(doc, node):
    """A `$ref`'d object of the document, or node itself."""
    while isinstance(node, dict) and "$ref" in node:
        at = doc
        for part in node["$ref"].lstrip("#/").split("/"):
            at = at[part]
        node = at
    return node


def query_args(doc, path_item, op):
    params = [resolve(doc, p) for p in path_item.get("parameters", []) + op.get("parameters", [])]
    return sorted(p["name"] for p in params if p["in"] == "query")


def document_rows(doc):
    """{(METHOD, path): row} in the table's terms, from the document (HEAD included)."""
    rows = {}
    for path, item in doc["paths"].items():
        for method in METHODS:
            if method not in item:
                continue
            op = item[method]
            security = json.dumps(op.get("security", doc.get("security")))
            rows[(method.upper(), path)] = {
                "label": item.get("x-sdfd-label"), "args": query_args(doc, item, op),
                "auth": AUTH_OF_SECURITY.get(security, f"unknown security {security}"),
                "frame": op.get("x-sdfd-frame"), "body": "requestBody" in op}
    return rows


def table_rows(table):
    """{(METHOD, path): row} from the server's table, with HEAD added beside every GET."""
    rows, problems = {}, []
    for r in table["routes"]:
        if r["path"] is None:  # the binary protocol's alone
            if r["method"] is not None or r["frame"] is None:
                problems.append(f"the table's row {r} has no path but is not a frame's")
            continue
        key = (r["method"], r["path"])
        if key in rows:
            problems.append(f"the table lists {r['method']} {r['path']} twice")
        if r["method"] == "HEAD":
            problems.append(f"the table lists HEAD {r['path']}, which GET implies")
        if len(set(r["args"])) != len(r["args"]):
            problems.append(f"the table gives {r['method']} {r['path']} an argument twice")
        rows[key] = {"label": r["label"], "args": sorted(r["args"]), "auth": r["auth"],
                     "frame": r["frame"], "body": r["body"]}
    for (method, path), row in list(rows.items()):
        if method == "GET":
            rows.setdefault(("HEAD", path), dict(row, frame=None))  # the work is GET's
    return rows, problems


def differences(doc, table):
    """Every way the document and the table disagree, as sentences."""
    ours = document_rows(doc)
    theirs, problems = table_rows(table)
    for key in sorted(set(theirs) - set(ours)):
        problems.append(f"the server has {key[0]} {key[1]}; the document does not")
    for key in sorted(set(ours) - set(theirs)):
        problems.append(f"the document has {key[0]} {key[1]}; the server does not")
    for key in sorted(set(ours) & set(theirs)):
        a, b = ours[key], theirs[key]
        for field in ("label", "auth", "frame", "body"):
            if a[field] != b[field]:
                problems.append(f"{key[0]} {key[1]}: {field} {a[field]!r} in the document, "
                                f"{b[field]!r} in the server")
        if a["args"] != b["args"]:
            only_doc = sorted(set(a["args"]) - set(b["args"]))
            only_srv = sorted(set(b["args"]) - set(a["args"]))
            problems.append(f"{key[0]} {key[1]}: URL arguments only in the document "
                            f"{only_doc}, only in the server {only_srv}")
    return problems


def first_difference(a, b, at="#"):
    """The JSON pointer of the first place two JSON values differ, or None."""
    if type(a) is not type(b):
        return f"{at}: {type(a).__name__} vs {type(b).__name__}"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{at}/{k}: only in {'the file' if k in a else 'the answer'}"
            d = first_difference(a[k], b[k], f"{at}/{k}")
            if d:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{at}: {len(a)} items vs {len(b)}"
        for i, (x, y) in enumerate(zip(a, b)):
            d = first_difference(x, y, f"{at}/{i}")
            if d:
                return d
        return None
    return None if a == b else f"{at}: {a!r} vs {b!r}"


class ComparisonTest(unittest.TestCase):
    """The comparison catches each kind of difference (tables made from the document)."""

    def setUp(self):
        self.doc = load_document()
        self.table = {"routes": [
            {"method": m, "path": p, **row} for (m, p), row in document_rows(self.doc).items()
            if m != "HEAD"]}

    def row(self, method, path):
        return next(r for r in self.table["routes"] if (r["method"], r["path"]) == (method, path))

    def test_agrees_with_itself(self):
        self.assertEqual(differences(self.doc, self.table), [])

    def test_catches_each_difference(self):
        cases = {
            "a route the document lacks": lambda t: t["routes"].append(
                {"method": "GET", "path": "/v1/extra", "label": "/v1/extra", "auth": "none",
                 "args": [], "frame": None, "body": False}),
            "a route the server lacks": lambda t: t["routes"].remove(
                self.row("DELETE", "/v1/jobs/{id}")),
            "a method": lambda t: self.row("PUT", "/v1/meshes/{name}").update(method="PATCH"),
            "an argument": lambda t: self.row("POST", "/v1/volumes/{name}/query")["args"].append(
                "sign"),
            "a missing argument": lambda t: self.row("GET", "/v1/volumes/{name}/data").update(
                args=[]),
            "a label": lambda t: self.row("GET", "/").update(label="page"),
            "auth": lambda t: self.row("POST", "/v1/meshes/{name}/query").update(auth="write"),
            "a frame": lambda t: self.row("POST", "/v1/volumes/{name}/query").update(frame=None),
            "a body": lambda t: self.row("DELETE", "/v1/jobs/{id}").update(body=True),
            "HEAD listed": lambda t: t["routes"].append(
                dict(self.row("GET", "/healthz"), method="HEAD")),
            "a path-less row that is no frame's": lambda t: t["routes"].append(
                dict(self.row("GET", "/healthz"), method=None, path=None)),
        }
        for what, mutate in cases.items():
            with self.subTest(what):
                self.setUp()
                mutate(self.table)
                self.assertNotEqual(differences(self.doc, self.table), [], what)

    def test_first_difference(self):
        self.assertIsNone(first_difference({"a": [1, {"b": 2}]}, {"a": [1, {"b": 2}]}))
        self.assertEqual(first_difference({"a": [1, {"b": 2}]}, {"a": [1, {"b": 3}]}),
                         "#/a/1/b: 2 vs 3")


class ServerTest(unittest.TestCase):
    def test_route_table_matches_document(self):
        problems = differences(load_document(), describe_routes())
        self.assertEqual(problems, [], "docs/openapi.yaml and sdfd --describe-routes differ:\n" +
                         "\n".join(problems))

    def test_served_document_is_the_file(self):
        with Server() as server:
            with urllib.request.urlopen(server.url + "/openapi.json", timeout=30) as resp:
                self.assertEqual(resp.headers.get_content_type(), "application/json")
                served = json.loads(resp.read())
        where = first_difference(load_document(), served)
        self.assertIsNone(where, "GET /openapi.json differs from docs/openapi.yaml at " +
                          str(where))


if __name__ == "__main__":
    unittest.main(verbosity=2)
