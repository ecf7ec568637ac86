#!/usr/bin/env python3
"""Fly one `aeris eval` spread over a Ray cluster, and print the one table of it.

Each of N Ray tasks runs `aeris eval EVAL_ARGS... --shard K/N --out OUT/shard-K-of-N` on
whichever node has the CPUs it asks for; when all are done, `aeris eval merge` of their
folders prints the table one run of those episodes would print (on simulated time,
`--clock sim`, the very same table but for the compute columns, which measure the machines:
the flights do not depend on them).

    scripts/eval-ray.py --shards 8 --out runs/eval-test -- --split test_unseen --episodes 48 --clock sim
    scripts/eval-ray.py --address HEAD:6379 --shards 32 --out /shared/eval -- --split test_unseen ...

Without --address, Ray starts a local cluster on this machine for the run (`ray start --head`
on one machine and `ray start --address HEAD:6379` on the others makes a real one). Every
node must have the `aeris` executable at the path given (--aeris) and see OUT at the same
path (a shared file system), as a Slurm array would need too.

Why Ray: an evaluation is a bag of independent shards, which Ray's tasks (`num_cpus` per
shard, retried on a lost node, scheduled where CPUs are free) express directly; it installs
from PyPI (`pip install ray`, pinned by scripts/setup-test-deps.sh) and runs a local cluster
on one machine, so the launcher is tested by the suite, where a Slurm array could not be.

Security: a Ray cluster runs whatever code its clients send, so it must never be open. The
local cluster this script starts requires Ray's token authentication (RAY_AUTH_MODE=token)
with a fresh random token that lives only in this process's environment and its children's
(no token file is written), and its node is addressed on 127.0.0.1; a RAY_AUTH_MODE other
than `token` is refused. A real cluster (--address) must run with token authentication
itself and sit on a private network (Ray's own guidance); the launcher then uses the
operator's token (RAY_AUTH_TOKEN or ~/.ray/auth_token) and refuses RAY_AUTH_MODE=disabled.
"""

import argparse
import os
import secrets
import socket
import subprocess
import sys
import time
from pathlib import Path


def default_aeris() -> str:
    root = Path(__file__).resolve().parent.parent
    for build in ("release", "debug"):
        exe = root / "target" / build / "aeris"
        if exe.is_file():
            return str(exe)
    return "aeris"


def parse_args(argv):
    p = argparse.ArgumentParser(
        prog="eval-ray.py",
        description="Fly `aeris eval EVAL_ARGS` as N shards on a Ray cluster and print the "
        "merged table (`aeris eval merge`).",
        epilog="Everything after -- goes to `aeris eval` on every shard "
        "(not --shard, --out or --json: the launcher sets them).",
    )
    p.add_argument("--shards", type=int, required=True, metavar="N", help="how many shards (at least 1)")
    p.add_argument("--out", required=True, metavar="DIR", help="the shards' folders go to DIR/shard-K-of-N")
    p.add_argument(
        "--address",
        metavar="HOST:PORT",
        help="a running Ray cluster's head; default: a local cluster started for this run",
    )
    p.add_argument(
        "--cpus-per-shard",
        type=float,
        default=2.0,
        metavar="C",
        help="CPUs Ray reserves for each shard's flights (default 2: the roles of one flight)",
    )
    p.add_argument("--aeris", default=default_aeris(), metavar="PATH", help="the aeris executable on every node")
    p.add_argument("--json", action="store_true", help="print the merged table as JSON on the last line too")
    p.add_argument("eval_args", nargs=argparse.REMAINDER, metavar="-- EVAL_ARGS")
    args = p.parse_args(argv)
    if args.eval_args and args.eval_args[0] == "--":
        args.eval_args = args.eval_args[1:]
    if args.shards < 1:
        p.error(f"--shards {args.shards}: at least 1")
    if args.cpus_per_shard <= 0:
        p.error(f"--cpus-per-shard {args.cpus_per_shard}: must be positive")
    for own in ("--shard", "--out", "--json"):
        if any(a == own or a.startswith(own + "=") for a in args.eval_args):
            p.error(f"{own} is the launcher's to set; leave it out of EVAL_ARGS")
    return args


def fly_shard(aeris, eval_args, k, n, out):
    """One shard: `aeris eval ... --shard K/N --out OUT`, on whichever node Ray chose."""
    started = time.monotonic()
    result = {"shard": k, "out": out, "node": socket.gethostname()}
    try:
        run = subprocess.run(
            [aeris, "eval", *eval_args, "--shard", f"{k}/{n}", "--out", out],
            stdin=subprocess.DEVNULL,
            capture_output=True,
            text=True,
        )
        result.update(returncode=run.returncode, stderr_tail=run.stderr[-4000:])
    except OSError as e:
        # no such executable on this node, or it cannot run
        result.update(returncode=127, stderr_tail=f"cannot run {aeris} on {result['node']}: {e}")
    result["seconds"] = time.monotonic() - started
    return result


def require_token_auth(address, env):
    """Make Ray's token authentication the only way into the cluster; say why not, or None.

    A local cluster gets a fresh token in `env` (inherited by the Ray processes this run
    starts, written to no file); a remote one must already use tokens."""
    mode = env.get("RAY_AUTH_MODE")
    if mode is not None and mode.lower() != "token":
        return (
            f"RAY_AUTH_MODE={mode}: refused; a Ray cluster runs any code a client sends, "
            "so the launcher only uses one with token authentication (unset it, or set `token`)"
        )
    env["RAY_AUTH_MODE"] = "token"
    if address is None:
        env["RAY_AUTH_TOKEN"] = secrets.token_hex(32)
    return None


def main(argv):
    args = parse_args(argv)
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    refusal = require_token_auth(args.address, os.environ)
    if refusal:
        print(f"eval-ray: {refusal}", file=sys.stderr)
        return 2
    import ray  # after the arguments: --help works without Ray installed

    out_root = Path(args.out).resolve()
    out_root.mkdir(parents=True, exist_ok=True)
    # a path (not a bare name looked up on each node's PATH) means the same on every node
    aeris = os.path.abspath(args.aeris) if os.sep in args.aeris else args.aeris
    local = {} if args.address else {"_node_ip_address": "127.0.0.1"}
    ray.init(
        address=args.address, include_dashboard=False, logging_level="warning", log_to_driver=False, **local
    )
    try:
        largest = max((node["Resources"].get("CPU", 0) for node in ray.nodes() if node.get("Alive")), default=0)
        if args.cpus_per_shard > largest:
            print(
                f"eval-ray: --cpus-per-shard {args.cpus_per_shard:g}: the cluster's largest node has "
                f"{largest:g} CPUs, so no shard could ever start",
                file=sys.stderr,
            )
            return 2
        task = ray.remote(fly_shard).options(num_cpus=args.cpus_per_shard, max_retries=1)
        pending = {}
        for k in range(1, args.shards + 1):
            out = str(out_root / f"shard-{k}-of-{args.shards}")
            pending[task.remote(aeris, args.eval_args, k, args.shards, out)] = k
        print(
            f"eval-ray: {args.shards} shard(s) of `aeris eval {' '.join(args.eval_args)}` "
            f"on {ray.cluster_resources().get('CPU', 0):.0f} CPUs of the cluster",
            file=sys.stderr,
        )
        done, failed = [], []
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                k = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except ray.exceptions.RayError as e:
                    # the task itself failed (its node was lost, twice)
                    result = {"shard": k, "returncode": 1, "node": "?", "seconds": 0.0, "stderr_tail": str(e)}
                (done if result["returncode"] == 0 else failed).append(result)
                print(
                    f"eval-ray: shard {result['shard']}/{args.shards} "
                    f"{'done' if result['returncode'] == 0 else 'FAILED (exit %d)' % result['returncode']} "
                    f"on {result['node']} in {result['seconds']:.0f} s "
                    f"({len(done) + len(failed)}/{args.shards})",
                    file=sys.stderr,
                )
    finally:
        ray.shutdown()
    if failed:
        for result in sorted(failed, key=lambda r: r["shard"]):
            print(f"eval-ray: shard {result['shard']} failed; its stderr ends:\n{result['stderr_tail']}", file=sys.stderr)
        print(f"eval-ray: {len(failed)} of {args.shards} shard(s) failed; nothing merged", file=sys.stderr)
        return 1
    folders = [r["out"] for r in sorted(done, key=lambda r: r["shard"])]
    merge = [aeris, "eval", "merge", *folders] + (["--json"] if args.json else [])
    return subprocess.run(merge, stdin=subprocess.DEVNULL).returncode


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
