#!/usr/bin/env python3
"""Run the examples the docs show against a real sdfd and compare what they print with the
output the docs show under them, so that a doc whose example no longer works, or no longer
prints what it says, fails a test.

The marking convention (tests/docs/README.md has it in full): an HTML comment
`<!-- example: NAME [exit=N] [timeout=S] -->` before a fenced block of `sh`, `python` or `js`
makes it an example; `<!-- output -->` before the next fenced block makes that block the
output the example must print (standard output; `{{any}}`, `{{num}}`, `{{~X}}` and a line
`{{lines}}` mask what legitimately varies); `<!-- not-run: WHY -->` exempts a block. Every
sh, python or js block in the files must carry one of the two, so no new example escapes.

Per file, in a workspace that looks like the repository root (build/ and clients/ linked,
tests/data copied), one fresh sdfd is started from BUILD_DIR on free loopback ports with its
demo mesh, and the file's examples run in order against it: sh through `sh -e`, python
through this interpreter with clients/python on PYTHONPATH, js as an ES module through node
with `sdfd-client` resolving to clients/js. The documented default addresses in an example's
text (127.0.0.1:8080 or localhost:8080, and :9090 for the binary port) are replaced by the
test server's, and written back in what it prints; SDFD_URL and SDFD_BIN name the server too,
and build/clients/c (sdfq) is on PATH. Nothing is built here: meson builds sdfd and sdfq first.

    run_examples.py BUILD_DIR [--source DIR] [--only NAME] [--keep] [FILE.md ...]

Prints one line per example (`ok`, `FAIL` with the reason and a diff) and ends with
`examples: N passed, N failed`; exits 1 if any example failed or a file breaks the
convention."""
import argparse
import difflib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

LANGUAGES = {"sh": "sh", "shell": "sh", "bash": "sh", "python": "python", "py": "python",
             "js": "js", "javascript": "js"}
DEFAULT_FILES = ["README.md", "docs/*.md", "clients/python/README.md", "clients/js/README.md"]
MARKER = re.compile(r"^\s*<!--\s*(example|output|not-run)\s*(?::\s*(.*?))?\s*-->\s*$")
FENCE = re.compile(r"^( {0,3})(`{3,}|~{3,})\s*([\w+-]*)")  # 4 spaces: indented code
NUMBER = r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?"
MASK = re.compile(r"\{\{(any|num|~" + NUMBER + r")\}\}")
# Sanitizer builds (meson's b_sanitize, which the test passes) run everything several times
# slower: the examples' timeouts stretch with them.
SLOWER = 1 if os.environ.get("SDF_SANITIZE", "none") in ("", "none") else 5


class DocError(Exception):
    """A file that breaks the marking convention; names the file and line."""


class Example:
    def __init__(self, path, line, name, lang, code, options):
        self.path, self.line, self.name, self.lang, self.code = path, line, name, lang, code
        self.exit, self.timeout = options.get("exit", 0), options.get("timeout", 60.0)
        self.output = None  # the expected lines, when the doc shows them


# ---- reading the Markdown ---------------------------------------------------------------

def fenced_blocks(path, lines):
    """Yield (marker, argument, marker line, fence line, language, code) for each fenced block
    outside other blocks; marker is None for an unmarked block. A marker must be followed by
    a block, with only blank lines between."""
    pending, i = None, 0
    while i < len(lines):
        m, f = MARKER.match(lines[i]), FENCE.match(lines[i])
        if m:
            if pending:
                raise DocError(f"{path}:{pending[2]}: marker not followed by a code block")
            pending = (m.group(1), m.group(2) or "", i + 1)
        elif f:
            indent, fence, lang = f.groups()
            end = i + 1
            while end < len(lines) and not re.match(r"^ {0,3}" + re.escape(fence[0]) + "{%d,}\\s*$"
                                                   % len(fence), lines[end]):
                end += 1
            if end == len(lines):
                raise DocError(f"{path}:{i + 1}: code block never closed")
            code = [ln[len(indent):] if ln.startswith(indent) else ln.lstrip()
                    for ln in lines[i + 1:end]]
            kind, arg, mline = pending or (None, "", None)
            yield kind, arg, mline, i + 1, lang.lower(), "\n".join(code) + "\n"
            pending, i = None, end
        elif lines[i].strip() and pending:
            raise DocError(f"{path}:{pending[2]}: marker not followed by a code block")
        i += 1
    if pending:
        raise DocError(f"{path}:{pending[2]}: marker not followed by a code block")


def parse_example_marker(path, line, arg):
    words = arg.split()
    if not words or "=" in words[0]:
        raise DocError(f"{path}:{line}: an example needs a name: <!-- example: NAME -->")
    options, kinds = {}, {"exit": int, "timeout": float}
    for w in words[1:]:
        key, eq, value = w.partition("=")
        if not eq or key not in kinds:
            raise DocError(f"{path}:{line}: unknown option(s) {w} (exit=N and timeout=S are)")
        try:
            options[key] = kinds[key](value)
        except ValueError:
            raise DocError(f"{path}:{line}: option {w}: not a number") from None
    return words[0], options


def read_examples(path):
    """The file's examples in order, with their expected output; DocError on a block of a
    runnable language that is neither an example nor marked not-run, an output with no
    example before it, or a name used twice."""
    examples, names, last = [], set(), None
    for kind, arg, mline, fline, lang, code in fenced_blocks(path, path.read_text().splitlines()):
        if kind is None and lang in LANGUAGES:
            raise DocError(f"{path}:{fline}: a {lang} block that is neither an example nor "
                           "marked not-run: add <!-- example: NAME --> or <!-- not-run: WHY -->")
        if kind == "not-run" and not arg:
            raise DocError(f"{path}:{mline}: not-run needs a reason: <!-- not-run: WHY -->")
        if kind == "example":
            name, options = parse_example_marker(path, mline, arg)
            if lang not in LANGUAGES:
                raise DocError(f"{path}:{fline}: example '{name}' is '{lang or 'plain'}', "
                               f"not one of {', '.join(sorted(LANGUAGES))}")
            if name in names:
                raise DocError(f"{path}:{mline}: example name '{name}' used twice")
            names.add(name)
            last = Example(path, fline, name, LANGUAGES[lang], code, options)
            examples.append(last)
        elif kind == "output":
            if last is None or last.output is not None:
                raise DocError(f"{path}:{mline}: an output block with no example of its own "
                               "before it")
            last.output = code.splitlines()
        elif kind == "not-run":
            last = None  # an output after it would be its output, which nothing checks
    return examples


# ---- comparing output -------------------------------------------------------------------

def normalize(text):
    """Lines without trailing blanks, and no blank lines at the end."""
    lines = [ln.rstrip() for ln in text.splitlines()]
    while lines and not lines[-1]:
        lines.pop()
    return lines


def line_pattern(line, tolerances):
    out, pos = [], 0
    for m in MASK.finditer(line):
        out.append(re.escape(line[pos:m.start()]))
        mask = m.group(1)
        if mask == "any":
            out.append(".*?")
        elif mask == "num":
            out.append(NUMBER)
        else:  # ~X: a number that rounds to X at X's precision
            tolerances.append(mask[1:])
            out.append(f"(?P<t{len(tolerances) - 1}>{NUMBER})")
        pos = m.end()
    out.append(re.escape(line[pos:]))
    return "".join(out)


def within(shown, value):
    """Whether value rounds to shown at shown's precision (its last digit, exponent included)."""
    mantissa, _, exponent = shown.lower().partition("e")
    decimals = len(mantissa.partition(".")[2])
    step = 10.0 ** (int(exponent or 0) - decimals)
    return abs(float(value) - float(shown)) <= step / 2 * (1 + 1e-9)


def matches(expected, actual):
    """Whether the actual lines fit the expected ones, masks and all."""
    tolerances, parts = [], []
    for line in expected:
        parts.append(r"(?:[^\n]*\n)*?" if line.strip() == "{{lines}}"
                     else line_pattern(line, tolerances) + r"\n")
    m = re.fullmatch("".join(parts), "".join(ln + "\n" for ln in actual))
    return bool(m) and all(within(t, m.group(f"t{i}")) for i, t in enumerate(tolerances))


# ---- the server and the workspace -------------------------------------------------------

class Sdfd:
    """build/server/sdfd on free loopback ports, its ports read from its JSON log."""

    def __init__(self, build, env):
        self.proc = subprocess.Popen([str(build / "server" / "sdfd"), "--http", "127.0.0.1:0",
                                      "--bin", "127.0.0.1:0"], env=env,
                                     stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        self.log, self.ports, self.ready = [], {}, threading.Event()
        threading.Thread(target=self._read, daemon=True).start()
        if not self.ready.wait(60 * SLOWER):
            self.stop()
            raise RuntimeError("sdfd did not become ready:\n" + "".join(self.log[-20:]))

    def _read(self):
        for raw in self.proc.stderr:
            line = raw.decode(errors="replace")
            self.log.append(line)
            try:
                entry = json.loads(line)
            except ValueError:
                continue
            if entry.get("event") == "listening":
                self.ports[entry["proto"]] = entry["port"]
            elif entry.get("event") == "ready":
                self.ready.set()

    def sanitizer_report(self):
        """The log from a sanitizer's first report on (its lines are not JSON), or ''."""
        for i, line in enumerate(self.log):
            if "Sanitizer" in line or "runtime error" in line:
                return "".join(self.log[i:i + 40])
        return ""

    def stop(self):
        """SIGTERM, then the exit code (0 after a clean drain)."""
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            return self.proc.wait(60)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            return self.proc.wait()


def make_workspace(root, source, build):
    """A folder shaped like the repository root, and the tools folder beside it: python3 (this
    interpreter, which has numpy) and node_modules/sdfd-client (for the js examples' scripts,
    which are written there so that node resolves the package from them)."""
    work, tools = root / "repo", root / "tools"
    (work / "tests").mkdir(parents=True)
    shutil.copytree(source / "tests" / "data", work / "tests" / "data")
    (work / "build").symlink_to(build)
    (work / "clients").symlink_to(source / "clients")
    (tools / "bin").mkdir(parents=True)
    (tools / "bin" / "python3").symlink_to(sys.executable)
    (tools / "node_modules").mkdir()
    (tools / "node_modules" / "sdfd-client").symlink_to(source / "clients" / "js")
    return work, tools


def clean_env():
    """The caller's environment without SDFD_* (which would set sdfd's flags or sdfq's
    server)."""
    return {k: v for k, v in os.environ.items() if not k.startswith("SDFD_")}


def example_env(build, source, tools, ports):
    env = clean_env()
    env.update(SDFD_URL=f"http://127.0.0.1:{ports['http']}",
               SDFD_BIN=f"127.0.0.1:{ports['binary']}",
               PYTHONPATH=str(source / "clients" / "python"), PYTHONDONTWRITEBYTECODE="1",
               PATH=os.pathsep.join([str(tools / "bin"), str(build / "clients" / "c"),
                                     env.get("PATH", "")]))
    return env


# ---- running one example ----------------------------------------------------------------

def to_test_server(code, ports):
    """The example's text with the documented default addresses replaced by the server's."""
    http, binary = ports["http"], ports["binary"]
    code = re.sub(r"\b(?:localhost|127\.0\.0\.1):8080\b", f"127.0.0.1:{http}", code)
    code = re.sub(r"\b(?:localhost|127\.0\.0\.1):9090\b", f"127.0.0.1:{binary}", code)
    code = re.sub(r"""(["']127\.0\.0\.1["'],\s*)9090\b""", rf"\g<1>{binary}", code)
    return re.sub(r"\bport:\s*9090\b", f"port: {binary}", code)


def from_test_server(text, ports):
    text = text.replace(f"127.0.0.1:{ports['http']}", "127.0.0.1:8080")
    return text.replace(f"127.0.0.1:{ports['binary']}", "127.0.0.1:9090")


def command(example, code, tools):
    if example.lang == "sh":
        return ["sh", "-e", "-c", code]
    if example.lang == "python":
        return [sys.executable, "-c", code]
    script = tools / f"example-{example.name}.mjs"
    script.write_text(code)
    return [os.environ.get("NODE", "node"), str(script)]


def run_example(example, work, tools, env, ports):
    """None when the example did what its doc says, else the reason it did not."""
    argv = command(example, to_test_server(example.code, ports), tools)
    # A session of its own, so that a timeout ends what the example started, too.
    p = subprocess.Popen(argv, cwd=work, env=env, stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, start_new_session=True)
    try:
        stdout, stderr = p.communicate(timeout=example.timeout * SLOWER)
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        p.communicate()
        return f"did not finish within {example.timeout * SLOWER:g} s"
    out = normalize(from_test_server(stdout.decode(errors="replace"), ports))
    err = from_test_server(stderr.decode(errors="replace"), ports)
    problems = []
    if p.returncode != example.exit:
        problems.append(f"exit status {p.returncode}, the doc expects {example.exit}")
    if example.output is not None and not matches(normalize("\n".join(example.output)), out):
        diff = difflib.unified_diff(normalize("\n".join(example.output)), out,
                                    "shown in the doc", "printed", lineterm="")
        problems.append("its output differs:\n" + "\n".join(diff))
    if problems and err.strip():
        problems.append("its standard error:\n" + err.rstrip())
    return "\n".join(problems) or None


# ---- main ---------------------------------------------------------------------------------

def shown(path, source):
    """The path as the report prints it: from the repository's root when it is inside."""
    return str(path.relative_to(source)) if path.is_relative_to(source) else str(path)


def run_file(path, examples, source, build, root, only):
    """Run one file's examples on a fresh sdfd; returns (passed, failed)."""
    chosen = [e for e in examples if only is None or e.name in only]
    if not chosen:
        return 0, 0
    work, tools = make_workspace(root / re.sub(r"\W", "_", shown(path, source)), source, build)
    server = Sdfd(build, clean_env())
    env = example_env(build, source, tools, server.ports)
    passed = failed = 0
    try:
        for e in chosen:
            t = time.monotonic()
            reason = run_example(e, work, tools, env, server.ports)
            where = f"{shown(path, source)}:{e.line} {e.name}"
            if reason:
                failed += 1
                print(f"FAIL {where}: " + reason.replace("\n", "\n    "), flush=True)
            else:
                passed += 1
                print(f"ok   {where} ({time.monotonic() - t:.1f} s)", flush=True)
    finally:
        code = server.stop()
    report = server.sanitizer_report()
    if code != 0 or report:
        failed += 1
        print(f"FAIL {shown(path, source)}: sdfd exited {code}:\n" +
              (report or "".join(server.log[-20:])))
    return passed, failed


def doc_files(source, names):
    if names:
        return [Path(n).resolve() for n in names]
    files = []
    for pattern in DEFAULT_FILES:
        files += sorted(source.glob(pattern))
    return files


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("build", type=Path, help="the build directory (meson's)")
    ap.add_argument("files", nargs="*", help="Markdown files (default: README.md, docs/*.md, "
                    "the clients' READMEs)")
    ap.add_argument("--source", type=Path, default=Path(__file__).resolve().parents[2],
                    help="the repository's root (default: this script's)")
    ap.add_argument("--only", action="append", help="run only the example(s) of this name")
    ap.add_argument("--keep", action="store_true", help="keep the workspaces, and say where")
    args = ap.parse_args()
    source, build = args.source.resolve(), args.build.resolve()
    try:
        parsed = [(p, read_examples(p)) for p in doc_files(source, args.files)]
    except DocError as e:
        print(f"FAIL {e}")
        print("examples: 0 passed, 1 failed")
        return 1
    root = Path(tempfile.mkdtemp(prefix="sdfd-doc-examples-"))
    passed = failed = 0
    try:
        for path, examples in parsed:
            p, f = run_file(path, examples, source, build, root, args.only)
            passed, failed = passed + p, failed + f
    finally:
        if args.keep:
            print(f"workspaces kept in {root}")
        else:
            shutil.rmtree(root, ignore_errors=True)
    if not passed and not failed:
        print("FAIL no example ran: the files mark none (or --only names none)")
    print(f"examples: {passed} passed, {failed} failed")
    return 1 if failed or not passed else 0


if __name__ == "__main__":
    sys.exit(main())
