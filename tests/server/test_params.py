"""Every HTTP route takes only the URL arguments docs/api.md lists for it (server/ops/urlargs.c).

For each route and method: every argument it takes is accepted with a good value; an unknown
one, one given twice and a misspelt one (answered with the nearest name it takes) are 422
EINVAL naming the argument in "argument", and the refusal comes before the route acts (a
refused PUT stores nothing, a refused DELETE deletes nothing). Queries are checked in both
body forms: with octet-stream and npy bodies the filter's arguments give the same bits as the
same values in a JSON body's "filter"; a JSON body takes URL arguments for what it leaves out,
refuses one given in both, and either form refuses the filter's parameters without a
filtered mode and the keys of the other query route."""
import http.client
import io
import json
import os
import sys
import unittest
import urllib.parse

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "clients", "python"))
import sdfclient  # noqa: E402
from harness import Server  # noqa: E402

OCTET = {"Content-Type": "application/octet-stream"}
NPY = {"Content-Type": "application/x-npy"}
JSON = {"Content-Type": "application/json"}
POINTS = np.array([[0.3, -0.2, 0.1], [2.0, 1.0, -1.5], [3.35, 0, 0]], np.float32)
TRIANGLE_OFF = b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"

# The filter's URL arguments, each with a good value and the same in a JSON "filter" object
# (numbers stay numbers, booleans true/false, smooth_* nest in "smooth").
FILTER_ARGS = [
    ("kernel", "gaussian", {"kernel": "gaussian"}),
    ("cap", "0.5", {"cap": 0.5}),
    ("a", "0.2", {"a": 0.2}),
    ("b", "0.1", {"kernel": "bump", "b": 0.1}),
    ("samples", "8", {"samples": 8}),
    ("min_samples", "4", {"min_samples": 4}),
    ("medial", "0.05", {"medial": 0.05}),
    ("grid", "1", {"grid": True}),
    ("unsigned", "1", {"unsigned": True}),
    ("allow_wide_bump", "1", {"kernel": "bump", "allow_wide_bump": True}),
    ("sample_gradient", "1", {"sample_gradient": True}),
    ("seed", "7", {"seed": 7}),
    ("smooth_sphere", "0,0,0,1", {"smooth": {"sphere": [0, 0, 0, 1]}}),
    ("smooth_box", "-1,-1,-1,1,1,1", {"smooth": {"box": [-1, -1, -1, 1, 1, 1]}}),
    ("smooth_mesh", "demo", {"smooth": {"mesh": "demo"}}),
    ("smooth_depth", "0.2", {"smooth": {"sphere": [0, 0, 0, 1], "depth": 0.2}}),
    ("smooth_scale", "0.5", {"smooth": {"sphere": [0, 0, 0, 1], "scale": 0.5}}),
]


def url_of(filter_json):
    """A JSON filter object as URL arguments (as the clients write them)."""
    args = {}
    for k, v in filter_json.items():
        if k == "smooth":
            for sk, sv in v.items():
                args["smooth_" + sk] = ",".join(map(str, sv)) if isinstance(sv, list) else str(sv)
        else:
            args[k] = ("1" if v else "0") if isinstance(v, bool) else str(v)
    return args


def npy_bytes(points):
    buf = io.BytesIO()
    np.save(buf, points)
    return buf.getvalue()


class Params(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server()
        cls.port = int(cls.server.url.rsplit(":", 1)[1])
        c = sdfclient.Client(cls.server.url)
        cls.job = c.wait(c.bake("demo", volume="vol", resolution=6, margin=0.5), timeout=120)
        c.close()
        if cls.job["state"] != "done":
            raise RuntimeError(f"the test volume's bake ended {cls.job}")

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    def request(self, method, path, body=b"", headers=None):
        c = http.client.HTTPConnection("127.0.0.1", self.port, timeout=60)
        try:
            c.request(method, path, body=body, headers=headers or {})
            r = c.getresponse()
            data = r.read()
            is_json = r.getheader("Content-Type", "").startswith("application/json")
            return r.status, (json.loads(data) if data and is_json else data)
        finally:
            c.close()

    def ok(self, method, path, body=b"", headers=None, status=200):
        got, data = self.request(method, path, body, headers)
        self.assertEqual(got, status, f"{method} {path}: {data}")
        return data

    def refused(self, method, path, argument, words=(), body=b"", headers=None):
        """422 EINVAL naming `argument`, with every one of `words` in its message."""
        got, data = self.request(method, path, body, headers)
        self.assertEqual(got, 422, f"{method} {path}: {data}")
        err = data["error"]
        self.assertEqual(err["code"], "EINVAL", err)
        self.assertEqual(err.get("argument"), argument, err)
        for w in (f"'{argument}'",) + tuple(words):
            self.assertIn(w, err["message"])
        return err["message"]

    def strict(self, method, path, misspelt=None, repeated=None, body=b"", headers=None):
        """The three refusals of a route: an unknown argument, a known one twice (`repeated`:
        "name=value"), a misspelling (`misspelt`: (given, meant))."""
        sep = "&" if "?" in path else "?"
        msg = self.refused(method, f"{path}{sep}colour=red", "colour", ("unknown",), body,
                           headers)
        self.assertNotIn("did you mean", msg)
        if repeated:
            name = repeated.split("=")[0]
            self.refused(method, f"{path}{sep}{repeated}&{repeated}", name, ("twice",), body,
                         headers)
        else:  # a route without arguments: a repeated unknown one is refused as unknown
            self.refused(method, f"{path}{sep}x=1&x=2", "x", ("no URL arguments",), body,
                         headers)
            # and an argument of other routes is not this one's
            self.refused(method, f"{path}{sep}format=npy", "format", ("not this route's",),
                         body, headers)
        if misspelt:
            given, meant = misspelt
            self.refused(method, f"{path}{sep}{given}=1", given, (f"did you mean '{meant}'?",),
                         body, headers)

    # ---- routes without arguments ----

    def test_simple_routes(self):
        for path in ("/healthz", "/readyz", "/metrics", "/v1/meshes", "/v1/meshes/demo",
                     "/v1/jobs", f"/v1/jobs/{self.job['id']}", "/v1/volumes", "/v1/volumes/vol",
                     "/", "/static/page.js"):
            for method in ("GET", "HEAD"):
                with self.subTest(method=method, path=path):
                    self.ok(method, path)
                    if method == "GET":
                        self.strict(method, path)
                    else:  # HEAD: the same status, no body
                        got, _ = self.request(method, path + "?colour=red")
                        self.assertEqual(got, 422)
        self.ok("GET", "/healthz?")  # an empty query string holds no argument

    def test_refusal_comes_before_the_route_acts(self):
        self.ok("PUT", "/v1/meshes/kept?format=off", TRIANGLE_OFF, status=201)
        self.strict("DELETE", "/v1/meshes/kept")
        self.ok("GET", "/v1/meshes/kept")
        self.ok("DELETE", "/v1/meshes/kept", status=204)
        self.strict("PUT", "/v1/meshes/never", misspelt=("fromat", "format"),
                    repeated="format=off", body=TRIANGLE_OFF)
        self.assertEqual(self.request("GET", "/v1/meshes/never")[0], 404)

    def test_mesh_upload_format(self):
        for fmt in ("off", "obj"):
            body = TRIANGLE_OFF if fmt == "off" else b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
            with self.subTest(format=fmt):
                self.ok("PUT", f"/v1/meshes/up_{fmt}?format={fmt}", body, status=201)
                self.ok("DELETE", f"/v1/meshes/up_{fmt}", status=204)
        self.ok("PUT", "/v1/meshes/sniffed", TRIANGLE_OFF, status=201)  # no argument: sniffed
        self.refused("PUT", "/v1/meshes/x?format", "format", ("needs a value",), TRIANGLE_OFF)

    def test_bake_and_jobs(self):
        path = "/v1/meshes/demo/bake"
        body = json.dumps({"volume": "baked", "resolution": 4}).encode()
        self.strict("POST", path, body=body, headers=JSON)
        self.refused("POST", path + "?volume=x", "volume", ("no URL arguments",), body, JSON)
        job = self.ok("POST", path, body, JSON, status=202)
        self.strict("DELETE", f"/v1/jobs/{job['id']}")
        c = sdfclient.Client(self.server.url)
        self.assertEqual(c.wait(job, timeout=120)["state"], "done")
        c.close()
        self.ok("DELETE", f"/v1/jobs/{job['id']}")

    def test_field_ops(self):
        path = "/v1/volumes/vol/ops"
        body = json.dumps({"ops": [{"offset": 0.01}], "volume": "grown"}).encode()
        self.strict("POST", path, body=body, headers=JSON)
        self.refused("POST", path + "?solver=sweep", "solver", ("no URL arguments",), body, JSON)
        job = self.ok("POST", path, body, JSON, status=202)
        c = sdfclient.Client(self.server.url)
        self.assertEqual(c.wait(job, timeout=120)["state"], "done")
        c.close()

    # ---- volumes ----

    def test_volume_upload_and_delete(self):
        exr = self.ok("GET", "/v1/volumes/vol/data?format=exr")
        self.strict("PUT", "/v1/volumes/copy", body=exr)
        self.assertEqual(self.request("GET", "/v1/volumes/copy")[0], 404)
        self.ok("PUT", "/v1/volumes/copy", exr, status=201)
        self.strict("DELETE", "/v1/volumes/copy")
        self.ok("GET", "/v1/volumes/copy")
        self.ok("DELETE", "/v1/volumes/copy", status=204)

    def test_volume_data_format(self):
        raw = self.ok("GET", "/v1/volumes/vol/data?format=raw")
        npy = self.ok("GET", "/v1/volumes/vol/data?format=npy")
        self.assertTrue(npy.startswith(b"\x93NUMPY") and npy.endswith(raw))
        self.assertEqual(self.ok("GET", "/v1/volumes/vol/data"),
                         self.ok("GET", "/v1/volumes/vol/data?format=exr"))
        self.ok("HEAD", "/v1/volumes/vol/data?format=npy")
        self.strict("GET", "/v1/volumes/vol/data", misspelt=("fromat", "format"),
                    repeated="format=npy")

    def post_points(self, route, args, form, body_keys=None):
        """POINTS to a query route in one body form, with URL arguments and JSON keys."""
        path = route + ("?" + urllib.parse.urlencode(args) if args else "")
        if form == "json":
            body = json.dumps({"points": POINTS.tolist(), **(body_keys or {})}).encode()
            return self.request("POST", path, body, {**JSON, "Accept": "application/x-npy"})
        if form == "npy":
            return self.request("POST", path, npy_bytes(POINTS), NPY)
        return self.request("POST", path, POINTS.tobytes(),
                            {**OCTET, "Accept": "application/x-npy"})

    def volume_query(self, args, form, body_keys=None):
        return self.post_points("/v1/volumes/vol/query", args, form, body_keys)

    def test_volume_query(self):
        for args in ({"mode": "gradient"}, {"interpolation": "nearest"},
                     {"mode": "value", "interpolation": "trilinear"}):
            answers = []
            for form in ("octet", "npy", "json"):
                with self.subTest(args=args, form=form):
                    status, data = self.volume_query(args, form)
                    self.assertEqual(status, 200, data)
                    answers.append(data)
            # the JSON body's keys give the same answer as the URL's
            status, data = self.volume_query({}, "json", args)
            self.assertEqual(status, 200, data)
            self.assertTrue(all(a == data for a in answers), args)
        path = "/v1/volumes/vol/query"
        for body, headers in ((POINTS.tobytes(), OCTET), (npy_bytes(POINTS), NPY),
                              (json.dumps({"points": POINTS.tolist()}).encode(), JSON)):
            with self.subTest(type=headers["Content-Type"]):
                self.strict("POST", path, misspelt=("interpolaton", "interpolation"),
                            repeated="mode=value", body=body, headers=headers)
                self.refused("POST", path + "?sign=auto", "sign", ("not this route's",), body,
                             headers)
                self.refused("POST", path + "?mode=filtered&samples=4", "samples",
                             ("not this route's",), body, headers)
        for key, value in (("sign", "auto"), ("filter", {"samples": 4})):
            status, data = self.volume_query({}, "json", {key: value})
            self.assertEqual((status, data["error"]["code"]), (422, "EINVAL"), data)
            self.assertIn(f'"{key}"', data["error"]["message"])
        status, data = self.volume_query({"mode": "value"}, "json", {"mode": "value"})
        self.assertEqual((status, data["error"].get("argument")), (422, "mode"), data)

    # ---- mesh queries ----

    def query(self, args, form, body_keys=None):
        return self.post_points("/v1/meshes/demo/query", args, form, body_keys)

    def test_query_mode_and_sign(self):
        for args in ({"mode": "closest"}, {"sign": "winding"},
                     {"mode": "gradient", "sign": "raycast"}):
            answers = []
            for form in ("octet", "npy", "json"):
                with self.subTest(args=args, form=form):
                    status, data = self.query(args, form)
                    self.assertEqual(status, 200, data)
                    answers.append(data)
            status, data = self.query({}, "json", args)
            self.assertEqual(status, 200, data)
            self.assertTrue(all(a == data for a in answers), args)
        # a JSON body takes the URL's arguments for what it leaves out
        self.assertEqual(self.query({"sign": "winding"}, "json", {"mode": "gradient"}),
                         self.query({}, "json", {"mode": "gradient", "sign": "winding"}))

    def test_query_filter_arguments(self):
        """Each of the filter's URL arguments is taken, and means what its JSON key does."""
        for name, value, filter_json in FILTER_ARGS:
            with self.subTest(argument=name):
                self.assertIn(name, url_of(filter_json))
                self.assertEqual(url_of(filter_json)[name], value)
                mode = "filtered-gradient" if name == "sample_gradient" else "filtered"
                base = {"samples": 4, "seed": 3, **filter_json}
                args = {"mode": mode, **url_of(base)}
                status, octet = self.query(args, "octet")
                self.assertEqual(status, 200, octet)
                status, npy = self.query(args, "npy")
                self.assertEqual(status, 200, npy)
                status, body = self.query({}, "json", {"mode": mode, "filter": base})
                self.assertEqual(status, 200, body)
                self.assertEqual(octet, body)
                self.assertEqual(npy, body)
                # the URL's filter with a JSON body that has none
                self.assertEqual(self.query(args, "json"), (200, body))
        # booleans as true/false too
        args = {"mode": "filtered", "samples": 4, "grid": "1", "unsigned": "0"}
        words = {**args, "grid": "true", "unsigned": "false"}
        self.assertEqual(self.query(words, "octet"), self.query(args, "octet"))
        self.assertEqual(self.query(words, "octet")[0], 200)

    def test_query_refusals(self):
        path = "/v1/meshes/demo/query"
        for body, headers in ((POINTS.tobytes(), OCTET), (npy_bytes(POINTS), NPY),
                              (json.dumps({"points": POINTS.tolist()}).encode(), JSON)):
            with self.subTest(type=headers["Content-Type"]):
                self.strict("POST", path + "?mode=filtered", misspelt=("sample", "samples"),
                            repeated="samples=8", body=body, headers=headers)
                self.refused("POST", path + "?mode=filtered&smoothness=3", "smoothness",
                             ("unknown",), body, headers)
                self.refused("POST", path + "?mode=filtered&smaples=3", "smaples",
                             ("did you mean 'samples'?",), body, headers)
                self.refused("POST", path + "?interpolation=nearest", "interpolation",
                             ("not this route's",), body, headers)
                self.refused("POST", path + "?mode", "mode", ("needs a value",), body, headers)
                self.refused("POST", path + "?sign=", "sign", ("needs a value",), body, headers)
                # the filter's arguments go with the filtered modes only
                for mode in ("signed", "distance", "gradient", "closest"):
                    self.refused("POST", f"{path}?mode={mode}&samples=8", "samples",
                                 ("filtered",), body, headers)
                self.refused("POST", f"{path}?seed=1", "seed", ("filtered",), body, headers)
                many = "&".join(f"x{i}=1" for i in range(65))
                got, data = self.request("POST", f"{path}?{many}", body, headers)
                self.assertEqual(got, 422)
                self.assertIn("more than 64", data["error"]["message"])

    def test_query_json_with_url_arguments(self):
        # given in the body and in the URL: refused, whichever the values
        for key, value in (("mode", "signed"), ("sign", "auto")):
            status, data = self.query({key: value}, "json", {key: value})
            self.assertEqual((status, data["error"].get("argument")), (422, key), data)
            self.assertIn("twice", data["error"]["message"])
        status, data = self.query({"mode": "filtered", "seed": 1}, "json",
                                  {"filter": {"samples": 4}})
        self.assertEqual((status, data["error"].get("argument")), (422, "seed"), data)
        # a "filter" without a filtered mode, an "interpolation" (a volume query's)
        for keys in ({"filter": {"samples": 4}}, {"mode": "closest", "filter": {}},
                     {"interpolation": "nearest"}):
            status, data = self.query({}, "json", keys)
            self.assertEqual((status, data["error"]["code"]), (422, "EINVAL"), (keys, data))
            self.assertNotIn("argument", data["error"])

    # ---- slices ----

    def test_mesh_slice(self):
        path = "/v1/meshes/demo/slice.png?size=16"
        taken = {"axis": "x", "at": "0.1", "bounds": "-2,-2,-2,2,2,2", "mode": "distance",
                 "sign": "winding", "step": "0.5", "format": "npy"}
        for name, value in taken.items():
            with self.subTest(argument=name):
                self.ok("GET", f"{path}&{name}={value}")
        self.ok("GET", f"{path}&normal=1,1,0&origin=0,0,0")
        for name, value, filter_json in FILTER_ARGS:
            with self.subTest(argument=name):
                args = url_of({"samples": 4, **filter_json})
                self.ok("GET", f"{path}&mode=filtered&" + urllib.parse.urlencode(args))
        self.strict("GET", path, misspelt=("szie", "size"), repeated="axis=x")
        self.refused("GET", path + "&interpolation=nearest", "interpolation",
                     ("not this route's",))

    def test_volume_slice(self):
        path = "/v1/volumes/vol/slice.png?size=16"
        taken = {"axis": "y", "at": "0.1", "bounds": "-2,-2,-2,2,2,2", "mode": "error",
                 "interpolation": "nearest", "step": "0.5", "format": "npy"}
        for name, value in taken.items():
            with self.subTest(argument=name):
                self.ok("GET", f"{path}&{name}={value}")
        self.ok("GET", f"{path}&normal=0,1,1&origin=0,0,0")
        self.strict("GET", path, misspelt=("interpolatoin", "interpolation"),
                    repeated="step=1")
        for name in ("sign", "samples"):
            self.refused("GET", f"{path}&{name}=1", name, ("not this route's",))


if __name__ == "__main__":
    unittest.main()
