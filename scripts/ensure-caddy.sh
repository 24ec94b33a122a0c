#!/usr/bin/env bash
# Make sure Caddy is installed for the proxy tests (tests/test_proxy.py starts it in front of
# the app with deploy/Caddyfile). If `caddy` is already there, nothing happens; otherwise
# Debian's `caddy` package is installed (version 2.6 or newer: handle_response and local_certs).
set -euo pipefail

if command -v caddy >/dev/null 2>&1; then
    exit 0
fi
"$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" caddy
