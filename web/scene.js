// The 3D view: three.js renderer, an orbit camera (drag to orbit, shift/right-drag to pan, wheel to
// zoom), per-frame hooks, and the light layers: trajectories, sparse map points, robot frusta.
// Each group is drawn in its own fused frame; all groups share the scene (select one to see it alone).

export const PALETTE = [0xe6194b, 0x3cb44b, 0x4363d8, 0xf58231, 0x911eb4, 0x42d4f4, 0xf032e6, 0x9a6324];
export const colour = (id) => PALETTE[(id - 1 + PALETTE.length) % PALETTE.length];
export const BACKGROUND = 0x111827;

// The renderer's name if WebGL runs in software (SwiftShader, llvmpipe), else ''.
export function softwareRenderer() {
  try {
    const gl = document.createElement('canvas').getContext('webgl2');
    const ext = gl.getExtension('WEBGL_debug_renderer_info');
    const name = String(gl.getParameter(ext ? ext.UNMASKED_RENDERER_WEBGL : gl.RENDERER));
    gl.getExtension('WEBGL_lose_context')?.loseContext();
    return /swiftshader|llvmpipe|software/i.test(name) ? name : '';
  } catch (e) {
    return '';
  }
}

// Renders on demand: when view.invalidate() was called, the camera moved, a hook asks for it
// (returns true), or a second has passed. view.frameMs: time between consecutive renders (EMA),
// i.e. the frame time while something moves.
export function createView(THREE, el, { antialias } = {}) {
  THREE.ColorManagement.enabled = false;  // vertex colours are the cameras' sRGB bytes: draw them as they are
  const software = softwareRenderer();
  const renderer = new THREE.WebGLRenderer({ antialias: antialias ?? !software, preserveDrawingBuffer: true });
  renderer.outputColorSpace = THREE.LinearSRGBColorSpace;
  renderer.setPixelRatio(software ? 1 : window.devicePixelRatio);
  renderer.setSize(el.clientWidth, el.clientHeight);
  renderer.setClearColor(BACKGROUND);
  el.appendChild(renderer.domElement);
  const scene = new THREE.Scene();
  const camera = new THREE.PerspectiveCamera(50, el.clientWidth / el.clientHeight, 0.01, 2000);
  camera.up.set(0, -1, 0);  // camera frames: y points down
  scene.add(new THREE.AxesHelper(0.3));
  const layers = {};
  for (const name of ['dense', 'sparse', 'trajectories', 'occupancy', 'robots']) {
    layers[name] = new THREE.Group();
    layers[name].name = name;
    scene.add(layers[name]);
  }
  const view = { THREE, renderer, scene, camera, layers, hooks: [], frames: 0, renders: 0, frameMs: 16, frameMsAt: 0,
    software, el, dirty: true, orbit: { yaw: 0.6, pitch: 0.7, dist: 3, target: new THREE.Vector3(), user: false } };
  view.invalidate = () => { view.dirty = true; };
  attachOrbit(view);
  new ResizeObserver(() => {
    renderer.setSize(el.clientWidth, el.clientHeight);
    camera.aspect = el.clientWidth / Math.max(1, el.clientHeight);
    camera.updateProjectionMatrix();
    view.invalidate();
  }).observe(el);
  const lastMatrix = new THREE.Matrix4();
  let lastRender = -1e9, previousRendered = false;
  const frame = (t) => {
    placeCamera(view);
    let render = view.dirty || !camera.matrixWorld.equals(lastMatrix) || t - lastRender > 1000;
    for (const h of view.hooks) if (h(t)) render = true;
    if (render) {
      if (previousRendered) { view.frameMs = 0.8 * view.frameMs + 0.2 * (t - lastRender); view.frameMsAt = t; }
      view.dirty = false;
      renderer.render(scene, camera);
      lastMatrix.copy(camera.matrixWorld);
      lastRender = t;
      view.renders += 1;
    }
    previousRendered = render;
    view.frames += 1;
    requestAnimationFrame(frame);
  };
  requestAnimationFrame(frame);
  return view;
}

export function placeCamera({ camera, orbit: o }) {
  const d = Math.max(o.dist, 0.2);
  camera.position.set(o.target.x + d * Math.cos(o.pitch) * Math.sin(o.yaw), o.target.y - d * Math.sin(o.pitch),
    o.target.z + d * Math.cos(o.pitch) * Math.cos(o.yaw));
  camera.lookAt(o.target);
  camera.updateMatrixWorld();
}

function attachOrbit(view) {
  const { el, orbit, camera, THREE } = view;
  let drag = null;
  el.addEventListener('contextmenu', (e) => e.preventDefault());
  el.addEventListener('pointerdown', (e) => { drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey || e.button === 2 }; orbit.user = true; });
  window.addEventListener('pointerup', () => { drag = null; });
  window.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x, dy = e.clientY - drag.y;
    if (drag.pan) {
      const s = orbit.dist / el.clientHeight;
      const right = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 0);
      const up = new THREE.Vector3().setFromMatrixColumn(camera.matrixWorld, 1);
      orbit.target.addScaledVector(right, -dx * s).addScaledVector(up, dy * s);
    } else {
      orbit.yaw -= dx * 0.01;
      orbit.pitch = Math.max(-1.5, Math.min(1.5, orbit.pitch + dy * 0.01));
    }
    drag.x = e.clientX;
    drag.y = e.clientY;
  });
  el.addEventListener('wheel', (e) => { e.preventDefault(); orbit.user = true; orbit.dist *= e.deltaY > 0 ? 1.1 : 0.9; }, { passive: false });
}

// Keeps `box` framed until the user moves the view.
export function frame(view, box) {
  if (box.isEmpty() || view.orbit.user) return;
  box.getCenter(view.orbit.target);
  view.orbit.dist = 1.3 * Math.max(box.getSize(new view.THREE.Vector3()).length(), 1.5);
  placeCamera(view);  // now, so that level-of-detail decisions see the framed camera
}

function disposeChildren(group) {
  for (const c of group.children) {
    c.traverse((o) => { o.geometry?.dispose(); o.material?.dispose?.(); });
  }
  group.clear();
}

// Trajectories (lines per client) and the sparse points (16-byte records: xyz float32, rgb, client).
export function drawTrajectories(view, trajectories, visibleGroup) {
  const { THREE } = view;
  const layer = view.layers.trajectories;
  disposeChildren(layer);
  view.invalidate();
  const box = new THREE.Box3();
  for (const t of trajectories) {
    if (t.poses.length === 0 || (visibleGroup !== null && t.group !== visibleGroup)) continue;
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(t.poses.flatMap((p) => [p[1], p[2], p[3]]), 3));
    g.computeBoundingBox();
    box.union(g.boundingBox);
    layer.add(new THREE.Line(g, new THREE.LineBasicMaterial({ color: colour(t.client) })));
  }
  return box;
}

export function drawPoints(view, points, groupOfClient, visibleGroup) {
  const { THREE } = view;
  const layer = view.layers.sparse;
  disposeChildren(layer);
  view.invalidate();
  const box = new THREE.Box3();
  if (!points || points.byteLength < 16) return box;
  const n = points.byteLength >> 4, dv = new DataView(points);
  const pos = new Float32Array(3 * n), col = new Float32Array(3 * n);
  let m = 0;
  const c = new THREE.Color();
  for (let i = 0; i < n; i++) {
    const client = dv.getUint8(16 * i + 15);
    if (visibleGroup !== null && groupOfClient(client) !== visibleGroup) continue;
    for (let k = 0; k < 3; k++) pos[3 * m + k] = dv.getFloat32(16 * i + 4 * k, true);
    c.setHex(colour(client));
    col.set([c.r, c.g, c.b], 3 * m);
    m++;
  }
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', new THREE.BufferAttribute(pos.subarray(0, 3 * m), 3));
  g.setAttribute('color', new THREE.BufferAttribute(col.subarray(0, 3 * m), 3));
  g.computeBoundingBox();
  if (m) box.union(g.boundingBox);
  layer.add(new THREE.Points(g, new THREE.PointsMaterial({ size: 2.5, sizeAttenuation: false, vertexColors: true })));
  return box;
}

// A camera frustum (apex at the optical centre, looking down +z, y down) per robot, in its colour;
// a lost robot's frustum is red and drawn larger, a not-yet-initialised one grey.
export class Robots {
  constructor(view) {
    this.view = view;
    this.byId = new Map();
  }
  frustum(id) {
    const { THREE } = this.view;
    const w = 0.12, h = 0.09, d = 0.15;
    const p = [[0, 0, 0], [-w, -h, d], [w, -h, d], [w, h, d], [-w, h, d]];
    const edges = [0, 1, 0, 2, 0, 3, 0, 4, 1, 2, 2, 3, 3, 4, 4, 1, 1, 3];
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.Float32BufferAttribute(edges.flatMap((i) => p[i]), 3));
    const obj = new THREE.LineSegments(g, new THREE.LineBasicMaterial({ color: colour(id) }));
    obj.name = `robot-${id}`;
    this.view.layers.robots.add(obj);
    return obj;
  }
  // clients: [{id, tracking, group, pose: {position, quaternion}}]
  update(clients, visibleGroup) {
    const live = new Set();
    for (const c of clients) {
      if (!c.pose) continue;
      live.add(c.id);
      const obj = this.byId.get(c.id) || this.frustum(c.id);
      this.byId.set(c.id, obj);
      const key = JSON.stringify([c.pose.position, c.pose.quaternion, c.tracking, c.group, visibleGroup]);
      if (obj.userData.key === key) continue;
      this.view.invalidate();
      obj.position.fromArray(c.pose.position);
      obj.quaternion.fromArray(c.pose.quaternion);
      obj.visible = visibleGroup === null || c.group === visibleGroup;
      const lost = c.tracking === 'lost', idle = c.tracking === 'not_initialized';
      obj.material.color.setHex(lost ? 0xff2020 : idle ? 0x808080 : colour(c.id));
      obj.scale.setScalar(lost ? 1.6 : 1);
      obj.userData = { tracking: c.tracking, group: c.group, key };
    }
    for (const [id, obj] of this.byId) {
      if (live.has(id)) continue;
      obj.geometry.dispose();
      obj.material.dispose();
      obj.removeFromParent();
      this.byId.delete(id);
      this.view.invalidate();
    }
  }
}
