#!/usr/bin/env bash
# Make sure a headless-capable Chromium is installed for the browser tests.
#
# The end-to-end tests drive Debian's `chromium` package through Playwright (never a
# downloaded browser). If $CHROMIUM or `chromium` is already there, nothing happens.
set -euo pipefail

if [[ -n "${CHROMIUM:-}" && -x "${CHROMIUM}" ]] || command -v chromium >/dev/null 2>&1; then
    exit 0
fi
"$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" chromium
