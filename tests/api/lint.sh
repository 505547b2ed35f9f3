#!/bin/sh
# lint.sh - lint docs/openapi.yaml with @redocly/cli's recommended rules, every warning raised to
# an error (redocly.yaml). The linter is the one tests/api/package-lock.json pins, installed
# into node_modules beside this file by .ci/deps (npm ci): nothing is fetched here, and the
# CLI's telemetry and update check are off. It runs on the Node.js node.sh picks (the linter
# needs 20.19 or later).
set -eu
cd "$(dirname "$0")"
bin=node_modules/.bin/redocly
if [ ! -x "$bin" ]; then
    echo "lint.sh: $PWD/$bin is missing: run .ci/deps (it runs npm ci in tests/api)" >&2
    exit 1
fi
node=$(./node.sh)
REDOCLY_TELEMETRY=off REDOCLY_SUPPRESS_UPDATE_NOTICE=true \
    exec "$node" "$bin" lint --config redocly.yaml --format=stylish ../../docs/openapi.yaml
