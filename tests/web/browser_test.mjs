// Drives the viewer in headless Chromium against a real cslam-server (behind --http-token, no
// --datasets-dir) while two clients stream: both clients listed with their state, the 3D canvas
// drawn; the live dense map: a mesh with > 0 triangles per fused group in the page's scene graph,
// after the fusion every submap drawn at the server's T_world_submap (1 mm), the mesh visible on the
// canvas (screenshot), its cloud downloaded from the download menu; the full-rate reconstruction
// button; the bytes the page downloaded (reported; the index costs <= 1 KB per submap).
// Usage: node browser_test.mjs URL WEB_DIR ARTIFACT_DIR TOKEN
import { createRequire } from 'node:module';
import { readFileSync } from 'node:fs';
import path from 'node:path';

const [url, webDir, artifacts, token] = process.argv.slice(2);
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');
const fail = (msg) => { throw new Error(msg); };
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const auth = { Authorization: `Bearer ${token}` };
const server = async (p) => {
  const res = await fetch(new URL(p, url), { headers: auth });
  if (!res.ok) fail(`${p}: ${res.status} ${await res.text()}`);
  return res;
};
async function waitFor(what, fn, timeout) {
  const t0 = Date.now();
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() - t0 > timeout) fail(`timed out after ${timeout / 1000} s waiting for ${what}`);
    await sleep(250);
  }
}
function plyVertices(file) {
  const bytes = readFileSync(file);
  const header = bytes.subarray(0, Math.min(bytes.length, 1024)).toString('latin1');
  if (!header.startsWith('ply\n') || header.indexOf('end_header\n') < 0) return -1;
  return Number((/element vertex (\d+)/.exec(header) || [])[1] || 0);
}

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
    '--no-first-run', '--disable-sync', '--enable-unsafe-swiftshader'],
});
try {
  // https (browser_test.sh tls): the test's self-signed certificate is accepted by the browser.
  const page = await browser.newPage({ viewport: { width: 1400, height: 860 }, acceptDownloads: true,
    ignoreHTTPSErrors: url.startsWith('https:') });
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  const t0 = Date.now();
  await page.goto(`${url}#token=${token}`);
  await page.waitForFunction(() => window.cslamViewer, null, { timeout: 60000 }).catch(() =>
    fail('the page did not start (does the server serve the viewer modules web/*.js?)'));

  // Both clients appear, each with a tracking state, and SLAM is running on them.
  await page.waitForFunction(() => {
    const rows = [...document.querySelectorAll('#clients tbody tr')];
    return rows.length === 2 && rows.every((r) => r.cells[3].textContent === 'tracking' && Number(r.cells[5].textContent) > 5);
  }, null, { timeout: 30000 });
  const names = await page.$$eval('#clients tbody tr', (rows) => rows.map((r) => `${r.cells[1].textContent}:${r.cells[2].textContent}:${r.cells[3].textContent}`));
  console.log('clients:', names.join(' '));
  if (!names.some((n) => n.startsWith('robot1:')) || !names.some((n) => n.startsWith('robot2:'))) fail(`clients ${names}`);
  // Each robot's link: bytes per second while it streams, and a compression ratio above 1.
  await page.waitForFunction(() => [...document.querySelectorAll('#clients tbody tr')].every((r) =>
    Number(r.querySelector('.rate').textContent) > 0 && parseFloat(r.querySelector('.ratio').textContent) > 1), null, { timeout: 30000 })
    .catch(() => fail('no MB/s and compression ratio in the client table'));
  console.log('links:', (await page.$$eval('#clients tbody tr', (rows) => rows.map((r) =>
    `${r.cells[1].textContent} ${r.querySelector('.rate').textContent} MB/s ${r.querySelector('.ratio').textContent}`))).join(', '));

  // Pixels of the 3D canvas (or of a rectangle of it) that differ from the background.
  const coloured = (rect) => page.evaluate((r) => {
    const gl = document.querySelector('#view canvas');
    if (!gl) return -1;
    const c = Object.assign(document.createElement('canvas'), { width: gl.width, height: gl.height });
    const ctx = c.getContext('2d');
    ctx.drawImage(gl, 0, 0);
    const box = r || { x0: 0, y0: 0, x1: c.width, y1: c.height };
    const d = ctx.getImageData(box.x0, box.y0, Math.max(1, box.x1 - box.x0), Math.max(1, box.y1 - box.y0)).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x11) + Math.abs(d[i + 1] - 0x18) + Math.abs(d[i + 2] - 0x27) > 60) n++;
    return n;
  }, rect);
  // three.js (1.3 MB) is parsed by a software-rendering browser that shares two cores with the
  // server, the robots and the other tests: wait for the canvas itself, then for pixels.
  await page.waitForSelector('#view canvas', { timeout: 90000 }).catch(async () =>
    fail(`the 3D view did not start in 90 s (${await page.textContent('#view-msg')})`));
  let drawn = -1;
  for (let i = 0; i < 120 && drawn < 200; i++) { await page.waitForTimeout(250); drawn = await coloured(); }
  console.log('non-background canvas pixels:', drawn);
  if (drawn < 200) fail(`3D view not drawn (${drawn} coloured pixels; ${await page.textContent('#view-msg')})`);

  // The fusion of the two robots, then the dense map settled on the server (its status says so) and
  // in the page: same index version, every submap with a surface drawn at its geometry version and
  // the server's pose, and the panel showing the server's map as settled.
  await waitFor('the fusion of the two robots', async () =>
    (await (await server('/api/fusion/events')).json()).events.some((e) => e.kind === 'fusion'), 60000);
  let last = null;
  const match = await waitFor('the page to show the server\'s dense map', async () => {
    const st = await (await server('/api/dense/status')).json();
    const index = await (await server('/api/dense/submaps')).json();
    const mine = await page.evaluate(() => window.cslamViewer.denseState());
    const pageSubs = new Map(Object.values(mine.groups).flatMap((g) => g.submaps).map((s) => [s.id, s]));
    let worstMm = 0, worstRad = 0, subs = 0;
    const panel = await page.textContent('#dense-info');
    last = `server version ${index.version} settled ${st.settled} queue ${st.queue} pending ${st.pending}, page version ${mine.version}, panel "${panel}"`;
    if (!st.enabled || !st.settled || mine.version !== index.version || index.groups.length === 0) return null;
    if (!panel.includes(', settled')) return null;  // the panel says so once it has read the status
    for (const g of index.groups) {
      for (const s of g.submaps) {
        const m = pageSubs.get(s.id);
        if (!m || m.version !== s.version || m.pose_version !== s.pose_version) return null;
        if (s.triangles > 0 && (m.loaded_version !== s.version || m.state !== 'loaded')) return null;
        const T = s.T_world_submap, qn = Math.hypot(...T.slice(3));
        worstMm = Math.max(worstMm, 1000 * Math.hypot(m.position[0] - T[0], m.position[1] - T[1], m.position[2] - T[2]));
        worstRad = Math.max(worstRad, 2 * Math.acos(Math.min(1, Math.abs(m.quaternion.reduce((a, q, i) => a + q * T[3 + i] / qn, 0)))));
        subs += 1;
      }
    }
    return { index, mine, worstMm, worstRad, subs };
  }, 60000).catch((e) => fail(`${e.message} (${last})`));
  const groups = match.index.groups.map((g) => `group ${g.group} (clients ${g.clients.join('+')}): ${g.submaps.length} submaps`);
  console.log(`dense map: ${groups.join('; ')}; worst page-vs-server submap offset ${match.worstMm.toFixed(4)} mm, ${(1000 * match.worstRad).toFixed(4)} mrad`);
  if (match.worstMm > 1 || match.worstRad > 1e-3) fail('the page draws submaps away from the server\'s T_world_submap');
  const fused = match.index.groups.find((g) => g.clients.length >= 2);
  if (!fused) fail('no fused group in the dense map');
  const scene = await page.evaluate(() => window.cslamViewer.sceneMeshes());
  console.log('scene graph:', JSON.stringify(scene));
  for (const g of match.index.groups)
    if (g.submaps.some((s) => s.triangles > 0) && !(scene[g.group]?.triangles > 0)) fail(`group ${g.group}: no mesh in the scene graph`);

  // The mesh on the canvas: only the dense layer, the fused group's screen area.
  await page.evaluate(() => { for (const n of ['trajectories', 'robots']) document.getElementById(`show-${n}`).click(); });
  await page.waitForTimeout(700);
  const rect = await page.evaluate((G) => window.cslamViewer.screenRect(G), fused.group);
  const inside = rect ? await coloured(rect) : 0, area = rect ? (rect.x1 - rect.x0) * (rect.y1 - rect.y0) : 0;
  console.log(`dense mesh of group ${fused.group}: ${inside} of ${area} pixels of its screen area ${JSON.stringify(rect)} coloured`);
  if (inside < 500 || inside < 0.05 * area) fail('the dense mesh is not visible on the canvas');
  await page.screenshot({ path: path.join(artifacts, 'viewer_dense.png') });
  await page.evaluate(() => { for (const n of ['trajectories', 'robots']) document.getElementById(`show-${n}`).click(); });

  // Download menu: the fused group's cloud through fetch with the token.
  await page.selectOption('#group', String(fused.group));
  const [cloud] = await Promise.all([page.waitForEvent('download'), page.click('#downloads a[data-route="cloud.ply"]')]);
  const cloudFile = path.join(artifacts, 'viewer_dense_cloud.ply');
  await cloud.saveAs(cloudFile);
  console.log(`dense cloud from the download menu: ${plyVertices(cloudFile)} vertices`);
  if (plyVertices(cloudFile) <= 0) fail('the download menu\'s cloud.ply is not a PLY with vertices');

  // Full-rate reconstruction (from the keyframe store): trigger, wait for the links, download.
  await page.click('#recon-start');
  const recon = await waitFor('the reconstruction job', () => page.evaluate(() =>  // the button is disabled while it runs
    document.getElementById('recon-start').disabled ? null : document.getElementById('recon-state').textContent || '(no state)'), 60000);
  console.log('reconstruction:', recon);
  if (!(await page.isHidden('#recon-links'))) {
    const [download] = await Promise.all([page.waitForEvent('download'), page.click('#dl-cloud')]);
    const file = path.join(artifacts, 'viewer_cloud.ply');
    await download.saveAs(file);
    console.log(`reconstruction PLY: ${plyVertices(file)} vertices`);
    if (plyVertices(file) <= 0) fail('downloaded file is not a PLY with vertices');
  } else {
    console.log('NOTE: the reconstruction job did not finish (the server answered as shown above); not checked');
  }
  await page.screenshot({ path: path.join(artifacts, 'viewer_screenshot.png') });

  // Bytes: what the page downloaded since it opened, per category, and the cost of the index.
  const st = await page.evaluate(() => window.cslamViewer.denseState());
  const minutes = (Date.now() - t0) / 60000;
  const indexBody = JSON.stringify(match.index).length, perSubmap = (indexBody + 200) / Math.max(1, match.subs);
  console.log(`bytes: ${st.bytesDownloaded} in the page's first ${(60 * minutes).toFixed(0)} s (initial load and downloads included: ${(st.bytesDownloaded / minutes / 1e6).toFixed(2)} MB per minute);`,
    `by category ${JSON.stringify(st.bytesByCategory)}; meshes ${st.meshLoaded} loaded of ${st.meshDownloads} requested;`,
    `index: ${st.indexFetches} requests, ${st.index304} not modified (${(st.notModified.bytes / Math.max(1, st.notModified.count)).toFixed(0)} B each)`);
  for (const u of st.poseUpdates) console.log(`pose-only update seen by the page: index of ${u.bytes} B for ${u.moved} moved of ${u.submaps} submaps`);
  console.log(`a pose-only correction costs one index: ${indexBody} B body + ~200 B headers for ${match.subs} submaps = ${perSubmap.toFixed(0)} B per submap`);
  if (perSubmap > 1024) fail('the index costs more than 1 KB per submap');
  if (st.meshDownloads > 0 && st.poseOnlyUpdates > 0) console.log(`pose-only updates applied without downloads: ${st.poseOnlyUpdates}`);
  if (errors.length) fail(`page errors: ${errors.join('; ')}`);
  console.log('browser test passed');
} finally {
  await browser.close();
}
