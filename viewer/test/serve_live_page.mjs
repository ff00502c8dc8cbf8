// Opens the page of a running `slamvdb map --serve --serve-wait-viewer` (live mode) in Debian's
// headless chromium (playwright-core, no browser download) and watches it follow the map: what it
// drew when it opened (before it followed GET /api/events, which is what lets mapping go on), and
// once more submaps have come (or mapping ended), without a reload. Prints JSON: {"ready",
// "opened": {"submaps": ids drawn, "points"} when the page began to follow the map, "first" (the
// first look from here) and "later": {"submaps", "points", "drawn": pixels, "events", "progress":
// text, "liveErrors"}, "reloaded", "errors", "requests": URLs not of the server}.
// The states are waited for, never a fixed time: the caller's mapping is held until the page
// follows, so however late chromium starts, the page sees the submaps that come after it opened.
//   node viewer/test/serve_live_page.mjs URL
import { chromium } from 'playwright-core';
import { countPixels } from './page_pixels.mjs';

const [url] = process.argv.slice(2);
if (!url) {
  console.error('usage: node serve_live_page.mjs URL');
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
    result.opened = await page.evaluate(() => window.slamvdbServe.live && window.slamvdbServe.live.opened);
    result.first = { ...(await page.evaluate(look)), drawn: (await page.evaluate(countPixels)).drawn };
    const drawnAtOpening = result.opened ? result.opened.submaps.length : 0;
    // Two more submaps drawn, or mapping over (the caller judges what was drawn).
    await page.waitForFunction((n) => {
      const live = window.slamvdbServe.live;
      return live && (live.submaps.length >= n + 2 || (live.progress && !live.progress.mapping));
    }, drawnAtOpening, { timeout: 90000, polling: 100 }).catch((error) => { result.wait_error = String(error); });
    // The changes received so far applied (each event is applied in turn: live.pending counts them).
    await page.waitForFunction(() => window.slamvdbServe.live.pending === 0, null, { timeout: 30000, polling: 100 })
      .catch((error) => { result.wait_error = String(error); });
    result.later = { ...(await page.evaluate(look)), drawn: (await page.evaluate(countPixels)).drawn };
    result.reloaded = !(await page.evaluate(() => window.slamvdbOpened === true));
  }
  console.log(JSON.stringify(result));
} finally {
  await browser.close();
}
