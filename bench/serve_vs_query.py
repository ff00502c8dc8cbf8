#!/usr/bin/env python3
"""A served text question against `slamvdb query` per call, on the same map (issue 21, "Speed":
compare against today's `slamvdb query` per call, load included, and report the ratio).

Times whole processes, so it is a script rather than a Google Benchmark: N distinct text questions
(top 100) are asked of one `slamvdb serve MAP --port 0` over loopback (Python's http.client, one
keep-alive connection), and M of them through `slamvdb query MAP --text T --top-k 100 -o X.csv`
(process start, map load and encoder set-up included). Reported per question: wall time, and CPU
time (the server's from /proc/PID/stat, the commands' from getrusage(RUSAGE_CHILDREN)), since wall
time is noisy on a shared machine; and the load average at the time.

usage: bench/serve_vs_query.py --cli build/slamvdb --map MAP.svdb [--served 150] [--commands 8]
Without --map: `slamvdb demo --length 60` makes one in a temporary folder (the issue's demo map).
"""
import argparse
import http.client
import itertools
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

WORDS = ["grass", "dirt", "tree", "bush", "asphalt", "concrete", "mud", "rubble", "fence", "pole", "log",
         "building", "vehicle", "barrier", "puddle", "water", "person", "sky"]


def texts(n):
    """n distinct questions: single words, then pairs (no cache can answer one from another)."""
    all_texts = WORDS + [f"{a} and {b}" for a, b in itertools.combinations(WORDS, 2)]
    if n > len(all_texts):
        sys.exit(f"at most {len(all_texts)} distinct questions")
    return all_texts[:n]


def cpu_seconds_of(pid):
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime + stime


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cli", default="build/slamvdb")
    ap.add_argument("--map")
    ap.add_argument("--served", type=int, default=150, help="questions asked of the server")
    ap.add_argument("--commands", type=int, default=8, help="questions asked through `slamvdb query`")
    args = ap.parse_args()
    work = tempfile.mkdtemp(prefix="serve_vs_query.")
    map_path = args.map
    if not map_path:
        subprocess.run([args.cli, "demo", "--length", "60", "-o", work], check=True, stdout=subprocess.DEVNULL)
        found = [os.path.join(root, f) for root, _, files in os.walk(work) for f in files if f.endswith(".svdb")]
        if not found:
            sys.exit(f"slamvdb demo wrote no .svdb in {work}")
        map_path = sorted(found)[0]
    questions = texts(max(args.served, args.commands))
    load_before = os.getloadavg()

    # The server: started once, its load not counted (it is paid once per robot, not per question).
    server = subprocess.Popen([args.cli, "serve", map_path, "--port", "0", "--rate-limit", "0"],
                              stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    port = None
    for line in server.stdout:
        if "://" in line:
            port = int(line.split("://", 1)[1].split("/", 1)[0].rsplit(":", 1)[1])
            break
    if port is None:
        sys.exit("slamvdb serve printed no address")
    conn = http.client.HTTPConnection("127.0.0.1", port)
    conn.request("GET", "/healthz")
    health = json.loads(conn.getresponse().read())
    cpu0 = cpu_seconds_of(server.pid)
    t0 = time.perf_counter()
    served_rows = None
    for text in questions[:args.served]:
        conn.request("POST", "/api/query", json.dumps({"text": text, "top_k": 100}), {"Content-Type": "application/json"})
        res = conn.getresponse()
        body = res.read()
        if res.status != 200:
            sys.exit(f"{text}: HTTP {res.status} {body[:200]!r}")
        served_rows = served_rows if served_rows is not None else json.loads(body)["count"]
    served_wall = (time.perf_counter() - t0) / args.served
    served_cpu = (cpu_seconds_of(server.pid) - cpu0) / args.served
    server.terminate()
    server.wait()

    usage0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    out = os.path.join(work, "query.csv")
    for text in questions[:args.commands]:
        subprocess.run([args.cli, "query", map_path, "--text", text, "--top-k", "100", "-o", out], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    command_wall = (time.perf_counter() - t0) / args.commands
    usage1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    command_cpu = ((usage1.ru_utime - usage0.ru_utime) + (usage1.ru_stime - usage0.ru_stime)) / args.commands
    load_after = os.getloadavg()

    print(f"map: {map_path} ({health['semantic_cells']} semantic voxels, ANN index: {health['index']})")
    print(f"load average before / after: {load_before[0]:.1f} / {load_after[0]:.1f} on {os.cpu_count()} cores")
    print("| per text question (top 100) | wall ms | CPU ms |")
    print("|---|---:|---:|")
    print(f"| served (POST /api/query, {args.served} distinct texts) | {served_wall * 1e3:.2f} | {served_cpu * 1e3:.2f} |")
    print(f"| `slamvdb query` per call ({args.commands} texts, load included) | {command_wall * 1e3:.1f} | {command_cpu * 1e3:.1f} |")
    print(f"| ratio (query / served) | {command_wall / served_wall:.0f} x | "
          f"{command_cpu / served_cpu if served_cpu > 0 else float('inf'):.0f} x |")


if __name__ == "__main__":
    main()
