// A stand-in for cslam-server's HTTP API (node:http, no dependencies) for the viewer's browser tests
// and measurements: serves web/ like the real server (/, /index.html, /<module>.js, /vendor/three.module.js)
// and the dense-map routes of the contract (/api/dense/*) over synthetic submaps (UV spheres, CSM1),
// plus minimal /api/status, /api/clients/{id}, /api/fusion/events, /api/trajectories, /api/map/points.
// Test controls (POST, not part of the contract): /mock/move?id=&dx=  (pose-only change),
// /mock/corrupt?id=&mode=truncate|magic|index|404|reset  (new geometry version served broken),
// /mock/heal?id=, /mock/add?client=[&mode=...], /mock/remove?id=, /mock/fuse  (group 3 joins group 1),
// /mock/track?client=&state=lost; GET /mock/state (index, mesh requests per submap).
// Usage: node mock_dense_server.mjs --web DIR [--port 0] [--port-file F] [--token T]
//        [--clients 3] [--submaps 4] [--triangles 2000] [--tick-ms 0]
import http from 'node:http';
import { readFileSync, writeFileSync, existsSync, renameSync } from 'node:fs';
import path from 'node:path';

const arg = (k, d) => { const i = process.argv.indexOf(`--${k}`); return i > 0 ? process.argv[i + 1] : d; };
const web = path.resolve(arg('web', 'web'));
const cfg = { port: Number(arg('port', 0)), token: arg('token', ''), clients: Number(arg('clients', 3)),
  submaps: Number(arg('submaps', 4)), triangles: Number(arg('triangles', 2000)), tickMs: Number(arg('tick-ms', 0)) };
const start = Date.now();

// ---- the synthetic map ----
// Clients 1..n; client 3 starts in its own group until /mock/fuse. Submap k of client c sits on a grid.
const state = { version: 1, events: [], tracking: {}, meshRequests: {}, broken: {}, submaps: new Map() };
const groupOf = (client) => (client === 3 && !state.fused ? 3 : 1);
function addSubmap(client) {
  const k = [...state.submaps.values()].filter((s) => s.client === client).length;
  const id = (client << 16) | k;
  const T = [1.2 * (k % 6), 0.9 * (client - 1), 1.2 * Math.floor(k / 6), 0, 0, 0, 1];
  state.submaps.set(id, { id, client, version: 1, pose_version: 1, T, keyframes: 5 });
  state.version += 1;
  return id;
}
for (let c = 1; c <= cfg.clients; c++) for (let k = 0; k < cfg.submaps; k++) addSubmap(c);

// CSM1 (see the contract; written here independently of the page's decoder in web/csm1.js).
function encodeCsm1(version, pos, col, idx) {
  const nv = pos.length / 3, nt = idx.length / 3, colBytes = (3 * nv + 3) & ~3;
  const b = Buffer.alloc(16 + 12 * nv + colBytes + 12 * nt);
  b.write('CSM1', 0, 'latin1');
  b.writeUInt32LE(version, 4);
  b.writeUInt32LE(nv, 8);
  b.writeUInt32LE(nt, 12);
  let o = 16;
  for (const v of pos) { b.writeFloatLE(v, o); o += 4; }
  for (const c of col) b.writeUInt8(c, o++);
  o = 16 + 12 * nv + colBytes;
  for (const i of idx) { b.writeUInt32LE(i, o); o += 4; }
  return b;
}

// A UV sphere of ~`triangles` triangles (radius 0.45), coloured by its normal and the client.
const meshCache = new Map();
function sphere(triangles, client) {
  const key = `${triangles}/${client}`;
  if (meshCache.has(key)) return meshCache.get(key);
  const n = Math.max(2, Math.round(Math.sqrt(triangles / 4))), m = 2 * n;
  const pos = [], col = [], idx = [];
  const tint = [[255, 90, 90], [90, 255, 90], [90, 140, 255], [255, 180, 60]][(client - 1) % 4];
  for (let i = 0; i <= n; i++) {
    for (let j = 0; j <= m; j++) {
      const th = Math.PI * i / n, ph = 2 * Math.PI * j / m;
      const x = Math.sin(th) * Math.cos(ph), y = Math.cos(th), z = Math.sin(th) * Math.sin(ph);
      pos.push(0.45 * x, 0.45 * y, 0.45 * z);
      col.push(...tint.map((t) => Math.round(t * (0.6 + 0.4 * (0.5 + 0.5 * y)))));
    }
  }
  for (let i = 0; i < n; i++) {
    for (let j = 0; j < m; j++) {
      const a = i * (m + 1) + j, b = a + m + 1;
      idx.push(a, b, a + 1, a + 1, b, b + 1);
    }
  }
  const buf = encodeCsm1(0, pos, col, idx);
  meshCache.set(key, buf);
  return buf;
}

function meshBody(s, lod) {
  const base = Buffer.from(sphere(Math.max(8, cfg.triangles / 4 ** lod), s.client));
  const body = Buffer.from(base);  // a copy: the version goes into the header
  body.writeUInt32LE(s.version, 4);
  const mode = state.broken[s.id];
  if (mode === 'truncate') return body.subarray(0, Math.floor(body.length / 2));
  if (mode === 'magic') { body.write('XXXX', 0, 'latin1'); return body; }
  if (mode === 'index') { body.writeUInt32LE(0xffffff, body.length - 4); return body; }
  return body;
}

function index() {
  const groups = new Map();
  for (const s of state.submaps.values()) {
    const G = groupOf(s.client);
    if (!groups.has(G)) groups.set(G, { group: G, clients: [], submaps: [] });
    const g = groups.get(G);
    if (!g.clients.includes(s.client)) g.clients.push(s.client);
    const t = Math.max(8, cfg.triangles);
    g.submaps.push({ id: s.id, client: s.client, version: s.version, pose_version: s.pose_version, T_world_submap: s.T,
      keyframes: s.keyframes, vertices: Math.round(t / 2), triangles: t, mesh_url: `/api/dense/submaps/${s.id}/mesh.bin` });
  }
  return { version: state.version, groups: [...groups.values()].sort((a, b) => a.group - b.group) };
}

// Hamilton product a * b, quaternions [x, y, z, w].
const qmul = ([ax, ay, az, aw], [bx, by, bz, bw]) => [aw * bx + ax * bw + ay * bz - az * by,
  aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz];
function movePose(s, dx, yaw) {
  const q = qmul([0, Math.sin(yaw / 2), 0, Math.cos(yaw / 2)], s.T.slice(3));
  s.T = [s.T[0] + dx, s.T[1], s.T[2] + dx / 2, ...q];
  s.pose_version += 1;
  state.version += 1;
}

function clientsJson() {
  const t = (Date.now() - start) / 1000;
  return [...new Set([...state.submaps.values()].map((s) => s.client))].sort().map((c) => {
    const last = [...state.submaps.values()].filter((s) => s.client === c).at(-1);
    return { id: c, name: `robot${c}`, connection: 'streaming', tracking: state.tracking[c] || 'tracking',
      frames_received: Math.round(30 * t), frames_processed: Math.round(30 * t), frames_dropped: 0, fps: 30, keyframes: 10,
      map_points: 100, group: groupOf(c), last_timestamp: t,
      pose: { timestamp: t, position: [last.T[0] + 0.3 * Math.sin(t), last.T[1] - 0.2, last.T[2] - 0.8], quaternion: [0, 0, 0, 1] } };
  });
}

function statusJson() {
  const clients = clientsJson(), groups = {};
  for (const c of clients) (groups[c.group] ||= []).push(c.id);
  return { server: 'cslam-mock', version: 'mock', uptime_s: (Date.now() - start) / 1000, generation: 1, clients,
    groups: Object.entries(groups).map(([g, ids]) => [Number(g), ids]), fusion_events: state.events.length };
}

function pointsBin() {
  const subs = [...state.submaps.values()], buf = Buffer.alloc(16 * subs.length * 8);
  let o = 0;
  for (const s of subs) for (let k = 0; k < 8; k++) {
    buf.writeFloatLE(s.T[0] + 0.6 * Math.cos(k), o);
    buf.writeFloatLE(s.T[1] - 0.5, o + 4); buf.writeFloatLE(s.T[2] + 0.6 * Math.sin(k), o + 8);
    buf.writeUInt8(200, o + 12); buf.writeUInt8(200, o + 13); buf.writeUInt8(200, o + 14); buf.writeUInt8(s.client, o + 15);
    o += 16;
  }
  return buf;
}

function occupancyJson(G) {
  const W = 40, H = 30, cells = Buffer.alloc(W * H);
  for (let j = 0; j < H; j++) for (let i = 0; i < W; i++) cells.writeInt8(i === 0 || j === 0 || i === W - 1 || j === H - 1 ? 100 : (i + j) % 7 === 0 ? -1 : 0, j * W + i);
  const s = Math.SQRT1_2;
  return { group: G, resolution: 0.1, width: W, height: H, T_world_grid: [-0.5, 1.2, -0.5, s, 0, 0, s], data: cells.toString('base64') };
}

// ---- HTTP ----
const send = (res, code, body, type = 'application/json', extra = {}) => {
  const b = typeof body === 'string' || Buffer.isBuffer(body) ? body : JSON.stringify(body);
  res.writeHead(code, { 'Content-Type': type, 'Cache-Control': 'no-store', ...extra });
  res.end(b);
};
const conditional = (req, res, etag, body, type) => {
  if (req.headers['if-none-match'] === etag) { res.writeHead(304, { ETag: etag }); return res.end(); }
  send(res, 200, body, type, { ETag: etag });
};
const WEB_FILES = /^\/([a-z0-9_]+\.js)$/;

function route(req, res) {
  const url = new URL(req.url, 'http://x'), p = url.pathname, q = url.searchParams;
  const file = (f, type) => (existsSync(f) ? send(res, 200, readFileSync(f), type) : send(res, 404, { error: `missing ${f}` }));
  if (p === '/' || p === '/index.html') return file(path.join(web, 'index.html'), 'text/html; charset=utf-8');
  if (p === '/vendor/three.module.js') return file(path.join(web, 'node_modules/three/build/three.module.js'), 'text/javascript');
  if (WEB_FILES.test(p)) return file(path.join(web, WEB_FILES.exec(p)[1]), 'text/javascript; charset=utf-8');
  if (p.startsWith('/mock/')) return control(p, q, res);
  if (!p.startsWith('/api/')) return send(res, 404, { error: 'no such resource' });
  if (cfg.token && req.headers.authorization !== `Bearer ${cfg.token}`) return send(res, 401, { error: 'missing or wrong bearer token' });
  const G = Number(q.get('group') || 1);
  if (p === '/api/status') return send(res, 200, statusJson());
  const cm = /^\/api\/clients\/(\d+)$/.exec(p);
  if (cm) { const c = clientsJson().find((x) => x.id === Number(cm[1])); return c ? send(res, 200, c) : send(res, 404, { error: 'unknown client' }); }
  if (p === '/api/fusion/events') return send(res, 200, { events: state.events });
  if (p === '/api/trajectories') return send(res, 200, { trajectories: clientsJson().map((c) => ({ client: c.id, group: c.group,
    poses: [...state.submaps.values()].filter((s) => s.client === c.id).map((s, i) => [i, ...s.T]) })) });
  if (p === '/api/map/points') return send(res, 200, pointsBin(), 'application/octet-stream');
  if (p === '/api/dense/status') return send(res, 200, { enabled: true, version: state.version, submaps: state.submaps.size,
    keyframes_integrated: 5 * state.submaps.size, queue: 0, integrate_ms: { p50: 3.1, max: 9.5 },
    store: { keyframes: 5 * state.submaps.size, payload_bytes: 1e6, max_bytes: 1e9, refused_full: 0, errors: 0, last_error: '' } });
  if (p === '/api/dense/submaps') return conditional(req, res, `"${state.version}"`, JSON.stringify(index()), 'application/json');
  const mm = /^\/api\/dense\/submaps\/(\d+)\/mesh\.bin$/.exec(p);
  if (mm) {
    const s = state.submaps.get(Number(mm[1]));
    state.meshRequests[mm[1]] = (state.meshRequests[mm[1]] || 0) + 1;
    if (!s || state.broken[s.id] === '404') return send(res, 404, { error: `unknown submap ${mm[1]}` });
    if (state.broken[s.id] === 'reset') return req.socket.destroy();
    const lod = Math.min(2, Math.max(0, Number(q.get('lod') || 0)));
    return conditional(req, res, `"${s.version}"`, meshBody(s, lod), 'application/octet-stream');
  }
  if (p === '/api/dense/occupancy.json') return send(res, 200, occupancyJson(G));
  if (p === '/api/dense/occupancy.yaml') return send(res, 200, `image: occupancy.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n`, 'text/yaml');
  if (p === '/api/dense/occupancy.pgm') return send(res, 200, Buffer.concat([Buffer.from('P5\n4 4\n255\n'), Buffer.alloc(16, 254)]), 'image/x-portable-graymap');
  if (p === '/api/dense/cloud.ply' || p === '/api/dense/mesh.ply')
    return send(res, 200, 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n', 'application/octet-stream');
  if (p === '/api/dense/octomap.bt') return send(res, 200, '# Octomap OcTree binary file\nid OcTree\nsize 0\nres 0.05\ndata\n', 'application/octet-stream');
  return send(res, 404, { error: `no such resource: ${p}` });
}

function control(p, q, res) {
  const id = Number(q.get('id'));
  const s = state.submaps.get(id);
  const need = () => (s ? null : send(res, 404, { error: `unknown submap ${id}` }));
  if (p === '/mock/state') return send(res, 200, { index: index(), meshRequests: state.meshRequests, broken: state.broken });
  if (p === '/mock/move') { if (need()) return; movePose(s, Number(q.get('dx') || 0.1), Number(q.get('yaw') || 0.2)); return send(res, 200, { id, T: s.T }); }
  if (p === '/mock/corrupt') { if (need()) return; state.broken[id] = q.get('mode') || 'truncate'; s.version += 1; state.version += 1; return send(res, 200, { id, version: s.version }); }
  if (p === '/mock/heal') { delete state.broken[id]; return send(res, 200, { id }); }
  if (p === '/mock/add') {
    const added = addSubmap(Number(q.get('client') || 1));
    if (q.get('mode')) state.broken[added] = q.get('mode');
    return send(res, 200, { id: added });
  }
  if (p === '/mock/remove') { state.submaps.delete(id); state.version += 1; return send(res, 200, { id }); }
  if (p === '/mock/track') { state.tracking[Number(q.get('client'))] = q.get('state'); return send(res, 200, {}); }
  if (p === '/mock/fuse') {
    state.fused = true;
    for (const x of state.submaps.values()) if (x.client === 3) movePose(x, 0.5, 0.3);
    state.events.push({ time_s: (Date.now() - start) / 1000, kind: 'fusion', clients: [1, 3], group: 1, inliers: 80, duration_ms: 12 });
    return send(res, 200, index());
  }
  return send(res, 404, { error: 'unknown control' });
}

const server = http.createServer((req, res) => {
  try { route(req, res); } catch (e) { send(res, 500, { error: String(e) }); }
});
server.listen(cfg.port, '127.0.0.1', () => {
  const port = server.address().port;
  if (arg('port-file')) {  // written whole, then renamed: a reader never sees an empty file
    writeFileSync(arg('port-file') + '.tmp', String(port));
    renameSync(arg('port-file') + '.tmp', arg('port-file'));
  }
  console.log(`mock dense server on http://127.0.0.1:${port}/ (${state.submaps.size} submaps x ${cfg.triangles} triangles)`);
});
if (cfg.tickMs > 0) {  // a live map: every tick one submap grows, one moves
  let n = 0;
  setInterval(() => {
    const all = [...state.submaps.values()];
    const s = all[n++ % all.length];
    if (n % 2) { s.version += 1; state.version += 1; } else movePose(s, 0.01, 0.01);
  }, cfg.tickMs).unref();
}
process.on('SIGTERM', () => { server.closeAllConnections(); server.close(() => process.exit(0)); });
