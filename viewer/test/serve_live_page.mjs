// Opens the page of a running `slamvdb map --serve` (live mode) in Debian's headless chromium
// (playwright-core, no browser download) and watches it follow the map: what it draws when it opens
// and once more submaps have come (or mapping ended), without a reload. Prints JSON: {"ready",
// "first" and "later": {"submaps": ids drawn, "points", "drawn": pixels, "events", "progress": text},
// "reloaded", "errors", "requests": URLs not of the server}.
// Chromium takes seconds to start on a busy machine, longer than a short drive is mapped: the
// browser starts first and says so (DIR/browser-ready), then the page is opened at the URL the
// caller writes to DIR/url once `map --serve` runs.
//   node viewer/test/serve_live_page.mjs DIR
import { existsSync, readFileSync, writeFileSync } from 'node:fs';
import { chromium } from 'playwright-core';
import { countPixels } from './page_pixels.mjs';

const [dir] = process.argv.slice(2);
if (!dir) {
  console.error('usage: node serve_live_page.mjs DIR');
  process.exit(2);
}
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  // No network here: background services would only fail; SwiftShader draws WebGL without a GPU.
  args: ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
const look = () => {
  const s = window.slamvdbServe;
  return { submaps: s.live ? s.live.submaps : null, points: s.points, events: s.live ? s.live.events : 0,
           progress: document.getElementById('slamvdb-progress').textContent, liveErrors: s.live ? s.live.errors : [] };
};
try {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  writeFileSync(`${dir}/browser-ready`, '');
  let url = '';
  for (const start = Date.now(); !url; await new Promise((resolve) => setTimeout(resolve, 50))) {
    if (existsSync(`${dir}/url`)) url = readFileSync(`${dir}/url`, 'utf8').trim();
    if (Date.now() - start > 120000) throw new Error(`no ${dir}/url after 120 s`);
  }
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  const origin = new URL(url).origin;
  const requests = [];
  page.on('request', (r) => { if (!r.url().startsWith(origin)) requests.push(r.url()); });
  await page.goto(url);
  await page.waitForFunction(() => window.slamvdbServe !== undefined, null, { timeout: 60000 });
  const ready = await page.evaluate(() => ({ ready: window.slamvdbServe.ready, error: window.slamvdbServe.error }));
  const result = { ...ready, errors, requests };
  if (ready.ready) {
    await page.evaluate(() => { window.slamvdbOpened = true; });  // gone if the page reloads
    result.first = { ...(await page.evaluate(look)), drawn: (await page.evaluate(countPixels)).drawn };
    const drawnAtFirst = result.first.submaps ? result.first.submaps.length : 0;
    // Two more submaps drawn, or mapping over (the page opened late: what it drew is reported, the
    // caller judges).
    await page.waitForFunction((n) => {
      const live = window.slamvdbServe.live;
      return live && (live.submaps.length >= n + 2 || (live.progress && !live.progress.mapping));
    }, drawnAtFirst, { timeout: 90000, polling: 100 }).catch((error) => { result.wait_error = String(error); });
    await page.waitForTimeout(500);  // a change being applied
    result.later = { ...(await page.evaluate(look)), drawn: (await page.evaluate(countPixels)).drawn };
    result.reloaded = !(await page.evaluate(() => window.slamvdbOpened === true));
  }
  console.log(JSON.stringify(result));
} finally {
  await browser.close();
}
