"""apicheck.py - every HTTP answer a test receives, checked against docs/openapi.yaml.

install() wraps http.client.HTTPConnection (so also HTTPSConnection, urllib.request and the
Python client, which all send through it): each request's method and path are noted, and
each response is matched to the document's operation by path template and method, then
checked. Its status must be one the operation documents; its Content-Type one documented
for that status; every header that response documents must be present with a value its
schema allows (sdfd sends each one it documents); a JSON body must be valid against the
response's schema (JSON Schema 2020-12, which OpenAPI 3.1's schemas are) and a body the
document gives no content must be empty. A JSON body is read whole for the check and handed
back to the caller unread, so callers see the response as the server sent it. A method a
documented path lacks must be answered 405 with the error body and an `Allow` header
listing exactly the document's methods; a path no template matches, 404 `ENOTFOUND`.

A violation raises ApiViolation (an AssertionError, so the test fails) from getresponse(),
and is kept in `violations`, which harness.Server.stop() reports as well: one raised on a
test's worker thread, or caught by the code under test, still fails the test.

With SDF_APICHECK_LOG=FILE, each checked answer's method, path template, status and type
is appended to FILE (which operations and statuses the tests reach).

Standard library, python3-yaml and python3-jsonschema (Debian's)."""
import http.client
import io
import json
import os
import re
import urllib.parse

import jsonschema
import yaml

DOCUMENT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "docs",
                        "openapi.yaml")
METHODS = ("get", "put", "post", "delete", "options", "head", "patch", "trace")


class ApiViolation(AssertionError):
    """A response that the document does not describe."""


def load(path=DOCUMENT):
    with open(path, encoding="utf-8") as f:
        return yaml.safe_load(f)


def media_type(value):
    """'Application/JSON ; charset=x' -> 'application/json; charset=x' (for comparing)."""
    parts = [p.strip() for p in (value or "").split(";")]
    return "; ".join([parts[0].lower()] + [p for p in parts[1:] if p])


class Document:
    """An OpenAPI document's paths, matched and checked (see the module's comment)."""

    def __init__(self, doc):
        self.doc = doc
        self._validators = {}
        self.templates = []
        for template, item in doc["paths"].items():
            pattern = re.sub(r"\\\{[^}]*\\\}", "[^/]*", re.escape(template))
            self.templates.append((re.compile(pattern + r"\Z"), template, item))

    def resolve(self, node):
        while isinstance(node, dict) and "$ref" in node:
            at = self.doc
            for part in node["$ref"].lstrip("#/").split("/"):
                at = at[part]
            node = at
        return node

    def match(self, path):
        """(template, path item) of a request path (its query string removed, %-decoded as
        sdfd decodes it: every %HH but %00), or (None, None)."""
        path = path.split("?", 1)[0].split("#", 1)[0]
        if "://" in path:  # an absolute-form target
            path = urllib.parse.urlsplit(path).path or "/"
        path = urllib.parse.unquote_to_bytes(path.replace("%00", "%2500")).decode("latin-1")
        for pattern, template, item in self.templates:
            if pattern.match(path):
                return template, item
        return None, None

    def validate(self, schema, instance):
        """jsonschema's errors for instance against a schema of the document, as text."""
        key = id(schema)
        if key not in self._validators:
            # The root carries the document's components, so '#/components/...' resolves
            # within it whatever jsonschema version reads it.
            root = dict(schema, components=self.doc["components"])
            self._validators[key] = jsonschema.Draft202012Validator(root)
        errors = sorted(self._validators[key].iter_errors(instance), key=lambda e: e.path)
        return [f"{'/'.join(map(str, e.absolute_path)) or '(top)'}: {e.message[:300]}"
                for e in errors[:5]]

    def check(self, method, target, status, headers, body):
        """Everything wrong with one response, as sentences (empty: it is documented).
        headers: a case-insensitive mapping (an http.client.HTTPMessage); body: the bytes
        of a JSON body, or None when it was not read (not JSON, or a HEAD)."""
        template, item = self.match(target)
        if item is None:
            return self._check_no_route(status, headers, body)
        op = item.get(method.lower())
        if op is None:
            return self._check_no_method(item, status, headers, body)
        response = op["responses"].get(str(status))
        if response is None:
            return [f"status {status} is not documented for {method} {template}"]
        response = self.resolve(response)
        problems = self._check_headers(response, headers)
        content = response.get("content")
        if method == "HEAD":
            return problems
        if not content:
            if body or int(headers.get("Content-Length") or 0):
                problems.append(f"{status} has a body; the document gives it none")
            return problems
        ctype = media_type(headers.get("Content-Type"))
        kinds = {media_type(k): v for k, v in content.items()}
        if ctype not in kinds:
            return problems + [f"{status} Content-Type {ctype!r} is not documented "
                               f"({', '.join(sorted(kinds))})"]
        if body is not None:
            problems += self._check_json(kinds[ctype].get("schema", {}), body)
        return problems

    def _check_headers(self, response, headers):
        problems = []
        for name, header in response.get("headers", {}).items():
            header = self.resolve(header)
            value = headers.get(name)
            if value is None:
                problems.append(f"header {name} is missing")
                continue
            schema = header.get("schema", {})
            if self.resolve(schema).get("type") == "integer":
                try:
                    value = int(value)
                except ValueError:
                    problems.append(f"header {name}: {value!r} is not an integer")
                    continue
            problems += [f"header {name}: {e}" for e in self.validate(schema, value)]
        return problems

    def _check_json(self, schema, body):
        try:
            instance = json.loads(body)
        except ValueError as e:
            return [f"the body is not JSON ({e}): {body[:200]!r}"]
        return [f"body {e}" for e in self.validate(schema, instance)]

    def _error_body(self, status, headers, body, code):
        if media_type(headers.get("Content-Type")) != "application/json":
            return [f"{status} is not a JSON error body"]
        if body is None:
            return []
        problems = self._check_json({"$ref": "#/components/schemas/Error"}, body)
        if not problems and json.loads(body)["error"]["code"] != code:
            problems.append(f"{status} has code {json.loads(body)['error']['code']}, not {code}")
        return problems

    def _check_no_route(self, status, headers, body):
        if status != 404:
            return [f"no documented path matches, yet the status is {status}, not 404"]
        return self._error_body(status, headers, body, "ENOTFOUND")

    def _check_no_method(self, item, status, headers, body):
        if status != 405:
            return [f"the method is not documented for this path, yet the status is {status}"]
        documented = {m.upper() for m in METHODS if m in item}
        allow = {m.strip() for m in (headers.get("Allow") or "").split(",") if m.strip()}
        problems = [] if allow == documented else [
            f"405's Allow is {sorted(allow)}; the document has {sorted(documented)}"]
        return problems + self._error_body(status, headers, body, "EMETHOD")


_document = None
violations = []
LOG = os.environ.get("SDF_APICHECK_LOG")  # a file to note each checked answer in, if set


def document():
    global _document
    if _document is None:
        _document = Document(load())
    return _document


def use(doc):
    """Check against `doc` (a Document) from now on; returns the one used until now."""
    global _document
    old, _document = _document, doc
    return old


def _read_json(resp, method):
    """The body of a JSON response, read whole and put back for the caller; else None."""
    if method == "HEAD" or media_type(resp.getheader("Content-Type")) != "application/json":
        return None
    body = resp.read()
    resp.fp = io.BytesIO(body)  # read() serves it again from here, then closes it
    resp.length, resp.chunked = len(body), False
    return body


def _checked_getresponse(original):
    def getresponse(self):
        resp = original(self)
        method, target = getattr(self, "_apicheck_request", (None, None))
        if method is None:
            return resp
        body = _read_json(resp, method)
        doc = document()
        problems = doc.check(method, target, resp.status, resp.headers, body)
        if LOG:
            with open(LOG, "a", encoding="utf-8") as f:
                f.write(f"{method} {doc.match(target)[0]} {resp.status} "
                        f"{media_type(resp.getheader('Content-Type'))}\n")
        if problems:
            text = (f"{method} {target} answered {resp.status}, which docs/openapi.yaml does "
                    "not describe:\n  " + "\n  ".join(problems))
            if body:
                text += f"\n  body: {body[:500]!r}"
            violations.append(text)
            raise ApiViolation(text)
        return resp
    return getresponse


def _noting_putrequest(original):
    def putrequest(self, method, url, *args, **kwargs):
        self._apicheck_request = (method, url)
        return original(self, method, url, *args, **kwargs)
    return putrequest


def install():
    """Check every response received through http.client from now on (once per process)."""
    conn = http.client.HTTPConnection
    if getattr(conn, "_apicheck_installed", False):
        return
    conn.putrequest = _noting_putrequest(conn.putrequest)
    conn.getresponse = _checked_getresponse(conn.getresponse)
    conn._apicheck_installed = True


def take_violations():
    """The violations seen since the last call (and forget them)."""
    out = violations[:]
    del violations[:]
    return out
