// Saves a screenshot of the viewer after WAIT seconds (for docs/viewer.png during a demo run).
// Usage: node screenshot.mjs URL WEB_DIR OUT.png [WAIT=20]
import { createRequire } from 'node:module';
import path from 'node:path';

const [url, webDir, out, wait = '20'] = process.argv.slice(2);
const { chromium } = createRequire(path.join(webDir, 'package.json'))('playwright-core');
const browser = await chromium.launch({ executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--no-first-run', '--disable-sync', '--enable-unsafe-swiftshader'] });
const page = await browser.newPage({ viewport: { width: 1400, height: 700 } });
await page.goto(url);
await page.waitForTimeout(1000 * Number(wait));
await page.screenshot({ path: out });
await browser.close();
