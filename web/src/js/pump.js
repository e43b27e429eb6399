// One pump: its health and alarms (acknowledge, shelve), trends of its
// series with the reference band and alarm limits (zoom by dragging, a
// point opens its run), its runs, model versions and reference.
import { get, seg, missingRoute } from './api.js';
import { h, esc, fmtTime, fmtNum, healthHtml, errorBox, debounce } from './dom.js';
import { trendChart, limitLines } from './charts.js';
import { alarmTable, fetchAlarms } from './alarms.js';
import { actionNote } from './roles.js';

const toS = (iso) => Date.parse(iso) / 1000;

// The series a control-room engineer looks at first.
function defaultSeries(names) {
  const pick = names.filter((n) => n === 'detection.ratio' || n === 'fit.nrmse' || n.startsWith('fault.'));
  pick.push(...names.filter((n) => /^mode\..*\.f_hz$/.test(n)).slice(0, 2));
  pick.push(...names.filter((n) => /^mode\..*\.zeta$/.test(n)).slice(0, 1));
  return pick.slice(0, 8);
}

// A reply's series as chart data: points, or min/max buckets.
export function seriesData(s) {
  const pts = s.points || [];
  const bucketed = pts.length > 0 && pts[0].min !== undefined;
  const t = new Float64Array(pts.length);
  const v = new Array(pts.length);
  const lo = bucketed ? new Array(pts.length) : null;
  const hi = bucketed ? new Array(pts.length) : null;
  pts.forEach((p, i) => {
    t[i] = toS(p.time);
    v[i] = bucketed ? p.last : p.value;
    if (bucketed) (lo[i] = p.min), (hi[i] = p.max);
  });
  const r = s.reference;
  const band = r && Number.isFinite(r.mean) ? { mean: r.mean, lo: r.mean - 2 * (r.sd || 0), hi: r.mean + 2 * (r.sd || 0) } : null;
  const limits = s.limits ? limitLines(s.limits) : [];
  // detection.ratio is statistic / threshold: 1 is where detection fires.
  if (s.name === 'detection.ratio' && !limits.length) limits.push({ value: 1, label: 'detection threshold' });
  return { t, v, lo, hi, band, limits, runs: bucketed ? null : pts.map((p) => p.run_id) };
}

async function trendsSection(pumpId, box) {
  let list;
  try {
    list = (await get(`/api/v1/pumps/${seg(pumpId)}/series`)).series;
  } catch (e) {
    if (missingRoute(e)) return box.replaceChildren(h('p', { class: 'note' }, 'This server has no trends yet (rest.md "Trends", issue 19).'));
    throw e;
  }
  if (!list.length)
    return box.replaceChildren(h('p', { class: 'muted' }, 'No series yet: trends come from analysed identification runs (the pump needs a model) and monitoring snapshots.'));
  const names = list.map((s) => s.name);
  const chosen = new Set(defaultSeries(names));
  const range = h('select', { id: 'trend-range', 'aria-label': 'range' },
    ...[['', 'all history'], ['7', 'last 7 days'], ['30', 'last 30 days'], ['365', 'last year']].map(([v, l]) => h('option', { value: v }, l)));
  const pick = h('div', { class: 'series-pick', id: 'series-pick' },
    ...list.map((s) => h('label', { title: s.name }, h('input', { type: 'checkbox', value: s.name, checked: chosen.has(s.name) }), ' ', s.name, s.unit ? ` [${s.unit}]` : '')));
  const charts = h('div', { class: 'charts', id: 'trend-charts' });
  // The time range shown: null (the range select) or {from, to} in s. Where
  // the reply came as min/max buckets, a zoom asks the server again for the
  // zoomed range, so months narrow down to single runs (as a historian does).
  let view = null;
  const iso = (s) => new Date(s * 1000).toISOString().replace(/\.\d+Z$/, 'Z');
  const pan = (share) => () => {
    const [a, b] = view ? [view.from, view.to] : plots.length ? [plots[0].scales.x.min, plots[0].scales.x.max] : [0, 0];
    if (!(b > a)) return;
    view = { from: a + share * (b - a), to: b + share * (b - a) };
    draw().catch((e) => charts.replaceChildren(errorBox(e)));
  };
  const all = () => ((view = null), draw().catch((e) => charts.replaceChildren(errorBox(e))));
  box.replaceChildren(
    h('div', { class: 'row' }, range,
      h('button', { type: 'button', onclick: pan(-0.5), title: 'earlier' }, '◀'),
      h('button', { type: 'button', onclick: pan(0.5), title: 'later' }, '▶'),
      h('button', { type: 'button', onclick: all }, 'whole range'),
      h('span', { class: 'muted' }, 'drag across a chart to zoom, double-click for the whole range; click a point to open its run; grey band: reference mean ± 2 sd; red dashed: alarm limits')),
    pick, charts);
  let plots = [];
  async function draw() {
    plots.forEach((p) => p.destroy());
    plots = [];
    const names = [...pick.querySelectorAll('input:checked')].map((i) => i.value).slice(0, 20);
    if (!names.length) return charts.replaceChildren(h('p', { class: 'muted' }, 'Choose series above.'));
    const q = new URLSearchParams();
    names.forEach((n) => q.append('series', n));
    q.set('max_points', '2000');
    if (view) q.set('from', iso(view.from)), q.set('to', iso(view.to));
    else if (range.value) q.set('from', iso(Date.now() / 1000 - range.value * 86400));
    // %20, not URLSearchParams' "+", for the spaces of mode labels.
    const reply = await get(`/api/v1/pumps/${seg(pumpId)}/trends?${q.toString().replace(/\+/g, '%20')}`);
    charts.replaceChildren();
    const bucketed = reply.series.some((s) => s.points?.[0]?.min !== undefined);
    const syncX = (u) => {
      const { min, max } = u.scales.x;
      for (const p of plots) if (p !== u && (p.scales.x.min !== min || p.scales.x.max !== max)) p.setScale('x', { min, max });
    };
    const zoomed = debounce(() => {
      const { min, max } = plots[0].scales.x;
      view = { from: min, to: max };
      draw().catch((e) => charts.replaceChildren(errorBox(e)));
    }, 300);
    for (const s of reply.series) {
      const d = seriesData(s);
      const el = h('div', { class: 'chart', 'data-series': s.name });
      charts.append(el);
      if (!d.t.length) {
        el.append(h('p', { class: 'chart-title' }, `${s.name}: no point in this range`));
        continue;
      }
      const u = trendChart(el, {
        title: s.name, unit: s.unit, ...d, sync: 'trend-' + pumpId,
        // A fault parameter or the detection ratio is read against its limits.
        allLimits: /^(fault\.|detection\.ratio$)/.test(s.name),
        onPoint: d.runs ? (i) => d.runs[i] && (location.hash = '#/run/' + encodeURIComponent(d.runs[i])) : null,
      });
      u.hooks.setScale = [(uu, key) => key === 'x' && syncX(uu)];
      u.hooks.setSelect = [(uu) => bucketed && uu.select.width > 2 && zoomed()];
      u.over.addEventListener('dblclick', () => view && all());
      plots.push(u);
    }
  }
  pick.addEventListener('change', () => draw().catch((e) => charts.replaceChildren(errorBox(e))));
  range.addEventListener('change', all);
  await draw();
  return { redraw: draw, dispose: () => plots.forEach((p) => p.destroy()) };
}

async function prognosisSection(pumpId, box) {
  let list;
  try {
    list = (await get(`/api/v1/pumps/${seg(pumpId)}/series`)).series.filter((s) => /^fault\..*clearance_factor$/.test(s.name));
  } catch (_) {
    return;
  }
  for (const s of list) {
    try {
      const p = await get(`/api/v1/pumps/${seg(pumpId)}/prognosis?series=${encodeURIComponent(s.name)}`);
      box.append(h('p', {}, h('b', {}, s.name), ` reaching ${fmtNum(p.limit, 3)}: ${p.status}` +
        (p.estimated_at ? `, estimated ${fmtTime(p.estimated_at)}` : '') +
        (p.interval ? ` (${Math.round(100 * p.interval.level)} %: ${fmtTime(p.interval.from)} … ${fmtTime(p.interval.to)})` : '') +
        (p.reason ? ` (${p.reason})` : '')));
    } catch (_) { /* no prognosis for it */ }
  }
}

function runsTable(runs) {
  if (!runs.length) return h('p', { class: 'muted' }, 'No run received yet.');
  const t = h('table', { id: 'runs' });
  const rows = runs.slice(-300).reverse();
  t.innerHTML =
    '<thead><tr><th>started</th><th>run</th><th>kind</th><th>status</th><th class="num">speed [rpm]</th></tr></thead><tbody>' +
    rows
      .map((r) => `<tr><td>${esc(fmtTime(r.started_at))}</td><td><a href="#/run/${esc(encodeURIComponent(r.run_id))}">${esc(r.run_id)}</a></td><td>${esc(r.kind)}</td><td>${r.status === 'complete' ? esc(r.status) : `<span class="st st-warning">◆ ${esc(r.status)}</span>`}</td><td class="num">${fmtNum(r.speed_rpm, 4)}</td></tr>`)
      .join('') +
    '</tbody>';
  return t;
}

export async function pumpView({ main, crumbs, session }, pumpId) {
  crumbs([['Fleet', '#/fleet'], [pumpId]]);
  const base = `/api/v1/pumps/${seg(pumpId)}`;
  const [pump, { runs }, models] = await Promise.all([get(base), get(base + '/runs'), get(base + '/models').catch(() => ({ models: [] }))]);
  const head = h('div', { class: 'panel row', id: 'pump-head' });
  const alarmsBox = h('div', { class: 'panel', id: 'pump-alarms' });
  const trendBox = h('div', { class: 'panel', id: 'trends' });
  const progBox = h('div', { class: 'panel', id: 'prognosis' });
  main.append(h('h1', {}, 'Pump ', h('span', { id: 'pump-id' }, pumpId)), head,
    h('h2', {}, 'Alarms'), alarmsBox, h('h2', {}, 'Trends'), trendBox, h('h2', {}, 'Prognosis'), progBox,
    h('h2', {}, 'Runs'), h('div', { class: 'scroll', style: 'max-height:320px' }, runsTable(runs)),
    h('h2', {}, 'Model versions and reference'), h('div', { class: 'panel', id: 'pump-models' }, modelsPanel(pump, models.models || [])));

  function showHead(p) {
    const a = p.last_analysis;
    head.innerHTML =
      `<div>${healthHtml(p.health)}</div><div class="kv"><span class="muted">active alarms</span><span>${p.active_alarms ?? 0}</span>` +
      `<span class="muted">last run</span><span>${p.last_run_id ? `<a href="#/run/${esc(encodeURIComponent(p.last_run_id))}">${esc(p.last_run_id)}</a>` : '–'}</span>` +
      `<span class="muted">last conclusion</span><span>${a ? (a.detected ? `<b>change detected</b>${a.fault ? ': ' + esc(a.fault) : ''}` : a.detected === false ? 'no change' : 'no detection (no reference)') + (a.ratio !== undefined ? ` (ratio ${fmtNum(a.ratio, 3)})` : '') : 'not analysed'}</span></div>`;
  }
  async function loadAlarms() {
    const list = await fetchAlarms('?pump_id=' + encodeURIComponent(pumpId));
    if (list === null) return alarmsBox.replaceChildren(h('p', { class: 'note' }, 'This server has no alarms yet (rest.md "Alarms").'));
    const open = list.filter((a) => a.state !== 'normal');
    alarmsBox.replaceChildren(
      open.length ? alarmTable(open, { session, onChange: refresh, showPump: false }) : h('p', { class: 'muted' }, 'No open alarm.'),
      list.length > open.length ? h('p', { class: 'muted' }, `${list.length - open.length} returned to normal (see Alarms)`) : '',
      open.length ? actionNote(session, 'operator', 'acknowledge or shelve alarms') ?? '' : '',
    );
  }
  async function refresh() {
    showHead(await get(base));
    await loadAlarms();
  }
  showHead(pump);
  const showTrends = () => trendsSection(pumpId, trendBox).catch((e) => trendBox.replaceChildren(errorBox(e)));
  let [trends] = await Promise.all([
    showTrends(),
    loadAlarms().catch((e) => alarmsBox.replaceChildren(errorBox(e))),
    prognosisSection(pumpId, progBox),
  ]);
  if (!progBox.childElementCount) progBox.append(h('p', { class: 'muted' }, 'No fault parameter with a trend to forecast.'));
  const reload = debounce(() => {
    refresh().catch(() => {});
    // The first series of a pump that had none come with its first analysis.
    if (trends?.redraw) trends.redraw().catch(() => {});
    else showTrends().then((t) => (trends = t));
  }, 800);
  return {
    onEvent: (ev) => (!ev.data?.pump_id || ev.data.pump_id === pumpId) && reload(),
    dispose() {
      reload.cancel();
      trends?.dispose?.();
    },
  };
}

function modelsPanel(pump, models) {
  const ref = pump.reference;
  return h('div', { class: 'row' },
    h('div', {}, h('b', {}, 'Models'),
      models.length ? null : h('p', { class: 'muted' }, 'none: the pump is not analysed until an engineer registers its model'),
      h('ul', {}, ...models.slice().reverse().map((m) => h('li', {}, `v${m.model_version} ${fmtTime(m.created_at)} by ${m.created_by || '–'}${m.comment ? ': ' + m.comment : ''}${m.model_version === pump.model_version ? ' (current)' : ''}`)))),
    h('div', {}, h('b', {}, 'Reference'),
      ref
        ? h('div', {}, h('p', {}, ref.status === 'active' ? `v${ref.version}, ${fmtTime(ref.created_at)} by ${ref.created_by}` : 'proposed (not set by an engineer yet)'),
          h('ul', {}, ...ref.runs.map((r) => h('li', {}, h('a', { href: '#/run/' + encodeURIComponent(r) }, r)))))
        : h('p', { class: 'muted' }, 'none')));
}
