#!/usr/bin/env bash
# Make sure axe-core, the accessibility checker the browser tests run in each page
# (tests/test_accessibility.py), is installed: the version pinned, with its integrity hash,
# by tests/axe/package.json and package-lock.json, installed with npm into var/node/
# (not committed). If that version is already there, nothing happens.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
pinned="$root/tests/axe"
target="$root/var/node"
want="$(sed -n 's/.*"axe-core": *"\([^"]*\)".*/\1/p' "$pinned/package.json")"
installed="$target/node_modules/axe-core/package.json"

if [[ -f "$installed" && -f "$target/node_modules/axe-core/axe.min.js" ]] \
        && grep -q "\"version\": *\"$want\"" "$installed"; then
    exit 0
fi
if ! command -v npm >/dev/null 2>&1; then
    echo "npm is not installed: the accessibility tests need axe-core $want, which is installed with npm" >&2
    echo "(install Node.js 18 or newer with npm, e.g. apt-get install nodejs npm, then run make test again)" >&2
    exit 1
fi
mkdir -p "$target"
cp "$pinned/package.json" "$pinned/package-lock.json" "$target/"
npm ci --prefix "$target" --no-audit --no-fund --loglevel=error
