// The viewer in a real browser (Debian's Chromium, headless, driven by playwright-core): against a
// real `zipfusion serve` of a synthetic capture, the page loads, frames arrive and are drawn (the
// canvas is not blank and changes as the subject moves), the overlay shows a frame rate, and with
// a token a client without it is refused. Usage:
//   node web/tests/viewer_test.mjs --zipfusion build/zipfusion --web build/web
import { spawn, spawnSync } from 'node:child_process';
import { mkdtempSync, rmSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join } from 'node:path';
import { chromium } from 'playwright-core';

const arg = (name, fallback) => {
  const i = process.argv.indexOf(name);
  return i >= 0 ? process.argv[i + 1] : fallback;
};
const zipfusion = arg('--zipfusion', 'build/zipfusion');
const web = arg('--web', 'build/web');
const artifacts = arg('--artifacts', '');

let failures = 0;
function check(condition, what) {
  console.log(`${condition ? 'ok  ' : 'FAIL'} ${what}`);
  if (!condition) failures += 1;
}

const work = mkdtempSync(join(tmpdir(), 'zf_viewer_test_'));
const capture = join(work, 'capture');
const synth = spawnSync(zipfusion, ['synth', '--out', capture, '--frames', '12', '--cameras', '3'], { encoding: 'utf8' });
if (synth.status !== 0) throw new Error(`synth failed: ${synth.stderr}`);

// Starts `zipfusion serve` on a free port; resolves with its URL once it listens.
function serve(extra, port = '0') {
  const child = spawn(zipfusion, ['serve', capture, '--loop', '--port', port, '--web', web, ...extra], { stdio: ['ignore', 'pipe', 'pipe'] });
  return new Promise((resolve, reject) => {
    let out = '';
    const timer = setTimeout(() => reject(new Error(`serve did not start: ${out}`)), 20000);
    child.stdout.on('data', (chunk) => {
      out += chunk;
      const match = out.match(/serving (http:\/\/\S+)/);
      if (match) {
        clearTimeout(timer);
        resolve({ child, url: match[1] });
      }
    });
    child.stderr.on('data', (chunk) => { out += chunk; });
    child.on('exit', (code) => reject(new Error(`serve exited with ${code}: ${out}`)));
  });
}

// Non-background pixels of the WebGL canvas and a cheap fingerprint of its content.
async function canvasSummary(page) {
  return page.evaluate(() => {
    const source = document.querySelector('#view canvas');
    const probe = document.createElement('canvas');
    probe.width = 160;
    probe.height = 120;
    const context = probe.getContext('2d');
    context.drawImage(source, 0, 0, probe.width, probe.height);
    const { data } = context.getImageData(0, 0, probe.width, probe.height);
    let lit = 0;
    let hash = 0;
    for (let i = 0; i < data.length; i += 4) {
      // The background is (27, 29, 34) and the grid a little lighter: count clearly other pixels.
      if (Math.abs(data[i] - 27) + Math.abs(data[i + 1] - 29) + Math.abs(data[i + 2] - 34) > 60) lit += 1;
      hash = (hash * 31 + data[i] + 7 * data[i + 1] + 13 * data[i + 2]) >>> 0;
    }
    return { lit: lit / (probe.width * probe.height), hash };
  });
}

const browser = await chromium.launch({
  executablePath: '/usr/bin/chromium',
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const servers = [];
try {
  const plain = await serve([]);
  servers.push(plain.child);
  const page = await browser.newPage({ viewport: { width: 800, height: 600 } });
  const errors = [];
  page.on('pageerror', (e) => errors.push(String(e)));
  await page.goto(plain.url);
  await page.waitForFunction(() => Number(document.body.dataset.frames || 0) >= 10, null, { timeout: 60000 });
  const first = await canvasSummary(page);
  const firstShot = await page.screenshot();
  // The capture loops over 12 frames and a slow viewer skips some, so two samples may show the
  // same capture frame by chance: sample a few times, spaced apart, until one differs.
  let second = first;
  for (let sample = 0; sample < 6 && second.hash === first.hash; sample += 1) {
    await page.waitForFunction((n) => Number(document.body.dataset.frames || 0) >= n,
      Number(await page.evaluate(() => document.body.dataset.frames)) + 5, { timeout: 60000 });
    second = await canvasSummary(page);
  }
  const secondShot = await page.screenshot();
  if (artifacts) {
    writeFileSync(join(artifacts, 'viewer_first.png'), firstShot);
    writeFileSync(join(artifacts, 'viewer_second.png'), secondShot);
  }
  check(first.lit > 0.01, `the canvas shows the mesh (${(100 * first.lit).toFixed(1)} % of it is not background)`);
  check(first.hash !== second.hash, 'the drawing changes between frames (the subject moves)');
  // The overlay's frame rate agrees, within a factor of two, with the frames the page counts
  // drawn over three seconds: a rate, not just a number, on a machine of any speed (under
  // ThreadSanitizer the server makes about one frame a second).
  const drawnSoFar = () => page.evaluate(() => [Number(document.body.dataset.frames || 0), performance.now()]);
  const [framesBefore, before] = await drawnSoFar();
  await page.waitForTimeout(3000);
  const [framesAfter, after] = await drawnSoFar();
  const counted = (framesAfter - framesBefore) * 1000 / (after - before);
  const fps = Number(await page.textContent('#fps'));
  check(counted > 0 && fps >= counted / 2 && fps <= counted * 2, `the overlay shows the frame rate (${fps} fps; ${counted.toFixed(1)} counted)`);
  check(/\d+ ms/.test(await page.textContent('#latency')), `the overlay shows a latency (${await page.textContent('#latency')})`);
  check(/\d/.test(await page.textContent('#triangles')), `the overlay shows the triangles (${await page.textContent('#triangles')})`);
  check(/Mbit\/s/.test(await page.textContent('#bitrate')), `the overlay shows the bitrate (${await page.textContent('#bitrate')})`);
  const views = await page.$$eval('#viewpoint option', (options) => options.map((o) => o.textContent));
  check(views.length === 4 && views[1] === 'cam0', `a view from each camera is offered (${views.join(', ')})`);
  // Through camera 0, then without colour and as wireframe: the picture changes each time.
  await page.selectOption('#viewpoint', '1');
  await page.waitForTimeout(300);
  const fromCamera = await canvasSummary(page);
  check(fromCamera.lit > 0.01 && fromCamera.hash !== second.hash, 'the view from a camera shows the mesh');
  await page.uncheck('#color');
  await page.check('#wireframe');
  await page.waitForTimeout(300);
  const wire = await canvasSummary(page);
  check(wire.hash !== fromCamera.hash, 'colour off and wireframe redraw the mesh');
  // Pause: no frame is drawn any more.
  await page.click('#play');
  await page.waitForTimeout(500);
  const pausedAt = Number(await page.evaluate(() => document.body.dataset.frames));
  await page.waitForTimeout(1000);
  check(Number(await page.evaluate(() => document.body.dataset.frames)) === pausedAt, 'pause stops the drawing');
  // A paused viewer stays paused when it reconnects: the server restarts on the same port, and
  // no frames come (the overlay's bitrate is of the last second's bytes).
  const port = new URL(plain.url).port;
  const stopped = new Promise((resolve) => plain.child.once('exit', resolve));
  plain.child.kill('SIGINT');
  await stopped;
  const restarted = await serve([], port);
  servers.push(restarted.child);
  await page.waitForFunction(() => document.querySelector('#status').textContent.includes('cameras'), null, { timeout: 20000 });
  await page.waitForTimeout(2500);
  const bitrate = await page.textContent('#bitrate');
  check(/^0\.0 Mbit\/s/.test(bitrate), `a paused viewer that reconnects receives no frames (${bitrate})`);
  check(Number(await page.evaluate(() => document.body.dataset.frames)) === pausedAt, 'and draws none');
  check(errors.length === 0, `no script errors (${errors.join('; ')})`);

  // With a token: refused without it, served with it.
  const guarded = await serve(['--token', 'k3y']);
  servers.push(guarded.child);
  const base = guarded.url.replace(/\?token=.*/, '');
  const refused = await page.request.get(base);
  check(refused.status() === 401, `a request without the token is refused (${refused.status()})`);
  const second_page = await browser.newPage();
  await second_page.goto(guarded.url);
  await second_page.waitForFunction(() => Number(document.body.dataset.frames || 0) >= 5, null, { timeout: 60000 });
  check(true, 'the page with the token receives frames');
} catch (error) {
  check(false, `unexpected: ${error.stack || error}`);
} finally {
  for (const child of servers) child.kill('SIGINT');
  await browser.close();
  rmSync(work, { recursive: true, force: true });
}
process.exit(failures === 0 ? 0 : 1);
