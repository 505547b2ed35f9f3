#!/usr/bin/python3
"""report.py - every table of docs/performance.md from one run on one commit: it runs the
benchmarks behind each table (compare.sh, the filtered and sign runs of sdf-bench, scale.sh,
bake-compare.sh, server-compare.sh, slices through sdfd, deploy/lb_bench.py,
store_first_answer.py, catalog_bench.py, extract_bench.py, feature-normals) and prints the tables in Markdown, headed by the commit and the machine,
then the targets those tables decide.

    tests/bench/report.py [--quick] [--only SECTION,...] [--write docs/performance.md]
                          [--build DIR]

The full run takes about 10-15 minutes of both cores. --quick shrinks every size (20,000
points instead of a million, one mesh, 24^3 bakes, one round each) so that the whole report
runs in about 30 s: a smoke run of every benchmark's path, whose figures mean nothing. --write replaces each region of the file that sits between
`<!-- report: SECTION -->` and `<!-- /report -->` with that section's fresh table (refused with
--quick); the targets' table only after a run of every section. Progress goes to standard error. A section whose benchmark fails prints why in its
place and the script exits 1 after the rest.

Run it on a quiet machine, from the repository root, after `meson setup build
--buildtype=release && meson compile -C build`. Needs /usr/bin/python3 with numpy, Debian's
python3-open3d and python3-openvdb (the peers), node, haproxy, nginx-light and
libnginx-mod-stream (the balancers)."""
import argparse
import json
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DATA = ROOT / "tests" / "data"
FANDISK, ELEPHANT = str(DATA / "fandisk.off"), str(DATA / "refined_elephant.off")

FULL = dict(n=1000000, meshes=[FANDISK, ELEPHANT], repeat=3, filtered_n=100000, samples=64,
            bakes=[(128, 3), (256, 2)], scale_mesh=ELEPHANT, scale_times=2, rounds=3,
            slice_size=512, slice_requests=5, slice_mesh=ELEPHANT, index_meshes=[
                FANDISK, ELEPHANT, str(DATA / "cow.off")], extract_res=512, extract_repeat=3)
QUICK = dict(n=20000, meshes=[FANDISK], repeat=1, filtered_n=2000, samples=16,
             bakes=[(24, 1)], scale_mesh=FANDISK, scale_times=1, rounds=1, slice_size=64,
             slice_requests=2, slice_mesh=FANDISK, index_meshes=[FANDISK], extract_res=48,
             extract_repeat=1)


# ---- running things -----------------------------------------------------------------------

def say(*args):
    print(*args, file=sys.stderr, flush=True)


def run(argv, env=None):
    """Standard output of a benchmark; its standard error goes to ours (progress). The
    scripts find the build in BUILD, which main sets."""
    say("+ " + " ".join(map(str, argv)))
    full_env = dict(os.environ, **(env or {}))
    return subprocess.run(list(map(str, argv)), cwd=ROOT, env=full_env, check=True,
                          stdout=subprocess.PIPE, text=True).stdout


def table_lines(text):
    return [ln for ln in text.splitlines() if ln.startswith("|")]


def rows(lines):
    """The rows of a Markdown table as dicts by column heading."""
    cells = [[c.strip() for c in ln.strip().strip("|").split("|")] for ln in lines]
    head = cells[0]
    return [dict(zip(head, r)) for r in cells[2:]]


def mqs(text):
    return float(re.search(r"^throughput: ([\d.]+) Mq/s", text, re.M).group(1))


def mesh_line(text):
    """triangles, index B/triangle and build seconds from sdf-bench's first line."""
    m = re.search(r"triangles: (\d+) .*\(([\d.]+) B/triangle\) build: ([\d.]+) s", text)
    return int(m.group(1)), float(m.group(2)), float(m.group(3))


def name(path):
    return os.path.basename(path)


def bench(s, program):
    return Path(s["build"]) / "tests" / "bench" / program


# ---- the sections -------------------------------------------------------------------------
# Each returns (the command that reproduces it, its Markdown lines) and leaves in `found`
# what the targets need.

def peers(s, found):
    env = {"WORKLOADS": "box band grid", "N": str(s["n"])}
    out = table_lines(run(["tests/bench/compare.sh", *s["meshes"]], env))
    found["peers"] = rows(out)
    return f"WORKLOADS='box band grid' N={s['n']} tests/bench/compare.sh", out


def filtered(s, found):
    out = ["| mesh | points | raw signed Mq/s | filtered Mq/s | filtered cost / raw |",
           "| --- | ---: | ---: | ---: | ---: |"]
    found["filtered"] = []
    for mesh in s["meshes"]:
        rate = {}
        for mode in ("signed", "filtered"):
            rate[mode] = mqs(run([bench(s, "sdf-bench"), mesh, "--workload", "band", "--n",
                                  s["filtered_n"], "--threads", 2, "--repeat", 3, "--mode",
                                  mode, "--samples", s["samples"]]))
        cost = rate["signed"] / rate["filtered"]
        found["filtered"].append((name(mesh), cost))
        out.append(f"| {name(mesh)} | {s['filtered_n']} | {rate['signed']:.3f} | "
                   f"{rate['filtered']:.4f} | {cost:.1f} |")
    return (f"sdf-bench MESH --workload band --n {s['filtered_n']} --threads 2 --repeat 3 "
            f"--mode signed|filtered --samples {s['samples']}"), out


def scale(s, found):
    env = {"N": str(s["n"]), "MESH": s["scale_mesh"], "TIMES": str(s["scale_times"]),
           "WORK": found["tmp"]}
    out = table_lines(run(["tests/bench/scale.sh"], env))
    found["scale"] = rows(out)
    return f"N={s['n']} tests/bench/scale.sh", out


def volumes(s, found):
    out, found["volumes"] = [], []
    for dim, repeat in s["bakes"]:
        lines = table_lines(run(["tests/bench/bake-compare.sh", s["build"], dim, *s["meshes"]],
                                {"REPEAT": str(repeat)}))
        out += lines if not out else lines[2:]
        found["volumes"] += rows(lines)
    dims = " and ".join(f"REPEAT={r} ... build {d}" for d, r in s["bakes"])
    return f"tests/bench/bake-compare.sh ({dims})", out


def server(s, found):
    env = {"N": str(s["n"]), "R": str(s["rounds"])}
    out = table_lines(run(["tests/bench/server-compare.sh", *s["meshes"]], env))
    found["server"] = rows(out)
    return f"N={s['n']} R={s['rounds']} tests/bench/server-compare.sh", out


def signs(s, found):
    mesh, base = FANDISK, None
    out = ["| mesh | sign | mode | Mq/s | vs pseudonormal signed |", "| --- | --- | --- | ---: | ---: |"]
    for sign, mode in [("pseudonormal", "signed"), ("none", "signed"), ("raycast", "signed"),
                       ("winding", "signed"), ("auto", "distance"), ("auto", "gradient"),
                       ("auto", "closest")]:
        rate = mqs(run([bench(s, "sdf-bench"), mesh, "--workload", "band", "--n", s["n"],
                        "--threads", 2, "--repeat", s["repeat"], "--sign", sign, "--mode",
                        mode]))
        base = base or rate
        out.append(f"| {name(mesh)} | {sign} | {mode} | {rate:.3f} | {rate / base:.2f} |")
    return (f"sdf-bench tests/data/fandisk.off --workload band --n {s['n']} --threads 2 "
            f"--repeat {s['repeat']} --sign S --mode M"), out


def index(s, found):
    out = ["| mesh | triangles | index B/triangle | build s |", "| --- | ---: | ---: | ---: |"]
    found["index"] = []
    for mesh in s["index_meshes"]:
        tris, bpt, secs = mesh_line(run([bench(s, "sdf-bench"), mesh, "--n", 10]))
        found["index"].append(bpt)
        out.append(f"| {name(mesh)} | {tris} | {bpt:.1f} | {secs:.3f} |")
    return "sdf-bench MESH --n 10 (its first line)", out


def slices(s, found):
    sys.path.insert(0, str(ROOT / "tests" / "server"))
    os.environ["SDFD"] = str(Path(s["build"]) / "server" / "sdfd")
    from harness import Server
    size, k = s["slice_size"], s["slice_requests"]
    kinds = [("signed, PNG", ""), ("signed, npy", "&format=npy"),
             ("filtered, 64 samples, PNG", "&mode=filtered&samples=64")]
    out = ["| mesh | slice | pixels | requests, s |", "| --- | --- | ---: | --- |"]
    found["slices"] = []
    with Server("--mesh", f"m={s['slice_mesh']}", "--threads", "2") as srv:
        url = f"{srv.url}/v1/meshes/m/slice.png?axis=z&size={size}"
        urllib.request.urlopen(url).read()  # once, untimed
        for label, args in kinds:
            times, pixels = [], ""
            for _ in range(k):
                t = time.perf_counter()
                with urllib.request.urlopen(url + args) as r:
                    r.read()
                    pixels = r.headers["X-SDF-Slice-Size"].replace(",", " x ")
                times.append(time.perf_counter() - t)
            found["slices"].append((label, max(times)))
            out.append(f"| {name(s['slice_mesh'])} | {label} | {pixels} | "
                       f"{' '.join(f'{t:.3f}' for t in times)} |")
    return f"GET /v1/meshes/m/slice.png?axis=z&size={size}[...], {k} requests each", out


def balancers(s, found):
    text = run(["/usr/bin/python3", "deploy/lb_bench.py", "--mesh", s["meshes"][-1], "--n",
                s["n"], "--rounds", s["rounds"]])
    return (f"/usr/bin/python3 deploy/lb_bench.py --mesh {name(s['meshes'][-1])} --n {s['n']} "
            f"--rounds {s['rounds']}"), table_lines(text)


def store(s, found):
    stem = Path(s["scale_mesh"]).stem
    meshes = [s["scale_mesh"], os.path.join(found["tmp"], f"{stem}_x{4 ** s['scale_times']}.off")]
    if not os.path.exists(meshes[1]):  # scale.sh's, when it ran
        run(["/usr/bin/python3", "tests/bench/subdivide.py", meshes[0], meshes[1], "--times",
             s["scale_times"]])
    text = run(["/usr/bin/python3", "tests/server/store_first_answer.py", *meshes],
               {"SDFD": str(Path(s["build"]) / "server" / "sdfd")})
    out = ["| mesh | file MB | first answer s (3 runs) | next query ms |",
           "| --- | ---: | --- | --- |"]
    for mesh in meshes:
        got = re.findall(rf"^{re.escape(name(mesh))}: first answer ([\d.]+) s, next ([\d.]+) ms",
                         text, re.M)
        out.append(f"| {name(mesh)} | {os.path.getsize(mesh) / 1e6:.1f} | "
                   f"{' '.join(f for f, _ in got)} | {' '.join(n for _, n in got)} |")
    return ("SDFD=build/server/sdfd python3 tests/server/store_first_answer.py "
            f"{name(meshes[0])} {name(meshes[1])}"), out


def catalog(s, found):
    n, seconds = (50, 3) if s["repeat"] > 1 else (5, 0.5)
    text = run(["/usr/bin/python3", "tests/bench/catalog_bench.py", "--n", n, "--seconds",
                seconds], {"SDFD": str(Path(s["build"]) / "server" / "sdfd")})
    return (f"SDFD=build/server/sdfd /usr/bin/python3 tests/bench/catalog_bench.py --n {n} "
            f"--seconds {seconds}"), text.strip().splitlines()


def extraction(s, found):
    args = ["--mesh", ELEPHANT, "--resolution", s["extract_res"], "--repeat",
            s["extract_repeat"], "--build", s["build"]]
    text = run(["/usr/bin/python3", "tests/bench/extract_bench.py"] + args)
    normals = run([Path(s["build"]) / "tests" / "bench" / "feature-normals", "--resolution",
                   128 if s["repeat"] > 1 else 32, "--threads", 2])
    return ("/usr/bin/python3 tests/bench/extract_bench.py --resolution "
            f"{s['extract_res']} --repeat {s['extract_repeat']}; build/tests/bench/"
            f"feature-normals --resolution {128 if s['repeat'] > 1 else 32}"), \
        text.strip().splitlines() + [""] + normals.strip().splitlines()


SECTIONS = {"peers": peers, "filtered": filtered, "scale": scale, "volumes": volumes,
            "server": server, "slices": slices, "balancers": balancers, "signs": signs,
            "index": index, "store": store, "catalog": catalog, "extraction": extraction}


# ---- the targets --------------------------------------------------------------------------

def verdict(per_mesh):
    """'yes', 'no', or the meshes it holds on, from (mesh, holds) pairs."""
    held = [m for m, ok in per_mesh if ok]
    if len(held) == len(per_mesh):
        return "yes"
    return "no" if not held else "on " + ", ".join(held) + " only"


def peer_targets(found):
    out = []
    for workload, goal in (("box", 20), ("band", 10), ("grid", 30)):
        rs = [r for r in found["peers"] if r["workload"] == workload]
        got = [(r["mesh"], float(r["packets / Open3D"])) for r in rs]
        out.append((f"{workload} >= {goal}x Open3D", ", ".join(f"{m} {v:.2f}x" for m, v in got),
                    verdict([(m, v >= goal) for m, v in got])))
    rs = [r for r in found["peers"] if r["workload"] in ("band", "grid")]
    got = [(f"{r['mesh']} {r['workload']}", float(r["packets / single"])) for r in rs]
    out.append(("packets >= 3x the single traversal (band, grid)",
                ", ".join(f"{m} {v:.2f}x" for m, v in got), verdict([(m, v >= 3) for m, v in got])))
    return out


def scale_targets(found):
    small, big = found["scale"][0], found["scale"][-1]
    label = f"{big['mesh']} ({int(big['triangles']):,} triangles)"
    ratio, build = float(big["band vs original"]), float(big["build s"])
    index = found.get("index", []) + [float(r["index B/triangle"]) for r in found["scale"]]
    return [(f"{label}: band >= 50 % of {small['mesh']}'s rate", f"{ratio:.0%}",
             "yes" if ratio >= 0.5 else "no"),
            (f"{label}: build <= 1.5 s", f"{build:.2f} s", "yes" if build <= 1.5 else "no"),
            ("index <= 150 B/triangle", f"at most {max(index):.1f}",
             "yes" if max(index) <= 150 else "no")]


def volume_targets(found):
    first_dim = found["volumes"][0]["nodes"]
    rs = [r for r in found["volumes"] if r["nodes"] == first_dim]
    vdb = [(r["mesh"], float(r["ours / OpenVDB"])) for r in rs]
    order = [(r["mesh"], float(r["first / zero"])) for r in rs]
    return [(f"zero-order bake >= 5x OpenVDB (nodes/s over active voxels/s, {first_dim})",
             ", ".join(f"{m} {v:.2f}x" for m, v in vdb), verdict([(m, v >= 5) for m, v in vdb])),
            (f"first-order bake <= 4x the zero order ({first_dim})",
             ", ".join(f"{m} {v:.2f}x" for m, v in order),
             verdict([(m, v <= 4) for m, v in order]))]


def server_targets(found):
    rs, out = found["server"], []
    goals = [("sdfd-bench binary", "1", 0.90), ("sdfd-bench octet", "1", 0.85),
             ("sdfd-bench json", "1", 0.40), ("sdfd-bench binary", "64", 0.75),
             ("sdfd-bench octet", "64", 0.75), ("C client binary", "1", 0.85),
             ("JS client binary", "1", 0.85), ("JS client octet", "1", 0.70)]
    for path, clients, goal in goals:
        got = [(r["mesh"], float(r["vs in-process"])) for r in rs
               if r["path"] == path and r["clients x points"].startswith(clients + " x")]
        what = "one request of all points" if clients == "1" else "64 clients x 1,000 points"
        out.append((f"{path}, {what}: >= {goal:.2f} of in-process",
                    ", ".join(f"{m} {v:.2f}" for m, v in got),
                    verdict([(m, v >= goal) for m, v in got])))
    differ = [f"{r['mesh']} {r['path']}" for r in rs if r["same bits"] == "NO"]
    out.append(("every client's distances bit-equal to in-process",
                ", ".join(differ) + " differ" if differ else "all equal", "no" if differ else "yes"))
    return out


def targets(found):
    """(target, measured, holds) rows for the sections that ran."""
    out = []
    if "peers" in found:
        out += peer_targets(found)
    if "scale" in found:
        out += scale_targets(found)
    if "filtered" in found:
        got = found["filtered"]
        out.append(("filtered, 64 samples: <= 8x a raw query",
                    ", ".join(f"{m} {v:.1f}x" for m, v in got),
                    verdict([(m, v <= 8) for m, v in got])))
    if "volumes" in found:
        out += volume_targets(found)
    if "server" in found:
        out += server_targets(found)
    for label, worst in found.get("slices", []):
        if not label.startswith("filtered"):
            out.append((f"a slice, {label}: < 100 ms", f"at most {worst * 1000:.0f} ms",
                        "yes" if worst < 0.1 else "no"))
    return out


# ---- the report ---------------------------------------------------------------------------

def git(*args):
    """git's answer, or "" where git is not installed (a copy of the tree on a bare machine:
    the report then names no commit)."""
    try:
        return subprocess.run(["git", *args], cwd=ROOT, capture_output=True,
                              text=True).stdout.strip()
    except FileNotFoundError:
        return ""


def package_versions():
    names = ["libembree3-3", "python3-open3d", "python3-openvdb", "haproxy", "nginx-light",
             "nodejs"]
    out = subprocess.run(["dpkg-query", "-W", "-f", "${Package} ${Version}\\n", *names],
                         capture_output=True, text=True).stdout
    return ", ".join(ln for ln in out.splitlines() if ln.split()[1:])


def environment(quick, build):
    cpu = re.search(r"^model name\s*: (.*)$", Path("/proc/cpuinfo").read_text(), re.M)
    options = json.loads((build / "meson-info" / "intro-buildoptions.json").read_text())
    buildtype = next(o["value"] for o in options if o["name"] == "buildtype")
    cc = subprocess.run(["cc", "--version"], capture_output=True, text=True).stdout.splitlines()
    # Changes to the docs (this report's --write among them) measure nothing else.
    dirty = " with uncommitted changes" if git("status", "--porcelain", "--untracked-files=no",
                                               "--", ".", ":!*.md") else ""
    commit = git("rev-parse", "--short", "HEAD") + dirty
    lines = [f"- commit `{commit}`, {time.strftime('%Y-%m-%d', time.gmtime())}" +
             (" (**--quick**: smoke-run sizes, not figures)" if quick else ""),
             f"- {os.cpu_count()} CPUs ({cpu.group(1) if cpu else platform.machine()}), "
             f"Linux {platform.release()}",
             f"- build: {buildtype}, {cc[0] if cc else 'cc'}",
             f"- packages: {package_versions()}"]
    return commit, lines


def write_regions(path, sections):
    """Replace each <!-- report: NAME --> ... <!-- /report --> region whose section ran."""
    def fill(m):
        body = sections.get(m.group(2))
        return m.group(0) if body is None else \
            m.group(1) + "\n" + "\n".join(body) + "\n<!-- /report -->"
    text = Path(path).read_text()
    Path(path).write_text(re.sub(r"(?ms)^(<!-- report: ([\w-]+) -->)$.*?^<!-- /report -->$", fill,
                                 text))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="smoke-run sizes (about a minute)")
    ap.add_argument("--only", help="comma-separated sections: " + ", ".join(SECTIONS))
    ap.add_argument("--write", metavar="FILE.md", help="replace the file's report regions")
    ap.add_argument("--build", type=Path, default=ROOT / "build",
                    help="the build directory (default: build/)")
    a = ap.parse_args()
    chosen = a.only.split(",") if a.only else list(SECTIONS)
    unknown = [c for c in chosen if c not in SECTIONS]
    if unknown:
        ap.error(f"unknown section(s) {', '.join(unknown)}; the sections: {', '.join(SECTIONS)}")
    if a.write and a.quick:
        ap.error("--quick figures are not for the docs: --write takes a full run")
    build = a.build.resolve()
    if not (build / "build.ninja").exists():
        sys.exit(f"report.py: no build in {build}: meson setup build --buildtype=release first")
    os.environ["BUILD"] = str(build)
    sizes = dict(QUICK if a.quick else FULL, build=str(build))
    commit, env_lines = environment(a.quick, build)
    print("# sdfd performance report\n\n" + "\n".join(env_lines))
    found, bodies, failed = {"tmp": tempfile.mkdtemp(prefix="sdfd-report-")}, {}, []
    stamp = f"Printed by `tests/bench/report.py` at commit `{commit}`"
    try:
        for section in chosen:
            started = time.monotonic()
            try:
                command, lines = SECTIONS[section](sizes, found)
                bodies[section] = [f"{stamp}: `{command}`", "", *lines]
            except Exception as e:  # a benchmark failed: say so in its place, go on
                failed.append(section)
                bodies[section] = [f"**Not measured** at `{commit}`: {e}"]
            print(f"\n## {section}\n\n" + "\n".join(bodies[section]), flush=True)
            say(f"report: {section} took {time.monotonic() - started:.0f} s")
    finally:
        shutil.rmtree(found.pop("tmp"), ignore_errors=True)
    rows_ = targets(found)
    if rows_:
        bodies["targets"] = [f"{stamp}", "", "| target | measured | holds |",
                             "| --- | --- | --- |", *(f"| {t} | {m} | {h} |" for t, m, h in rows_)]
        print("\n## targets\n\n" + "\n".join(bodies["targets"]))
    bodies["environment"] = env_lines[1:]  # the tables name their commits
    if a.only:  # a part's targets would stand for all of them
        bodies.pop("targets", None)
    if a.write:
        write_regions(a.write, bodies)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
