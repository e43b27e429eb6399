// Bode plots of one run (uPlot, as charts.js): magnitude on a log axis over
// the phase, the measured FRF solid, the model dashed, the modal fit
// dotted, each entry in its own colour. The phase is wrapped to +-180 deg,
// as analysers show it, and the line is broken where it wraps: drawn
// through, every wrap would be a stroke across the whole panel (above the
// modes a compliance sits near -180 deg, and the noise flips it to +180 at
// every other line).
import { INK, GRID, AXIS_INK, width } from './charts.js';

const DASH = { measured: undefined, model: [6, 4], fit: [1.5, 3] };

// The phase curves on a grid with a point inserted between two lines
// wherever a curve jumps by more than 180 deg (a wrap, not a change of the
// system): null there for the curves that wrap (uPlot leaves a gap), the
// middle of the straight segment for the others (drawn as before). `curves`
// are arrays over `x` (or null); returns {x, curves} with plain arrays.
export function wrapGaps(x, curves) {
  const wraps = (c, k) => c && Math.abs(c[k] - c[k - 1]) > 180;
  const outX = [];
  const out = curves.map((c) => (c ? [] : null));
  for (let k = 0; k < x.length; k++) {
    if (k > 0 && curves.some((c) => wraps(c, k))) {
      outX.push((x[k - 1] + x[k]) / 2);
      curves.forEach((c, i) => c && out[i].push(wraps(c, k) ? null : (c[k - 1] + c[k]) / 2));
    }
    outX.push(x[k]);
    curves.forEach((c, i) => c && out[i].push(c[k]));
  }
  return { x: outX, curves: out };
}

// The phase's line, broken at the nulls by lifting the pen: uPlot's own
// line clips every gap out of the drawing, which took 120 ms for 12 noisy
// curves wrapping at every other line (a few ms this way). A point alone
// between two gaps is drawn as a short dash, so the noise stays visible.
function brokenLine(u, si, i0, i1) {
  const xs = u.data[0], ys = u.data[si];
  const path = new Path2D();
  const dot = 1.5 * devicePixelRatio;
  let prev = null; // the last point's [x, y] in canvas pixels while the pen is down
  let alone = false;
  for (let i = i0; i <= i1; i++) {
    const y = ys[i];
    if (y === null || y === undefined || !Number.isFinite(y)) {
      if (prev && alone) (path.moveTo(prev[0] - dot, prev[1]), path.lineTo(prev[0] + dot, prev[1]));
      prev = null;
      continue;
    }
    const px = u.valToPos(xs[i], 'x', true), py = u.valToPos(y, 'y', true);
    if (prev) path.lineTo(px, py);
    else path.moveTo(px, py);
    alone = !prev;
    prev = [px, py];
  }
  if (prev && alone) (path.moveTo(prev[0] - dot, prev[1]), path.lineTo(prev[0] + dot, prev[1]));
  return { stroke: path, fill: null, clip: null, flags: 0 };
}

// Decade splits of a log axis (at most 8 labels): uPlot's own also splits
// each decade at 2..9, which on a 6-decade FRF paints the grid into bands.
function decades(u, axisIdx, min, max) {
  const a = Math.ceil(Math.log10(min) - 1e-9), b = Math.floor(Math.log10(max) + 1e-9);
  const step = Math.max(1, Math.ceil((b - a + 1) / 8));
  const out = [];
  for (let k = a; k <= b; k += step) out.push(10 ** k);
  return out;
}

const expFmt = (v) => (v == null ? '–' : v.toExponential(2));

// Bode plot of entries: each {label, mag, phase, model_mag?, model_phase?,
// fit_mag?, fit_phase?} (arrays over f in Hz; phase in degrees, wrapped).
export function bodeCharts(magEl, phaseEl, f, entries, { logX = false, height = 260, sync = 'bode', unit = 'm/N' } = {}) {
  const curves = []; // {label, stroke, dash, mag, phase}
  entries.forEach((e, i) => {
    const stroke = INK[i % INK.length];
    curves.push({ label: `${e.label} measured`, stroke, dash: DASH.measured, mag: e.mag, phase: e.phase });
    if (e.model_mag) curves.push({ label: `${e.label} model`, stroke, dash: DASH.model, mag: e.model_mag, phase: e.model_phase });
    if (e.fit_mag) curves.push({ label: `${e.label} fit`, stroke, dash: DASH.fit, mag: e.fit_mag, phase: e.fit_phase });
  });
  const xAxis = { stroke: AXIS_INK, grid: GRID, label: 'frequency [Hz]', labelSize: 20, size: 30 };
  const mk = (el, data, yScale, yAxis, showLegend, paths) =>
    new uPlot(
      {
        width: width(el),
        height,
        cursor: { sync: { key: sync }, drag: { x: true, y: false } },
        scales: { x: { time: false, distr: logX ? 3 : 1 }, y: yScale },
        axes: [xAxis, { stroke: AXIS_INK, grid: GRID, size: 70, ...yAxis }],
        series: [
          { label: 'f [Hz]', value: (u, v) => (v == null ? '–' : v.toPrecision(5)) },
          ...curves.map((c) => ({ label: c.label, stroke: c.stroke, width: 1.25, dash: c.dash, ...(paths ? { paths } : {}), ...(showLegend ? { value: (u, v) => expFmt(v) } : {}) })),
        ],
        legend: { show: showLegend },
      },
      data,
      el,
    );
  const mag = mk(
    magEl,
    [f, ...curves.map((c) => c.mag)],
    { distr: 3 },
    // Every split labelled (uPlot's own log filter drops some of ours).
    { label: `|H| [${unit}]`, splits: decades, filter: (u, splits) => splits, values: (u, vals) => vals.map((v) => (v ? v.toExponential(0) : '')) },
    true,
  );
  const gapped = wrapGaps(f, curves.map((c) => c.phase));
  const phase = mk(
    phaseEl,
    [gapped.x, ...gapped.curves],
    { range: [-180, 180] },
    { label: 'phase [°]', splits: () => [-180, -90, 0, 90, 180] },
    false,
    brokenLine,
  );
  // For tests and the browser's console: the charts behind the elements.
  magEl.plot = mag;
  phaseEl.plot = phase;
  return [mag, phase];
}
