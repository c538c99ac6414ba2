// Measure a kerf through `kerfmeter serve` (Node 22+; Node 20: --experimental-websocket).
const ws = new WebSocket(process.argv[2] ?? "ws://127.0.0.1:7878/rpc");
const waiting = new Map();
let nextId = 1;
const call = (method, params = {}) => new Promise((resolve, reject) => {
  waiting.set(nextId, (m) => (m.error ? reject(new Error(m.error.message)) : resolve(m.result)));
  ws.send(JSON.stringify({ jsonrpc: "2.0", id: nextId++, method, params }));
});
// Answers go to their caller; notifications (progress, run_started, ...) have no id.
ws.onmessage = (e) => { const m = JSON.parse(e.data); waiting.get(m.id)?.(m); };
ws.onerror = () => { console.error("cannot reach the server"); process.exitCode = 1; };
ws.onopen = async () => {
  const result = await call("run_kerfmeter", { thickness_mm: 3.0, label: "birch-3mm" });
  console.log(`kerf ${result.kerf_um.toFixed(1)} µm`);
  console.log(`last ${(await call("get_kerf_value")).kerf_um.toFixed(1)} µm`);
  ws.close();
};
