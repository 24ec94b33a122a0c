#!/usr/bin/env bash
# Install Debian/Ubuntu packages with apt-get, as root or through sudo.
#
#   scripts/apt-install.sh PACKAGE...
#
# The package lists may be missing or stale on a fresh machine, so a failed install
# is retried once after `apt-get update`.
set -euo pipefail

say() { echo "apt-install: $*" >&2; }

as_root=()
if [[ "$(id -u)" != 0 ]]; then
    if ! command -v sudo >/dev/null 2>&1; then
        say "installing $* needs root, and there is no sudo here"
        exit 1
    fi
    as_root=(sudo)
fi
apt_get=("${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get -q -y)
say "installing $*"
"${apt_get[@]}" install "$@" >&2 || { "${apt_get[@]}" update >&2 && "${apt_get[@]}" install "$@" >&2; }
