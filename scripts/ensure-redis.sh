#!/usr/bin/env bash
# Make sure a Redis server answers at $REDIS_URL (default redis://127.0.0.1:6379/0).
#
# The Redis tests need a real server. If one already answers, nothing happens.
# Otherwise, for a local address, redis-server is installed from the system's
# packages when missing and started daemonised on 127.0.0.1 with its pidfile,
# log and working folder under var/redis/ (or $STUDYAPP_VAR_DIR/redis/).
# Running it again is harmless.
set -euo pipefail

redis_url="${REDIS_URL:-redis://127.0.0.1:6379/0}"
repo_root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
redis_dir="${STUDYAPP_VAR_DIR:-$repo_root/var}/redis"

# redis[s]://[user:password@]host[:port][/db]
authority="${redis_url#*://}"
authority="${authority##*@}"
authority="${authority%%/*}"
host="${authority%%:*}"
port=6379
if [[ "$authority" == *:* ]]; then
    port="${authority##*:}"
fi

say() { echo "ensure-redis: $*" >&2; }

# A server that demands a password still answers PING with -NOAUTH: it is up.
answers() {
    timeout 2 bash -c "exec 3<>/dev/tcp/$host/$port && printf 'PING\r\n' >&3 && head -c 5 <&3" 2>/dev/null \
        | grep -qE '^(\+PONG|-NOAU)'
}

wait_until_answers() {
    for _ in $(seq 100); do
        answers && return 0
        sleep 0.1
    done
    return 1
}

if answers; then
    say "Redis answers at $host:$port"
    exit 0
fi

case "$host" in
    127.0.0.1|localhost) ;;
    *) say "no Redis answers at $host:$port, and only a local one can be started here"; exit 1 ;;
esac

if ! command -v redis-server >/dev/null 2>&1; then
    "$(dirname "${BASH_SOURCE[0]}")/apt-install.sh" redis-server
    # Some systems start the packaged service on install (before apt-get returns).
    if answers; then
        say "Redis answers at $host:$port (started by the package)"
        exit 0
    fi
fi

mkdir -p "$redis_dir"
say "starting redis-server on 127.0.0.1:$port (log: $redis_dir/redis.log)"
# A throwaway server for development and tests: nothing is persisted.
redis-server --daemonize yes --bind 127.0.0.1 --port "$port" \
    --pidfile "$redis_dir/redis.pid" --logfile "$redis_dir/redis.log" --dir "$redis_dir" \
    --save "" --appendonly no

if wait_until_answers; then
    say "Redis answers at $host:$port"
    exit 0
fi
say "redis-server did not answer within 10 s; the end of its log:"
tail -n 20 "$redis_dir/redis.log" >&2 || true
exit 1
