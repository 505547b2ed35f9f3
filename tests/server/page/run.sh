#!/bin/bash
# run.sh - run the browser test with node's test runner. Its one dependency, puppeteer-core
# (pinned by the committed package-lock.json), is installed into node_modules beside it by
# .ci/deps; without it, or with one installed from another lock file, the test fails here.
set -euo pipefail
cd "$(dirname "$0")"
if ! cmp -s package-lock.json node_modules/.installed-lock.json 2>/dev/null; then
    echo "server_page: tests/server/page/node_modules is missing or was not installed from" \
         "package-lock.json: run .ci/deps (it runs npm ci there)" >&2
    exit 1
fi
exec node --test test_page.mjs
