// cslam live viewer (loaded by viewer.js): polls the JSON API of cslam-server and draws, per fused group, the live dense
// map (per-submap meshes, see dense.js), the robots as camera frusta, trajectories, the sparse map
// and the occupancy grid, with fusion and loop events highlighted. three.js is loaded from the
// server (/vendor, installed by npm ci); without it the client table and the events still work.
// URL hash options: token=..., dense_ms, status_ms, sparse_ms, mesh_interval_ms, settle_ms, budget (triangles), lod_near / lod_far (metres),
// aa=0|1 (multisampling; default: on unless WebGL runs in software).
import { api, connection, traffic } from './net.js';
import { createView, drawTrajectories, drawPoints, Robots, frame } from './scene.js';
import { DenseLayer } from './dense.js';
import { OccupancyLayer } from './occupancy.js';
import { $, renderStatus, renderEvents, renderDenseInfo, showConnection, setupDownloads, setupReconstruction } from './panel.js';

const opts = new URLSearchParams(location.hash.slice(1));
const num = (k, d) => (opts.has(k) && Number.isFinite(Number(opts.get(k))) ? Number(opts.get(k)) : d);
const config = { statusMs: num('status_ms', 500), denseMs: num('dense_ms', 1000), sparseMs: num('sparse_ms', 2000), occupancyMs: 5000,
  denseStatusMs: 5000, meshMinIntervalMs: num('mesh_interval_ms', 3000), settleMs: num('settle_ms', 6000), triangleBudget: num('budget', 3e6), lodNear: num('lod_near', 8), lodFar: num('lod_far', 20) };
const app = { view: null, dense: null, occupancy: null, robots: null, groups: new Map(), visibleGroup: null,
  uptime: -1, eventsSeen: -1, denseStatus: undefined, sparseBox: null, clientPoses: new Map(), restarts: 0 };
const shown = (name) => $(`show-${name}`).checked;

// Status `groups`: [[G, [clients]], ...] or {"G": [clients]}.
function parseGroups(g) {
  const entries = Array.isArray(g) ? g : Object.entries(g || {});
  return new Map(entries.map(([G, clients]) => [Number(G), clients]));
}

function toast(text) {
  $('toast').textContent = text;
  clearTimeout(toast.timer);
  toast.timer = setTimeout(() => { $('toast').textContent = ''; }, 5000);
}

function updateGroupSelect() {
  const sel = $('group'), want = ['all', ...[...app.groups.keys()].map(String)];
  if ([...sel.options].map((o) => o.value).join() === want.join()) return;
  const keep = sel.value;
  sel.innerHTML = want.map((v) => `<option value="${v}">${v === 'all' ? 'all' : `group ${v} (clients ${app.groups.get(Number(v)).join(', ')})`}</option>`).join('');
  sel.value = want.includes(keep) ? keep : 'all';
}

const largestGroup = () => [...app.groups.entries()].sort((a, b) => b[1].length - a[1].length || a[0] - b[0])[0]?.[0] ?? null;
const downloadGroup = () => app.visibleGroup ?? largestGroup();

async function pollStatus() {
  const s = await (await api('/api/status')).json();
  if (s.uptime_s < app.uptime) serverRestarted();
  app.uptime = s.uptime_s;
  renderStatus(s);
  app.groups = parseGroups(s.groups);
  app.clients = s.clients;
  updateGroupSelect();
  $('download-group').textContent = downloadGroup() === null ? 'no group yet' : `group ${downloadGroup()}`;
  if (!app.robots) return;
  // Live poses: from /api/status when it carries them, else one small request per client (1 Hz).
  const now = performance.now(), fetchPoses = now - (app.posesFetched || 0) >= 1000;
  if (fetchPoses && s.clients.some((c) => !c.pose)) app.posesFetched = now;
  const clients = await Promise.all(s.clients.map(async (c) => {
    if (c.pose || !fetchPoses) return { ...c, pose: c.pose || app.clientPoses.get(c.id) };
    const j = await (await api(`/api/clients/${c.id}`)).json().catch(() => ({}));
    if (j.pose) app.clientPoses.set(c.id, j.pose);
    return { ...c, pose: j.pose };
  }));
  app.robots.update(clients.filter((c) => c.pose && c.frames_processed > 0), app.visibleGroup);
}

function serverRestarted() {
  app.restarts += 1;
  app.eventsSeen = -1;
  app.dense?.serverRestarted();
  showConnection(true, 'the server restarted: reloading the map');
}

async function pollEvents() {
  const { events } = await (await api('/api/fusion/events')).json();
  renderEvents(events, app.uptime);
  if (app.eventsSeen >= 0 && events.length > app.eventsSeen) {
    for (const e of events.slice(app.eventsSeen)) {
      app.dense?.flashClients(e.group, e.clients);
      toast(`${e.kind}: clients ${e.clients.join(' + ')} → group ${e.group}`);
    }
  }
  app.eventsSeen = events.length;
}

async function pollSparse() {
  if (!app.view || !(shown('sparse') || shown('trajectories'))) return;
  const [t, p] = await Promise.all([api('/api/trajectories?client=all&format=json').then((r) => r.json()),
    shown('sparse') ? api('/api/map/points?format=bin').then((r) => r.arrayBuffer()) : null]);
  const groupOf = (client) => app.clients?.find((c) => c.id === client)?.group;
  app.sparseBox = drawTrajectories(app.view, t.trajectories, app.visibleGroup);
  const pts = drawPoints(app.view, p, groupOf, app.visibleGroup);
  if (!app.dense || app.dense.entries.size === 0) app.sparseBox.union(pts);
}

async function pollDenseStatus() {
  try {
    app.denseStatus = await (await api('/api/dense/status')).json();
  } catch (e) {
    if (e.status !== 404) throw e;
    app.denseStatus = null;  // a server without the dense map routes
  }
}

async function pollDense() {
  if (!app.dense) return;
  if (app.denseStatus === undefined) return;  // not known yet
  if (app.denseStatus === null || app.denseStatus.enabled === false) {
    if (app.dense.entries.size) app.dense.clear();
  } else {
    try {
      await app.dense.poll();
    } catch (e) {
      if (e.status !== 404 && e.status !== 503) throw e;
    }
  }
  const box = app.dense.bounds();
  if (app.sparseBox) box.union(app.sparseBox);
  frame(app.view, box);
  app.dense.updateLod();
  renderDenseInfo(app.denseStatus, app.dense.state(), traffic);
}

async function pollOccupancy() {
  if (!app.occupancy || !shown('occupancy') || !app.denseStatus?.enabled) return;
  await app.occupancy.poll([...app.groups.keys()]);
}

async function poll(fn, ms) {
  for (;;) {
    try { await fn(); } catch (e) { app.lastError = `${fn.name}: ${e.message}`; }
    await new Promise((r) => setTimeout(r, ms));
  }
}

function setupControls() {
  for (const name of ['dense', 'sparse', 'trajectories', 'occupancy', 'robots']) {
    $(`show-${name}`).addEventListener('change', () => {
      if (app.view) { app.view.layers[name].visible = shown(name); app.view.invalidate(); }
      if (name === 'occupancy' && shown(name)) pollOccupancy().catch(() => {});
    });
  }
  $('group').addEventListener('change', () => {
    app.visibleGroup = $('group').value === 'all' ? null : Number($('group').value);
    app.dense?.setVisibleGroup(app.visibleGroup);
    app.occupancy?.setVisibleGroup(app.visibleGroup);
    if (app.view) app.view.orbit.user = false;  // frame the selection
    pollSparse().catch(() => {});
  });
  connection.listeners.push((c) => {
    if (c.ok) {
      showConnection(true, 'connection to the server restored');
      app.dense?.reconnected();
    } else {
      showConnection(false, `connection to the server lost (${c.lastError}); retrying…`);
    }
  });
}

async function initView() {
  let THREE;
  try {
    THREE = await import('/vendor/three.module.js');
  } catch (e) {
    $('view-msg').textContent = '3D view unavailable: three.js is not installed on the server (run scripts/install-web.sh)';
    return;
  }
  try {
    app.view = createView(THREE, $('view'), { antialias: opts.has('aa') ? num('aa', 1) !== 0 : undefined });
  } catch (e) {
    $('view-msg').textContent = `3D view unavailable: no WebGL in this browser (${e.message})`;
    return;
  }
  $('view-msg').style.display = 'none';
  for (const name of Object.keys(app.view.layers)) app.view.layers[name].visible = shown(name);
  app.dense = new DenseLayer(app.view, api, config);
  app.occupancy = new OccupancyLayer(app.view, api);
  app.robots = new Robots(app.view);
}

// For tests and measurements: the dense layer's state and what the scene graph holds.
window.cslamViewer = {
  config,
  denseState: () => ({ enabled: app.denseStatus?.enabled ?? false, ...(app.dense?.state() || { groups: {} }),
    bytesDownloaded: traffic.total, bytesPerMinute: traffic.perMinute(), bytesByCategory: { ...traffic.byCategory }, requestsByCategory: { ...traffic.counts },
    notModified: { ...traffic.notModified },
    connection: { ok: connection.ok, failures: connection.failures }, restarts: app.restarts, frames: app.view?.frames ?? 0 }),
  sceneMeshes: () => {
    const out = {};
    app.view?.layers.dense.traverseVisible((o) => {
      if (!o.isMesh || !o.name.startsWith('submap-mesh-')) return;
      const G = o.parent.parent.name.replace('dense-group-', '');
      const g = (out[G] ||= { meshes: 0, triangles: 0 });
      g.meshes += 1;
      g.triangles += o.geometry.index.count / 3;
    });
    return out;
  },
  // The dense map's (or one group's) bounding box on the canvas, in canvas pixels.
  screenRect: (group = null) => {
    if (!app.view || !app.dense) return null;
    const { THREE, camera, renderer } = app.view, box = app.dense.bounds(group, { meshesOnly: true });
    if (box.isEmpty()) return null;
    const { width: W, height: H } = renderer.domElement;
    let x0 = W, y0 = H, x1 = 0, y1 = 0;
    for (let i = 0; i < 8; i++) {
      const p = new THREE.Vector3(i & 1 ? box.max.x : box.min.x, i & 2 ? box.max.y : box.min.y, i & 4 ? box.max.z : box.min.z).project(camera);
      const x = (p.x + 1) / 2 * W, y = (1 - p.y) / 2 * H;
      x0 = Math.min(x0, x); x1 = Math.max(x1, x); y0 = Math.min(y0, y); y1 = Math.max(y1, y);
    }
    const c = (v, m) => Math.round(Math.max(0, Math.min(m, v)));
    return { x0: c(x0, W), y0: c(y0, H), x1: c(x1, W), y1: c(y1, H), width: W, height: H };
  },
  robots: () => [...(app.robots?.byId || [])].map(([id, o]) => ({ id, position: o.position.toArray(), quaternion: o.quaternion.toArray(), ...o.userData })),
  occupancy: () => app.occupancy?.state() ?? null,
  view: () => app.view,
  // Keeps the camera orbiting (every frame renders), for frame-rate measurements.
  spin: (on = true) => {
    app.spinning = on;
    if (on && !app.spinHook && app.view) {
      app.spinHook = true;
      app.view.hooks.push(() => { if (app.spinning) app.view.orbit.yaw += 0.01; return app.spinning; });
    }
  },
  renderStats: () => ({ frames: app.view?.frames ?? 0, renders: app.view?.renders ?? 0, frameMs: app.view?.frameMs ?? 0,
    software: app.view?.software ?? '', gpu: app.view ? { ...app.view.renderer.info.memory } : null,
    sceneGeometries: app.view ? (() => { const g = new Set(); app.view.scene.traverse((o) => o.geometry && g.add(o.geometry)); return g.size; })() : 0 }),
};

setupControls();
setupDownloads(downloadGroup);
setupReconstruction();
poll(pollStatus, config.statusMs);
poll(pollEvents, 1000);
poll(pollDenseStatus, config.denseStatusMs);
initView().then(() => {
  poll(pollSparse, config.sparseMs);
  poll(pollDense, config.denseMs);
  poll(pollOccupancy, config.occupancyMs);
});
