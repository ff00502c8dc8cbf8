// Opens the page of a running `slamvdb serve` in Debian's headless chromium (playwright-core, no
// browser download), hides and shows a class layer, types a question, clicks a point, and prints
// what was drawn as JSON: {"ready", "points", "drawn", "drawn_without_first_class", "hot",
// "hot_centroid": [x, y], "answer_centroid": [x, y] (the given world points projected), "colour_bar",
// "picked": text of the clicked point, "errors", "requests": URLs not of the server}.
//   node viewer/test/serve_page.mjs URL QUERY SHOT.png '[[x,y,z],...]'
import { chromium } from 'playwright-core';
import { countPixels } from './page_pixels.mjs';

const [url, query, shotPath, answerText] = process.argv.slice(2);
if (!url || !query || !shotPath || !answerText) {
  console.error("usage: node serve_page.mjs URL QUERY SHOT.png '[[x,y,z],...]'");
  process.exit(2);
}
const answerPoints = JSON.parse(answerText);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  // No network here: background services would only fail; SwiftShader draws WebGL without a GPU.
  args: ['--no-sandbox', '--disable-gpu', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
         '--disable-background-networking', '--disable-component-update', '--disable-sync', '--no-first-run'],
});
try {
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  const origin = new URL(url).origin;
  const requests = [];
  page.on('request', (r) => { if (!r.url().startsWith(origin)) requests.push(r.url()); });
  await page.goto(url);
  await page.waitForFunction(() => window.slamvdbServe !== undefined, null, { timeout: 60000 });
  const ready = await page.evaluate(() => ({ ready: window.slamvdbServe.ready, error: window.slamvdbServe.error,
                                             points: window.slamvdbServe.points }));
  const result = { ...ready, errors, requests };
  if (ready.ready) {
    result.drawn = (await page.evaluate(countPixels)).drawn;
    await page.click('input[data-value="0"]');  // hide the first class's layer
    result.drawn_without_first_class = (await page.evaluate(countPixels)).drawn;
    await page.click('input[data-value="0"]');
    await page.fill('#slamvdb-query', query);
    await page.press('#slamvdb-query', 'Enter');
    await page.waitForFunction((q) => window.slamvdbServe.query === q, query, { timeout: 60000 });
    const heat = await page.evaluate(countPixels);
    result.hot = heat.hot;
    result.hot_centroid = heat.centroid;
    result.pixels = heat.pixels;
    const projected = await page.evaluate((points) => points.map((p) => window.slamvdbServe.project(p)), answerPoints);
    result.answer_centroid = [0, 1].map((k) => projected.reduce((s, p) => s + p[k], 0) / projected.length);
    result.colour_bar = await page.evaluate(() => document.querySelector('.colour-bar-labels').textContent);
    await page.screenshot({ path: shotPath });
    // A click on the first answer point that the panel does not cover.
    const target = await page.evaluate((points) => points.find(([x, y]) => document.elementFromPoint(x, y) === window.slamvdbServe.canvas), projected);
    result.clicked = target || null;
    if (!target) throw new Error('every answer point is under the panel or off the view');
    await page.mouse.click(target[0], target[1]);
    await page.waitForFunction(() => document.getElementById('slamvdb-picked').textContent !== '', null, { timeout: 30000 });
    result.picked = await page.evaluate(() => document.getElementById('slamvdb-picked').textContent);
  }
  console.log(JSON.stringify(result));
} finally {
  await browser.close();
}
