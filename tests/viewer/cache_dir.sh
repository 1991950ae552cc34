#!/usr/bin/env bash
# terrain-view --cache-dir (issue 52): an archive by URL from a real nginx, started here on a free
# 127.0.0.1 port with its config and logs in WORK_DIR. The first headless run fills the cache; the
# second draws the same PNG, byte for byte, and sends exactly one request (the open's header probe,
# which learns the file's size and validator: the directory, metadata and payloads come from the
# cache). Requests are counted in nginx's access log.
# Usage: cache_dir.sh TERRAIN_VIEW ARCHIVE WORK_DIR
set -uo pipefail
[ $# -eq 3 ] || { echo "usage: $0 TERRAIN_VIEW ARCHIVE WORK_DIR" >&2; exit 2; }
view=$1 archive=$2 work=$3
fail() { echo "cache_dir: $*" >&2; exit 1; }
nginx=$(command -v nginx || echo /usr/sbin/nginx)
[ -x "$nginx" ] || { echo "nginx is not installed (scripts/setup.sh installs nginx-light): skipped"; exit 0; }
rm -rf "$work"
mkdir -p "$work/www" "$work/tmp" "$work/logs"
cp "$archive" "$work/www/a.terrain"
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
cat >"$work/nginx.conf" <<CONF
worker_processes 1;
pid $work/nginx.pid;
events { worker_connections 64; }
http {
  access_log $work/logs/access.log;
  client_body_temp_path $work/tmp; proxy_temp_path $work/tmp; fastcgi_temp_path $work/tmp;
  uwsgi_temp_path $work/tmp; scgi_temp_path $work/tmp;
  server { listen 127.0.0.1:$port; root $work/www; }
}
CONF
"$nginx" -p "$work" -c "$work/nginx.conf" -e "$work/logs/error.log" -g 'daemon off;' &
server=$!
trap 'kill $server 2>/dev/null; wait $server 2>/dev/null' EXIT
for _ in $(seq 100); do
  (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null && break
  sleep 0.05
done
(exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || fail "nginx does not answer on port $port: $(cat "$work/logs/error.log")"
url="http://127.0.0.1:$port/a.terrain"
requests() { [ -f "$work/logs/access.log" ] && wc -l <"$work/logs/access.log" || echo 0; }
run() {
  "$view" "$url" --headless --size 320x180 --cache-dir "$work/cache" --out "$work/$1.png" >"$work/$1.out" 2>&1
}
run first
rc=$?
if grep -q "no Vulkan device" "$work/first.out"; then echo "no Vulkan device: skipped"; exit 0; fi
[ $rc -eq 0 ] || fail "first run: exit $rc: $(tail -n 3 "$work/first.out")"
first=$(requests)
[ "$first" -gt 3 ] || fail "the first run made $first requests: it did not stream from the server"
run second || fail "second run: exit $?: $(tail -n 3 "$work/second.out")"
second=$(($(requests) - first))
cmp -s "$work/first.png" "$work/second.png" || fail "the two runs drew different images"
[ "$second" -eq 1 ] || fail "the second run made $second requests, expected 1 (the header probe)"
echo "cache_dir: ok (first run $first requests, second $second; the same PNG)"
