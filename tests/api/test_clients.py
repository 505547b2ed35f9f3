"""The names and codes the clients use, against the sources they mirror: proto/ (proto.h,
proto.c and PROTOCOL.md: message types, modes and their answer widths, signs,
interpolations, kernels, smoothing volumes), the error tables (lib's SDF_ERRNO_MAP,
server/errors.h) and docs/openapi.yaml (which takes its names from lib's name tables, also
checked here). Each client is read as its users get it: the Python package imported, the JS
modules imported by node, the C client's header and name tables parsed. Any difference fails,
naming both sides.

The C client encodes frames with proto/'s own codec (proto.h), so its message types and mode
codes cannot drift; its public enums and name tables can, and are checked.

Standard library, numpy (the Python client), python3-yaml; node for the JS client."""
import json
import os
import re
import subprocess
import sys
import typing
import unittest

import yaml

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "clients", "python"))
import sdfclient  # noqa: E402
from sdfclient import _wire  # noqa: E402

# Error codes no operation of the document answers with: the binary protocol's framing error,
# a canceled job's end (a state, not an answer), and 405, the answer to a method a path lacks
# (outside every operation: info.description says it, apicheck.py checks it).
NOT_IN_OPERATIONS = {"EPROTO", "ECANCELED", "EMETHOD"}


def read(*path):
    with open(os.path.join(ROOT, *path), encoding="utf-8") as f:
        return f.read()


def server_file(name):
    """server/'s file `name`, in whichever of its folders it is."""
    found = [os.path.join(d, name) for d, _, files in os.walk(os.path.join(ROOT, "server"))
             if name in files]
    if len(found) != 1:
        raise AssertionError(f"server/ holds {len(found)} files named {name}")
    with open(found[0], encoding="utf-8") as f:
        return f.read()


def c_block(text, start):
    """The text between `start` and the next '}' (an enum's or an array's body)."""
    at = text.index(start) + len(start)
    return text[at:text.index("}", at)]


def c_block_of(text, member):
    """The body of the braces around the definition `member = ...`."""
    at = re.search(r"\b" + member + r"\s*=", text).start()
    return text[text.rindex("{", 0, at) + 1:text.index("}", at)]


def c_enum(text, start, prefix, block=None):
    """{NAME: value} of an enum's `PREFIXNAME = value` lines; values given or counted. The
    enum is the one after `start`, or the one holding the member `block`."""
    out, value = {}, -1
    body = c_block_of(text, block) if block else c_block(text, start)
    for m in re.finditer(r"\b" + prefix + r"([A-Z0-9_]+)\b(?:\s*=\s*(-?(?:0x[0-9A-Fa-f]+|\d+)))?",
                         body):
        value = int(m.group(2), 0) if m.group(2) else value + 1
        out[m.group(1)] = value
    return out


def c_strings(text, start):
    return re.findall(r'"([^"]*)"', c_block(text, start))


def md_codes(text, field):
    """{name: code} of a PROTOCOL.md table cell "field: 0 name, 1 name (...), ..."."""
    cell = re.search(r"\| " + re.escape(field) + r": ([^|]*)\|", text).group(1)
    return {m.group(2).lower(): int(m.group(1))
            for m in re.finditer(r"(\d+) (?:a loaded )?([A-Za-z-]+)", cell)}


def x_macro(text, name):
    """The X(...) rows of a #define NAME(X) table, as lists of their arguments."""
    body = re.search(r"#define " + name + r"\(X\)(.*?)(?:\n\n|\n#)", text, re.S).group(1)
    return [[a.strip() for a in row.split(",")] for row in re.findall(r"X\(([^)]*)\)", body)]


class Sources:
    """What the clients mirror, read once."""
    proto_h = read("proto", "proto.h")
    proto_c = read("proto", "proto.c")
    protocol = read("proto", "PROTOCOL.md")
    sdf_h = read("lib", "include", "sdf", "sdf.h")
    names_c = read("lib", "core", "names.c")
    errors_h = server_file("errors.h")
    doc = yaml.safe_load(read("docs", "openapi.yaml"))

    frames = c_enum(proto_h, "enum sdf_proto_type {", "SDF_PROTO_")
    md_frames = {m.group(2): int(m.group(1), 16)
                 for m in re.finditer(r"^\| (0x[0-9A-Fa-f]{2}) \| ([A-Z_]+) \|", protocol, re.M)}
    mode_values = c_enum(proto_h, "typedef enum sdf_proto_mode {", "SDF_MODE_")
    mode_names = c_strings(proto_c, "mode_names[] = {")
    modes = dict(zip(mode_names, range(len(mode_names))))
    words = dict(enumerate(int(w) for w in re.findall(r"\d+", c_block(proto_c, "words[] = {"))))
    signs = md_codes(protocol, "sign")
    interpolations = md_codes(protocol, "interpolation")
    kernels = md_codes(protocol, "kernel")
    smoothing = md_codes(protocol, "smoothing volume")
    flags = [int(b) for b in re.findall(r"bit (\d+)", re.search(r"\| flags: ([^|]*)\|",
                                                                 protocol).group(1))]

    @classmethod
    def lib_names(cls, table):
        return [row[1].strip('"') for row in x_macro(cls.names_c, table)]

    @classmethod
    def error_statuses(cls):
        """{code name: HTTP status} of every code sdfd answers with."""
        out = {row[0]: int(row[2]) for row in x_macro(cls.errors_h, "SDFD_ERRNO_MAP")}
        lib = x_macro(cls.errors_h, "SDFD_LIBRARY_STATUS_MAP")
        out.update({row[0]: int(row[1]) for row in lib})
        return out

    @classmethod
    def schema(cls, name):
        return cls.doc["components"]["schemas"][name]

    @classmethod
    def param_enum(cls, name):
        return cls.doc["components"]["parameters"][name]["schema"]["enum"]


S = Sources


class ProtoAgreesWithItself(unittest.TestCase):
    """proto.h, proto.c and PROTOCOL.md say the same (the clients are held to them below)."""

    def test_message_types(self):
        self.assertEqual(S.frames, S.md_frames)

    def test_modes(self):
        self.assertEqual({n.lower().replace("_", "-"): v for n, v in S.mode_values.items()},
                         S.modes)
        self.assertEqual(md_codes(S.protocol, "mode"), S.modes)
        self.assertEqual(sorted(S.words), sorted(S.modes.values()))

    def test_signs_are_the_librarys(self):
        self.assertEqual(list(S.signs), S.lib_names("SIGN_NAMES"))
        self.assertEqual(c_enum(S.sdf_h, "typedef enum sdf_sign_method {", "SDF_SIGN_"),
                         {k.upper(): v for k, v in S.signs.items()})


class DocumentAgrees(unittest.TestCase):
    """docs/openapi.yaml's names are proto/'s and the library's."""

    def test_names(self):
        self.assertEqual(S.schema("QueryMode")["enum"], list(S.modes))
        self.assertEqual(S.schema("Sign")["enum"], list(S.signs))
        self.assertEqual(sorted(S.schema("Interpolation")["enum"]), sorted(S.interpolations))
        self.assertEqual(sorted(S.schema("Interpolation")["enum"]),
                         sorted(S.lib_names("FILTER_NAMES")))
        self.assertEqual(S.schema("Kernel")["enum"], list(S.kernels))
        self.assertEqual(sorted(k for k in S.schema("Smooth")["properties"]
                                if k not in ("depth", "scale")),
                         sorted(k for k in S.smoothing if k != "none"))
        # the library's file formats, then the arrays server/ops/mesharrays.c reads
        self.assertEqual(S.param_enum("MeshFormat"), S.lib_names("FORMAT_NAMES") + ["json", "npz"])
        arrays = open(os.path.join(ROOT, "server", "ops", "mesharrays.c")).read()
        self.assertIn('strcasecmp(format, "json")', arrays)
        self.assertIn('strcasecmp(format, "npz")', arrays)
        self.assertEqual(S.param_enum("VolumeFileFormat"), S.lib_names("FILE_NAMES"))
        info = S.schema("VolumeInfo")["properties"]
        self.assertEqual(info["encoding"]["enum"], S.lib_names("ENCODING_NAMES"))
        self.assertEqual(info["normalize"]["enum"], S.lib_names("NORMALIZE_NAMES"))
        ops = [row[2].strip('"') for row in x_macro(S.sdf_h, "SDF_FIELD_OP_MAP")]
        self.assertEqual([list(o["properties"])[0] for o in S.schema("Op")["oneOf"]], ops)
        solvers = [row[2].split('"')[1] for row in x_macro(S.sdf_h, "SDF_FIELD_SOLVER_MAP")]
        self.assertEqual(sorted(S.schema("Solver")["enum"]), sorted(solvers))

    def test_frames(self):
        used = {op["x-sdfd-frame"] for item in S.doc["paths"].values()
                for op in item.values() if isinstance(op, dict) and "x-sdfd-frame" in op}
        self.assertTrue(used)
        self.assertLessEqual(used, set(S.frames))

    def test_error_codes(self):
        """The ErrorCode enum is every code; each error response's codes are those of its
        status (but for the three no operation answers with)."""
        statuses = S.error_statuses()
        self.assertEqual(sorted(S.schema("ErrorCode")["enum"]), sorted(statuses))
        documented = {}
        for item in S.doc["paths"].values():
            for op in item.values():
                if not isinstance(op, dict) or "responses" not in op:
                    continue
                for status, response in op["responses"].items():
                    ref = response.get("$ref", "")
                    if not ref.startswith("#/components/responses/"):
                        continue
                    schema = S.doc["components"]["responses"][ref.split("/")[-1]]
                    schema = schema.get("content", {}).get("application/json", {}).get("schema")
                    if schema and "allOf" in schema:
                        codes = schema["allOf"][1]["properties"]["error"]["properties"]["code"]
                        documented.setdefault(int(status), set()).update(codes["enum"])
        expected = {}
        for code, status in statuses.items():
            if code not in NOT_IN_OPERATIONS:
                expected.setdefault(status, set()).add(code)
        self.assertEqual(documented, expected)


def node_json(script):
    out = subprocess.run(["node", "--input-type=module", "-e", script], capture_output=True,
                         text=True, timeout=60, cwd=ROOT)
    if out.returncode:
        raise AssertionError(f"node failed: {out.stderr}")
    return json.loads(out.stdout)


class PythonClient(unittest.TestCase):
    def test_tables(self):
        self.assertEqual(_wire.MODES, S.modes)
        self.assertEqual(_wire.WORDS, S.words)
        self.assertEqual(_wire.SIGNS, S.signs)
        self.assertEqual(_wire.INTERPOLATIONS, S.interpolations)
        self.assertEqual(_wire.KERNELS, S.kernels)
        self.assertEqual(_wire.VOLUMES, {k: v for k, v in S.smoothing.items() if k != "none"})
        self.assertEqual(_wire.FRAMES, S.frames)
        self.assertEqual(list(_wire.FILTER_KEYS), list(S.schema("Filter")["properties"]))

    def test_types(self):
        args = typing.get_args
        self.assertEqual(list(args(sdfclient.Mode)), list(S.modes))
        self.assertEqual(list(args(sdfclient.Sign)), list(S.signs))
        self.assertEqual(sorted(args(sdfclient.Interpolation)), sorted(S.interpolations))
        self.assertEqual(sorted(args(sdfclient.ErrorCode)), sorted(S.schema("ErrorCode")["enum"]))


class JsClient(unittest.TestCase):
    def test_tables(self):
        js = node_json(
            "const w = await import('./clients/js/src/wire.js');"
            "console.log(JSON.stringify({modes: w.MODES, signs: w.SIGNS, words: w.WORDS,"
            " interpolations: w.INTERPOLATIONS, frames: w.FRAMES, filter: w.FILTER_KEYS}));")
        self.assertEqual(js["modes"], S.modes)
        self.assertEqual(dict(enumerate(js["words"])), S.words)
        self.assertEqual(js["signs"], S.signs)
        self.assertEqual(js["interpolations"], S.interpolations)
        self.assertEqual(js["frames"], S.frames)
        self.assertEqual(js["filter"], list(S.schema("Filter")["properties"]))


class CClient(unittest.TestCase):
    header = read("clients", "c", "sdfclient.h")
    source = read("clients", "c", "sdfclient.c")

    def test_enums(self):
        modes = c_enum(self.header, "typedef enum sdfc_mode {", "SDFC_")
        self.assertEqual(modes, S.mode_values)
        signs = c_enum(self.header, "typedef enum sdfc_sign {", "SDFC_SIGN_")
        self.assertEqual(signs, {k.upper(): v for k, v in S.signs.items()})
        interps = c_enum(self.header, "typedef enum sdfc_interpolation {", "SDFC_INTERP_")
        self.assertEqual(interps, {k.upper(): v for k, v in S.interpolations.items()})
        smooth = c_enum(self.header, None, "SDFC_SMOOTH_", block="SDFC_SMOOTH_NONE")
        self.assertEqual(smooth, {k.upper(): v for k, v in S.smoothing.items()})
        flags = c_enum(self.header, None, "SDFC_FILTER_", block="SDFC_FILTER_GRID")
        self.assertEqual(sorted(flags.values()), [1 << b for b in S.flags])

    def test_name_tables(self):
        """The tables sdfc_*_from_name read are in the enums' (the wire's) order."""
        self.assertEqual(c_strings(self.source, "interpolation_names[] = {"),
                         sorted(S.interpolations, key=S.interpolations.get))
        signs = re.search(r"sdfc_sign_from_name[^{]*\{[^{]*\{([^}]*)\}", self.source).group(1)
        self.assertEqual(re.findall(r'"([^"]*)"', signs), list(S.signs))
        sdfq_signs = c_strings(read("clients", "c", "commands.c"), "signs[] = {")
        self.assertEqual(sdfq_signs, list(S.signs))

    def test_error_codes(self):
        """SDFC_E* codes that share a name with sdfd's have its value (sdfclient.h)."""
        ours = c_enum(self.header, None, "SDFC_", block="SDFC_OK")
        lib = {row[0]: int(row[1]) for row in x_macro(S.sdf_h, "SDF_ERRNO_MAP")}
        lib.update({row[0]: int(row[1]) for row in x_macro(S.errors_h, "SDFD_ERRNO_MAP")})
        shared = {name: value for name, value in ours.items() if name in lib}
        self.assertGreaterEqual(len(shared), 4)
        self.assertEqual(shared, {name: lib[name] for name in shared})

    def test_sdfq_arguments(self):
        """sdfq's slice options go out as URL arguments; its bake keys into the body."""
        passed = c_strings(read("clients", "c", "slice.c"), "passed[] = {")
        routes = ("/v1/meshes/{name}/slice.png", "/v1/volumes/{name}/slice.png")
        taken = set()
        for route in routes:
            for p in S.doc["paths"][route]["get"]["parameters"]:
                taken.add(S.doc["components"]["parameters"][p["$ref"].split("/")[-1]]["name"])
        self.assertLessEqual(set(passed), taken)
        keys = c_strings(read("clients", "c", "bake.c"), "text[] = {")
        self.assertLessEqual(set(keys) | {"resolution", "order", "margin", "ops"},
                             set(S.schema("BakeRequest")["properties"]))


if __name__ == "__main__":
    unittest.main(verbosity=2)
