// Open-loop load test of GET /api/status: RATE requests/s for SECONDS over one keep-alive
// connection pool, each request timed from its scheduled send to the end of its body.
// Usage: node status_load.mjs URL [RATE=50] [SECONDS=20]   (prints n, median, p90, p99, max in ms)
import http from 'node:http';

const [url, rate = '50', seconds = '20'] = process.argv.slice(2);
const agent = new http.Agent({ keepAlive: true, maxSockets: 4 });
const lat = [];
let errors = 0;
const get = () => new Promise((resolve) => {
  const t0 = process.hrtime.bigint();
  http.get(url, { agent }, (res) => {
    res.resume();
    res.on('end', () => {
      if (res.statusCode !== 200) errors++;
      lat.push(Number(process.hrtime.bigint() - t0) / 1e6);
      resolve();
    });
  }).on('error', () => { errors++; resolve(); });
});
const n = Math.round(Number(rate) * Number(seconds));
const start = Date.now();
const pending = [];
for (let i = 0; i < n; i++) {
  const due = start + (1000 * i) / Number(rate);
  await new Promise((r) => setTimeout(r, Math.max(0, due - Date.now())));
  pending.push(get());
}
await Promise.all(pending);
agent.destroy();
lat.sort((a, b) => a - b);
const q = (p) => lat[Math.min(lat.length - 1, Math.floor(p * lat.length))].toFixed(2);
console.log(JSON.stringify({ requests: lat.length, errors, rate: Number(rate), median_ms: +q(0.5), p90_ms: +q(0.9),
  p99_ms: +q(0.99), max_ms: +lat[lat.length - 1].toFixed(2) }));
