// Measures the viewer in headless Chromium (SwiftShader): the time until the dense map is loaded,
// the frame rate (requestAnimationFrame callbacks over 10 s), the JS heap (CDP Performance.getMetrics
// and performance.memory), what is drawn (triangles, level of detail) and the bytes downloaded.
// Run by hand, not in CTest:
//   node tests/web/measure_viewer.mjs --mock [--submaps 100 --clients 3 --triangles 30000]   (starts the mock)
//   node tests/web/measure_viewer.mjs --url http://127.0.0.1:PORT/#token=...              (a running server)
// Options: --watch S (bytes per minute over S s after the page opened), --seconds 10 (frame-rate window), --load-timeout 180, --hash "budget=3000000&..." (viewer options),
//          --screenshot FILE, --width 1400 --height 900.
import { createRequire } from 'node:module';
import { spawn } from 'node:child_process';
import { existsSync, readFileSync, mkdtempSync, rmSync } from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const webDir = path.resolve(here, '../../web');
const arg = (k, d) => { const i = process.argv.indexOf(`--${k}`); return i > 0 ? process.argv[i + 1] : d; };
const has = (k) => process.argv.includes(`--${k}`);
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');

let mock = null, url = arg('url', '');
const tmp = mkdtempSync(path.join(os.tmpdir(), 'cslam-measure-'));
if (has('mock')) {
  const portFile = path.join(tmp, 'port');
  mock = spawn(process.execPath, [path.join(here, 'mock_dense_server.mjs'), '--web', webDir, '--port-file', portFile,
    '--clients', arg('clients', '3'), '--submaps', arg('submaps', '100'), '--triangles', arg('triangles', '30000')], { stdio: 'inherit' });
  for (let i = 0; i < 200 && !existsSync(portFile); i++) await sleep(50);
  url = `http://127.0.0.1:${readFileSync(portFile, 'utf8')}/`;
}
if (!url) throw new Error('give --mock or --url');
if (arg('hash')) url += (url.includes('#') ? '&' : '#') + arg('hash');

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
    '--no-first-run', '--disable-sync', '--enable-unsafe-swiftshader', '--enable-precise-memory-info'],
});
try {
  const page = await browser.newPage({ viewport: { width: Number(arg('width', 1400)), height: Number(arg('height', 900)) } });
  const cdp = await page.context().newCDPSession(page);
  await cdp.send('Performance.enable');
  const t0 = Date.now();
  await page.goto(url);
  await page.waitForFunction(() => window.cslamViewer, null, { timeout: 30000 });
  const state = () => page.evaluate(() => window.cslamViewer.denseState());
  // --watch S: the bytes the page downloads over S seconds right after it opened (robots mapping).
  let watch = null;
  if (Number(arg('watch', 0)) > 0) {
    await page.waitForFunction(() => window.cslamViewer?.denseState().frames > 0, null, { timeout: 30000 });  // past the page's own files
    const a = await state(), S = Number(arg('watch', 0));
    const tw = Date.now();
    await sleep(1000 * S);
    const b = await state(), s = (Date.now() - tw) / 1000;
    const cat = Object.fromEntries(Object.keys(b.bytesByCategory).map((k) => [k, Math.round((b.bytesByCategory[k] - (a.bytesByCategory[k] || 0)) * 60 / s)]));
    watch = { seconds: +s.toFixed(1), bytes_per_minute: Math.round((b.bytesDownloaded - a.bytesDownloaded) * 60 / s), per_minute_by_category: cat,
      mesh_downloads: b.meshDownloads - a.meshDownloads, pose_only_updates: b.poseOnlyUpdates - a.poseOnlyUpdates, pose_updates: b.poseUpdates };
    console.log('while watching:', JSON.stringify(watch, null, 1));
  }
  // Loaded: something drawn, nothing in flight, no submap waiting, twice in a row.
  let st = null, quiet = 0;
  const timeout = 1000 * Number(arg('load-timeout', 180));
  while (Date.now() - t0 < timeout && quiet < 2) {
    await sleep(1000);
    st = await state();
    const subs = Object.values(st.groups).flatMap((g) => g.submaps);
    const waiting = subs.filter((s) => s.state === 'pending' || s.loaded_version !== s.version).length;
    quiet = subs.length && st.inFlight === 0 && waiting === 0 ? quiet + 1 : 0;
  }
  const loadS = (Date.now() - t0) / 1000;
  // Frame rate while the camera orbits (every frame renders): requestAnimationFrame callbacks and
  // renders over the window; then idle (the page renders on demand).
  const seconds = Number(arg('seconds', 10));
  const rate = (spin) => page.evaluate(([s, spin]) => new Promise((resolve) => {
    window.cslamViewer.spin(spin);
    let n = 0;
    const t = performance.now(), r0 = window.cslamViewer.renderStats().renders;
    const f = () => {
      n++;
      if (performance.now() - t < 1000 * s) return requestAnimationFrame(f);
      window.cslamViewer.spin(false);
      const ms = performance.now() - t;
      resolve({ raf_per_s: n / (ms / 1000), renders_per_s: (window.cslamViewer.renderStats().renders - r0) / (ms / 1000) });
    };
    requestAnimationFrame(f);
  }), [seconds, spin]);
  const moving = await rate(true), idle = await rate(false);
  const render = await page.evaluate(() => window.cslamViewer.renderStats());
  await page.evaluate(() => new Promise((r) => setTimeout(r, 100)));
  const metrics = Object.fromEntries((await cdp.send('Performance.getMetrics')).metrics.map((m) => [m.name, m.value]));
  const mem = await page.evaluate(() => (performance.memory ? { used: performance.memory.usedJSHeapSize, total: performance.memory.totalJSHeapSize } : null));
  st = await state();
  const subs = Object.values(st.groups).flatMap((g) => g.submaps);
  const lods = [0, 1, 2].map((l) => subs.filter((s) => s.lod === l).length);
  const scene = await page.evaluate(() => window.cslamViewer.sceneMeshes());
  const triangles = Object.values(scene).reduce((a, g) => a + g.triangles, 0);
  console.log(JSON.stringify({ url: url.replace(/token=[^&]*/, 'token=…'), submaps: subs.length, drawn_triangles: triangles,
    index_triangles: subs.reduce((a, s) => a + s.index_triangles, 0), lod_counts: lods, load_s: +loadS.toFixed(1),
    fps_orbiting: +moving.renders_per_s.toFixed(1), raf_per_s_orbiting: +moving.raf_per_s.toFixed(1),
    renders_per_s_idle: +idle.renders_per_s.toFixed(2), raf_per_s_idle: +idle.raf_per_s.toFixed(1),
    software_gl: render.software, triangle_budget: st.triangleBudget, js_heap_used_mb: +(metrics.JSHeapUsedSize / 1e6).toFixed(1), js_heap_total_mb: +(metrics.JSHeapTotalSize / 1e6).toFixed(1),
    performance_memory_used_mb: mem ? +(mem.used / 1e6).toFixed(1) : null, mesh_downloads: st.meshDownloads, mesh_bytes: st.meshBytes,
    bytes_downloaded: st.bytesDownloaded, bytes_last_minute: st.bytesPerMinute, bytes_by_category: st.bytesByCategory,
    errors: st.errors }, null, 1));
  if (arg('screenshot')) await page.screenshot({ path: arg('screenshot') });
} finally {
  await browser.close();
  if (mock) mock.kill('SIGKILL');
  rmSync(tmp, { recursive: true, force: true });
}
