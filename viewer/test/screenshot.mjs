// Opens a page written by `slamvdb export --html` in Debian's headless chromium (playwright-core,
// no browser download), waits for the viewer, saves a screenshot and prints what was drawn as JSON:
// {"ready": true, "points": N, "drawn": <pixels that are not the background>, "pixels": W*H,
//  "legend": [...], "errors": [...]}.
//   node viewer/test/screenshot.mjs PAGE.html SHOT.png
import { chromium } from 'playwright-core';
import { pathToFileURL } from 'node:url';

const [page_path, shot_path] = process.argv.slice(2);
if (!page_path || !shot_path) {
  console.error('usage: node screenshot.mjs PAGE.html SHOT.png');
  process.exit(2);
}
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
  const requests = [];
  page.on('request', (r) => { if (!r.url().startsWith('file:') && !r.url().startsWith('data:')) requests.push(r.url()); });
  await page.goto(pathToFileURL(page_path).href);
  await page.waitForFunction(() => window.slamvdbViewer !== undefined, null, { timeout: 60000 });
  const result = await page.evaluate(() => {
    const v = window.slamvdbViewer;
    if (!v.ready) return { ready: false, error: v.error };
    // Read the WebGL canvas back (preserveDrawingBuffer) and count pixels unlike the background.
    const canvas = v.canvas;
    const copy = document.createElement('canvas');
    copy.width = canvas.width;
    copy.height = canvas.height;
    const context = copy.getContext('2d');
    context.drawImage(canvas, 0, 0);
    const data = context.getImageData(0, 0, copy.width, copy.height).data;
    let drawn = 0;
    for (let i = 0; i < data.length; i += 4) {
      if (Math.abs(data[i] - 0x10) + Math.abs(data[i + 1] - 0x14) + Math.abs(data[i + 2] - 0x18) > 24) ++drawn;
    }
    const legend = [...document.querySelectorAll('#slamvdb-panel .legend')].map((e) => e.textContent);
    return { ready: true, points: v.points, drawn, pixels: copy.width * copy.height, legend };
  });
  await page.screenshot({ path: shot_path });
  result.errors = errors;
  result.requests = requests;
  console.log(JSON.stringify(result));
} finally {
  await browser.close();
}
