// cslam live viewer: polls the JSON API of cslam-server and draws clients, trajectories, cameras,
// map points and fusion events. three.js is loaded from the server (/vendor, installed by npm ci);
// without it the client table and the events still work.
const token = new URLSearchParams(location.hash.slice(1)).get('token');
const headers = token ? { Authorization: `Bearer ${token}` } : {};
const PALETTE = [0xe6194b, 0x3cb44b, 0x4363d8, 0xf58231, 0x911eb4, 0x42d4f4, 0xf032e6, 0x9a6324];
const colour = (id) => PALETTE[(id - 1 + PALETTE.length) % PALETTE.length];
const hex = (c) => '#' + c.toString(16).padStart(6, '0');
const $ = (id) => document.getElementById(id);

async function api(path, options = {}) {
  const res = await fetch(path, { ...options, headers });
  if (!res.ok) throw new Error(`${path}: ${res.status} ${(await res.text()).slice(0, 200)}`);
  return res;
}

// ---- client table, events ----
let uptime = 0;
function renderStatus(s) {
  uptime = s.uptime_s;
  $('server').textContent = `${s.server} ${s.version} · up ${s.uptime_s.toFixed(0)} s · ${s.clients.length} client(s) · ${s.fusion_events} event(s)`;
  $('clients').tBodies[0].innerHTML = s.clients.map((c) => `
    <tr data-client="${c.id}"><td><span class="swatch" style="background:${hex(colour(c.id))}"></span>${c.id}</td>
    <td>${c.name}</td><td class="connection">${c.connection}</td><td class="${c.tracking}">${c.tracking}</td>
    <td>${c.frames_received}</td><td>${c.frames_processed}</td><td>${c.frames_dropped}</td><td>${c.fps.toFixed(1)}</td>
    <td>${c.keyframes}</td><td>${c.map_points}</td><td>${c.group}</td></tr>`).join('');
}

function renderEvents(events) {
  const span = Math.max(uptime, ...events.map((e) => e.time_s), 1);
  $('timeline').innerHTML = events.map((e) =>
    `<div class="event ${e.kind}" style="left:${(98 * e.time_s / span).toFixed(2)}%" title="${e.kind} ${e.clients.join('+')} at ${e.time_s.toFixed(1)} s"></div>`).join('');
  $('events').innerHTML = events.length ? events.map((e) =>
    `${e.time_s.toFixed(1)} s: ${e.kind} of clients ${e.clients.join(' + ')} → group ${e.group}, ${e.inliers} inliers, ${e.duration_ms.toFixed(0)} ms`).join('<br>') : 'none yet';
}

// ---- 3D view ----
let view = null;  // { THREE, renderer, scene, camera, groups }
async function initView() {
  let THREE;
  try {
    THREE = await import('/vendor/three.module.js');
  } catch (e) {
    $('view-msg').textContent = '3D view unavailable: three.js is not installed on the server (run scripts/install-web.sh)';
    return;
  }
  const el = $('view');
  let renderer;
  try {
    renderer = new THREE.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  } catch (e) {
    $('view-msg').textContent = '3D view unavailable: no WebGL in this browser';
    return;
  }
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(el.clientWidth, el.clientHeight);
  renderer.setClearColor(0x111827);
  el.appendChild(renderer.domElement);
  $('view-msg').style.display = 'none';
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(50, el.clientWidth / el.clientHeight, 0.01, 1000);
  camera.up.set(0, -1, 0);  // camera frames: y points down
  scene.add(new THREE.AxesHelper(0.3));
  const content = new THREE.Group();
  scene.add(content);
  view = { THREE, renderer, scene, camera, content, orbit: { yaw: 0.6, pitch: 0.7, dist: 0, target: new THREE.Vector3(), user: false } };
  let drag = null;
  el.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY }; view.orbit.user = true; });
  window.addEventListener('pointerup', () => { drag = null; });
  window.addEventListener('pointermove', (e) => {
    if (!drag) return;
    view.orbit.yaw -= (e.clientX - drag.x) * 0.01;
    view.orbit.pitch = Math.max(-1.5, Math.min(1.5, view.orbit.pitch + (e.clientY - drag.y) * 0.01));
    drag = { x: e.clientX, y: e.clientY };
  });
  el.addEventListener('wheel', (e) => { e.preventDefault(); view.orbit.user = true; view.orbit.dist *= e.deltaY > 0 ? 1.1 : 0.9; }, { passive: false });
  const frame = () => {
    const o = view.orbit;
    const d = Math.max(o.dist, 0.5);
    camera.position.set(o.target.x + d * Math.cos(o.pitch) * Math.sin(o.yaw), o.target.y - d * Math.sin(o.pitch),
      o.target.z + d * Math.cos(o.pitch) * Math.cos(o.yaw));
    camera.lookAt(o.target);
    renderer.render(scene, camera);
    requestAnimationFrame(frame);
  };
  frame();
}

function updateView(trajectories, points) {
  if (!view) return;
  const { THREE, content } = view;
  content.children.forEach((c) => c.geometry && c.geometry.dispose());
  content.clear();
  const box = new THREE.Box3();
  for (const t of trajectories) {
    if (t.poses.length === 0) continue;
    const xyz = t.poses.flatMap((p) => [p[1], p[2], p[3]]);
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(xyz, 3));
    content.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: colour(t.client) })));
    const last = t.poses[t.poses.length - 1];
    const cam = new THREE.Mesh(new THREE.SphereGeometry(0.03, 12, 8), new THREE.MeshBasicMaterial({ color: colour(t.client) }));
    cam.position.set(last[1], last[2], last[3]);
    content.add(cam);
    g.computeBoundingBox();
    box.union(g.boundingBox);
  }
  if (points && points.byteLength >= 16) {
    const n = points.byteLength / 16, dv = new DataView(points);
    const pos = new Float32Array(3 * n), col = new Float32Array(3 * n);
    for (let i = 0; i < n; i++) {
      for (let k = 0; k < 3; k++) pos[3 * i + k] = dv.getFloat32(16 * i + 4 * k, true);
      const c = new THREE.Color(colour(dv.getUint8(16 * i + 15)));
      col.set([c.r, c.g, c.b], 3 * i);
    }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(pos, 3));
    g.setAttribute('color', new THREE.BufferAttribute(col, 3));
    g.computeBoundingBox();
    box.union(g.boundingBox);
    content.add(new THREE.Points(g, new THREE.PointsMaterial({ size: 2.5, sizeAttenuation: false, vertexColors: true })));
  }
  if (!box.isEmpty() && !view.orbit.user) {  // keep the trajectories framed until the user moves the view
    box.getCenter(view.orbit.target);
    view.orbit.dist = 1.6 * Math.max(box.getSize(new THREE.Vector3()).length(), 1.5);
  }
}

// ---- reconstruction ----
async function startReconstruction() {
  $('recon-start').disabled = true;
  $('recon-links').hidden = true;
  try {
    const { job } = await (await api('/api/reconstruction', { method: 'POST' })).json();
    for (;;) {
      const s = await (await api(`/api/reconstruction/${job}`)).json();
      $('recon-state').textContent = `job ${job}: ${s.state} ${(100 * s.progress).toFixed(0)}% ${s.message}`;
      if (s.state === 'done') {
        $('dl-cloud').href = s.cloud_url;
        $('dl-mesh').href = s.mesh_url || '';
        $('dl-mesh').hidden = !s.mesh_url;
        $('recon-links').hidden = false;
        break;
      }
      if (s.state !== 'running' && s.state !== 'queued') break;
      await new Promise((r) => setTimeout(r, 500));
    }
  } catch (e) {
    $('recon-state').textContent = String(e.message);
  }
  $('recon-start').disabled = false;
}
// With a token the links cannot carry the header: download through fetch.
for (const id of ['dl-cloud', 'dl-mesh']) {
  $(id).addEventListener('click', async (e) => {
    if (!token) return;
    e.preventDefault();
    const blob = await (await api($(id).getAttribute('href'))).blob();
    const a = Object.assign(document.createElement('a'), { href: URL.createObjectURL(blob), download: $(id).textContent });
    a.click();
  });
}
$('recon-start').addEventListener('click', startReconstruction);

// ---- polling ----
async function poll(fn, ms) {
  for (;;) {
    try { await fn(); } catch (e) { $('server').textContent = `error: ${e.message}`; }
    await new Promise((r) => setTimeout(r, ms));
  }
}
poll(async () => renderStatus(await (await api('/api/status')).json()), 500);
poll(async () => renderEvents((await (await api('/api/fusion/events')).json()).events), 1000);
initView().then(() => poll(async () => {
  if (!view) return;
  const [t, p] = await Promise.all([api('/api/trajectories?client=all&format=json').then((r) => r.json()),
    api('/api/map/points?format=bin').then((r) => r.arrayBuffer())]);
  updateView(t.trajectories, p);
}, 1000));
