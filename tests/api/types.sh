#!/bin/sh
# types.sh - generate TypeScript types from docs/openapi.yaml with openapi-typescript and
# compile compat.ts against them and the JS client's index.d.ts (tsc --noEmit, strict): a
# disagreement is a compile error. Both tools are tests/api/package-lock.json's, installed
# into node_modules by .ci/deps (npm ci); nothing is fetched here. The generated file lives
# in a temporary directory.
set -eu
here=$(cd "$(dirname "$0")" && pwd)
for tool in openapi-typescript tsc; do
    if [ ! -x "$here/node_modules/.bin/$tool" ]; then
        echo "types.sh: $here/node_modules/.bin/$tool is missing: run .ci/deps" >&2
        exit 1
    fi
done
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Tuples from minItems/maxItems; a default does not make a request's key required.
"$here/node_modules/.bin/openapi-typescript" "$here/../../docs/openapi.yaml" \
    -o "$tmp/openapi.d.ts" --array-length --default-non-nullable false
cat >"$tmp/tsconfig.json" <<JSON
{
  "compilerOptions": {
    "strict": true, "noEmit": true, "target": "es2022", "module": "esnext",
    "moduleResolution": "bundler", "lib": ["es2022", "dom"], "types": [],
    "paths": {"sdfd-openapi": ["$tmp/openapi.d.ts"]}
  },
  "files": ["$here/compat.ts"]
}
JSON
"$here/node_modules/.bin/tsc" -p "$tmp/tsconfig.json"
echo "types.sh: clients/js/src/index.d.ts agrees with docs/openapi.yaml"
