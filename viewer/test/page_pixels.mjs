// What the serve page's canvas shows, counted in the page (page.evaluate(countPixels)): pixels that
// differ from the background, and the hot ones of the heat map (its top quarter: orange to
// yellow) with their centroid. Shared by serve_page.mjs and serve_live_page.mjs.
export const countPixels = () => {
  const canvas = window.slamvdbServe.canvas;
  const copy = document.createElement('canvas');
  copy.width = canvas.width;
  copy.height = canvas.height;
  const context = copy.getContext('2d');
  context.drawImage(canvas, 0, 0);
  const data = context.getImageData(0, 0, copy.width, copy.height).data;
  let drawn = 0, hot = 0, sx = 0, sy = 0;
  for (let i = 0; i < data.length; i += 4) {
    const [r, g, b] = [data[i], data[i + 1], data[i + 2]];
    if (Math.abs(r - 0x10) + Math.abs(g - 0x14) + Math.abs(b - 0x18) > 24) ++drawn;
    if (r > 200 && g > 120 && b < 110) {
      ++hot;
      const p = i / 4;
      sx += p % copy.width;
      sy += Math.floor(p / copy.width);
    }
  }
  return { drawn, hot, centroid: hot ? [sx / hot, sy / hot] : null, pixels: copy.width * copy.height };
};
