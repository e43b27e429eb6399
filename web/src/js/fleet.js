// The fleet: every pump with its health, active alarms, last run and what
// its analysis concluded; sortable and filterable. Rows are rendered as one
// HTML string (1000 pumps in a few ms) and clicks are delegated.
import { get, missingRoute } from './api.js';
import { h, esc, fmtTime, fmtNum, healthHtml, sevHtml, debounce } from './dom.js';

const ROW_PX = 26; // every row's height (app.css), for the window of rows in the document
const RANK = { alarm: 3, warning: 2, unknown: 1, ok: 0 };
const SEV_RANK = { critical: 4, high: 3, medium: 2, low: 1 };

const COLUMNS = [
  ['pump_id', 'Pump', (p) => p.pump_id],
  ['health', 'Health', (p) => RANK[p.health] ?? 1],
  ['active_alarms', 'Active alarms', (p) => (p.active_alarms || 0) * 10 + (SEV_RANK[p.worst_severity] || 0)],
  ['last', 'Last run', (p) => p.last_started_at || ''],
  ['conclusion', 'Conclusion', (p) => p.last_analysis?.ratio ?? -1],
  ['n_runs', 'Runs', (p) => p.n_runs || 0],
  ['model_version', 'Model', (p) => p.model_version || 0],
  ['reference', 'Reference', (p) => (p.reference?.status === 'active' ? 2 : p.reference ? 1 : 0)],
];

function conclusion(p) {
  const a = p.last_analysis;
  if (!a) return '<span class="muted">not analysed</span>';
  if (a.detected === undefined) return '<span class="muted">analysed, no reference</span>';
  const ratio = `ratio ${fmtNum(a.ratio, 2)}`;
  if (!a.detected) return `no change <span class="muted">(${ratio})</span>`;
  return `<b>change detected</b>${a.fault ? ': ' + esc(a.fault) : ''} <span class="muted">(${ratio})</span>`;
}

function row(p) {
  const alarms = p.active_alarms
    ? `${p.worst_severity ? sevHtml(p.worst_severity) + ' ' : ''}${p.active_alarms}`
    : '<span class="muted">0</span>';
  const ref = p.reference
    ? p.reference.status === 'active'
      ? `v${p.reference.version}`
      : '<span class="muted">proposed</span>'
    : '<span class="muted">none</span>';
  return (
    `<tr class="link" data-pump="${esc(p.pump_id)}"><td><a href="#/pump/${esc(encodeURIComponent(p.pump_id))}">${esc(p.pump_id)}</a></td>` +
    `<td>${healthHtml(p.health)}</td><td class="num">${alarms}</td>` +
    `<td>${p.last_run_id ? `<a href="#/run/${esc(encodeURIComponent(p.last_run_id))}">${esc(fmtTime(p.last_started_at))}</a>` : '–'}</td>` +
    `<td>${conclusion(p)}</td><td class="num">${p.n_runs ?? 0}</td>` +
    `<td class="num">${p.model_version ? 'v' + p.model_version : '<span class="muted">none</span>'}</td><td>${ref}</td></tr>`
  );
}

// The fleet table's state and rendering, apart from fetching.
export class FleetTable {
  constructor(container) {
    this.pumps = [];
    this.sort = { key: 'health', dir: -1 };
    this.filter = { text: '', health: '' };
    this.table = h('table', { id: 'fleet-table' });
    this.table.innerHTML =
      '<thead><tr>' +
      COLUMNS.map(([k, label]) => `<th data-sort="${k}"${['active_alarms', 'n_runs', 'model_version'].includes(k) ? ' class="num"' : ''}>${label}</th>`).join('') +
      '</tr></thead><tbody></tbody>';
    this.body = this.table.tBodies[0];
    this.rows = [];
    this.scroller = container;
    let queued = false;
    container.addEventListener('scroll', () => {
      if (queued) return;
      queued = true;
      requestAnimationFrame(() => ((queued = false), this.paint()));
    }, { passive: true });
    this.table.tHead.addEventListener('click', (e) => {
      const k = e.target.closest('th')?.dataset.sort;
      if (!k) return;
      this.sort = { key: k, dir: this.sort.key === k ? -this.sort.dir : k === 'pump_id' ? 1 : -1 };
      this.render();
    });
    this.body.addEventListener('click', (e) => {
      if (e.target.closest('a')) return;
      const tr = e.target.closest('tr[data-pump]');
      if (tr) location.hash = '#/pump/' + encodeURIComponent(tr.dataset.pump);
    });
    container.append(this.table);
  }

  set(pumps) {
    this.pumps = pumps;
    this.render();
  }

  render() {
    const t0 = performance.now();
    const { key, dir } = this.sort;
    const val = COLUMNS.find((c) => c[0] === key)[2];
    const text = this.filter.text.toLowerCase();
    const rows = this.pumps.filter(
      (p) =>
        (!text || p.pump_id.toLowerCase().includes(text) || (p.last_analysis?.fault || '').includes(text)) &&
        (!this.filter.health || p.health === this.filter.health),
    );
    const keyed = rows.map((p) => [val(p), p]);
    keyed.sort((a, b) => (a[0] < b[0] ? -dir : a[0] > b[0] ? dir : a[1].pump_id < b[1].pump_id ? -1 : 1));
    this.rows = keyed.map(([, p]) => p);
    for (const th of this.table.tHead.rows[0].cells) {
      th.classList.toggle('asc', th.dataset.sort === key && dir > 0);
      th.classList.toggle('desc', th.dataset.sort === key && dir < 0);
    }
    this.shown = rows.length;
    this.paint();
    this.renderMs = performance.now() - t0;
  }

  // Only the rows in view (and a margin) are in the document, between two
  // spacer rows: laying out a 1000-row table took 160 ms in headless
  // Chromium on the 2-core test machine, a window of ~60 rows a few ms.
  paint() {
    const rh = ROW_PX;
    const view = this.scroller.clientHeight || 800;
    const first = Math.max(0, Math.floor(this.scroller.scrollTop / rh) - 20);
    const last = Math.min(this.rows.length, first + Math.ceil(view / rh) + 40);
    const spacer = (n) => (n > 0 ? `<tr class="spacer" style="height:${n * rh}px"><td colspan="8"></td></tr>` : '');
    this.body.innerHTML = spacer(first) + this.rows.slice(first, last).map(row).join('') + spacer(this.rows.length - last);
  }
}

function summary(pumps) {
  const n = { alarm: 0, warning: 0, unknown: 0, ok: 0 };
  let alarms = 0;
  for (const p of pumps) {
    n[p.health in n ? p.health : 'unknown']++;
    alarms += p.active_alarms || 0;
  }
  return (
    `<div class="box"><span class="muted">pumps</span><b>${pumps.length}</b></div>` +
    ['alarm', 'warning', 'unknown', 'ok']
      .map((k) => `<div class="box">${healthHtml(k, n[k] === 0)}<b data-count="${k}">${n[k]}</b></div>`)
      .join('') +
    `<div class="box"><span class="muted">active alarms</span><b>${alarms}</b></div>`
  );
}

// The worst active alarm's severity per pump, where the server has alarms.
async function worstSeverity() {
  try {
    const { alarms } = await get('/api/v1/alarms?active=true');
    const worst = new Map();
    for (const a of alarms) if ((SEV_RANK[a.severity] || 0) > (SEV_RANK[worst.get(a.pump_id)] || 0)) worst.set(a.pump_id, a.severity);
    return worst;
  } catch (e) {
    if (missingRoute(e)) return new Map();
    throw e;
  }
}

export async function fleetView({ main, crumbs }) {
  crumbs([['Fleet']]);
  const sum = h('div', { class: 'summary', id: 'fleet-summary' });
  const text = h('input', { type: 'search', placeholder: 'filter: pump or fault', id: 'fleet-filter', 'aria-label': 'filter' });
  const health = h('select', { id: 'fleet-health', 'aria-label': 'health' },
    h('option', { value: '' }, 'every health'),
    ...['alarm', 'warning', 'unknown', 'ok'].map((k) => h('option', { value: k }, k)));
  const info = h('span', { class: 'muted', id: 'fleet-info' });
  const scroll = h('div', { class: 'scroll' });
  const empty = h('p', { class: 'note', id: 'fleet-empty', hidden: true },
    'No pump yet. A pump appears once its model is registered (PUT /api/v1/pumps/{pump_id}/model) or its agent streams a run.');
  main.append(h('h1', {}, 'Fleet'), sum, h('div', { class: 'row panel' }, text, health, info), empty, scroll);
  const table = new FleetTable(scroll);
  const apply = () => {
    table.filter = { text: text.value.trim(), health: health.value };
    table.render();
    info.textContent = `${table.shown} of ${table.pumps.length} pumps shown`;
  };
  text.addEventListener('input', apply);
  health.addEventListener('change', apply);

  async function load() {
    const [{ pumps }, worst] = await Promise.all([get('/api/v1/fleet'), worstSeverity()]);
    for (const p of pumps) p.worst_severity = worst.get(p.pump_id);
    sum.innerHTML = summary(pumps);
    empty.hidden = pumps.length > 0;
    scroll.hidden = pumps.length === 0;
    table.pumps = pumps;
    apply();
  }
  await load();
  // New runs, analyses and alarms: read the fleet again, at most once a second.
  const reload = debounce(() => load().catch(() => {}), 1000);
  return { onEvent: reload, dispose: reload.cancel };
}
