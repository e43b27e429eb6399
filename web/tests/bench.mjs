// Benchmarks of the web UI in headless Chromium (docs/benchmarks.md,
// "Web UI"): the fleet view of 1000 pumps, a trend of 100 000 points, a
// Bode plot of 4 entries x 2000 lines with the model and the fit overlaid
// (the phase wrapping, so with its gaps), and the JS
// and CSS shipped, gzipped. No server: the built files (build/web) are
// served to the page by playwright's request routing, and the API calls are
// answered with generated data, so only the browser's work is timed.
//   node web/tests/bench.mjs [BUILD_WEB_DIR] [--runs N]
import { readFileSync, readdirSync, statSync } from 'node:fs';
import { join, extname, resolve, dirname } from 'node:path';
import { fileURLToPath } from 'node:url';
import { gzipSync } from 'node:zlib';
import { launch } from './browser.mjs';

const here = dirname(fileURLToPath(import.meta.url));
const args = process.argv.slice(2);
const webDir = resolve(args.find((a) => !a.startsWith('--')) || join(here, '../../build/web'));
const runs = Number(args[args.indexOf('--runs') + 1]) || 7;
const TYPES = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css' };

function files(dir) {
  return readdirSync(dir).flatMap((n) => (statSync(join(dir, n)).isDirectory() ? files(join(dir, n)) : [join(dir, n)]));
}

function shippedGzip() {
  let raw = 0, gz = 0;
  for (const f of files(webDir).filter((f) => ['.js', '.css', '.html'].includes(extname(f)))) {
    const b = readFileSync(f);
    raw += b.length;
    gz += gzipSync(b, { level: 6 }).length;
  }
  return { raw, gz };
}

function fleet(n) {
  const healths = ['ok', 'ok', 'ok', 'ok', 'ok', 'ok', 'warning', 'alarm', 'unknown'];
  return {
    pumps: Array.from({ length: n }, (_, i) => {
      const health = healths[i % healths.length];
      const t = new Date(Date.UTC(2026, 10, 1) + i * 60000).toISOString().replace(/\.\d+Z/, 'Z');
      return {
        pump_id: `P-${String(i).padStart(4, '0')}`, health, active_alarms: health === 'alarm' ? 2 : health === 'warning' ? 1 : 0,
        n_runs: 100 + i, model_version: 1, last_run_id: `P-${i}/run-${t}`, last_started_at: t,
        reference: { status: 'active', version: 1, runs: [] },
        last_analysis: { run_id: `P-${i}/run-${t}`, detected: health === 'alarm', ratio: health === 'alarm' ? 3.2 : 0.4, fault: health === 'alarm' ? 'balance_piston_wear' : undefined },
      };
    }),
  };
}

const median = (xs) => [...xs].sort((a, b) => a - b)[Math.floor(xs.length / 2)];

const browser = await launch();
const page = await browser.newPage({ viewport: { width: 1400, height: 1000 } });
const pageErrors = [];
page.on('pageerror', (e) => pageErrors.push(e.message));
const fleetJson = JSON.stringify(fleet(1000));
await page.route('**/*', (route) => {
  const u = new URL(route.request().url());
  const json = (body, status = 200) => route.fulfill({ status, contentType: 'application/json', body });
  if (u.pathname === '/') return route.fulfill({ contentType: 'text/html', body: readFileSync(join(webDir, 'index.html')) });
  if (u.pathname.startsWith('/ui/')) {
    const f = join(webDir, u.pathname.slice(4));
    return route.fulfill({ contentType: TYPES[extname(f)] || 'application/octet-stream', body: readFileSync(f) });
  }
  if (u.pathname === '/api/v1/fleet') return json(fleetJson);
  if (u.pathname === '/api/v1/events') return route.fulfill({ contentType: 'text/event-stream', body: 'retry: 600000\n\n' });
  if (u.pathname === '/api/v1/me') return json('{"name": "anonymous", "role": "viewer", "anonymous": true}');
  return json('{"error": "no such resource: ' + u.pathname + '"}', 404);
});
await page.goto('http://ambdiag.bench/#/fleet');
await page.waitForFunction(() => /^1000 of 1000/.test(document.querySelector('#fleet-info')?.textContent || ''));

// Fleet: from the route change to the 1000 pumps' table rendered and
// painted (fetch of the generated JSON, parse, sort, render, layout, a frame).
const fleetMs = [];
for (let i = 0; i < runs; i++) {
  fleetMs.push(
    await page.evaluate(async () => {
      location.hash = '#/alarms';
      await new Promise((r) => setTimeout(r, 50));
      const t0 = performance.now();
      location.hash = '#/fleet';
      while (!/^1000 of 1000/.test(document.querySelector('#fleet-info')?.textContent || '') || !document.querySelector('#fleet-table tr[data-pump]')) await new Promise((r) => setTimeout(r, 1));
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
      return performance.now() - t0;
    }),
  );
}
// The window of rows follows the scrolling (a check, not a timing).
const scrolled = await page.evaluate(async () => {
  document.querySelector('th[data-sort="pump_id"]').click();
  const box = document.querySelector('#fleet-table').parentElement;
  box.scrollTop = 500 * 26;
  await new Promise((r) => requestAnimationFrame(() => setTimeout(r, 30)));
  const top = box.getBoundingClientRect().top + 40;
  return document.elementFromPoint(200, top)?.closest('tr')?.dataset.pump;
});
if (!/^P-0(49|50)\d$/.test(scrolled || '')) throw new Error(`scrolled to row 500 but the row in view is ${scrolled}`);
await page.screenshot({ path: join(here, '../../build/web-screenshots/bench-fleet-1000.png') });
const sortMs = [];
for (let i = 0; i < runs; i++)
  sortMs.push(
    await page.evaluate(async () => {
      const t0 = performance.now();
      document.querySelector('th[data-sort="pump_id"]').click();
      await new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
      return performance.now() - t0;
    }),
  );

// Charts: the UI's own chart functions on generated data, until painted.
const chartMs = async (fn) => {
  const out = [];
  for (let i = 0; i < runs; i++) out.push(await page.evaluate(fn));
  return out;
};
const trendMs = await chartMs(async () => {
  const { trendChart } = await import('/ui/js/charts.js');
  const n = 100000;
  const t = new Float64Array(n), v = new Float64Array(n);
  for (let i = 0; i < n; i++) (t[i] = 1.7e9 + i * 3600), (v[i] = 1 + 0.1 * Math.sin(i / 500) + 0.02 * Math.random());
  const el = document.createElement('div');
  el.style.width = '1200px';
  document.body.append(el);
  const t0 = performance.now();
  const u = trendChart(el, { title: 'detection.ratio', t, v, band: { mean: 1, lo: 0.9, hi: 1.1 }, limits: [{ value: 1.2, label: 'raise' }] });
  await new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
  const ms = performance.now() - t0;
  u.destroy();
  el.remove();
  return ms;
});
const bodeMs = await chartMs(async () => {
  const { bodeCharts } = await import('/ui/js/bode.js');
  const n = 2000;
  const f = Float64Array.from({ length: n }, (_, i) => 1 + i * 0.5);
  const entries = Array.from({ length: 4 }, (_, e) => {
    const mk = (s) => Float64Array.from(f, (x) => 1e-6 / (1 + ((x - 200 - 50 * e) / (20 * s)) ** 2) + 1e-9);
    // A phase falling through -180 with noise: wraps (and gaps) all along the upper half.
    const wrap = (p) => ((((p + 180) % 360) + 360) % 360) - 180;
    const ph = (s) => Float64Array.from(f, (x) => wrap(-90 - 180 * Math.atan((x - 200) / (20 * s)) / Math.PI + 10 * (Math.random() - 0.5)));
    return { label: `e${e}`, mag: mk(1), phase: ph(1), model_mag: mk(1.1), model_phase: ph(1.1), fit_mag: mk(1.02), fit_phase: ph(1.02) };
  });
  const a = document.createElement('div'), b = document.createElement('div');
  a.style.width = b.style.width = '1200px';
  document.body.append(a, b);
  const t0 = performance.now();
  const plots = bodeCharts(a, b, f, entries, { logX: true });
  await new Promise((r) => requestAnimationFrame(() => setTimeout(r)));
  const ms = performance.now() - t0;
  plots.forEach((p) => p.destroy());
  a.remove();
  b.remove();
  return ms;
});
await browser.close();

const size = shippedGzip();
const fmt = (xs) => `median ${median(xs).toFixed(1)} ms (min ${Math.min(...xs).toFixed(1)}, max ${Math.max(...xs).toFixed(1)}, ${xs.length} runs)`;
console.log(`chromium headless, ${runs} runs each`);
console.log(`fleet view, 1000 pumps (route change to painted; target < 300 ms): ${fmt(fleetMs)}`);
console.log(`fleet view, re-sort 1000 pumps: ${fmt(sortMs)}`);
console.log(`trend of 100 000 points (target < 150 ms): ${fmt(trendMs)}`);
console.log(`Bode, 4 entries x 2000 lines + model + fit, magnitude and phase (target < 100 ms): ${fmt(bodeMs)}`);
console.log(`JS + CSS + HTML shipped: ${(size.raw / 1024).toFixed(1)} KiB, gzipped ${(size.gz / 1024).toFixed(1)} KiB (target < 150 KB)`);
if (pageErrors.length) {
  console.error('page errors:', pageErrors);
  process.exitCode = 1;
}
