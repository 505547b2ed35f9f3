#!/usr/bin/env python3
"""Writes the generated seed inputs of tests/fuzz/corpus/ (standard library only).

    python3 tests/fuzz/make_seeds.py

The seeds are small valid (and a few nearly valid) inputs of every surface, written from the
formats' descriptions (proto/PROTOCOL.md, docs/api.md, the NumPy .npy format), so the fuzzer
starts from inputs that reach deep into each parser. The corpus also holds copies of the
small meshes of tests/data and EXR volumes written by sdf-volume (docs/robustness.md says
how); this script only writes its own files (gen-*), and rewrites them identically.
"""
import json
import os
import struct

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")

TETRA_V = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)]
TETRA_F = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]


def put(harness, name, data):
    os.makedirs(os.path.join(ROOT, harness), exist_ok=True)
    if isinstance(data, str):
        data = data.encode()
    with open(os.path.join(ROOT, harness, "gen-" + name), "wb") as f:
        f.write(data)


def meshes():
    obj = "".join("v %g %g %g\n" % v for v in TETRA_V)
    obj += "".join("f %d %d %d\n" % tuple(i + 1 for i in f) for f in TETRA_F)
    put("mesh_obj", "tetra.obj", "# tetrahedron\no t\n" + obj)
    put("mesh_obj", "refs.obj",
        "mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1 1.0\nvt 0 0\nvn 0 0 1\n"
        "g side\nusemtl m\ns 1\nf 1/1/1 2/1/1 3/1/1 4/1/1\nf -5//-1 -4//-1 -1//-1\n"
        "f 2 3 5\nf 3 4 5\nf 4 1 5\nl 1 2\n")
    off = "OFF\n4 4 6\n" + "".join("%g %g %g\n" % v for v in TETRA_V)
    off += "".join("3 %d %d %d\n" % f for f in TETRA_F)
    put("mesh_off", "tetra.off", off)
    put("mesh_off", "quads.off",
        "OFF\n# a cube, comments and colours\n8 6 0\n0 0 0\n0 0 1\n0 1 1\n0 1 0\n1 0 0\n1 0 1\n"
        "1 1 1\n1 1 0\n4 0 1 2 3 255 0 0\n4 7 6 5 4\n4 0 4 5 1\n4 1 5 6 2\n4 2 6 7 3\n"
        "4 3 7 4 0\n")
    put("mesh_off", "coff.off", "COFF\n3 1 0\n0 0 0 1 1 1 1\n1 0 0 1 1 1 1\n0 1 0 1 1 1 1\n"
        "3 0 1 2\n")
    stl = "solid t\n"
    for f in TETRA_F:
        stl += " facet normal 0 0 0\n  outer loop\n"
        stl += "".join("   vertex %g %g %g\n" % TETRA_V[i] for i in f)
        stl += "  endloop\n endfacet\n"
    put("mesh_stl", "tetra_ascii.stl", stl + "endsolid t\n")
    binary = struct.pack("<80sI", b"binary tetra", len(TETRA_F))
    for f in TETRA_F:
        binary += struct.pack("<3f", 0, 0, 0)
        for i in f:
            binary += struct.pack("<3f", *TETRA_V[i])
        binary += struct.pack("<H", 0)
    put("mesh_stl", "tetra_binary.stl", binary)
    put("mesh_stl", "solid_binary.stl", b"solid but binary" + binary[16:])
    head = ("ply\nformat %s 1.0\ncomment tetra\nelement vertex 4\nproperty float x\n"
            "property float y\nproperty float z\nproperty uchar red\nelement face 4\n"
            "property list uchar int vertex_indices\nend_header\n")
    ascii_body = "".join("%g %g %g 7\n" % v for v in TETRA_V)
    ascii_body += "".join("3 %d %d %d\n" % f for f in TETRA_F)
    put("mesh_ply", "tetra_ascii.ply", head % "ascii" + ascii_body)
    for name, order in (("little", "<"), ("big", ">")):
        body = b"".join(struct.pack(order + "3fB", *v, 7) for v in TETRA_V)
        body += b"".join(struct.pack(order + "B3i", 3, *f) for f in TETRA_F)
        put("mesh_ply", "tetra_%s.ply" % name,
            (head % ("binary_%s_endian" % name)).encode() + body)
    double = ("ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty double x\n"
              "property double y\nproperty double z\nelement face 4\n"
              "property list uint8 uint32 vertex_index\nend_header\n").encode()
    double += b"".join(struct.pack("<3d", *v) for v in TETRA_V)
    double += b"".join(struct.pack("<B3I", 3, *f) for f in TETRA_F)
    put("mesh_ply", "tetra_double.ply", double)
    for name in ("tetra.obj", "tetra.off", "tetra_ascii.stl", "tetra_binary.stl"):
        src = os.path.join(ROOT, "mesh_" + name.split(".")[1], "gen-" + name)
        with open(src, "rb") as f:
            put("mesh_auto", name, f.read())
    with open(os.path.join(ROOT, "mesh_ply", "gen-tetra_little.ply"), "rb") as f:
        put("mesh_auto", "tetra_little.ply", f.read())


def npy(descr, shape, values, version=1, fortran=False, pad_to=64):
    header = "{'descr': '%s', 'fortran_order': %s, 'shape': %s, }" % (
        descr, "True" if fortran else "False", repr(tuple(shape)))
    prefix = 10 if version == 1 else 12
    header += " " * ((-(prefix + len(header) + 1)) % pad_to) + "\n"
    length = struct.pack("<H", len(header)) if version == 1 else struct.pack("<I", len(header))
    code = "<" + ("f" if descr[-1] == "4" else "d") * len(values)
    return b"\x93NUMPY" + bytes([version, 0]) + length + header.encode() + struct.pack(
        code, *values)


def arrays():
    pts = [0.1, 0.2, 0.3, 1, 2, 3, -1, -2, -3, 4, 5, 6]
    put("npy", "f4_4x3_npy", npy("<f4", (4, 3), pts))
    put("npy", "f8_2x3_npy", npy("<f8", (2, 3), pts[:6]))
    put("npy", "v2_f4_12_npy", npy("<f4", (12,), pts, version=2))
    put("npy", "f4_4d_npy", npy("<f4", (1, 2, 2, 3), pts))
    put("npy", "empty_npy", npy("<f4", (0, 3), []))
    put("npy", "fortran_npy", npy("<f4", (4, 3), pts, fortran=True))
    put("body_npy", "f4_4x3_npy", npy("<f4", (4, 3), pts))
    put("body_npy", "f8_2x3_npy", npy("<f8", (2, 3), pts[:6]))
    put("body_npy", "f4_pad16_npy", npy("<f4", (4, 3), pts, pad_to=16))
    put("body_npy", "octet_3.bin", struct.pack("<9f", *pts[:9]))


def frame(kind, payload, request_id=7):
    return b"SDFP" + struct.pack("<BBHII", 1, kind, 0, request_id, len(payload)) + payload


def name4(name):
    name = name.encode()
    return name + b"\0" * (-len(name) % 4)


def filter_block(volume=0, numbers=(0,) * 6, volume_name=b""):
    block = struct.pack("<BBBBI", 0, 1, volume, len(volume_name), 64)
    block += struct.pack("<3dQ2d", 0.05, 0, 0, 42, 0.1, 0.2)
    block += struct.pack("<6d", *numbers)
    block += struct.pack("<IId", 8, 0, 0)
    return block + volume_name + b"\0" * (-len(volume_name) % 4)


def frames():
    pts = struct.pack("<6f", 0, 0, 0, 1, 2, 3)
    query = lambda mode, sign, extra=b"": frame(
        3, struct.pack("<BBHI", mode, sign, 4, 2) + name4("demo") + extra + pts)
    put("proto", "query_signed", query(0, 0))
    put("proto", "query_closest_winding", query(3, 2))
    put("proto", "query_filtered_sphere", query(4, 0, filter_block(1, (0, 0, 0, 1, 0, 0))))
    put("proto", "query_filtered_mesh", query(5, 0, filter_block(3, volume_name=b"knot")))
    put("proto", "volume_query", frame(4, struct.pack("<BBHI", 1, 0, 3, 2) + name4("vol") + pts))
    put("proto", "volume_query_hermite",
        frame(4, struct.pack("<BBHI", 0, 2, 3, 2) + name4("vol") + pts))
    put("proto", "result_closest",
        frame(0x83, struct.pack("<BBHI", 3, 5, 0, 1) + struct.pack("<4fI", 1, 0, 0, 0, 9)))
    put("proto", "error", frame(0x7F, struct.pack("<HH", 404, 9) + b"ENOTFOUND" +
                                struct.pack("<H", 12) + b"no mesh demo"))
    put("proto", "hello_ok", frame(0x81, struct.pack("<HHIIH", 1, 0, 1 << 20, 4096, 5) + b"0.1.0"))
    meshes = struct.pack("<I", 2)
    for name, tris in ((b"demo", 12288), (b"fandisk", 12946)):
        meshes += struct.pack("<H", len(name)) + name + struct.pack("<QBB", tris, 1, 1)
    put("proto", "meshes", frame(0x82, meshes))
    put("proto", "hello", frame(1, b"fuzz client"))
    put("proto", "auth", frame(5, b"secret"))


def texts():
    queries = [
        {"points": [[0, 0, 0], [1, 2, 3]], "mode": "signed", "sign": "winding"},
        {"points": [0.5, -1e-3, 2e10, 1, 2, 3], "mode": "closest", "ignored": {"a": [1, None]}},
        {"points": [[0, 0, 0]], "mode": "filtered",
         "filter": {"kernel": "bump", "cap": 0.1, "samples": 16,
                    "smooth": {"sphere": [0, 0, 0, 1]}}},
        {"mode": "value", "interpolation": "nearest", "points": [[1.5, 2.5, -3.5]]},
    ]
    for i, q in enumerate(queries):
        put("json_query", "query%d.json" % i, json.dumps(q))
    put("json_query", "escapes.json",
        '{"mo\\u0064e": "gradient", "x": "\\"\\\\\\/\\b\\f\\n\\r\\t",'
        ' "points": [ [ 1E2 , -0.0, 3e-2 ] ]}')
    filters = [
        {"kernel": "gaussian", "cap": 0.05, "a": 0.5, "samples": 64, "min_samples": 8, "seed": 7},
        {"kernel": "bump", "cap": 0.2, "b": 0.1, "allow_wide_bump": True, "grid": True,
         "unsigned": False, "medial": 0.01},
        {"cap": 0.1, "smooth": {"box": [0, 0, 0, 1, 1, 1], "depth": 0.1, "scale": 0.2}},
        {"cap": 0.1, "smooth": {"mesh": "knot", "depth": 0.3}},
    ]
    for i, f in enumerate(filters):
        put("json_filter", "filter%d.json" % i, json.dumps(f))
    bakes = [
        {"volume": "v", "resolution": 16, "order": 0},
        {"bounds": {"min": [-1, -1, -1], "max": [1, 1, 1]}, "resolution": [8, 9, 10],
         "order": 1, "H": 2, "delta": 0.5, "normalize": "gradient", "encoding": "packed32"},
        {"margin": 0, "field": "filtered", "filter": filters[2], "sign": "winding"},
        {"margin": 0.1, "field": "raw", "encoding": "float32", "normalize": "plane"},
    ]
    for i, b in enumerate(bakes):
        put("json_bake", "bake%d.json" % i, json.dumps(b))
    urls = [
        "mode=filtered&kernel=gaussian&cap=0.05&samples=64&seed=7",
        "mode=filtered-gradient&kernel=bump&cap=0.2&b=0.1&allow_wide_bump=1&grid=true",
        "cap=0.1&smooth_sphere=0,0,0,1&smooth_depth=0.1&smooth_scale=0.2",
        "cap=0.1&smooth_box=0,0,0,1,1,1&unsigned=false&min_samples=8&medial=0.01",
        "cap=0.1&smooth_mesh=kn%6Ft+x&sign=winding&interpolation=nearest&format=npy",
        "axis=x&at=0.1&size=64&bounds=-1,-1,-1,1,1,1&mode=filtered&samples=4&step=0.1&format=npy",
        "normal=1,1,0&origin=0,0,0&mode=error&interpolation=nearest&size=32",
        "sample=8&samples=8&samples=9&mode&fromat=npy&=x",
    ]
    for i, u in enumerate(urls):
        put("url", "args%d" % i, u)


if __name__ == "__main__":
    meshes()
    arrays()
    frames()
    texts()
