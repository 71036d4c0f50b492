// The page's HTTP side: every request carries the bearer token from the URL hash (#token=...),
// conditional requests (If-None-Match) pass 304s through, and every byte the page downloads is
// counted (Resource Timing transferSize: headers + body as sent; the body length where the browser
// reports 0) per category, with a sliding one-minute rate. The connection state (ok / lost) is
// derived from the outcome of the requests and shown by the page as a banner.

export const token = new URLSearchParams(location.hash.slice(1)).get('token');
export const authHeaders = token ? { Authorization: `Bearer ${token}` } : {};

export class HttpError extends Error {
  constructor(path, status, text) {
    super(`${path}: ${status} ${text}`);
    this.status = status;
  }
}

const categoryOf = (url) => {
  const p = new URL(url, location.href).pathname;
  if (p.startsWith('/api/dense/submaps/')) return 'mesh';
  if (p === '/api/dense/submaps') return 'dense_index';
  if (p.startsWith('/api/dense/')) return 'dense_other';
  if (p.startsWith('/api/')) return 'api';
  return 'static';
};

export class Traffic {
  constructor() {
    this.total = 0;
    this.byCategory = {};
    this.window = [];  // [time_ms, bytes] of the last minute
    this.requests = 0;
    this.counts = {};  // requests per category
    this.notModified = { count: 0, bytes: 0 };  // 304 answers (where the browser reports the status)
    const seen = new Set();
    if (typeof PerformanceObserver !== 'undefined') {
      performance.setResourceTimingBufferSize?.(100000);
      new PerformanceObserver((list) => {
        for (const e of list.getEntries()) {
          const key = `${e.name}@${e.startTime}`;
          if (seen.has(key)) continue;
          seen.add(key);
          if (seen.size > 5000) seen.clear();
          this.add(e.name, e.transferSize || e.encodedBodySize || 0, e.responseStatus);
        }
        performance.clearResourceTimings();
      }).observe({ type: 'resource', buffered: true });
    }
  }
  add(url, bytes, status) {
    const cat = categoryOf(url);
    this.total += bytes;
    this.requests += 1;
    this.byCategory[cat] = (this.byCategory[cat] || 0) + bytes;
    this.counts[cat] = (this.counts[cat] || 0) + 1;
    if (status === 304) { this.notModified.count += 1; this.notModified.bytes += bytes; }
    const now = performance.now();
    this.window.push([now, bytes, cat]);
    while (this.window.length && now - this.window[0][0] > 60000) this.window.shift();
  }
  perMinute(category) {
    const now = performance.now();
    const inWindow = this.window.filter((w) => now - w[0] <= 60000 && (!category || w[2] === category));
    return inWindow.reduce((s, w) => s + w[1], 0);
  }
}

export const traffic = new Traffic();

// Connection state: lost after a network error (or a gateway error), ok again after any answer.
export const connection = { ok: true, since: performance.now(), failures: 0, lastError: '', listeners: [] };
function setConnection(ok, error) {
  if (!ok) { connection.failures += 1; connection.lastError = error; }
  if (ok === connection.ok) return;
  connection.ok = ok;
  connection.since = performance.now();
  if (ok) connection.failures = 0;
  for (const f of connection.listeners) f(connection);
}

// fetch with the token; throws HttpError for statuses other than 2xx and 304 (304 is returned,
// res.status === 304, no body). `etag` adds If-None-Match.
export async function api(path, { etag, method, signal } = {}) {
  const headers = { ...authHeaders };
  if (etag) headers['If-None-Match'] = etag;
  let res;
  try {
    res = await fetch(path, { method: method || 'GET', headers, cache: 'no-store', signal });
  } catch (e) {
    if (e.name !== 'AbortError') setConnection(false, `${path}: ${e.message}`);
    throw e;
  }
  // A 502/504 is a proxy saying the server is gone; other answers prove the server is reachable.
  setConnection(res.status !== 502 && res.status !== 504, `${path}: ${res.status}`);
  if (res.ok || res.status === 304) return res;
  throw new HttpError(path, res.status, (await res.text()).slice(0, 200));
}

// A download that sends the token: fetch, then save the blob under `name`.
export async function downloadWithToken(url, name) {
  const blob = await (await api(url)).blob();
  const a = Object.assign(document.createElement('a'), { href: URL.createObjectURL(blob), download: name });
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(a.href), 10000);
}
