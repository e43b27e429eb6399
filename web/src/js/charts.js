// uPlot charts (web/node_modules/uplot, loaded as the global uPlot by
// index.html): trends over time with a reference band and alarm limits
// (Bode plots: bode.js). Lines are greys and dark blues; colour is kept for
// what is abnormal (limits in red, the band in a light grey). Times in UTC,
// 24 h, as everywhere else in the UI.
export const INK = ['#1b1b1b', '#1f5fa8', '#5a5a5a', '#6b3fa0', '#2e7d6b', '#8a5a00'];
export const GRID = { stroke: '#d6d6d6' };
export const AXIS_INK = '#444';

export const width = (el) => Math.max(320, el.clientWidth || 900);

// Time axis labels (uPlot's table: tick increment in s, then the format and
// the formats where the year, month, day, hour, minute change): ISO dates,
// 24 h, instead of uPlot's US defaults (11/26/26 2:54pm).
const TIME_VALUES = [
  [3600 * 24 * 365, '{YYYY}', null, null, null, null, null, null, 1],
  [3600 * 24 * 28, '{YYYY}-{MM}', null, null, null, null, null, null, 1],
  [3600 * 24, '{MM}-{DD}', '\n{YYYY}', null, null, null, null, null, 1],
  [3600, '{HH}:{mm}', '\n{YYYY}-{MM}-{DD}', null, '\n{MM}-{DD}', null, null, null, 1],
  [60, '{HH}:{mm}', '\n{YYYY}-{MM}-{DD}', null, '\n{MM}-{DD}', null, null, null, 1],
  [1, '{HH}:{mm}:{ss}', '\n{YYYY}-{MM}-{DD}', null, '\n{MM}-{DD}', null, null, null, 1],
  [0.001, ':{ss}.{fff}', '\n{YYYY}-{MM}-{DD} {HH}:{mm}', null, '\n{MM}-{DD} {HH}:{mm}', null, '\n{HH}:{mm}', null, 1],
];
const utc = (s) => uPlot.tzDate(new Date(s * 1000), 'Etc/UTC');
// Tick steps of the time axis in s, whole seconds and up (uPlot's own go
// down to ms, labelled ":36.250": runs are seconds apart at the least).
const DAY = 86400;
const TIME_INCRS = [
  1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200,
  DAY, 2 * DAY, 7 * DAY, 14 * DAY, 28 * DAY, 56 * DAY, 84 * DAY, 168 * DAY, 365 * DAY, 730 * DAY, 1825 * DAY,
];

// Right-aligned labels of horizontal lines, moved left of one another where
// two lines lie closer than a line of text (limits 0.05 apart on a 0..2 axis).
function placeLabels(ctx, items, right, lineH) {
  ctx.textAlign = 'right'; // uPlot leaves the context as its axes last set it
  ctx.textBaseline = 'alphabetic';
  const placed = [];
  for (const it of [...items].sort((a, b) => a.y - b.y)) {
    const w = ctx.measureText(it.text).width;
    let r = right;
    for (const p of placed) if (Math.abs(p.y - it.y) < lineH && p.left < r) r = Math.min(r, p.left - lineH);
    ctx.fillText(it.text, r, it.y - 3);
    placed.push({ y: it.y, left: r - w });
  }
}

// A band drawn under the series: the reference mean +- 2 sd, and the alarm
// limits as red dashed lines, from the series' `reference` and `limits`.
function bandPlugin(band, limits) {
  return {
    hooks: {
      drawClear: [
        (u) => {
          if (!band) return;
          const { ctx } = u;
          const y0 = u.valToPos(band.lo, 'y', true);
          const y1 = u.valToPos(band.hi, 'y', true);
          ctx.save();
          ctx.fillStyle = 'rgba(120,120,120,0.18)';
          ctx.fillRect(u.bbox.left, Math.min(y0, y1), u.bbox.width, Math.abs(y1 - y0));
          const ym = u.valToPos(band.mean, 'y', true);
          ctx.strokeStyle = '#8c8c8c';
          ctx.setLineDash([2, 3]);
          ctx.beginPath();
          ctx.moveTo(u.bbox.left, ym);
          ctx.lineTo(u.bbox.left + u.bbox.width, ym);
          ctx.stroke();
          ctx.restore();
        },
      ],
      draw: [
        (u) => {
          if (!limits?.length) return;
          const { ctx } = u;
          ctx.save();
          ctx.strokeStyle = '#d40000';
          ctx.fillStyle = '#d40000';
          ctx.setLineDash([6, 4]);
          ctx.font = `${11 * devicePixelRatio}px sans-serif`;
          const shown = [];
          for (const l of limits) {
            const y = u.valToPos(l.value, 'y', true);
            if (y < u.bbox.top || y > u.bbox.top + u.bbox.height) continue;
            ctx.beginPath();
            ctx.moveTo(u.bbox.left, y);
            ctx.lineTo(u.bbox.left + u.bbox.width, y);
            ctx.stroke();
            shown.push({ y, text: l.label });
          }
          placeLabels(ctx, shown, u.bbox.left + u.bbox.width - 4 * devicePixelRatio, 13 * devicePixelRatio);
          ctx.restore();
        },
      ],
    },
  };
}

// The lines of a series' `limits` (docs/service.md "Trends": {"rule",
// "lines": [{"kind": "raise"|"clear", "severity"?, "value"}]}), labelled
// "alarm (high)" (the severity in brackets: an upper limit of a low
// severity alarm must not read as a "LOW" limit), "clear".
export function limitLines(limits) {
  return (limits?.lines || [])
    .filter((l) => Number.isFinite(l.value))
    .map((l) => ({
      value: l.value,
      rule: limits.rule || '',
      label: l.kind === 'raise' ? `alarm${l.severity ? ` (${l.severity})` : ''}` : l.kind,
    }));
}

// A time scale padded by 1.5 % on each side when it shows all the data (so
// the first and last points are not cut in half by the frame); a zoomed
// range is kept as chosen.
function paddedTime(u, min, max) {
  const t = u.data[0];
  if (!t.length || min !== t[0] || max !== t[t.length - 1]) return [min, max];
  const pad = max > min ? (max - min) * 0.015 : 60;
  return [min - pad, max + pad];
}

// One trend chart: time (s) and value arrays, optional min/max envelope
// (buckets), the reference band and limits; `onPoint(i)` on a click.
export function trendChart(el, { title, unit, t, v, lo, hi, band, limits, allLimits, sync, onPoint, height = 190 }) {
  const series = [
    { label: 'time (UTC)', value: '{YYYY}-{MM}-{DD} {HH}:{mm}:{ss}' },
    { label: title, stroke: INK[0], width: 1.25, points: { show: t.length < 400, size: 5, fill: '#1b1b1b' } },
  ];
  const data = [t, v];
  if (lo && hi) {
    series.push({ label: 'min', stroke: '#9a9a9a', width: 1 }, { label: 'max', stroke: '#9a9a9a', width: 1 });
    data.push(lo, hi);
  }
  // The y range: the data and the band, and (allLimits) every limit, or the
  // limits close enough to keep the data on at least 15 % of the height
  // (a window around the data's middle, so both sides alike); farther ones
  // would flatten the data to a line, so the title names them instead.
  let lo0 = Infinity, hi0 = -Infinity;
  for (const x of v) if (Number.isFinite(x)) (lo0 = Math.min(lo0, x)), (hi0 = Math.max(hi0, x));
  if (band) (lo0 = Math.min(lo0, band.lo)), (hi0 = Math.max(hi0, band.hi));
  const room = Math.max(hi0 - lo0, Math.abs(hi0) * 0.01, 1e-12) / 0.15;
  const mid = (lo0 + hi0) / 2;
  const near = (limits || []).filter((l) => allLimits || Math.abs(l.value - mid) <= room / 2);
  const far = (limits || []).filter((l) => !near.includes(l));
  const yr = (u, min, max) => {
    let a = min, b = max;
    if (band) (a = Math.min(a, band.lo)), (b = Math.max(b, band.hi));
    for (const l of near) (a = Math.min(a, l.value)), (b = Math.max(b, l.value));
    if (!(b > a)) (a -= 1e-9 + Math.abs(a) * 0.1), (b += 1e-9 + Math.abs(b) * 0.1);
    const pad = (b - a) * 0.08;
    return [a - pad, b + pad];
  };
  // The rule whose limits are drawn, where the series' name does not say it.
  const rules = [...new Set((limits || []).map((l) => l.rule).filter((r) => r && !title.startsWith(r)))];
  const ruleText = rules.length ? `, limits of rule ${rules.join(', ')}` : '';
  const farText = far.length ? `  (off scale: ${far.map((l) => `${l.label} ${+l.value.toPrecision(4)}`).join(', ')})` : '';
  const opts = {
    title: (unit ? `${title} [${unit}]` : title) + ruleText + farText,
    width: width(el),
    height,
    tzDate: utc,
    cursor: { sync: sync ? { key: sync } : undefined, drag: { x: true, y: false, setScale: true } },
    scales: { x: { time: true, range: paddedTime }, y: { range: yr } },
    padding: [8, 28, 0, 0], // room for the last time label at the right edge
    axes: [
      { stroke: AXIS_INK, grid: GRID, values: TIME_VALUES, incrs: TIME_INCRS, label: 'time (UTC)', labelSize: 20, size: 44 },
      { stroke: AXIS_INK, grid: GRID, size: 70, space: 18, label: `[${unit || '1'}]`, labelSize: 18 },
    ],
    series,
    plugins: [bandPlugin(band, near)],
  };
  const u = new uPlot(opts, data, el);
  el.plot = u; // for tests and the browser's console
  if (onPoint) {
    // A click, not the end of a drag that zoomed.
    let down = null;
    u.over.addEventListener('mousedown', (e) => (down = [e.clientX, e.clientY]));
    u.over.addEventListener('click', (e) => {
      const i = u.cursor.idx;
      const moved = down ? Math.hypot(e.clientX - down[0], e.clientY - down[1]) : 0;
      if (moved < 4 && i !== null && i !== undefined) onPoint(i);
    });
  }
  return u;
}
