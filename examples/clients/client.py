# Measure a kerf through `kerfmeter serve` (needs websockets 13+); argv[1]: the server's /rpc URL.
import asyncio, json, sys
from websockets.asyncio.client import connect

async def call(ws, method, **params):
    await ws.send(json.dumps({"jsonrpc": "2.0", "id": 1, "method": method, "params": params}))
    while "id" not in (reply := json.loads(await ws.recv())):  # skip the progress notifications
        pass
    if "error" in reply:
        raise RuntimeError(reply["error"]["message"])
    return reply["result"]

async def main(url):
    async with connect(url) as ws:
        result = await call(ws, "run_kerfmeter", thickness_mm=3.0, label="birch-3mm")
        print(f"kerf {result['kerf_um']:.1f} µm")
        print(f"last {(await call(ws, 'get_kerf_value'))['kerf_um']:.1f} µm")

asyncio.run(main(sys.argv[1] if len(sys.argv) > 1 else "ws://127.0.0.1:7878/rpc"))
