#!/bin/bash
# run.sh - install the browser test's one dependency (puppeteer-core, pinned by the committed
# package-lock.json) into node_modules beside it, then run the test with node's test runner.
set -euo pipefail
cd "$(dirname "$0")"
npm ci --no-audit --no-fund --loglevel=error
exec node --test test_page.mjs
