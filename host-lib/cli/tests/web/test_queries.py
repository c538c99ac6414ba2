"""Queries are answered while a measurement runs (issue 32 §3), by real WebSocket clients (the
`websockets` package): `status` and `get_kerf_value` are never "busy" during a run, answered from
the device's latest poll with its age; calls that write to the device are still refused; and the
run is unharmed by the load (a real-time twin: a late poll would show as a fault)."""

import asyncio

from websockets.asyncio.client import connect

from serve_load import call, load

BUSY = -32001


def test_watchers_are_answered_during_a_run_and_the_run_is_unharmed(server):
    replies, tally = asyncio.run(load(server.rpc_url, clients=10, hz=20, runs=1))
    assert "result" in replies[0], f"{replies[0]}\nserver:\n{server.log()}"
    kerf_um = replies[0]["result"]["kerf_um"]
    assert 100 < kerf_um < 200, kerf_um
    summary = tally.summary()
    assert tally.errors == [], f"{tally.errors[:5]} {summary}"
    # The run took long enough (real time) that many answers came from its polls.
    assert summary["answered_from_polls"] > 20, summary


def test_a_call_that_writes_is_refused_during_a_run_and_reads_carry_their_age(server):
    async def scenario():
        async with connect(server.rpc_url) as runner, connect(server.rpc_url) as other:
            run = asyncio.create_task(call(runner, "run_kerfmeter"))
            status = None
            for _ in range(200):
                status = (await call(other, "status"))["result"]
                if "poll_age_ms" in status:
                    break
                await asyncio.sleep(0.02)
            assert "poll_age_ms" in status, status
            assert status["poll_age_ms"] < 1000, status
            assert status["state"] != "idle", status
            refused = await call(other, "clear_fault")
            info = await call(other, "info")
            finished = await run
            return refused, info, finished

    refused, info, finished = asyncio.run(scenario())
    assert refused["error"]["code"] == BUSY, refused
    assert "poll_age_ms" in info["result"], info
    assert "result" in finished, finished
