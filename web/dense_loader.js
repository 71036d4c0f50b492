// Mesh downloads of the dense layer: a bounded number in flight, the most urgent first (submaps with
// nothing drawn, then new geometry, then level-of-detail changes; nearest first), each validated
// (CSM1) before a buffer is built. A failed download marks the submap missing and retries it with
// exponential backoff (1 s, 2 s, 4 s ... 30 s, jittered).
import { parseCsm1 } from './csm1.js';

export const BACKOFF_MIN_MS = 1000;
export const BACKOFF_MAX_MS = 30000;

export function backoffMs(failures) {
  const base = Math.min(BACKOFF_MAX_MS, BACKOFF_MIN_MS * 2 ** Math.max(0, failures - 1));
  return base * (0.8 + 0.4 * Math.random());
}

// The mesh URL for a level of detail (0 = the contract's default URL).
export function meshUrl(entry, lod) {
  return lod > 0 ? `${entry.mesh_url}${entry.mesh_url.includes('?') ? '&' : '?'}lod=${lod}` : entry.mesh_url;
}

// What an entry needs: 0 nothing (or an empty submap), 1 a LOD change, 2 new geometry, 3 nothing drawn yet.
export function urgency(e) {
  if (e.triangles === 0) return 0;  // no surface yet: nothing to fetch
  if (e.loadedVersion < 0) return 3;
  if (e.loadedVersion !== e.version) return 2;
  if (e.loadedLod !== e.desiredLod) return 1;
  return 0;
}

export class MeshLoader {
  // api(path, opts) -> Response; build(entry, parsed, lod) installs the geometry.
  constructor({ api, build, onError, maxConcurrent = 4, minIntervalMs = 0 }) {
    Object.assign(this, { api, build, onError, maxConcurrent, minIntervalMs });
    this.inFlight = new Map();  // id -> AbortController
    this.requests = 0;  // mesh requests sent
    this.loaded = 0;
    this.bytes = 0;  // mesh bodies received
    this.failures = 0;
  }

  // Starts downloads for the most urgent entries while fewer than maxConcurrent are in flight.
  pump(entries, now = performance.now()) {
    if (this.inFlight.size >= this.maxConcurrent) return;
    const want = [];
    for (const e of entries) {
      if (this.inFlight.has(e.id) || e.retryAt > now || !e.mesh_url) continue;
      const u = urgency(e);
      if (u === 2 && now - (e.loadedAt ?? -1e9) < this.minIntervalMs) continue;  // growing: not every version
      if (u > 0) want.push([u, e.distance ?? 0, e]);
    }
    want.sort((a, b) => b[0] - a[0] || a[1] - b[1]);
    for (const [, , e] of want) {
      if (this.inFlight.size >= this.maxConcurrent) break;
      this.start(e);
    }
  }

  async start(e) {
    const ctrl = new AbortController();
    this.inFlight.set(e.id, ctrl);
    const lod = e.desiredLod, url = meshUrl(e, lod);
    this.requests += 1;
    e.requests = (e.requests || 0) + 1;
    try {
      const res = await this.api(url, { signal: ctrl.signal });
      const buf = await res.arrayBuffer();
      this.bytes += buf.byteLength;
      const parsed = parseCsm1(buf);
      if (e.removed) return;
      this.build(e, parsed, lod);
      e.failures = 0;
      e.retryAt = 0;
      e.lastError = '';
      this.loaded += 1;
    } catch (err) {
      if (err.name === 'AbortError' || e.removed) return;
      this.failures += 1;
      e.failures = (e.failures || 0) + 1;
      e.retryAt = performance.now() + backoffMs(e.failures);
      e.lastError = String(err.message || err);
      e.networkError = err instanceof TypeError;  // fetch's network failure
      this.onError(e, err);
    } finally {
      if (this.inFlight.get(e.id) === ctrl) this.inFlight.delete(e.id);
      this.onSettled?.();
    }
  }

  cancel(id) {
    const ctrl = this.inFlight.get(id);
    if (ctrl) ctrl.abort();
    this.inFlight.delete(id);
  }
}
