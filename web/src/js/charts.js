// uPlot charts (web/node_modules/uplot, loaded as the global uPlot by
// index.html): trends over time with a reference band and limits, and Bode
// plots of measured vs model FRFs. Lines are greys and dark blues; colour is
// kept for what is abnormal (limits in red, the band in a light grey).
const INK = ['#1b1b1b', '#1f5fa8', '#5a5a5a', '#6b3fa0', '#2e7d6b', '#8a5a00'];

const width = (el) => Math.max(320, el.clientWidth || 900);

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
          for (const l of limits) {
            const y = u.valToPos(l.value, 'y', true);
            if (y < u.bbox.top || y > u.bbox.top + u.bbox.height) continue;
            ctx.beginPath();
            ctx.moveTo(u.bbox.left, y);
            ctx.lineTo(u.bbox.left + u.bbox.width, y);
            ctx.stroke();
            ctx.fillText(l.label, u.bbox.left + u.bbox.width - ctx.measureText(l.label).width - 4, y - 3);
          }
          ctx.restore();
        },
      ],
    },
  };
}

// The lines of a series' `limits` (docs/service.md "Trends": {"rule",
// "lines": [{"kind": "raise"|"clear", "severity"?, "value"}]}), labelled
// with the kind and severity.
export function limitLines(limits) {
  return (limits?.lines || [])
    .filter((l) => Number.isFinite(l.value))
    .map((l) => ({ value: l.value, label: `${limits.rule ? limits.rule + ' ' : ''}${l.kind}${l.severity ? ' ' + l.severity : ''}` }));
}

// One trend chart: time (s) and value arrays, optional min/max envelope
// (buckets), the reference band and limits; `onPoint(i)` on a click.
export function trendChart(el, { title, unit, t, v, lo, hi, band, limits, allLimits, sync, onPoint, height = 190 }) {
  const series = [{}, { label: title, stroke: INK[0], width: 1.25, points: { show: t.length < 400, size: 5, fill: '#1b1b1b' } }];
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
  const farText = far.length ? `  (limits off scale: ${far.map((l) => `${l.label.split(' ').slice(-2).join(' ')} ${+l.value.toPrecision(4)}`).join(', ')})` : '';
  const opts = {
    title: (unit ? `${title} [${unit}]` : title) + farText,
    width: width(el),
    height,
    cursor: { sync: sync ? { key: sync } : undefined, drag: { x: true, y: false, setScale: true } },
    scales: { x: { time: true }, y: { range: yr } },
    axes: [{ stroke: '#444', grid: { stroke: '#d6d6d6' } }, { stroke: '#444', grid: { stroke: '#d6d6d6' }, size: 70, space: 18 }],
    series,
    plugins: [bandPlugin(band, near)],
  };
  const u = new uPlot(opts, data, el);
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

// Bode plot of entries: each {label, f (Hz), mag, phase_deg, model_mag?,
// model_phase_deg?} on one frequency grid. Magnitude on a log axis.
export function bodeCharts(magEl, phaseEl, f, entries, { logX = false, height = 260, sync = 'bode' } = {}) {
  const mk = (el, key, ylabel, ylog) => {
    const series = [{}];
    const data = [f];
    entries.forEach((e, i) => {
      const stroke = INK[i % INK.length];
      series.push({ label: e.label + ' measured', stroke, width: 1.25 });
      data.push(key === 'mag' ? e.mag : e.phase);
      if (e.model_mag) {
        series.push({ label: e.label + ' model', stroke, width: 1.25, dash: [6, 4] });
        data.push(key === 'mag' ? e.model_mag : e.model_phase);
      }
    });
    return new uPlot(
      {
        width: width(el),
        height,
        cursor: { sync: { key: sync }, drag: { x: true, y: false } },
        scales: { x: { time: false, distr: logX ? 3 : 1 }, y: ylog ? { distr: 3 } : {} },
        axes: [
          { stroke: '#444', grid: { stroke: '#d6d6d6' }, label: 'frequency [Hz]' },
          { stroke: '#444', grid: { stroke: '#d6d6d6' }, label: ylabel, size: 70, values: ylog ? (u, vals) => vals.map((v) => (v ? v.toExponential(0) : '')) : undefined },
        ],
        series,
        legend: { show: key === 'mag' },
      },
      data,
      el,
    );
  };
  return [mk(magEl, 'mag', '|H| [m/N]', true), mk(phaseEl, 'phase', 'phase [°]', false)];
}
