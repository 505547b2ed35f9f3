"""Slice images through sdfd (GET /v1/meshes/{name}/slice.png, /v1/volumes/{name}/slice.png).

A sphere of radius R (an icosphere made here, PUT as OFF) is sliced and its picture checked
pixel by pixel: the PNG is decoded with zlib (the standard library's), its zero line must lie
within one pixel of the circle of radius R, the inside blue and the outside red, and the
iso-distance lines (the pixels that differ from the same slice drawn with one far-apart
step) within a pixel of the circles R + k * step. The values (?format=npy) are checked
against the sphere's distance, the plane against the X-SDF-Slice-* headers, a filtered slice
against the raw one (the same zero line, different away from it), a volume's slices
against the mesh's, and every bad argument gets 422 naming it."""
import json
import math
import os
import struct
import sys
import time
import unittest
import urllib.error
import urllib.request
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
from harness import Server  # noqa: E402

R = 1.0
BOX = "-1.5,-1.5,-1.5,1.5,1.5,1.5"


def icosphere(levels, radius):
    """Vertices (N, 3) and triangles (M, 3) of a subdivided icosahedron, outward facing."""
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
         (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
         (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8),
         (3, 8, 9), (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(levels):
        mid, faces = {}, []

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                m = verts[a] + verts[b]
                verts.append(m / np.linalg.norm(m))
                mid[key] = len(verts) - 1
            return mid[key]
        for a, b, c in f:
            ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
            faces += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = faces
    return np.array(verts) * radius, np.array(f)


def off_text(verts, faces):
    lines = ["OFF", f"{len(verts)} {len(faces)} 0"]
    lines += ["%.9f %.9f %.9f" % tuple(p) for p in verts]
    lines += ["3 %d %d %d" % tuple(t) for t in faces]
    return "\n".join(lines) + "\n"


def decode_png(data):
    """(H, W, 3) uint8 of an 8-bit RGB, non-interlaced PNG: chunks, zlib, the five filters."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "not a PNG"
    pos, idat, header = 8, b"", None
    while pos < len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        assert zlib.crc32(kind + body) == struct.unpack(">I", data[pos + 8 + n:pos + 12 + n])[0]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    w, h, depth, colour, _, _, interlace = header
    assert (depth, colour, interlace) == (8, 2, 0), header
    raw, stride = zlib.decompress(idat), 3 * w
    out = np.zeros((h, stride), np.int32)
    for y in range(h):
        kind, line = raw[y * (stride + 1)], np.frombuffer(raw, np.uint8, stride,
                                                          y * (stride + 1) + 1).astype(np.int32)
        up = out[y - 1] if y else np.zeros(stride, np.int32)
        if kind == 0:
            out[y] = line
        elif kind == 2:
            out[y] = (line + up) & 255
        else:  # 1 sub, 3 average, 4 Paeth: each byte depends on the one 3 to its left
            row = out[y]
            for x in range(stride):
                left = row[x - 3] if x >= 3 else 0
                ul = up[x - 3] if x >= 3 else 0
                if kind == 1:
                    pred = left
                elif kind == 3:
                    pred = (left + up[x]) // 2
                else:
                    p = left + up[x] - ul
                    pa, pb, pc = abs(p - left), abs(p - up[x]), abs(p - ul)
                    pred = left if pa <= pb and pa <= pc else up[x] if pb <= pc else ul
                row[x] = (line[x] + pred) & 255
    return out.reshape(h, w, 3).astype(np.uint8)


def vec(text):
    return np.array([float(x) for x in text.split(",")])


class Slice:
    """One slice answer: its body, headers and the world position of every pixel centre."""

    def __init__(self, body, headers):
        self.body, self.headers = body, headers
        self.width, self.height = (int(x) for x in headers["X-SDF-Slice-Size"].split(","))
        first, right, down = (vec(headers["X-SDF-Slice-" + k]) for k in ("First", "Right", "Down"))
        j, i = np.mgrid[0:self.height, 0:self.width]
        self.world = first + i[..., None] * right + j[..., None] * down
        self.pixel = float(np.linalg.norm(right))
        self.radius = np.linalg.norm(self.world, axis=2)

    def image(self):
        """The slice's pixels (the legend strip below them cut off)."""
        return decode_png(self.body)[:self.height]

    def values(self):
        n = self.width * self.height
        return np.frombuffer(self.body[-4 * n:], "<f4").reshape(self.height, self.width)


class SliceImages(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.server = Server("--max-bake-queries", "50000000")
        verts, faces = icosphere(5, R)
        cls.put("/v1/meshes/ball?format=off", off_text(verts, faces).encode())

    @classmethod
    def tearDownClass(cls):
        cls.server.stop()

    @classmethod
    def put(cls, path, body):
        req = urllib.request.Request(cls.server.url + path, data=body, method="PUT")
        with urllib.request.urlopen(req) as r:
            return r.status

    def get(self, path):
        with urllib.request.urlopen(self.server.url + path) as r:
            return r.read(), r.headers

    def slice(self, path):
        return Slice(*self.get(path))

    def refused(self, path):
        """(status, error object) of a request that must fail."""
        with self.assertRaises(urllib.error.HTTPError) as cm:
            self.get(path)
        with cm.exception as e:
            return e.code, json.load(e)["error"]

    # ---- the picture ----

    def test_zero_line_is_the_sphere(self):
        s = self.slice(f"/v1/meshes/ball/slice.png?axis=z&at=0&size=301&bounds={BOX}")
        self.assertEqual((s.width, s.height), (301, 301))
        img = s.image()
        black = np.all(img == 0, axis=2)
        self.assertGreater(black.sum(), 5 * R / s.pixel)  # an 8-connected circle: 4 sqrt(2) R
        off = np.abs(s.radius[black] - R)
        self.assertLessEqual(off.max(), s.pixel, "a zero-line pixel more than a pixel off")
        for angle in np.linspace(0, 2 * math.pi, 90, endpoint=False):  # no gap anywhere
            p = R * np.array([math.cos(angle), math.sin(angle), 0])
            near = np.linalg.norm(s.world - p, axis=2) <= 1.5 * s.pixel
            self.assertTrue(black[near].any(), f"no zero line near angle {angle:.2f}")

    def test_inside_blue_outside_red(self):
        s = self.slice(f"/v1/meshes/ball/slice.png?size=201&bounds={BOX}&step=100")
        img = s.image().astype(int)
        inside, outside = s.radius < R - 0.15, s.radius > R + 0.15
        blue = img[..., 2] > img[..., 0] + 10
        red = img[..., 0] > img[..., 2] + 10
        self.assertTrue(blue[inside].all(), "a pixel inside the sphere is not blue")
        self.assertTrue(red[outside].all(), "a pixel outside the sphere is not red")
        # and deeper means stronger: the centre is more saturated than near the surface
        centre = img[s.height // 2, s.width // 2]
        ring = img[inside & (s.radius > R - 0.25)].mean(axis=0)
        self.assertGreater(centre[2] - centre[0], ring[2] - ring[0])

    def test_iso_lines_where_expected(self):
        step = 0.25
        base = f"/v1/meshes/ball/slice.png?size=301&bounds={BOX}"
        lined = self.slice(base + f"&step={step}")
        self.assertEqual(float(lined.headers["X-SDF-Slice-Step"]), step)
        plain = self.slice(base + "&step=100")
        a, b = lined.image(), plain.image()
        iso = np.any(a != b, axis=2)
        self.assertGreater(iso.sum(), 0)
        d = lined.radius[iso] - R  # the sphere's distance at those pixels
        off = np.abs(d - step * np.round(d / step))
        self.assertLessEqual(off.max(), lined.pixel + 1e-3, "an iso pixel off its level")
        self.assertFalse(np.any(np.abs(d) < step / 2), "the zero level is the zero line's")
        # each level inside the image is drawn: -0.5, -0.25 (inside), 0.25, 0.5 (outside)
        for level in (-0.5, -0.25, 0.25, 0.5):
            on = np.abs(lined.radius - (R + level)) <= lined.pixel
            self.assertGreater(iso[on].mean(), 0.3, f"level {level} is missing")

    def test_legend_is_below_the_slice(self):
        body, headers = self.get(f"/v1/meshes/ball/slice.png?size=200&bounds={BOX}")
        full = decode_png(body)
        self.assertEqual(full.shape[:2], (200 + 18, 200))
        strip = full[200:]
        self.assertTrue(np.all(strip[:, :, 0] >= 0))
        # numbers in black, a colour bar with both hues
        self.assertTrue(np.any(np.all(strip == 0, axis=2)))
        self.assertTrue(np.any(strip[..., 2].astype(int) > strip[..., 0].astype(int) + 60))
        self.assertTrue(np.any(strip[..., 0].astype(int) > strip[..., 2].astype(int) + 60))

    def test_any_plane(self):
        n = np.array([1.0, 1.0, 0.5]) / np.linalg.norm([1.0, 1.0, 0.5])
        s = self.slice("/v1/meshes/ball/slice.png?normal=1,1,0.5&origin=0,0,0&size=241"
                       f"&bounds={BOX}")
        self.assertLess(np.abs(s.world @ n).max(), 1e-5, "a pixel off the plane")
        black = np.all(s.image() == 0, axis=2)
        self.assertLessEqual(np.abs(s.radius[black] - R).max(), s.pixel)
        # a plane at 0.6 from the centre cuts a circle of radius sqrt(R^2 - 0.36)
        s = self.slice("/v1/meshes/ball/slice.png?normal=0,0,2&origin=0,0,0.6&size=241"
                       f"&bounds={BOX}")
        black = np.all(s.image() == 0, axis=2)
        self.assertLessEqual(np.abs(s.radius[black] - R).max(), s.pixel)
        self.assertTrue(np.allclose(s.world[..., 2], 0.6))

    # ---- the values ----

    def test_npy_values(self):
        s = self.slice(f"/v1/meshes/ball/slice.png?format=npy&axis=x&at=0.3&size=128&bounds={BOX}")
        self.assertEqual(s.headers["Content-Type"], "application/x-npy")
        self.assertTrue(s.body.startswith(b"\x93NUMPY"))
        header = s.body[10:10 + struct.unpack("<H", s.body[8:10])[0]].decode()
        self.assertIn("'shape': (128, 128)", header)
        self.assertIn("'<f4'", header)
        v = s.values()
        self.assertTrue(np.allclose(s.world[..., 0], 0.3))
        # the icosphere lies within 0.001 of the sphere
        self.assertLess(np.abs(v - (s.radius - R)).max(), 2e-3)
        lo, hi = vec(s.headers["X-SDF-Slice-Range"])
        self.assertEqual((np.float32(lo), np.float32(hi)), (v.min(), v.max()))

    def test_npy_matches_a_query(self):
        s = self.slice(f"/v1/meshes/ball/slice.png?format=npy&axis=y&at=-0.2&size=40&bounds={BOX}")
        pts = s.world.reshape(-1, 3).astype(np.float32)
        req = urllib.request.Request(self.server.url + "/v1/meshes/ball/query",
                                     data=json.dumps({"points": pts.tolist()}).encode(),
                                     headers={"Content-Type": "application/json"})
        with urllib.request.urlopen(req) as r:
            d = np.array(json.load(r)["distance"], np.float32).reshape(s.height, s.width)
        self.assertLess(np.abs(d - s.values()).max(), 1e-5)

    def test_gradient_and_distance_modes(self):
        g = self.slice(f"/v1/meshes/ball/slice.png?mode=gradient&format=npy&size=64&bounds={BOX}")
        away = g.radius > 0.2
        self.assertLess(np.abs(g.values()[away] - 1).max(), 1e-3)
        d = self.slice(f"/v1/meshes/ball/slice.png?mode=distance&format=npy&size=64&bounds={BOX}")
        self.assertLess(np.abs(d.values() - np.abs(d.radius - R)).max(), 2e-3)
        png = self.slice(f"/v1/meshes/ball/slice.png?mode=distance&size=64&bounds={BOX}")
        self.assertFalse(np.all(png.image() == 0, axis=2).any(), "an unsigned field has no "
                         "zero line")

    def test_filtered_differs_only_away_from_the_zero_line(self):
        base = f"/v1/meshes/ball/slice.png?size=161&bounds={BOX}&step=0.25"
        flt = "&mode=filtered&samples=64&cap=0.5&seed=3"
        raw, filt = self.slice(base), self.slice(base + flt)
        a, b = raw.image().astype(int), filt.image().astype(int)
        zero_a, zero_b = np.all(a == 0, axis=2), np.all(b == 0, axis=2)
        self.assertTrue(np.array_equal(zero_a, zero_b), "the filter moved the zero line")
        differs = np.any(np.abs(a - b) > 2, axis=2)
        dist = np.abs(raw.radius - R)
        self.assertGreater(differs[dist > 0.2].sum(), 100, "the filter changed nothing")
        self.assertFalse(differs[dist < 0.5 * raw.pixel].any())
        rv = self.slice(base + "&format=npy").values()
        fv = self.slice(base + flt + "&format=npy").values()
        self.assertTrue(np.array_equal(rv < 0, fv < 0))

    # ---- volumes ----

    def wait_bake(self, volume, **body):
        req = urllib.request.Request(self.server.url + "/v1/meshes/ball/bake",
                                     data=json.dumps({"volume": volume, **body}).encode(),
                                     method="POST")
        with urllib.request.urlopen(req) as r:
            job = json.load(r)
        deadline = time.time() + 120
        while time.time() < deadline:
            state, _ = self.get(job["href"])
            state = json.loads(state)
            if state["state"] == "done":
                return
            self.assertIn(state["state"], ("queued", "running"))
            time.sleep(0.05)
        self.fail("the bake did not finish")

    def test_volume_slices(self):
        self.wait_bake("vball", resolution=48, order=1,
                       bounds={"min": [-1.5, -1.5, -1.5], "max": [1.5, 1.5, 1.5]})
        s = self.slice("/v1/volumes/vball/slice.png?size=150")
        self.assertEqual((s.width, s.height), (150, 150))
        black = np.all(s.image() == 0, axis=2)
        self.assertGreater(black.sum(), 200)
        self.assertLessEqual(np.abs(s.radius[black] - R).max(), 1.5 * s.pixel)
        v = self.slice("/v1/volumes/vball/slice.png?size=150&format=npy").values()
        self.assertLess(np.abs(v - (s.radius - R)).max(), 0.05)
        e = self.slice("/v1/volumes/vball/slice.png?size=150&format=npy&mode=error").values()
        m = self.slice("/v1/meshes/ball/slice.png?size=150&format=npy&bounds=" + BOX).values()
        self.assertTrue(np.allclose(e, np.abs(v - m), atol=1e-6))
        self.assertGreater(e.max(), 0)
        g = self.slice("/v1/volumes/vball/slice.png?size=150&format=npy&mode=gradient").values()
        near = np.abs(s.radius - R) < 0.2
        self.assertLess(np.abs(g[near] - 1).max(), 0.1)
        png = self.slice("/v1/volumes/vball/slice.png?size=150&mode=error&interpolation=nearest")
        self.assertEqual(png.image().shape, (150, 150, 3))
        # the default reconstruction is a volume query's: hermite on this first-order volume
        h = self.slice("/v1/volumes/vball/slice.png?size=150&format=npy"
                       "&interpolation=hermite").values()
        t = self.slice("/v1/volumes/vball/slice.png?size=150&format=npy"
                       "&interpolation=trilinear").values()
        self.assertEqual(v.tobytes(), h.tobytes())
        self.assertNotEqual(v.tobytes(), t.tobytes())

    def test_error_mode_needs_the_mesh(self):
        verts, faces = icosphere(2, 0.5)
        self.put("/v1/meshes/small?format=off", off_text(verts, faces).encode())
        req = urllib.request.Request(self.server.url + "/v1/meshes/small/bake",
                                     data=b'{"volume": "vsmall", "resolution": 16}', method="POST")
        with urllib.request.urlopen(req) as r:
            href = json.load(r)["href"]
        for _ in range(1000):
            if json.loads(self.get(href)[0])["state"] == "done":
                break
            time.sleep(0.02)
        self.get("/v1/volumes/vsmall/slice.png?mode=error&size=32")
        status, err = self.refused("/v1/volumes/vsmall/slice.png?interpolation=hermite&size=32")
        self.assertEqual((status, err["code"]), (422, "EINVAL"))
        self.assertIn("first-order", err["message"])
        urllib.request.urlopen(urllib.request.Request(self.server.url + "/v1/meshes/small",
                                                      method="DELETE")).close()
        status, err = self.refused("/v1/volumes/vsmall/slice.png?mode=error&size=32")
        self.assertEqual((status, err["code"]), (404, "ENOTFOUND"))
        self.assertIn("small", err["message"])

    # ---- refusals ----

    def test_bad_arguments_are_named(self):
        cases = {
            "size=0": "size", "size=2049": "size", "size=12x": "size", "axis=w": "axis",
            "at=nan": "at", "at=inf": "at", "at=1e400": "at", "axis=x&normal=1,0,0": "normal",
            "normal=0,0,0": "normal", "normal=1,0": "normal", "origin=0,0,0": "origin",
            "normal=0,0,1&at=1": "at", "normal=0,0,1&origin=0,nan,0": "origin",
            "bounds=1,0,0,0,1,1": "bounds", "bounds=0,0,0,1,1": "bounds",
            "mode=smooth": "mode", "mode=error": "mode", "sign=maybe": "sign",
            "interpolation=nearest": "interpolation", "step=0": "step", "step=-1": "step",
            "format=gif": "format", "colour=red": "colour", "size=10&size=20": "size",
            "samples=8": "samples", "mode=filtered&samples=0": "samples",
            "mode=filtered&kernel=box": "kernel", "mode=filtered&smooth_sphere=0,0": "smooth_sphere",
            "axis": "axis", "at=": "at",
        }
        for query, argument in cases.items():
            with self.subTest(query=query):
                status, err = self.refused("/v1/meshes/ball/slice.png?" + query)
                self.assertEqual(status, 422)
                self.assertEqual(err["code"], "EINVAL")
                self.assertEqual(err["argument"], argument, err["message"])
        for query, argument in {"mode=filtered": "mode", "sign=winding": "sign"}.items():
            status, err = self.refused("/v1/volumes/anything/slice.png?" + query)
            self.assertEqual((status, err["argument"]), (422, argument))
        status, err = self.refused("/v1/meshes/nothing/slice.png")
        self.assertEqual((status, err["code"]), (404, "ENOTFOUND"))
        status, err = self.refused("/v1/volumes/nothing/slice.png")
        self.assertEqual((status, err["code"]), (404, "ENOTFOUND"))

    def test_over_max_points(self):
        with Server("--max-points", "1000") as small:
            verts, faces = icosphere(1, 1)
            req = urllib.request.Request(small.url + "/v1/meshes/b?format=off",
                                         data=off_text(verts, faces).encode(), method="PUT")
            urllib.request.urlopen(req).close()
            with urllib.request.urlopen(small.url + "/v1/meshes/b/slice.png?size=31") as r:
                self.assertEqual(r.status, 200)
            with self.assertRaises(urllib.error.HTTPError) as cm:
                urllib.request.urlopen(small.url + "/v1/meshes/b/slice.png?size=32")
            with cm.exception as e:
                self.assertEqual((e.code, json.load(e)["error"]["argument"]), (413, "size"))


if __name__ == "__main__":
    unittest.main(verbosity=2)
