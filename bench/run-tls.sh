#!/usr/bin/env bash
# POST /api/stop over TLS (issue 19): the bundled sim robot with runtime.listen.tls (a throwaway CA and a P-256
# certificate for 127.0.0.1 made here with openssl), stops on one kept-alive TLS connection, then each on a fresh
# connection with a full handshake, then the same robot's loopback plain port for comparison.
#   bench/run-tls.sh [build-dir]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
port=18640
plain=18641
token=rcand-dev-owner
work=$(mktemp -d)
pid=
trap '[ -n "$pid" ] && { kill $pid 2>/dev/null || true; wait $pid 2>/dev/null || true; }; rm -rf "$work"' EXIT

ossl() { openssl "$@" 2>/dev/null; }
ossl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout "$work/ca.key" -out "$work/ca.pem" -days 2 \
  -subj "/CN=rcand bench CA" -addext basicConstraints=critical,CA:TRUE -addext keyUsage=critical,keyCertSign,cRLSign
ossl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -keyout "$work/robot.key" -out "$work/robot.csr" -subj /CN=localhost
printf 'subjectAltName=IP:127.0.0.1,DNS:localhost\nextendedKeyUsage=serverAuth\n' >"$work/robot.ext"
ossl x509 -req -in "$work/robot.csr" -CA "$work/ca.pem" -CAkey "$work/ca.key" -CAcreateserial -out "$work/robot.pem" \
  -days 2 -extfile "$work/robot.ext"
chmod 600 "$work/robot.key" "$work/ca.key"

# The bundled sim robot, rate limits off (this measures the server), TLS on its port, plain HTTP on loopback beside it.
sed -e '/^runtime:/a\  rate_limit: {per_principal_per_s: 0, per_address_per_s: 0}' \
    -e "/^  listen:/a\\    plain_loopback_port: $plain\n    tls: {cert_file: $work/robot.pem, key_file: $work/robot.key}" \
    config/sim-rover.rcan.yaml >"$work/robot.rcan.yaml"
cp config/dev-jwt.secret "$work/"
chmod 600 "$work/dev-jwt.secret"
"$build/kernel/rcand" --config "$work/robot.rcan.yaml" --plugin-path "$build/plugins" --port $port >"$work/out" 2>"$work/err" &
pid=$!
until grep -q "listening on http://" "$work/out"; do kill -0 $pid; sleep 0.05; done

echo "== POST /api/stop over TLS, one kept-alive connection =="
"$build/bench/bench_stop_latency" $port rcand-dev-guest 3000 keepalive $token "$work/ca.pem"
echo "== POST /api/stop over TLS, each on a fresh connection (TCP + TLS handshake + stop) =="
"$build/bench/bench_stop_latency" $port rcand-dev-guest 1000 fresh $token "$work/ca.pem"
echo "== the same robot's loopback plain port, one kept-alive connection =="
"$build/bench/bench_stop_latency" $plain rcand-dev-guest 3000 keepalive $token

# A handshake flood (4 openssl s_time loops, each a new full handshake after another) against the TLS port: the
# handshakes run on the HTTP worker threads, never on the accept thread that reads the loopback port's stops.
echo "== during a TLS handshake flood: stops on the loopback plain port, each on a fresh connection =="
flood=()
for _ in 1 2 3 4; do
  openssl s_time -connect 127.0.0.1:$port -new -time 15 -CAfile "$work/ca.pem" >"$work/flood.$_" 2>&1 &
  flood+=($!)
done
sleep 1
"$build/bench/bench_stop_latency" $plain rcand-dev-guest 3000 fresh $token
echo "== during the flood: stops over TLS, one kept-alive connection =="
"$build/bench/bench_stop_latency" $port rcand-dev-guest 3000 keepalive $token "$work/ca.pem"
for p in "${flood[@]}"; do wait $p 2>/dev/null || true; done
echo "flood: $(grep -h "real seconds" "$work"/flood.* | awk '{n += $1} END {print n}') handshakes in 15 s (4 loops)"
