// The live dense map: one Object3D per submap (its transform = T_world_submap) holding a mesh with
// per-vertex colours, under one node per fused group. The index (/api/dense/submaps) is polled with
// If-None-Match; only submaps whose geometry `version` changed (or that are new) are downloaded, a
// `pose_version` change only moves the object. Far submaps get a coarser level of detail and the
// whole map stays under a triangle budget; replaced and removed geometry is disposed.
import { MeshLoader, urgency } from './dense_loader.js';

// A submap whose geometry changed within settleMs is growing (being integrated): it is fetched one
// level coarser and at most every meshMinIntervalMs; once it settles, at its full level. New
// submaps are fetched at once.
export const DENSE_DEFAULTS = { maxConcurrent: 4, triangleBudget: 3e6, lodNear: 8, lodFar: 20, flashMs: 1500,
  meshMinIntervalMs: 3000, settleMs: 6000 };
const MAX_ERRORS_KEPT = 20;

const validSubmap = (s) => Number.isInteger(s.id) && Number.isInteger(s.version) && Number.isInteger(s.pose_version) &&
  Array.isArray(s.T_world_submap) && s.T_world_submap.length === 7 && s.T_world_submap.every(Number.isFinite) &&
  typeof s.mesh_url === 'string' && s.mesh_url.startsWith('/api/');

export class DenseLayer {
  constructor(view, api, options = {}) {
    const T = view.THREE;
    Object.assign(this, { view, THREE: T, api, o: { ...DENSE_DEFAULTS, ...options }, root: view.layers.dense });
    this.entries = new Map();  // submap id -> entry
    this.groups = new Map();  // group -> THREE.Group
    this.etag = null;
    this.version = -1;
    this.visibleGroup = null;
    this.poseOnlyUpdates = 0;
    this.poseUpdates = [];  // index answers that carried pose-only changes: {bytes, moved, submaps}
    this.indexFetches = 0;
    this.index304 = 0;
    this.indexBytes = 0;
    this.errors = [];  // the last few, for the page and the tests
    this.errorCount = 0;
    this.flashing = new Set();
    this.quality = 1;  // share of the triangle budget in use (adapted to the frame time)
    this.material = new T.MeshBasicMaterial({ vertexColors: true, side: T.DoubleSide });
    this.flashMaterial = new T.MeshBasicMaterial({ color: 0xfacc15, side: T.DoubleSide });
    this.missingGeometry = new T.OctahedronGeometry(0.08);
    this.missingMaterial = new T.MeshBasicMaterial({ color: 0xff3030, wireframe: true });
    this.loader = new MeshLoader({ api, maxConcurrent: this.o.maxConcurrent, minIntervalMs: this.o.meshMinIntervalMs,
      build: (e, p, lod) => this.build(e, p, lod), onError: (e, err) => this.failed(e, err) });
    this.loader.onSettled = () => this.updateLod();  // the next download starts as one ends
    view.hooks.push((t) => this.animate(t));
  }

  // One conditional request for the index; true if it changed.
  async poll() {
    const res = await this.api('/api/dense/submaps', { etag: this.etag });
    this.indexFetches += 1;
    if (res.status === 304) {
      this.index304 += 1;
      return false;
    }
    const body = await res.arrayBuffer();
    this.indexBytes += body.byteLength;
    const index = JSON.parse(new TextDecoder().decode(body));
    this.reconcile(index, body.byteLength);
    this.etag = res.headers.get('ETag');
    return true;
  }

  reconcile(index, bytes) {
    if (!index || !Array.isArray(index.groups)) throw new Error('dense index: no groups list');
    if (index.version < this.version) this.serverRestarted();
    const live = this.version >= 0;  // a submap that appears in a later index is being built
    this.version = index.version;
    const seen = new Set(), moved = [];
    let geometryChanges = 0;
    for (const g of index.groups) {
      for (const s of g.submaps || []) {
        if (!validSubmap(s)) { this.error(s?.id ?? -1, 'malformed submap entry in the index'); continue; }
        seen.add(s.id);
        let e = this.entries.get(s.id);
        if (!e) {
          e = this.create(s, g.group);
          if (live) e.changedAt = performance.now();
        } else {
          if (e.group !== g.group) this.reparent(e, g.group);
          if (s.version !== e.version) { geometryChanges += 1; e.changedAt = performance.now(); }
          else if (s.pose_version !== e.pose_version) this.poseOnlyUpdates += 1;
        }
        if (s.triangles === 0 && e.loadedVersion !== s.version) this.empty(e, s.version);
        const was = e.T;
        Object.assign(e, { version: s.version, pose_version: s.pose_version, client: s.client ?? s.id >> 16,
          triangles: s.triangles ?? 0, vertices: s.vertices ?? 0, keyframes: s.keyframes ?? 0, mesh_url: s.mesh_url });
        if (!was || s.T_world_submap.some((v, i) => v !== was[i])) {
          e.T = s.T_world_submap.slice();
          this.place(e);
          if (was) { moved.push(e.id); this.flash(e); }
        }
      }
    }
    for (const e of [...this.entries.values()]) if (!seen.has(e.id)) this.remove(e);
    for (const [G, node] of this.groups) if (node.children.length === 0) { node.removeFromParent(); this.groups.delete(G); }
    if (moved.length && geometryChanges === 0) {
      this.poseUpdates.push({ bytes, moved: moved.length, submaps: seen.size, ids: moved.slice(0, 50) });
      if (this.poseUpdates.length > 20) this.poseUpdates.shift();
    }
  }

  groupNode(G) {
    let node = this.groups.get(G);
    if (!node) {
      node = new this.THREE.Group();
      node.name = `dense-group-${G}`;
      node.visible = this.visibleGroup === null || this.visibleGroup === G;
      this.groups.set(G, node);
      this.root.add(node);
    }
    return node;
  }

  create(s, G) {
    const obj = new this.THREE.Group();
    obj.name = `submap-${s.id}`;
    const e = { id: s.id, group: G, obj, mesh: null, marker: null, loadedVersion: -1, loadedLod: -1, desiredLod: 0,
      drawnTriangles: 0, failures: 0, retryAt: 0, distance: 0, state: 'pending', requests: 0 };
    obj.userData.submap = s.id;
    this.groupNode(G).add(obj);
    this.entries.set(s.id, e);
    return e;
  }

  reparent(e, G) {
    e.group = G;
    this.groupNode(G).add(e.obj);  // add() removes it from its old parent
  }

  place(e) {
    const [tx, ty, tz, qx, qy, qz, qw] = e.T;
    e.obj.position.set(tx, ty, tz);
    e.obj.quaternion.set(qx, qy, qz, qw).normalize();
    e.obj.updateMatrixWorld(true);
    this.view.invalidate();
  }

  build(e, p, lod) {
    const T = this.THREE;
    this.disposeMesh(e);
    if (p.triangles > 0) {
      const g = new T.BufferGeometry();
      g.setAttribute('position', new T.BufferAttribute(p.positions, 3));
      g.setAttribute('color', new T.BufferAttribute(p.colours, 3, true));
      g.setIndex(new T.BufferAttribute(p.indices, 1));
      g.computeBoundingSphere();
      g.computeBoundingBox();
      // The page keeps no CPU copy once the GPU has the buffers (bounds computed above).
      for (const a of [g.attributes.position, g.attributes.color, g.index]) a.onUpload(function release() { this.array = null; });
      e.mesh = new T.Mesh(g, this.flashing.has(e) ? this.flashMaterial : this.material);
      e.mesh.name = `submap-mesh-${e.id}`;
      e.obj.add(e.mesh);
      e.centre = g.boundingSphere.center.clone();
      e.radius = g.boundingSphere.radius;
    }
    if (e.marker) { e.marker.removeFromParent(); e.marker = null; }
    e.loadedVersion = p.version;
    e.loadedAt = performance.now();
    e.loadedLod = lod;
    e.drawnTriangles = p.triangles;
    e.state = 'loaded';
    this.view.invalidate();
    if (p.version !== e.version) e.retryAt = performance.now() + 1000;  // the index moved on meanwhile
  }

  // A submap without a surface (yet): nothing drawn, nothing to download.
  empty(e, version) {
    this.disposeMesh(e);
    if (e.marker) { e.marker.removeFromParent(); e.marker = null; }
    e.loadedVersion = version;
    e.drawnTriangles = 0;
    e.state = 'empty';
  }

  failed(e, err) {
    e.state = e.mesh ? 'stale' : 'missing';
    if (!e.mesh && !e.marker) {
      e.marker = new this.THREE.Mesh(this.missingGeometry, this.missingMaterial);
      e.marker.name = `submap-missing-${e.id}`;
      e.obj.add(e.marker);
      this.view.invalidate();
    }
    this.error(e.id, e.lastError || String(err));
  }

  error(id, message) {
    this.errorCount += 1;
    this.errors.push({ id, message, time_s: performance.now() / 1000 });
    if (this.errors.length > MAX_ERRORS_KEPT) this.errors.shift();
  }

  disposeMesh(e) {
    if (!e.mesh) return;
    e.mesh.geometry.dispose();
    e.mesh.removeFromParent();
    e.mesh = null;
    this.view.invalidate();
  }

  remove(e) {
    e.removed = true;
    this.loader.cancel(e.id);
    this.disposeMesh(e);
    e.obj.removeFromParent();
    this.entries.delete(e.id);
    this.view.invalidate();
    this.flashing.delete(e);
  }

  // A restarted server may reuse geometry versions: everything is fetched again (old meshes stay
  // drawn until replaced).
  serverRestarted() {
    for (const e of this.entries.values()) e.loadedVersion = -1;
  }

  // After the connection came back: retry at once what failed for network reasons.
  reconnected() {
    for (const e of this.entries.values()) if (e.networkError) e.retryAt = 0;
  }

  clear() {
    for (const e of [...this.entries.values()]) this.remove(e);
    this.etag = null;
    this.version = -1;
  }

  setVisibleGroup(G) {
    this.visibleGroup = G;
    for (const [g, node] of this.groups) node.visible = G === null || g === G;
    this.view.invalidate();
  }

  lodFor(d, current) {
    const { lodNear: n, lodFar: f } = this.o;
    const h = 0.15;  // hysteresis: keep the current level near a boundary
    if (current === 0 && d < n * (1 + h)) return 0;
    if (current === 1 && d > n * (1 - h) && d < f * (1 + h)) return 1;
    if (current === 2 && d > f * (1 - h)) return 2;
    return d < n ? 0 : d < f ? 1 : 2;
  }

  // Distance-based level of detail, then coarser levels for the farthest submaps until the visible
  // map fits the triangle budget (estimate: each level has a quarter of the triangles); starts downloads.
  updateLod() {
    const T = this.THREE, cam = this.view.camera.position, v = new T.Vector3(), now = performance.now();
    const visible = [];
    for (const e of this.entries.values()) {
      e.hidden = !(this.visibleGroup === null || this.visibleGroup === e.group);
      v.copy(e.centre || v.set(0, 0, 0));
      e.obj.localToWorld(v);
      e.distance = Math.max(0, v.distanceTo(cam) - (e.radius || 0));
      if (e.hidden) { if (e.loadedLod >= 0) e.desiredLod = e.loadedLod; continue; }
      e.desiredLod = this.lodFor(e.distance, e.loadedLod);
      if (now - (e.changedAt ?? -1e9) < this.o.settleMs) e.desiredLod = Math.min(2, e.desiredLod + 1);  // growing
      visible.push(e);
    }
    const est = (e, lod) => e.triangles / 4 ** lod, budget = this.budget();
    let total = visible.reduce((s, e) => s + est(e, e.desiredLod), 0);
    visible.sort((a, b) => b.distance - a.distance);
    for (let pass = 0; pass < 2 && total > budget; pass++) {
      for (const e of visible) {
        if (total <= budget) break;
        if (e.desiredLod >= 2) continue;
        total -= est(e, e.desiredLod) - est(e, e.desiredLod + 1);
        e.desiredLod += 1;
      }
    }
    this.loader.pump(visible);
  }

  // The triangle budget, scaled down while frames are slow (> 80 ms apart while the view moves) and
  // back up while they are fast (< 35 ms).
  budget() {
    const v = this.view;
    if (performance.now() - v.frameMsAt < 2000) {
      if (v.frameMs > 80) this.quality = Math.max(0.05, this.quality * 0.8);
      else if (v.frameMs < 35) this.quality = Math.min(1, this.quality * 1.1);
    }
    return this.o.triangleBudget * this.quality;
  }

  // The visible map's bounds (a submap not loaded yet counts as a 1 m cube around its origin).
  bounds(group = null, { meshesOnly = false } = {}) {
    const T = this.THREE, box = new T.Box3(), b = new T.Box3(), half = new T.Vector3(0.5, 0.5, 0.5);
    for (const e of this.entries.values()) {
      if (e.hidden || (group !== null && e.group !== group)) continue;
      if (e.mesh) box.union(b.copy(e.mesh.geometry.boundingBox).applyMatrix4(e.obj.matrixWorld));
      else if (!meshesOnly) box.union(b.set(e.obj.position.clone().sub(half), e.obj.position.clone().add(half)));
    }
    return box;
  }

  flash(e, ms = this.o.flashMs) {
    e.flashUntil = performance.now() + ms;
    this.flashing.add(e);
  }

  flashClients(group, clients) {
    for (const e of this.entries.values()) if (e.group === group && clients.includes(e.client)) this.flash(e);
  }

  animate(t) {  // a frame hook: true while something flashes
    const busy = this.flashing.size > 0;
    for (const e of this.flashing) {
      const on = t < e.flashUntil && Math.floor(t / 180) % 2 === 0;
      if (e.mesh) e.mesh.material = on ? this.flashMaterial : this.material;
      if (t >= e.flashUntil) this.flashing.delete(e);
    }
    return busy;
  }

  state() {
    const groups = {};
    for (const e of this.entries.values()) {
      const g = (groups[e.group] ||= { submaps: [], triangles: 0, missing: 0 });
      g.triangles += e.drawnTriangles;
      if (e.state === 'missing') g.missing += 1;
      g.submaps.push({ id: e.id, client: e.client, version: e.version, pose_version: e.pose_version,
        loaded_version: e.loadedVersion, lod: e.loadedLod, state: e.state, triangles: e.drawnTriangles,
        index_triangles: e.triangles, requests: e.requests, failures: e.failures, last_error: e.lastError || '',
        position: e.obj.position.toArray(), quaternion: e.obj.quaternion.toArray() });
    }
    const l = this.loader;
    return { version: this.version, groups, triangleBudget: Math.round(this.o.triangleBudget * this.quality), meshDownloads: l.requests, meshLoaded: l.loaded, meshBytes: l.bytes,
      meshFailures: l.failures, inFlight: l.inFlight.size, poseOnlyUpdates: this.poseOnlyUpdates,
      poseUpdates: this.poseUpdates, indexFetches: this.indexFetches, index304: this.index304, indexBytes: this.indexBytes,
      errors: this.errorCount, lastErrors: this.errors.slice(-5) };
  }

  pending() {
    return [...this.entries.values()].filter((e) => urgency(e) > 0).length;
  }
}
