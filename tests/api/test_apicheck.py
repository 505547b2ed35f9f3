"""The response check of tests/api/apicheck.py fails on answers docs/openapi.yaml does not
describe: made-up answers of each kind of violation, then a real sdfd's answer checked
against a document that no longer describes it (the check fails the request, through the
Python client, as it would fail any integration test), and the same answer passing against
the real document.

Environment (meson sets it): SDFD. Standard library, numpy, python3-yaml, python3-jsonschema."""
import copy
import http.client
import json
import os
import sys
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "server"))
sys.path.insert(0, os.path.join(HERE, "..", "..", "clients", "python"))
import apicheck  # noqa: E402
import sdfclient  # noqa: E402
from harness import Server  # noqa: E402  (installs the check)

REPORT = {"name": "tet", "format": "obj", "vertices": 4, "input_vertices": 4, "triangles": 4,
          "bbox": {"min": [0, 0, 0], "max": [1, 1, 1]}, "diagonal": 1.7320508075688772,
          "closed": True, "edge_manifold": True, "self_intersecting": False, "flipped": False,
          "degenerate_triangles": 0, "boundary_edges": 0, "nonmanifold_edges": 0,
          "misoriented_edges": 0, "volume": 0.16666666666666666, "sign": "pseudonormal",
          "index_bytes": 472, "build_seconds": 0.0007, "warnings": 0}


def headers(**values):
    h = http.client.HTTPMessage()
    for name, value in values.items():
        h[name.replace("_", "-")] = value
    return h


JSON = headers(Content_Type="application/json")


def body(value):
    return json.dumps(value).encode()


class MadeUpAnswers(unittest.TestCase):
    doc = apicheck.Document(apicheck.load())

    def check(self, method, path, status, h, b):
        return self.doc.check(method, path, status, h, b)

    def test_documented_answers_pass(self):
        self.assertEqual(self.check("GET", "/v1/meshes/tet", 200, JSON, body(REPORT)), [])
        self.assertEqual(self.check("PUT", "/v1/meshes/tet?format=obj", 201, JSON, body(REPORT)),
                         [])
        self.assertEqual(self.check("POST", "/v1/meshes/tet/query", 200,
                                    headers(Content_Type="application/json", X_SDF_Count="1"),
                                    body({"distance": [-0.0], "gradient": [[1, 0, None]]})), [])
        self.assertEqual(self.check("PATCH", "/v1/meshes/tet", 405,
                                    headers(Content_Type="application/json",
                                            Allow="GET, HEAD, PUT, DELETE"),
                                    body({"error": {"code": "EMETHOD", "message": "no"}})), [])
        self.assertEqual(self.check("GET", "/v1/nothing", 404, JSON,
                                    body({"error": {"code": "ENOTFOUND", "message": "no"}})), [])
        self.assertEqual(self.check("DELETE", "/v1/meshes/tet", 204, JSON, None), [])
        self.assertEqual(self.check("HEAD", "/v1/meshes/tet", 200, JSON, None), [])

    def test_each_violation_is_caught(self):
        extra = dict(REPORT, colour="red")
        missing = {k: v for k, v in REPORT.items() if k != "warnings"}
        cases = {
            "an undocumented key": ("GET", "/v1/meshes/tet", 200, JSON, body(extra)),
            "a missing key": ("GET", "/v1/meshes/tet", 200, JSON, body(missing)),
            "a wrong type": ("GET", "/v1/meshes/tet", 200, JSON,
                             body(dict(REPORT, closed="yes"))),
            "a value outside the enum": ("GET", "/v1/meshes/tet", 200, JSON,
                                         body(dict(REPORT, sign="auto"))),
            "an undocumented status": ("GET", "/v1/meshes/tet", 418, JSON, body({})),
            "an undocumented Content-Type": ("GET", "/v1/meshes/tet", 200,
                                             headers(Content_Type="text/plain"), None),
            "a missing header": ("POST", "/v1/meshes/tet/query", 200, JSON,
                                 body({"distance": [1.0]})),
            "a header's bad value": ("POST", "/v1/meshes/tet/query", 200,
                                     headers(Content_Type="application/json", X_SDF_Count="x"),
                                     body({"distance": [1.0]})),
            "a result of no mode": ("POST", "/v1/meshes/tet/query", 200,
                                    headers(Content_Type="application/json", X_SDF_Count="1"),
                                    body({"distance": [1.0], "triangle": [0]})),
            "an error of another status's code": (
                "GET", "/v1/meshes/tet", 404, JSON,
                body({"error": {"code": "EINVAL", "message": "x"}})),
            "an error body with more": (
                "GET", "/v1/meshes/tet", 404, JSON,
                body({"error": {"code": "ENOTFOUND", "message": "x", "hint": "y"}})),
            "a 405 whose Allow differs": (
                "PATCH", "/v1/meshes/tet", 405,
                headers(Content_Type="application/json", Allow="GET, HEAD"),
                body({"error": {"code": "EMETHOD", "message": "no"}})),
            "an undocumented method answered": ("PATCH", "/v1/meshes/tet", 200, JSON, body({})),
            "an unknown path answered": ("GET", "/v1/nothing", 200, JSON, body({})),
            "a body on a 204": ("DELETE", "/v1/meshes/tet", 204, JSON, b"{}"),
            "JSON that is not UTF-8": ("GET", "/v1/meshes/tet", 404, JSON,
                                       b'{"error": {"code": "ENOTFOUND", "message": "\xff"}}'),
            "not JSON": ("GET", "/v1/meshes/tet", 200, JSON, b"{"),
        }
        for what, args in cases.items():
            with self.subTest(what):
                self.assertNotEqual(self.check(*args), [], what)


class RealAnswers(unittest.TestCase):
    def test_a_real_answer_outside_the_document_fails_the_request(self):
        drifted = copy.deepcopy(apicheck.load())
        report = drifted["components"]["schemas"]["MeshReport"]
        del report["properties"]["warnings"]  # as if sdfd had added the key since
        report["required"].remove("warnings")
        with Server() as server:
            client = sdfclient.Client(server.url)
            self.assertEqual(client.mesh("demo")["name"], "demo")  # the real document
            old = apicheck.use(apicheck.Document(drifted))
            other = sdfclient.Client(server.url)
            try:
                with self.assertRaises(apicheck.ApiViolation) as raised:
                    other.mesh("demo")
            finally:
                apicheck.use(old)
                other.close()
            self.assertIn("warnings", str(raised.exception))
            self.assertEqual(len(apicheck.take_violations()), 1)  # seen, and taken here
            self.assertEqual(client.mesh("demo")["name"], "demo")
            client.close()


if __name__ == "__main__":
    unittest.main(verbosity=2)
