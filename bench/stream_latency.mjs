// End-to-end latency of the live stream as a viewer sees it: a real browser (headless Chromium)
// opens the viewer of a running `zipfusion serve` and reads, after a warm-up, the overlay's
// median latency (capture → drawn, the last 60 frames) and frame rate, several times.
// Usage: node bench/stream_latency.mjs URL [--seconds 20]
import { chromium } from '../web/node_modules/playwright-core/index.mjs';

const url = process.argv[2];
const i = process.argv.indexOf('--seconds');
const seconds = i >= 0 ? Number(process.argv[i + 1]) : 20;
const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
await page.goto(url);
await page.waitForFunction(() => Number(document.body.dataset.frames || 0) >= 30, null, { timeout: 60000 });
const samples = [];
const end = Date.now() + seconds * 1000;
while (Date.now() < end) {
  await page.waitForTimeout(2000);
  const latency = parseFloat(await page.textContent('#latency'));
  const fps = parseFloat(await page.textContent('#fps'));
  const flowWindow = await page.evaluate(() => document.body.dataset.flowWindow);
  samples.push({ latency, fps, flowWindow });
}
await browser.close();
const median = (v) => [...v].sort((a, b) => a - b)[Math.floor(v.length / 2)];
const result = { latency_ms_median: median(samples.map((s) => s.latency)), fps_median: median(samples.map((s) => s.fps)), samples: samples.length,
  windows: samples.map((s) => s.flowWindow) };
console.log(JSON.stringify(result));
