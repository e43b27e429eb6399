// One run: what its analysis concluded (detection, diagnosis with the
// fault's parameters and intervals), the measured FRF against the model
// (any of the 5 x 5 entries, magnitude and phase), the modal table in the
// paper's layout (reference vs actual per labelled mode) and explain.
import { get, getText, getBlob, post, seg } from './api.js';
import { h, esc, fmtTime, fmtNum, errorBox } from './dom.js';
import { parseFrf, entryMagPhase } from './frf.js';
import { bodeCharts } from './bode.js';
import { gate, actionNote } from './roles.js';

const kv = (pairs) => h('dl', { class: 'kv' }, ...pairs.flatMap(([k, v]) => [h('dt', {}, k), h('dd', {}, v)]));
const pm = (v, sd, d = 4) => (v === undefined ? '–' : sd ? `${fmtNum(v, d)} ± ${fmtNum(sd, 2)}` : fmtNum(v, d));

function detectionPanel(a) {
  const d = a.detection;
  if (!d) return h('p', { class: 'muted' }, a.status === 'done' ? 'No detection: the pump had no reference when this run was analysed.' : '');
  const verdict = d.detected
    ? h('span', { class: 'st st-alarm', id: 'verdict' }, '▲ CHANGE DETECTED')
    : h('span', { class: 'st st-ok', id: 'verdict' }, 'no change');
  return kv([
    ['verdict', verdict],
    ['statistic / threshold', `${fmtNum(d.statistic, 4)} / ${fmtNum(d.threshold, 4)} (ratio ${fmtNum(d.ratio ?? d.statistic / d.threshold, 3)})`],
    ['p-value', fmtNum(d.p_value, 3)],
    ['false-alarm rate per run', fmtNum(d.false_alarm_rate, 2)],
  ]);
}

function paramText(params) {
  const out = [];
  for (const [k, v] of Object.entries(params || {})) {
    if (k.endsWith('_sd') || k.endsWith('_ci95')) continue;
    const ci = params[k + '_ci95'];
    out.push(`${k} ${fmtNum(v, 4)}${params[k + '_sd'] ? ' ± ' + fmtNum(params[k + '_sd'], 2) : ''}${ci ? ` (95 %: ${fmtNum(ci[0], 4)} … ${fmtNum(ci[1], 4)})` : ''}`);
  }
  return out.join('; ');
}

function diagnosisPanel(dg) {
  if (!dg?.faults?.length) return null;
  const t = h('table', { id: 'diagnosis' });
  t.innerHTML =
    '<thead><tr><th>#</th><th>fault</th><th class="num">score</th><th>location</th><th>parameters (estimate ± sd, 95 % interval)</th></tr></thead><tbody>' +
    dg.faults
      .slice(0, 6)
      .map(
        (f, i) =>
          `<tr><td>${i + 1}</td><td>${i === 0 ? '<b>' + esc(f.fault) + '</b>' : esc(f.fault)}</td><td class="num">${fmtNum(f.score, 3)}</td>` +
          `<td>${esc(Object.entries(f.location || {}).map(([k, v]) => `${k}: ${[].concat(v).join(', ')}`).join('; '))}</td><td>${esc(paramText(f.parameters))}</td></tr>`,
      )
      .join('') +
    '</tbody>';
  return h('div', {}, h('h2', {}, 'Diagnosis (ranked)'), t);
}

// Table 3 / 4 of the paper: per labelled mode, the reference (the mean of
// the pump's reference runs) against this run, frequency and damping, and
// the model's value at the run's speed.
function modalTable(modes, refModes) {
  const t = h('table', { id: 'modal-table' });
  const row = (m) => {
    const r = refModes.get(m.label);
    const df = r ? (100 * (m.f_hz - r.f_hz)) / r.f_hz : null;
    const dz = r ? (100 * (m.zeta - r.zeta)) / r.zeta : null;
    const big = (x) => (x !== null && Math.abs(x) > 5 ? ' class="num" style="font-weight:700"' : ' class="num"');
    return (
      `<tr><td>${esc(m.label || '(unlabelled)')}</td>` +
      `<td class="num">${fmtNum(m.model_f_hz, 4)}</td><td class="num">${fmtNum(m.model_zeta, 3)}</td>` +
      `<td class="num">${r ? fmtNum(r.f_hz, 4) : '–'}</td><td class="num">${r ? fmtNum(r.zeta, 3) : '–'}</td>` +
      `<td class="num">${pm(m.f_hz, m.f_sd_hz)}</td><td class="num">${pm(m.zeta, m.zeta_sd, 3)}</td>` +
      `<td${big(df)}>${df === null ? '–' : (df >= 0 ? '+' : '') + df.toFixed(2) + ' %'}</td><td${big(dz)}>${dz === null ? '–' : (dz >= 0 ? '+' : '') + dz.toFixed(1) + ' %'}</td></tr>`
    );
  };
  t.innerHTML =
    '<thead><tr><th rowspan="2">mode</th><th colspan="2">model at this speed</th><th colspan="2">reference (healthy)</th><th colspan="2">actual (this run)</th><th colspan="2">change vs reference</th></tr>' +
    '<tr><th class="num">f [Hz]</th><th class="num">ζ</th><th class="num">f [Hz]</th><th class="num">ζ</th><th class="num">f [Hz]</th><th class="num">ζ</th><th class="num">Δf</th><th class="num">Δζ</th></tr></thead><tbody>' +
    modes.filter((m) => m.label).map(row).join('') +
    '</tbody>';
  return t;
}

// The mean labelled modes of the pump's reference runs (their analyses).
async function referenceModes(pump) {
  const out = new Map();
  const runs = pump.reference?.status === 'active' ? pump.reference.runs : [];
  const analyses = await Promise.all(runs.map((r) => get(`/api/v1/runs/${seg(r)}/analysis`).catch(() => null)));
  const acc = new Map();
  for (const a of analyses)
    for (const m of a?.modes || []) {
      if (!m.label) continue;
      const s = acc.get(m.label) || { f: 0, z: 0, n: 0 };
      s.f += m.f_hz;
      s.z += m.zeta;
      s.n++;
      acc.set(m.label, s);
    }
  for (const [k, s] of acc) out.set(k, { f_hz: s.f / s.n, zeta: s.z / s.n, n: s.n });
  return out;
}

// The 5 x 5 entries as toggles; `onChange(selected)` with "out|in" keys.
function entryPicker(frf, selected, onChange) {
  const outs = [...new Set(frf.entries.map((e) => e.output))];
  const ins = [...new Set(frf.entries.map((e) => e.input))];
  const grid = h('div', { class: 'entries', id: 'entry-picker', style: `grid-template-columns: auto repeat(${ins.length}, auto)` });
  grid.append(h('span'), ...ins.map((i) => h('span', { class: 'muted' }, i)));
  for (const o of outs) {
    grid.append(h('span', { class: 'muted' }, o));
    for (const i of ins) {
      const key = `${o}|${i}`;
      const has = frf.entries.some((e) => e.output === o && e.input === i);
      const b = h('button', { type: 'button', 'data-entry': key, disabled: !has, class: selected.has(key) ? 'on' : '', title: `H ${o} / ${i}` }, '■');
      b.addEventListener('click', () => {
        if (selected.has(key)) selected.delete(key);
        else selected.add(key);
        b.classList.toggle('on', selected.has(key));
        onChange(selected);
      });
      grid.append(b);
    }
  }
  return grid;
}

export function drawBode(magEl, phaseEl, measured, model, fit, selected, logX) {
  const entries = [];
  for (const key of selected) {
    const [o, i] = key.split('|');
    const m = entryMagPhase(measured, o, i);
    if (!m) continue;
    const mm = model ? entryMagPhase(model, o, i) : null;
    const fm = fit ? entryMagPhase(fit, o, i) : null;
    entries.push({ label: `${o}/${i}`, mag: m.mag, phase: m.phase, model_mag: mm?.mag, model_phase: mm?.phase, fit_mag: fm?.mag, fit_phase: fm?.phase });
  }
  magEl.replaceChildren();
  phaseEl.replaceChildren();
  return bodeCharts(magEl, phaseEl, measured.f, entries, { logX, unit: measured.meta.unit || 'm/N' });
}

// A curve of the FRF section that may be missing: its parsed file, or the
// reason it is not drawn (shown under the legend).
async function optionalFrf(url) {
  try {
    return { frf: parseFrf(await getText(url)) };
  } catch (e) {
    return { why: e.message };
  }
}

async function frfSection(base, box) {
  box.append(h('p', { class: 'muted' }, 'Loading the FRFs…'));
  const [text, model, fit] = await Promise.all([getText(base + '/frf.csv'), optionalFrf(base + '/model_frf.csv'), optionalFrf(base + '/fit_frf.csv')]);
  const measured = parseFrf(text);
  const outs = [...new Set(measured.entries.map((e) => e.output))];
  const ins = [...new Set(measured.entries.map((e) => e.input))];
  const selected = new Set();
  for (let k = 0; k < Math.min(outs.length, ins.length) && selected.size < 4; k++)
    if (measured.entries.some((e) => e.output === outs[k] && e.input === ins[k])) selected.add(`${outs[k]}|${ins[k]}`);
  const magEl = h('div', { id: 'bode-mag', class: 'chart' });
  const phaseEl = h('div', { id: 'bode-phase', class: 'chart' });
  const logX = h('input', { type: 'checkbox', id: 'bode-logx' });
  const redraw = () => drawBode(magEl, phaseEl, measured, model.frf, fit.frf, selected, logX.checked);
  logX.addEventListener('change', redraw);
  const missing = [model.why && `model: ${model.why}`, fit.why && `fit: ${fit.why}`].filter(Boolean);
  box.replaceChildren(
    h('div', { class: 'row' },
      entryPicker(measured, selected, redraw),
      h('div', { id: 'bode-key' },
        h('p', {},
          h('span', { class: 'legend-line' }), 'measured',
          h('span', { class: 'legend-line dash' }), 'model at the run\'s speed',
          h('span', { class: 'legend-line dot' }), 'modal fit (the modes of the table below)',
          h('span', { class: 'muted' }, ' (each entry in its own colour)')),
        missing.length ? h('p', { class: 'note' }, 'Not drawn: ', missing.join('; ')) : null,
        h('label', {}, logX, ' log frequency axis'),
        h('p', { class: 'muted' }, `${measured.f.length} lines, ${fmtNum(measured.f[0], 3)} … ${fmtNum(measured.f[measured.f.length - 1], 4)} Hz; phase wrapped to ±180° (gaps at the wraps); drag to zoom, double-click to reset; click a legend entry to hide its curve`))),
    magEl,
    phaseEl,
  );
  redraw();
}

async function figure(url, alt) {
  const blob = await getBlob(url);
  return h('img', { class: 'figure', src: URL.createObjectURL(blob), alt });
}

// POST explain, poll its job, show the report and the fit before / after.
function explainSection(runId, box, session) {
  const out = h('div', { id: 'explain-report' });
  const allowed = gate(session, 'engineer', 'explain');
  const note = actionNote(session, 'engineer', 'run explain');
  if (!allowed) {
    box.append(note);
    return () => {};
  }
  const btn = h('button', { type: 'button', id: 'explain', ...allowed }, 'Explain the difference to the model');
  let timer = null;
  btn.addEventListener('click', async () => {
    btn.disabled = true;
    out.replaceChildren(h('p', { class: 'muted' }, 'Queued…'));
    try {
      const { job_id } = await post(`/api/v1/runs/${seg(runId)}/explain`);
      const poll = async () => {
        const j = await get(`/api/v1/jobs/${job_id}`);
        if (j.status === 'queued' || j.status === 'running') {
          out.replaceChildren(h('p', { class: 'muted' }, `explain job ${job_id}: ${j.status} ${Math.round(100 * (j.progress || 0))} %`));
          timer = setTimeout(poll, 1000);
          return;
        }
        btn.disabled = false;
        if (j.status !== 'done') return out.replaceChildren(errorBox(new Error(`explain job ${job_id} ${j.status}: ${j.error || ''}`)));
        out.replaceChildren(...(await explainReport(j)));
      };
      poll();
    } catch (e) {
      btn.disabled = false;
      out.replaceChildren(errorBox(e));
    }
  });
  box.append(btn, note ?? '', out);
  return () => clearTimeout(timer);
}

// An explanation's location ({"link": "coupling", "node": 0}) as words.
const placeText = (loc) =>
  loc && typeof loc === 'object'
    ? Object.entries(loc).map(([k, v]) => `${k} ${[].concat(v).join(', ')}`).join(', ')
    : String(loc ?? '');

async function explainReport(j) {
  const r = j.result || {};
  const parts = [
    kv([
      ['NRMSE model vs measured, before', fmtNum(r.nrmse_before, 4)],
      ['after, with the corrected model', fmtNum(r.nrmse_after, 4)],
      ['mismatches beyond the noise', String((r.mismatches || []).length)],
      ['left unexplained', String((r.unexplained || []).length)],
    ]),
  ];
  // Since explain's guarantee (docs/explain.md) its corrected model never fits
  // worse; an explain job stored before it can still hold one: say so.
  if (r.nrmse_after > r.nrmse_before)
    parts.push(h('p', { class: 'note', id: 'explain-worse' }, '◆ The corrected model matches this run less well than the current one (NRMSE rose): read its findings as candidates, do not adopt it.'));
  if (Array.isArray(r.story) && r.story.length) parts.push(h('ul', { class: 'story' }, ...r.story.map((line) => h('li', {}, line))));
  if (r.updated_parameters?.length) {
    const t = h('table', { id: 'updated-parameters' });
    t.innerHTML =
      '<thead><tr><th>model parameter</th><th class="num">from</th><th class="num">to</th><th class="num">factor</th></tr></thead><tbody>' +
      r.updated_parameters
        .map((u) => `<tr><td>${esc(u.path)}</td><td class="num">${fmtNum(u.from, 5)}</td><td class="num">${fmtNum(u.to, 5)}</td><td class="num">×${u.from ? fmtNum(u.to / u.from, 3) : '–'}</td></tr>`)
        .join('') +
      '</tbody>';
    parts.push(h('h2', {}, 'Parameters corrected'), t);
  }
  if (r.explanations?.length) {
    const t = h('table', { id: 'explanations', class: 'wrap' });
    t.innerHTML =
      '<thead><tr><th>physics</th><th>parameters</th><th>location</th><th class="num">NRMSE before</th><th class="num">after</th><th>evidence</th></tr></thead><tbody>' +
      r.explanations
        .map((x) => `<tr><td>${esc(x.physics)}</td><td>${esc(paramText(x.parameters))}</td><td>${esc(placeText(x.location))}</td><td class="num">${fmtNum(x.nrmse_before, 4)}</td><td class="num">${fmtNum(x.nrmse_after, 4)}</td><td>${esc(typeof x.evidence === 'string' ? x.evidence : JSON.stringify(x.evidence ?? ''))}</td></tr>`)
        .join('') +
      '</tbody>';
    parts.push(h('h2', {}, 'Missing physics: candidates'), t);
  }
  if (j.files?.['explain.svg']) parts.push(h('h2', {}, 'Measured vs model before and after'), await figure(j.files['explain.svg'], 'explain: measured, model before and improved model'));
  return parts;
}

export async function runView({ main, crumbs, session }, runId) {
  const base = `/api/v1/runs/${seg(runId)}`;
  const [run, a] = await Promise.all([get(base), get(base + '/analysis')]);
  crumbs([['Fleet', '#/fleet'], [run.pump_id, '#/pump/' + encodeURIComponent(run.pump_id)], [runId]]);
  const pump = await get(`/api/v1/pumps/${seg(run.pump_id)}`);
  main.append(
    h('h1', {}, 'Run ', h('span', { id: 'run-id' }, runId)),
    h('div', { class: 'panel row' },
      kv([
        ['pump', h('a', { href: '#/pump/' + encodeURIComponent(run.pump_id) }, run.pump_id)],
        ['started', fmtTime(run.started_at)],
        ['kind, status', `${run.kind}, ${run.status}`],
        ['speed', `${fmtNum(a.speed_rpm ?? run.speed_rpm, 4)} rpm`],
      ]),
      kv([
        ['analysis', a.status + (a.error ? ': ' + a.error : '')],
        ['model, reference', `v${a.model_version ?? '–'}, ${a.reference_version ? 'v' + a.reference_version : 'none'}`],
        ['fit to model (NRMSE)', fmtNum(a.nrmse, 3)],
        ['modes fitted / labelled', `${a.fit?.pole_pairs ?? '–'} / ${(a.modes || []).filter((m) => m.label).length}`],
      ])),
  );
  if (a.status !== 'done') {
    main.append(h('p', { class: 'note' }, `The analysis is ${a.status}${a.progress ? ` (${Math.round(100 * a.progress)} %)` : ''}; this page updates when it is done.`));
    return { onEvent: (ev) => ev.type.startsWith('job.') && ev.data.run_id === runId && window.dispatchEvent(new HashChangeEvent('hashchange')) };
  }
  main.append(h('h2', {}, 'Detection'), h('div', { class: 'panel' }, detectionPanel(a)));
  const dg = diagnosisPanel(a.diagnosis);
  if (dg) main.append(h('div', { class: 'panel' }, dg));
  const frfBox = h('div', { class: 'panel', id: 'frf' });
  main.append(h('h2', {}, 'FRF: measured vs model vs modal fit'), frfBox);
  const modalBox = h('div', { class: 'panel' });
  main.append(h('h2', {}, 'Modes: reference vs actual'), modalBox);
  const explainBox = h('div', { class: 'panel' });
  main.append(h('h2', {}, 'Explain'), explainBox);
  const figs = h('div', { class: 'panel' });
  if (a.files?.['diagnosis.svg']) main.append(h('h2', {}, 'Diagnosis figure'), figs);
  const stopExplain = explainSection(runId, explainBox, session);
  await Promise.all([
    frfSection(base, frfBox).catch((e) => frfBox.replaceChildren(errorBox(e))),
    referenceModes(pump)
      .then((ref) => modalBox.replaceChildren(modalTable(a.modes || [], ref), h('p', { class: 'muted' }, ref.size ? `reference: mean of the ${pump.reference.runs.length} reference runs (v${pump.reference.version}); bold: a change beyond 5 %` : 'no active reference: only the model is shown')))
      .catch((e) => modalBox.replaceChildren(errorBox(e))),
    a.files?.['diagnosis.svg'] ? figure(a.files['diagnosis.svg'], 'diagnosis').then((img) => figs.append(img)).catch((e) => figs.append(errorBox(e))) : null,
  ]);
  return { dispose: stopExplain, onEvent() {} };
}
