// Opens an HTML report (causaldrive report --html) from its file in headless Chromium (Debian's
// /usr/bin/chromium, driven by playwright-core) and prints one JSON line of what it saw:
//   node report_page.mjs PAGE.html SCREENSHOT.png
// console_errors (console errors and uncaught exceptions), the replays found, the first
// replay's frame index, frame source (and whether it is that frame's) and trace cursor before and after one click on its step
// button, then after its failure button, and the screenshot's size and distinct colours (a
// blank page has one or two). The Python test (tests/python/test_html_report.py) judges it.
import { chromium } from "playwright-core";
import { readFileSync } from "node:fs";
import { inflateSync } from "node:zlib";
import { pathToFileURL } from "node:url";

// The pixels of an 8-bit RGB or RGBA PNG (what Chromium's screenshots are).
function decodePng(buf) {
  let pos = 8, width = 0, height = 0, colourType = 0;
  const idat = [];
  while (pos < buf.length) {
    const len = buf.readUInt32BE(pos), type = buf.toString("ascii", pos + 4, pos + 8);
    const data = buf.subarray(pos + 8, pos + 8 + len);
    if (type === "IHDR") { width = data.readUInt32BE(0); height = data.readUInt32BE(4); colourType = data[9]; }
    if (type === "IDAT") idat.push(data);
    pos += 12 + len;
  }
  const bpp = colourType === 6 ? 4 : 3, stride = width * bpp;
  const raw = inflateSync(Buffer.concat(idat)), out = Buffer.alloc(height * stride);
  for (let y = 0; y < height; y++) {
    const f = raw[y * (stride + 1)], line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let i = 0; i < stride; i++) {
      const a = i >= bpp ? out[y * stride + i - bpp] : 0, b = y > 0 ? out[(y - 1) * stride + i] : 0;
      const c = i >= bpp && y > 0 ? out[(y - 1) * stride + i - bpp] : 0;
      let v = line[i];
      if (f === 1) v += a; else if (f === 2) v += b; else if (f === 3) v += (a + b) >> 1;
      else if (f === 4) { const p = a + b - c, pa = Math.abs(p - a), pb = Math.abs(p - b), pc = Math.abs(p - c);
        v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c; }
      out[y * stride + i] = v & 255;
    }
  }
  return { width, height, bpp, pixels: out };
}

const [page_path, shot_path] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox"] });
const result = { console_errors: [] };
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 1600 } });
  page.on("console", (m) => { if (m.type() === "error") result.console_errors.push(m.text()); });
  page.on("pageerror", (e) => result.console_errors.push(String(e)));
  page.on("requestfailed", (r) => result.console_errors.push("request failed: " + r.url()));
  await page.goto(pathToFileURL(page_path).href, { waitUntil: "load" });
  const state = () => page.evaluate(() => {
    const sec = document.querySelector("section.replay");
    if (!sec) return null;
    const frame = Number(sec.getAttribute("data-frame"));
    const src = sec.querySelector("img.frame").getAttribute("src");
    const frames = JSON.parse(sec.querySelector("script.replay-data").textContent).frames;
    return { frame, src, src_is_frame: src === frames[frame],
             cursor: Number(sec.querySelector("svg.trace line.cursor").getAttribute("x1")),
             values: sec.querySelector(".values").textContent };
  });
  result.replays = await page.locator("section.replay").count();
  result.charts = await page.locator("figure.chart svg rect[data-series]").count();
  result.table_rows = await page.locator("table.metrics tr").count();
  result.before = await state();
  if (result.replays > 0) {
    await page.locator("section.replay").first().locator("button.step").click();
    result.after_step = await state();
    await page.locator("section.replay").first().locator("button.to-mark").click();
    result.after_mark = await state();
    await page.locator("section.replay").first().scrollIntoViewIfNeeded();
  }
  const shot = await page.screenshot({ path: shot_path });
  const png = decodePng(shot), colours = new Set();
  for (let i = 0; i < png.pixels.length && colours.size < 1000; i += png.bpp)
    colours.add((png.pixels[i] << 16) | (png.pixels[i + 1] << 8) | png.pixels[i + 2]);
  result.screenshot = { width: png.width, height: png.height, distinct_colours: colours.size };
} finally {
  await browser.close();
}
console.log(JSON.stringify(result));
