"""`meson install` and what it installs, used the way README.md ("Installing") says: the build
is installed into a temporary DESTDIR, and then, with pkg-config pointed at the installed .pc
files and nothing of the source tree:
  - the files are where they belong: bin/sdfd and bin/sdfq, the shared libsdf (exporting
    sdf.h's sdf_ names and no internal sdf__ one) and libsdfclient with their sonames,
    include/sdf/sdf.h and include/sdfclient.h, sdf.pc and sdfclient.pc; on Debian in
    lib/<gcc -print-multiarch>, a directory the loader's configuration and pkg-config's
    default path list;
  - README.md's libsdf snippet ("Using the library"), put in a main, compiles with
    `pkg-config --cflags --libs sdf` (-Wall -Wextra -Werror), runs on an STL file and
    prints the distances sdfd answers over HTTP for the same mesh and points, bit for bit;
  - docs/sdfq.md's libsdfclient example compiles with `pkg-config --cflags --libs sdfclient`
    and prints, for the demo mesh of an sdfd on a loopback port, what that sdfd answers;
  - the installed sdfq finds the installed libsdfclient.so.0 by its run path (no
    LD_LIBRARY_PATH), prints `sdfq VERSION` and answers a query as sdfd does; the installed
    sdfd prints `sdfd VERSION`.
meson passes the build directory and the install layout (tests/meson.build)."""
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import unittest

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.join(HERE, "..", "..")
sys.path.insert(0, os.path.join(HERE, "..", "server"))
sys.path.insert(0, os.path.join(SOURCE, "clients", "python"))
import sdfclient  # noqa: E402
from harness import DATA, Server  # noqa: E402

BUILD = os.environ["SDF_BUILD_ROOT"]
PREFIX = os.environ["SDF_PREFIX"]
LIBDIR = os.environ["SDF_LIBDIR"]          # relative to PREFIX, as meson.build computed it
BINDIR = os.environ["SDF_BINDIR"]
INCLUDEDIR = os.environ["SDF_INCLUDEDIR"]
VERSION = os.environ["SDF_VERSION"]
MULTIARCH = os.environ["SDF_MULTIARCH"] == "true"
CC = os.environ.get("CC", "cc")


def run(args, **kw):
    """Run a command; its stdout (text). A failure fails the test with its output."""
    r = subprocess.run(args, capture_output=True, text=True, timeout=300, **kw)
    if r.returncode:
        raise AssertionError(f"{args} exited {r.returncode}:\n{r.stdout}{r.stderr}")
    return r.stdout


def code_block(path, heading, lang="c"):
    """The first ```lang block after the line `heading` in a Markdown file."""
    with open(path, encoding="utf-8") as f:
        text = f.read()
    at = text.index("\n" + heading + "\n")
    m = re.compile(r"```%s\n(.*?)```" % lang, re.S).search(text, at)
    return m.group(1)


def multiarch():
    """gcc's multiarch name when this is a Debian-like system (its /usr/lib has that
    directory), else ''."""
    name = subprocess.run([CC, "-print-multiarch"], capture_output=True, text=True).stdout.strip()
    return name if name and os.path.isdir("/usr/lib/" + name) else ""


def loader_dirs():
    """The directories ld.so.conf and the files it includes list."""
    dirs, todo = [], ["/etc/ld.so.conf"]
    while todo:
        path = todo.pop()
        try:
            with open(path, encoding="utf-8") as f:
                lines = f.read().splitlines()
        except OSError:
            continue
        for line in lines:
            line = line.split("#", 1)[0].strip()
            if line.startswith("include "):
                pattern = line.split(None, 1)[1]
                base = os.path.dirname(pattern)
                rx = re.compile("^" + re.escape(os.path.basename(pattern)).replace(r"\*", ".*")
                                + "$")
                todo += [os.path.join(base, f) for f in sorted(os.listdir(base)) if rx.match(f)]
            elif line:
                dirs.append(line)
    return dirs


class Installed(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.dest = os.path.join(cls.tmp.name, "dest")
        run(["meson", "install", "-C", BUILD, "--no-rebuild", "--quiet", "--destdir", cls.dest])
        cls.root = cls.dest + PREFIX  # the prefix inside DESTDIR
        cls.lib = os.path.join(cls.root, LIBDIR)
        cls.bin = os.path.join(cls.root, BINDIR)
        cls.include = os.path.join(cls.root, INCLUDEDIR)
        # pkg-config finds the installed .pc files first, with their prefix moved to DESTDIR
        cls.pc_env = dict(os.environ, PKG_CONFIG_PATH=os.path.join(cls.lib, "pkgconfig"))
        cls.run_env = dict(os.environ, LD_LIBRARY_PATH=cls.lib)  # not in the loader's cache
        cls.server = Server()

    @classmethod
    def tearDownClass(cls):
        code = cls.server.stop()
        cls.tmp.cleanup()
        assert code == 0, f"sdfd exited with {code}"

    def path(self, name):
        return os.path.join(self.tmp.name, name)

    def pkg_config(self, package):
        return run(["pkg-config", "--define-variable=prefix=" + self.root, "--cflags", "--libs",
                    package], env=self.pc_env).split()

    def compile(self, source_text, name, package):
        src = self.path(name + ".c")
        with open(src, "w", encoding="utf-8") as f:
            f.write(source_text)
        flags = self.pkg_config(package)
        self.assertIn("-I" + self.include, flags, flags)
        self.assertIn("-L" + self.lib, flags, flags)
        run([CC, "-std=c11", "-Wall", "-Wextra", "-Werror", src, "-o", self.path(name), *flags])
        return self.path(name)

    def http_distances(self, mesh, points):
        c = sdfclient.Client(self.server.url)
        self.addCleanup(c.close)
        return c.query(mesh, points, form="octet")["distance"]

    def test_files_and_places(self):
        for f in (os.path.join(self.bin, "sdfd"), os.path.join(self.bin, "sdfq"),
                  os.path.join(self.lib, "libsdf.so.0"), os.path.join(self.lib, "libsdf.so"),
                  os.path.join(self.lib, "libsdfclient.so.0"),
                  os.path.join(self.lib, "libsdfclient.so"),
                  os.path.join(self.lib, "pkgconfig", "sdf.pc"),
                  os.path.join(self.lib, "pkgconfig", "sdfclient.pc"),
                  os.path.join(self.include, "sdf", "sdf.h"),
                  os.path.join(self.include, "sdfclient.h")):
            self.assertTrue(os.path.exists(f), f)
        for lib, soname in (("libsdf.so", "libsdf.so.0"), ("libsdfclient.so", "libsdfclient.so.0")):
            dynamic = run(["readelf", "-d", os.path.join(self.lib, lib)])
            self.assertIn(f"Library soname: [{soname}]", dynamic)
        exported = run(["nm", "-D", "--defined-only", os.path.join(self.lib, "libsdf.so.0")])
        names = [line.split()[-1] for line in exported.splitlines()]
        self.assertIn("sdf_query", names)
        self.assertEqual([n for n in names if not re.match(r"sdf_[a-z]", n)], [])
        self.assertEqual(run(["pkg-config", "--modversion", "sdf"], env=self.pc_env).strip(),
                         VERSION)
        if MULTIARCH and multiarch():
            # Debian: the multiarch directory, even where meson had no dpkg-architecture
            self.assertEqual(LIBDIR, "lib/" + multiarch())
            live = os.path.join(PREFIX, LIBDIR)
            self.assertIn(live, loader_dirs(), "the loader does not search " + live)
            pc_path = run(["pkg-config", "--variable", "pc_path", "pkg-config"]).strip()
            self.assertIn(os.path.join(live, "pkgconfig"), pc_path.split(":"))

    def test_header_version(self):
        # sdf.h's version macros say the project's version (meson.build), as sdf.pc does
        exe = self.compile('#include <sdf/sdf.h>\n#include <stdio.h>\n\nint main(void)\n{\n'
                           '    printf("%d.%d.%d\\n", SDF_VERSION_MAJOR, SDF_VERSION_MINOR, '
                           'SDF_VERSION_PATCH);\n    return 0;\n}\n', "version", "sdf")
        self.assertEqual(run([exe], env=self.run_env), VERSION + "\n")

    def test_readme_libsdf_snippet(self):
        snippet = code_block(os.path.join(SOURCE, "README.md"), "## Using the library")
        includes = [line for line in snippet.splitlines() if line.startswith("#include")]
        body = [line for line in snippet.splitlines() if not line.startswith("#include")]
        program = ("#include <stdio.h>\n" + "\n".join(includes) + "\n\nint main(void)\n{\n"
                   + "\n".join(body) + '\n    printf("%.9g %.9g\\n", distance[0], distance[1]);\n'
                   "    return rc != 0;\n}\n")
        exe = self.compile(program, "readme", "sdf")
        shutil.copy(os.path.join(DATA, "Spider_binary.stl"), self.path("part.stl"))
        out = run([exe], cwd=self.tmp.name, env=self.run_env).split()
        self.assertEqual(len(out), 2, out)
        # the snippet's points, {0, 0, 0} and {1, 2, 3}, asked of sdfd for the same mesh
        c = sdfclient.Client(self.server.url)
        self.addCleanup(c.close)
        c.upload("part", self.path("part.stl"))
        want = self.http_distances("part", [[0, 0, 0], [1, 2, 3]])
        self.assertEqual([struct.pack("<f", float(v)) for v in out],
                         [struct.pack("<f", v) for v in want])

    def test_libsdfclient_example(self):
        example = code_block(os.path.join(SOURCE, "docs", "sdfq.md"), "## libsdfclient from C")
        exe = self.compile(example, "demo_client", "sdfclient")
        out = run([exe, "127.0.0.1", str(self.server.bin_port)], env=self.run_env).split()
        want = self.http_distances("demo", [[0, 0, 0], [10, 0, 0]])
        self.assertEqual([struct.pack("<f", float(v)) for v in out],
                         [struct.pack("<f", v) for v in want])

    def test_installed_programs(self):
        sdfq = os.path.join(self.bin, "sdfq")
        env = {k: v for k, v in os.environ.items() if k != "LD_LIBRARY_PATH"}
        # the run path, not the loader's cache or the build tree, gives the installed library
        ldd = run(["ldd", sdfq], env=env)
        found = re.search(r"libsdfclient\.so\.0 => (\S+)", ldd)
        self.assertIsNotNone(found, ldd)
        self.assertEqual(os.path.realpath(found.group(1)),
                         os.path.realpath(os.path.join(self.lib, "libsdfclient.so.0")))
        self.assertEqual(run([sdfq, "--version"], env=env), f"sdfq {VERSION}\n")
        self.assertEqual(run([os.path.join(self.bin, "sdfd"), "--version"], env=env),
                         f"sdfd {VERSION}\n")
        out = run([sdfq, "query", "demo", "-", "--bin", f"127.0.0.1:{self.server.bin_port}"],
                  input="0,0,0\n10,0,0\n", env=env).split()
        self.assertEqual(out[0], "distance")
        want = self.http_distances("demo", [[0, 0, 0], [10, 0, 0]])
        self.assertEqual([struct.pack("<f", float(v)) for v in out[1:]],
                         [struct.pack("<f", v) for v in want])


if __name__ == "__main__":
    unittest.main(verbosity=2)
