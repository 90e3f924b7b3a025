// The README's pictures of a report page (docs/images/): the tables, a chart, and a replay
// of an inertia episode stopped at its mark, taken in headless Chromium:
//   node tests/browser/screenshots.mjs PAGE.html OUT_DIR
import { chromium } from "playwright-core";
import { pathToFileURL } from "node:url";

const [page_path, out] = process.argv.slice(2);
const browser = await chromium.launch({ executablePath: "/usr/bin/chromium", args: ["--no-sandbox"] });
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 1000 } });
  await page.goto(pathToFileURL(page_path).href, { waitUntil: "load" });
  await page.locator("table.metrics").nth(1).screenshot({ path: out + "/report-table.png" });
  await page.locator("figure.chart").first().screenshot({ path: out + "/report-chart.png" });
  const replay = page.locator("section.replay", { hasText: "inertia" }).first();  // bc-oh freezes in the quickstart
  await replay.locator("button.to-mark").click();
  await replay.screenshot({ path: out + "/report-replay-inertia.png" });
  console.log("wrote " + out + "/report-{table,chart,replay-inertia}.png");
} finally {
  await browser.close();
}
