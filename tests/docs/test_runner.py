"""The doc-example runner's own test: on fixtures/selftest.md it must pass the examples that
print what their doc shows and fail, each for its own reason, the ones that do not (a stale
value, a number past its shown precision, an exit status, a run that does not end); it must
refuse a file that breaks the marking convention before running anything; and its output
masks must match what they promise and nothing more.

BUILD_ROOT names the build directory (meson sets it)."""
import os
import re
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
import run_examples  # noqa: E402

BUILD = os.environ.get("BUILD_ROOT", str(HERE.parents[1] / "build"))


def run(*files):
    # Timeouts unstretched, whatever the build, so that the fixture's 1 s one is 1 s.
    env = dict(os.environ, SDF_SANITIZE="none")
    p = subprocess.run([sys.executable, str(HERE / "run_examples.py"), BUILD, *map(str, files)],
                       capture_output=True, text=True, timeout=600, env=env)
    return p.returncode, p.stdout + p.stderr


class SelfTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.code, cls.out = run(HERE / "fixtures" / "selftest.md")

    def verdicts(self):
        return dict((m.group(2), m.group(1)) for m in
                    re.finditer(r"^(ok|FAIL) +\S+:\d+ ([\w-]+)", self.out, re.M))

    def test_right_and_wrong_told_apart(self):
        self.assertEqual(self.verdicts(), {
            "right-curl": "ok", "wrong-output": "FAIL", "right-masks": "ok",
            "wrong-tolerance": "FAIL", "right-exit": "ok", "wrong-exit": "FAIL",
            "wrong-timeout": "FAIL", "right-python": "ok", "right-js": "ok"}, self.out)
        self.assertIn("examples: 5 passed, 4 failed", self.out)
        self.assertEqual(self.code, 1)

    def test_each_failure_says_why(self):
        self.assertIn('-{"distance":[0.65]}\n    +{"distance":[0.649999976]}', self.out)
        self.assertIn("-value {{~0.603}}\n    +value 0.6046", self.out)
        self.assertIn("wrong-exit: exit status 1, the doc expects 0", self.out)
        self.assertIn("wrong-timeout: did not finish within 1 s", self.out)
        self.assertNotIn("not reached", self.out)


CONVENTION_ERRORS = {
    "unmarked": ("text\n\n```sh\necho hi\n```\n", 3, "neither an example nor marked not-run"),
    "orphan-output": ("<!-- output -->\n```text\nhi\n```\n", 1, "an output block with no example"),
    "two-outputs": ("<!-- example: a -->\n```sh\necho hi\n```\n<!-- output -->\n```\nhi\n```\n"
                    "<!-- output -->\n```\nhi\n```\n", 9, "an output block with no example"),
    "dangling-marker": ("<!-- example: a -->\nsome prose\n```sh\necho\n```\n", 1,
                        "marker not followed by a code block"),
    "same-name": ("<!-- example: a -->\n```sh\ntrue\n```\n<!-- example: a -->\n```sh\ntrue\n```\n",
                  5, "example name 'a' used twice"),
    "language": ("<!-- example: a -->\n```c\nint main;\n```\n", 2, "not one of"),
    "option": ("<!-- example: a retries=2 -->\n```sh\ntrue\n```\n", 1, "unknown option(s) retries"),
    "no-reason": ("<!-- not-run -->\n```sh\ntrue\n```\n", 1, "not-run needs a reason"),
    "unclosed": ("<!-- example: a -->\n```sh\ntrue\n", 2, "code block never closed"),
}


class Convention(unittest.TestCase):
    def test_refused_before_anything_runs(self):
        with tempfile.TemporaryDirectory() as tmp:
            for name, (text, line, message) in CONVENTION_ERRORS.items():
                with self.subTest(name):
                    path = Path(tmp) / f"{name}.md"
                    path.write_text(text)
                    code, out = run(path)
                    self.assertEqual(code, 1, out)
                    self.assertRegex(out, rf"FAIL \S*{name}\.md:{line}: .*{re.escape(message)}")
                    self.assertIn("examples: 0 passed, 1 failed", out)

    def test_other_blocks_need_no_marker(self):
        blocks = "```text\nsdfq query MESH\n```\n\n```c\nint x;\n```\n\n    ```sh\n    indented\n    ```\n"
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "plain.md"
            path.write_text(blocks)
            self.assertEqual(run_examples.read_examples(path), [])


class Masks(unittest.TestCase):
    def check(self, expected, actual, result):
        self.assertIs(run_examples.matches(expected.split("\n"), actual.split("\n")), result,
                      (expected, actual))

    def test_any_and_num(self):
        self.check('{"id":"{{any}}","s":{{num}}}', '{"id":"ab-1","s":5.1e-05}', True)
        self.check('{"id":"{{any}}","s":{{num}}}', '{"id":"ab-1","s":fast}', False)
        self.check("a {{any}}", "a\nb", False)  # within one line only

    def test_lines(self):
        self.check("a\n{{lines}}\nz", "a\nz", True)
        self.check("a\n{{lines}}\nz", "a\n1\n2\nz", True)
        self.check("a\n{{lines}}\nz", "a\n1\n2", False)

    def test_precision(self):
        self.check("{{~0.603}}", "0.6026", True)
        self.check("{{~0.603}}", "0.6035", True)
        self.check("{{~0.603}}", "0.6036", False)
        self.check("{{~0.000000}}", "-2.80593243e-16", True)
        self.check("{{~0.000000}}", "1e-6", False)
        self.check("{{~1.5e-3}}", "0.00154", True)
        self.check("{{~1.5e-3}}", "0.0016", False)

    def test_literal_text_is_not_a_pattern(self):
        self.check("a.b (c)", "axb (c)", False)
        self.check("a.b (c)", "a.b (c)", True)


if __name__ == "__main__":
    unittest.main(verbosity=2)
