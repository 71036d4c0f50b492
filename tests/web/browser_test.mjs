// Drives the viewer in headless Chromium: both clients listed with their state, trajectories drawn
// on the 3D canvas (non-background pixels), a reconstruction triggered and its PLY downloaded.
// Usage: node browser_test.mjs URL WEB_DIR ARTIFACT_DIR
import { createRequire } from 'node:module';
import { readFileSync } from 'node:fs';
import path from 'node:path';

const [url, webDir, artifacts] = process.argv.slice(2);
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');
const fail = (msg) => { throw new Error(msg); };

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-background-networking', '--disable-component-update',
    '--no-first-run', '--disable-sync', '--enable-unsafe-swiftshader'],
});
try {
  const page = await browser.newPage({ viewport: { width: 1400, height: 860 }, acceptDownloads: true });
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.goto(url);

  // Both clients appear, each with a tracking state, and SLAM is running on them.
  await page.waitForFunction(() => {
    const rows = [...document.querySelectorAll('#clients tbody tr')];
    return rows.length === 2 && rows.every((r) => r.cells[3].textContent === 'tracking' && Number(r.cells[5].textContent) > 5);
  }, null, { timeout: 30000 });
  const names = await page.$$eval('#clients tbody tr', (rows) => rows.map((r) => `${r.cells[1].textContent}:${r.cells[2].textContent}:${r.cells[3].textContent}`));
  console.log('clients:', names.join(' '));
  if (!names.some((n) => n.startsWith('robot1:')) || !names.some((n) => n.startsWith('robot2:'))) fail(`clients ${names}`);

  // The 3D canvas has drawn trajectories: count pixels that differ from the background.
  const coloured = async () => page.evaluate(() => {
    const gl = document.querySelector('#view canvas');
    if (!gl) return -1;
    const c = Object.assign(document.createElement('canvas'), { width: gl.width, height: gl.height });
    const ctx = c.getContext('2d');
    ctx.drawImage(gl, 0, 0);
    const d = ctx.getImageData(0, 0, c.width, c.height).data;
    let n = 0;
    for (let i = 0; i < d.length; i += 4) if (Math.abs(d[i] - 0x11) + Math.abs(d[i + 1] - 0x18) + Math.abs(d[i + 2] - 0x27) > 60) n++;
    return n;
  });
  let drawn = -1;
  for (let i = 0; i < 40 && drawn < 200; i++) { await page.waitForTimeout(250); drawn = await coloured(); }
  console.log('non-background canvas pixels:', drawn);
  if (drawn < 200) fail(`3D view not drawn (${drawn} coloured pixels; ${await page.textContent('#view-msg')})`);
  await page.screenshot({ path: path.join(artifacts, 'viewer_screenshot.png') });

  // Reconstruction: trigger from the page, wait for the links, download the cloud.
  await page.click('#recon-start');
  await page.waitForSelector('#recon-links:not([hidden])', { timeout: 60000 });
  console.log('reconstruction:', await page.textContent('#recon-state'));
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#dl-cloud')]);
  const file = path.join(artifacts, 'viewer_cloud.ply');
  await download.saveAs(file);
  const bytes = readFileSync(file);
  const header = bytes.subarray(0, Math.min(bytes.length, 1024)).toString('latin1');
  const vertices = Number((/element vertex (\d+)/.exec(header) || [])[1] || 0);
  const end = header.indexOf('end_header\n');
  console.log(`downloaded PLY: ${bytes.length} bytes, ${vertices} vertices`);
  if (!header.startsWith('ply\n') || end < 0 || vertices <= 0) fail('downloaded file is not a PLY with vertices');
  await page.screenshot({ path: path.join(artifacts, 'viewer_screenshot.png') });
  if (errors.length) fail(`page errors: ${errors.join('; ')}`);
  console.log('browser test passed');
} finally {
  await browser.close();
}
