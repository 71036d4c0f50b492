// The viewer's dense layer in headless Chromium against mock_dense_server.mjs (behind a token):
// a mesh per group in the scene graph; a pose-only change and a fusion move the page's submaps to the
// server's poses (1 mm) without any mesh download; corrupt meshes are shown missing/stale and
// retried; a killed and restarted server is shown and recovered; the mesh is visible on the canvas;
// the download menu sends the token. Prints the bytes the page downloaded.
// Usage: node dense_viewer_mock.mjs WEB_DIR ARTIFACT_DIR
import { createRequire } from 'node:module';
import { spawn } from 'node:child_process';
import { readFileSync, mkdtempSync, existsSync, rmSync } from 'node:fs';
import os from 'node:os';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const [webDir, artifacts] = process.argv.slice(2);
const here = path.dirname(fileURLToPath(import.meta.url));
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');
const fail = (msg) => { throw new Error(msg); };
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const TOKEN = 'mock-secret';
const tmp = mkdtempSync(path.join(os.tmpdir(), 'cslam-dense-mock-'));

let mock = null, port = 0;
async function startMock() {
  const portFile = path.join(tmp, 'port');
  rmSync(portFile, { force: true });
  mock = spawn(process.execPath, [path.join(here, 'mock_dense_server.mjs'), '--web', webDir, '--port', String(port),
    '--port-file', portFile, '--token', TOKEN, '--clients', '3', '--submaps', '4', '--triangles', '3000'], { stdio: ['ignore', 'ignore', 'inherit'] });
  port = 0;
  for (let i = 0; i < 100 && !(port > 0); i++) {
    if (existsSync(portFile)) port = Number(readFileSync(portFile, 'utf8'));
    if (!(port > 0)) await sleep(50);
  }
  if (!(port > 0)) throw new Error('the mock server did not write its port');
}
const control = async (p) => (await fetch(`http://127.0.0.1:${port}/mock/${p}`)).json();

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
    '--no-first-run', '--disable-sync', '--enable-unsafe-swiftshader'],
});
try {
  await startMock();
  const page = await browser.newPage({ viewport: { width: 1400, height: 900 }, acceptDownloads: true });
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  const indexSizes = [];  // [status, bytes on the wire] of every /api/dense/submaps answer
  page.on('requestfinished', async (req) => {
    if (!req.url().endsWith('/api/dense/submaps')) return;
    const s = await req.sizes().catch(() => null);
    const r = await req.response();
    if (s && r) indexSizes.push([r.status(), s.responseHeadersSize + s.responseBodySize]);
  });
  await page.goto(`http://127.0.0.1:${port}/#token=${TOKEN}&dense_ms=300`);
  await page.waitForFunction(() => window.cslamViewer, null, { timeout: 60000 });
  const dense = () => page.evaluate(() => window.cslamViewer.denseState());
  async function waitFor(what, fn, timeout = 15000) {
    const t0 = Date.now();
    for (;;) {
      const v = await fn();
      if (v) return v;
      if (Date.now() - t0 > timeout) fail(`timed out waiting for ${what}`);
      await sleep(150);
    }
  }
  const pageSubmaps = (st) => Object.values(st.groups).flatMap((g) => g.submaps);
  // Every submap of the server's index is drawn at the server's pose (position 1 mm, rotation 1 mrad).
  async function matchesServer() {
    const [st, srv] = [await dense(), await control('state')];
    const mine = new Map(pageSubmaps(st).map((s) => [s.id, s]));
    const theirs = srv.index.groups.flatMap((g) => g.submaps.map((s) => ({ ...s, group: g.group })));
    if (mine.size !== theirs.length) return null;
    let worstMm = 0, worstRad = 0;
    for (const s of theirs) {
      const m = mine.get(s.id);
      if (!m || m.pose_version !== s.pose_version || m.version !== s.version || m.state !== 'loaded' || !st.groups[s.group]) return null;
      const T = s.T_world_submap, qn = Math.hypot(...T.slice(3));
      worstMm = Math.max(worstMm, 1000 * Math.hypot(m.position[0] - T[0], m.position[1] - T[1], m.position[2] - T[2]));
      const dot = Math.abs(m.quaternion.reduce((a, q, i) => a + q * T[3 + i] / qn, 0));
      worstRad = Math.max(worstRad, 2 * Math.acos(Math.min(1, dot)));
    }
    return { worstMm, worstRad, st, srv };
  }
  const checkPoses = (m, what) => {
    console.log(`${what}: worst submap offset ${m.worstMm.toFixed(4)} mm, ${(1000 * m.worstRad).toFixed(4)} mrad`);
    if (m.worstMm > 1 || m.worstRad > 1e-3) fail(`${what}: page transforms differ from the server's`);
  };

  // 1. A mesh with > 0 triangles per group, in the scene graph.
  let m = await waitFor('all submaps loaded', matchesServer);
  checkPoses(m, 'initial');
  const meshes = await waitFor('meshes in the scene graph', async () => {
    const s = await page.evaluate(() => window.cslamViewer.sceneMeshes());
    return Object.keys(s).length === 2 && Object.values(s).every((g) => g.triangles > 0) ? s : null;
  });
  console.log('scene graph:', JSON.stringify(meshes));

  // Group selection: only the chosen group's meshes are drawn.
  await page.selectOption('#group', '3');
  const only3 = await waitFor('group 3 alone', async () => {
    const s = await page.evaluate(() => window.cslamViewer.sceneMeshes());
    return Object.keys(s).join() === '3' ? s : null;
  });
  console.log('group 3 selected:', JSON.stringify(only3));
  await page.selectOption('#group', 'all');

  // 2. A pose-only change: the page follows, nothing is downloaded again.
  const before = await dense(), reqBefore = (await control('state')).meshRequests;
  await control('move?id=65537&dx=0.25&yaw=0.3');
  m = await waitFor('pose-only update applied', async () => {
    const r = await matchesServer();
    return r && r.st.poseOnlyUpdates > before.poseOnlyUpdates ? r : null;
  });
  checkPoses(m, 'after a pose-only change');
  if (m.st.meshDownloads !== before.meshDownloads) fail(`pose-only change re-downloaded meshes (${before.meshDownloads} -> ${m.st.meshDownloads})`);
  if (JSON.stringify(m.srv.meshRequests) !== JSON.stringify(reqBefore)) fail('the server saw mesh requests after a pose-only change');
  const pu = m.st.poseUpdates.at(-1);
  console.log(`pose-only update: index body ${pu.bytes} B for ${pu.moved} moved of ${pu.submaps} submaps (${(pu.bytes / pu.submaps).toFixed(0)} B per submap in the index)`);

  // 3. A fusion: group 3 joins group 1 with new poses; no downloads; group 3 is gone.
  await control('fuse');
  m = await waitFor('fusion applied', async () => {
    const r = await matchesServer();
    return r && !r.st.groups[3] ? r : null;
  });
  checkPoses(m, 'after the fusion');
  if (m.st.meshDownloads !== before.meshDownloads) fail('the fusion re-downloaded meshes');
  const fusedBytes = m.st.poseUpdates.at(-1);
  console.log(`fusion: ${fusedBytes.moved} submaps moved by one index of ${fusedBytes.bytes} B (${(fusedBytes.bytes / fusedBytes.moved).toFixed(0)} B per moved submap)`);

  // 4. Bad meshes: a new submap served truncated is shown missing (marker) and retried with backoff;
  // an existing one whose new version has a bad index keeps its old mesh (stale); both recover.
  const added = (await control('add?client=1&mode=truncate')).id;
  await control('corrupt?id=131073&mode=index');
  const bad = await waitFor('bad meshes shown and retried', async () => {
    const st = await dense();
    const a = pageSubmaps(st).find((s) => s.id === added), b = pageSubmaps(st).find((s) => s.id === 131073);
    const marker = await page.evaluate((id) => !!window.cslamViewer.view().scene.getObjectByName(`submap-missing-${id}`), added);
    return a && b && a.state === 'missing' && a.failures >= 2 && marker && b.state === 'stale' && b.failures >= 1 ? { a, b, st } : null;
  });
  console.log(`truncated mesh: ${bad.a.state} after ${bad.a.failures} tries (${bad.a.last_error}); bad index: ${bad.b.state} (${bad.b.last_error})`);
  await control(`heal?id=${added}`);
  await control('heal?id=131073');
  await waitFor('bad meshes recovered', async () => {
    const st = await dense();
    return [added, 131073].every((id) => pageSubmaps(st).find((s) => s.id === id)?.state === 'loaded');
  }, 40000);

  // Removed submaps leave the scene and their geometry is disposed: the renderer holds no geometry
  // that is not in the scene (replaced and removed meshes freed, here after many replacements).
  const r0 = await page.evaluate(() => window.cslamViewer.renderStats());
  await control('remove?id=65536');
  await control('remove?id=65537');
  await waitFor('removed submaps gone', async () => {
    const st = await dense();
    return !pageSubmaps(st).some((x) => x.id === 65536 || x.id === 65537);
  });
  await page.waitForTimeout(300);
  const r1 = await page.evaluate(() => window.cslamViewer.renderStats());
  console.log(`geometries: renderer ${r0.gpu.geometries} -> ${r1.gpu.geometries}, scene ${r0.sceneGeometries} -> ${r1.sceneGeometries} after removing 2 submaps`);
  // (+ 1: the shared marker geometry of missing submaps stays for reuse)
  if (r1.gpu.geometries > r1.sceneGeometries + 1) fail('the renderer keeps geometries that left the scene');

  // Occupancy grid toggle: the grid of each group as a textured plane.
  await page.click('#show-occupancy');
  const occ = await waitFor('occupancy grid drawn', async () => {
    const o = await page.evaluate(() => window.cslamViewer.occupancy());
    return o && o.groups.length > 0 && o.groups.every((g) => g.width === 40 && g.height === 30) ? o : null;
  });
  console.log('occupancy:', JSON.stringify(occ.groups));
  await page.click('#show-occupancy');

  // 5. The screen: non-background pixels in the mesh's screen area.
  await page.evaluate(() => { for (const n of ['sparse', 'trajectories', 'robots']) document.getElementById(`show-${n}`).click(); });
  await page.waitForTimeout(500);
  const pix = await page.evaluate(() => {
    const r = window.cslamViewer.screenRect(), gl = document.querySelector('#view canvas');
    const c = Object.assign(document.createElement('canvas'), { width: gl.width, height: gl.height });
    const ctx = c.getContext('2d');
    ctx.drawImage(gl, 0, 0);
    const d = ctx.getImageData(r.x0, r.y0, Math.max(1, r.x1 - r.x0), Math.max(1, r.y1 - r.y0)).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x11) + Math.abs(d[i + 1] - 0x18) + Math.abs(d[i + 2] - 0x27) > 60) n++;
    return { rect: r, coloured: n, area: d.length / 4 };
  });
  console.log(`mesh screen area ${JSON.stringify(pix.rect)}: ${pix.coloured} of ${pix.area} pixels coloured`);
  if (pix.coloured < 500 || pix.coloured < 0.05 * pix.area) fail('dense mesh not visible on the canvas');
  await page.screenshot({ path: path.join(artifacts, 'dense_viewer_mock.png') });

  // 6. Download menu (token sent through fetch).
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#downloads a[data-route="cloud.ply"]')]);
  const file = path.join(artifacts, 'dense_viewer_mock_cloud.ply');
  await download.saveAs(file);
  if (!readFileSync(file, 'latin1').startsWith('ply\n')) fail('downloaded cloud is not a PLY');

  // 7. Tracking state on the frustum.
  await control('track?client=2&state=lost');
  await waitFor('lost robot shown', async () => (await page.evaluate(() => window.cslamViewer.robots())).some((r) => r.id === 2 && r.tracking === 'lost'));

  // 8. Server killed: the banner says so; restarted (fresh state): banner clears, the map reloads.
  mock.kill('SIGKILL');
  await waitFor('connection-lost banner', () => page.evaluate(() => {
    const b = document.getElementById('banner');
    return !b.hidden && b.className === 'lost' && !window.cslamViewer.denseState().connection.ok ? b.textContent : null;
  }));
  console.log('banner while down:', await page.textContent('#banner'));
  await sleep(1500);
  await startMock();
  await waitFor('connection restored', () => page.evaluate(() => window.cslamViewer.denseState().connection.ok));
  m = await waitFor('map reloaded after the restart', matchesServer, 30000);
  checkPoses(m, 'after the restart');
  console.log('banner after restart:', await page.textContent('#banner'));

  const st = await dense();
  console.log(`bytes: ${st.bytesDownloaded} total (${JSON.stringify(st.bytesByCategory)}), ${st.bytesPerMinute} in the last minute;`,
    `index: ${st.indexFetches} fetches, ${st.index304} not modified (${(st.notModified.bytes / Math.max(1, st.notModified.count)).toFixed(0)} B each on the wire);`,
    `meshes ${st.meshLoaded}/${st.meshDownloads}; index answers with a body: ${indexSizes.map(([, b]) => b).join(' ')} B on the wire`);
  if (errors.length) fail(`page errors: ${errors.join('; ')}`);
  console.log('dense viewer mock test passed');
} finally {
  await browser.close();
  if (mock) mock.kill('SIGKILL');
  rmSync(tmp, { recursive: true, force: true });
}
