"""Many WebSocket clients watch the device while another measures: the load of issue 32 §3.

Each watcher polls `status` and `get_kerf_value` in turn at a fixed rate over its own
connection (the `websockets` package: a client nobody on this project wrote); one more client
measures with `run_kerfmeter`. Every call's latency is timed; a refused call ("busy") or any
other error is counted. Used by `test_queries.py` (a smaller load, asserted) and by
`cargo xtask bench-serve` (the full load, printed: a benchmark, not a timed test).

    python serve_load.py ws://127.0.0.1:7878/rpc --clients 40 --hz 50 --runs 1
"""

import argparse
import asyncio
import itertools
import json
import statistics
import sys
import time

from websockets.asyncio.client import connect

_ids = itertools.count(1)


async def call(ws, method, **params):
    """One JSON-RPC call: its reply (result or error), skipping notifications."""
    request_id = next(_ids)
    await ws.send(json.dumps({"jsonrpc": "2.0", "id": request_id, "method": method, "params": params}))
    while True:
        reply = json.loads(await ws.recv())
        if reply.get("id") == request_id:
            return reply


class Tally:
    """What the watchers saw."""

    def __init__(self):
        self.latencies_ms = []
        self.errors = []
        self.from_polls = 0

    def summary(self):
        ordered = sorted(self.latencies_ms)
        if not ordered:
            return {"calls": 0, "errors": len(self.errors)}
        p99 = ordered[min(len(ordered) - 1, int(0.99 * len(ordered)))]
        return {
            "calls": len(ordered),
            "answered_from_polls": self.from_polls,
            "errors": len(self.errors),
            "p50_ms": round(statistics.median(ordered), 2),
            "p99_ms": round(p99, 2),
            "max_ms": round(ordered[-1], 2),
        }


async def watch(url, hz, stop, tally):
    """Poll status and get_kerf_value in turn at `hz` until `stop` is set."""
    period_s = 1.0 / hz
    async with connect(url, max_queue=None) as ws:
        for method in itertools.cycle(["status", "get_kerf_value"]):
            if stop.is_set():
                return
            started = time.perf_counter()
            reply = await call(ws, method)
            tally.latencies_ms.append((time.perf_counter() - started) * 1000.0)
            if "error" in reply:
                tally.errors.append((method, reply["error"]))
            elif isinstance(reply.get("result"), dict) and "poll_age_ms" in reply["result"]:
                tally.from_polls += 1
            await asyncio.sleep(max(0.0, period_s - (time.perf_counter() - started)))


async def measure(url, runs):
    """`runs` measurements; each run's reply (result or error)."""
    replies = []
    async with connect(url, max_queue=None) as ws:
        for _ in range(runs):
            replies.append(await call(ws, "run_kerfmeter", label="load"))
    return replies


async def load(url, clients, hz, runs):
    """Measure `runs` times while `clients` watchers poll at `hz`; the runs' replies and the
    watchers' tally."""
    stop = asyncio.Event()
    tally = Tally()
    watchers = [asyncio.create_task(watch(url, hz, stop, tally)) for _ in range(clients)]
    await asyncio.sleep(0.5 if clients else 0)
    try:
        replies = await measure(url, runs)
    finally:
        stop.set()
        await asyncio.gather(*watchers)
    return replies, tally


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("url")
    parser.add_argument("--clients", type=int, default=40)
    parser.add_argument("--hz", type=float, default=50.0)
    parser.add_argument("--runs", type=int, default=1)
    args = parser.parse_args()
    replies, tally = asyncio.run(load(args.url, args.clients, args.hz, args.runs))
    kerfs = [r["result"]["kerf_um"] for r in replies if "result" in r]
    failed = [r["error"] for r in replies if "error" in r]
    report = {"clients": args.clients, "hz": args.hz, "kerf_um": kerfs, "run_errors": failed}
    report.update(tally.summary())
    print(json.dumps(report))
    return 1 if failed or tally.errors else 0


if __name__ == "__main__":
    sys.exit(main())
