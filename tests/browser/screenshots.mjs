// Pictures of a report page for the docs (docs/images/), taken in headless Chromium:
//   node tests/browser/screenshots.mjs PAGE.html OUT_DIR [NAME=TEXT ...]
// Without NAME=TEXT: the README's pictures, the tables, a chart, and the first replay of a
// stuck episode stopped at its mark (report-{table,chart,replay-stuck}.png). With them: for
// each, the first replay whose title holds TEXT, stopped at its mark, as OUT_DIR/NAME.png;
// NAME=TEXT@F stops it at fraction F of the episode instead (e.g. @0.6).
import { chromium } from "playwright-core";
import { pathToFileURL } from "node:url";

const [page_path, out, ...shots] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 1000 } });
  await page.goto(pathToFileURL(page_path).href, { waitUntil: "load" });
  const replay_at_mark = async (text, file, fraction) => {
    const replay = page.locator("section.replay", { has: page.locator("h3", { hasText: text }) }).first();
    if (fraction === undefined) {
      await replay.locator("button.to-mark").click();
    } else {
      await replay.locator("input.seek").evaluate((s, f) => {
        s.value = String(Math.round(f * Number(s.max)));
        s.dispatchEvent(new Event("input"));
      }, fraction);
    }
    await replay.screenshot({ path: file });
    console.log("wrote " + file);
  };
  if (shots.length === 0) {
    await page.locator("table.metrics").nth(1).screenshot({ path: out + "/report-table.png" });
    await page.locator("figure.chart").first().screenshot({ path: out + "/report-chart.png" });
    console.log("wrote " + out + "/report-{table,chart}.png");
    await replay_at_mark(": stuck", out + "/report-replay-stuck.png");
  }
  for (const shot of shots) {
    const eq = shot.indexOf("=");
    if (eq < 1) throw new Error("expected NAME=TEXT, got " + shot);
    const [text, at] = shot.slice(eq + 1).split("@");
    await replay_at_mark(text, out + "/" + shot.slice(0, eq) + ".png", at === undefined ? undefined : Number(at));
  }
} finally {
  await browser.close();
}
