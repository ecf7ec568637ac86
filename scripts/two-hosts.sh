#!/usr/bin/env bash
# Fly a workflow with roles on a second host, both hosts on this machine: two network
# namespaces joined by a veth pair, each process with a private /dev/shm and iceoryx2 root
# (nothing but the network crosses), `aeris agent` on the ground host, `aeris run` on the
# vehicle. Needs root (ip netns, tc) and a built `aeris` (cargo build -p aeris).
#
#   scripts/two-hosts.sh [--roles reasoning,perception] [--delay MS] [--loss PCT]
#                        [--outside-load N] [--fallback VARIANT] [--cut-at S [--restore-at S]]
#                        [--release] [-- EXTRA aeris run ARGS]
#
# --roles          roles of the default flight moved to the ground host (default: reasoning)
# --delay, --loss  netem on the link, each way (default: none)
# --outside-load N N busy threads outside the flight (`yes`), unpinned, for the loaded figure
# --fallback V     the reasoner's fallback on the vehicle if the link is lost (executor perception)
# --cut-at S       cut the link (ip link set down) S seconds after the start; --restore-at S
#                  brings it back
# --release        use target/release/aeris
# --insecure       a plain TCP link (default: mutual TLS with keys made for the run by
#                  `aeris keys`, as a real deployment's)
# The flight's summary (aeris run --json) is the last line of the output.
set -euo pipefail
cd "$(dirname "$0")/.."

roles=reasoning delay="" loss="" load=0 bin=target/debug/aeris fallback="" cut="" restore="" insecure=""
while [ $# -gt 0 ]; do
  case "$1" in
    --roles) roles=$2; shift 2 ;;
    --delay) delay=$2; shift 2 ;;
    --loss) loss=$2; shift 2 ;;
    --outside-load) load=$2; shift 2 ;;
    --fallback) fallback=$2; shift 2 ;;
    --cut-at) cut=$2; shift 2 ;;
    --restore-at) restore=$2; shift 2 ;;
    --release) bin=target/release/aeris; shift ;;
    --insecure) insecure=1; shift ;;
    --) shift; break ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "two-hosts: unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
[ -x "$bin" ] || { echo "two-hosts: $bin is missing: build it first (cargo build -p aeris)" >&2; exit 1; }
[ "$(id -u)" = 0 ] || { echo "two-hosts: needs root for network namespaces" >&2; exit 1; }
bin=$(realpath "$bin")

tag=$$ v=aeris-v$$ g=aeris-g$$ dir=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  ip netns del "$v" 2>/dev/null || true
  ip netns del "$g" 2>/dev/null || true
  rm -rf "$dir"
}
trap cleanup EXIT
echo "two-hosts: vehicle namespace $v (10.99.0.1), ground namespace $g (10.99.0.2)" >&2
ip netns add "$v"; ip netns add "$g"
ip link add "av$tag" type veth peer name "ag$tag"
ip link set "av$tag" netns "$v"; ip link set "ag$tag" netns "$g"
ip -n "$v" addr add 10.99.0.1/24 dev "av$tag"; ip -n "$g" addr add 10.99.0.2/24 dev "ag$tag"
for ns in "$v" "$g"; do ip -n "$ns" link set lo up; done
ip -n "$v" link set "av$tag" up; ip -n "$g" link set "ag$tag" up
if [ -n "$delay$loss" ]; then
  netem=(netem ${delay:+delay ${delay}ms} ${loss:+loss ${loss}%})
  if ! ip netns exec "$v" tc qdisc add dev "av$tag" root "${netem[@]}"; then
    echo "two-hosts: tc could not add netem: this kernel has no sch_netem (--delay and --loss need it)" >&2
    exit 1
  fi
  ip netns exec "$g" tc qdisc add dev "ag$tag" root "${netem[@]}"
  echo "two-hosts: link ${netem[*]} each way" >&2
fi
private='mount -t tmpfs tmpfs /dev/shm && mkdir -p /tmp/iceoryx2 && mount -t tmpfs tmpfs /tmp/iceoryx2 && exec "$@"'

# the link: keys of a flight CA made for this run (the vehicle's and the ground's), or plain TCP
if [ -n "$insecure" ]; then
  endpoint=tcp/10.99.0.2:7447 host_link='insecure = true' agent_link=(--insecure)
else
  "$bin" keys init "$dir/keys" --days 1 >/dev/null
  "$bin" keys issue "$dir/keys" vehicle --days 1 >/dev/null
  "$bin" keys issue "$dir/keys" ground --address 10.99.0.2 --days 1 >/dev/null
  endpoint=tls/10.99.0.2:7447 host_link="keys = \"$dir/keys/vehicle\""
  agent_link=(--keys "$dir/keys/ground" --flight-host vehicle)
fi

# the default workflow with the chosen roles on executor `gs` of host `ground`
python3 - "$roles" "$fallback" "$endpoint" "$host_link" > "$dir/two-hosts.toml" <<'PY'
import sys
moved = sys.argv[1].split(",")
fallback = sys.argv[2]
text = open("workflows/default.toml").read()
text = text.replace("[executors.perception]",
    f'[hosts.ground]\nendpoint = "{sys.argv[3]}"\n{sys.argv[4]}\n\n[executors.gs]\nhost = "ground"\ncpus = "all"\n\n[executors.perception]', 1)
out, name = [], None
for line in text.splitlines():
    if line.startswith("name = "):
        name = line.split('"')[1]
    if line.startswith("executor = ") and name in moved:
        line = 'executor = "gs"'
        if name == "reasoning" and fallback:
            line += f'\nfallback = "{fallback}"\nfallback_executor = "perception"'
    out.append(line)
print("\n".join(out))
PY

ip netns exec "$g" sh -c "$private" sh "$bin" agent --host ground --listen "$endpoint" \
  "${agent_link[@]}" --run-dir "$dir/agent" > "$dir/agent.log" 2>&1 &
pids+=($!)
for _ in $(seq 100); do grep -q "listening on" "$dir/agent.log" && break; sleep 0.1; done
grep -q "listening on" "$dir/agent.log" || { cat "$dir/agent.log" >&2; exit 1; }
for _ in $(seq "$load"); do yes > /dev/null & pids+=($!); done
[ "$load" -gt 0 ] && echo "two-hosts: $load busy threads outside the flight" >&2
if [ -n "$cut" ]; then
  (sleep "$cut"; echo "two-hosts: cutting the link" >&2; ip -n "$v" link set "av$tag" down
   if [ -n "$restore" ]; then sleep "$(awk "BEGIN{print $restore - $cut}")"; echo "two-hosts: link restored" >&2
     ip -n "$v" link set "av$tag" up; fi) &
  pids+=($!)
fi
ip netns exec "$v" sh -c "$private" sh "$bin" run "$dir/two-hosts.toml" --flight "two-hosts-$tag" \
  --run-dir "$dir/run" --json "$@"
