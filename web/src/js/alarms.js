// Alarms after ANSI/ISA-18.2 (rest.md "Alarms"): the fleet's alarms by
// state and severity, acknowledge and shelve with a comment, the history of
// each. alarmTable is shared with the pump view.
import { get, post, seg, missingRoute } from './api.js';
import { h, esc, fmtTime, sevHtml, errorBox, toast, debounce } from './dom.js';
import { gatedButton, actionNote } from './roles.js';

const STATES = ['unack_active', 'ack_active', 'unack_rtn', 'shelved', 'suppressed', 'out_of_service', 'normal'];
const SEVERITIES = ['critical', 'high', 'medium', 'low'];
const STATE_TEXT = {
  unack_active: '▲ ACTIVE, UNACK',
  ack_active: '△ active, ack',
  unack_rtn: '▽ cleared, unack',
  shelved: '‖ shelved', // U+2016: DejaVu Sans has it, not U+23F8's pause sign
  suppressed: '⊘ suppressed',
  out_of_service: '⊘ out of service',
  normal: 'normal',
};
// The state as a word and a symbol; the colour stays with the severity
// (ISA-101), an unacknowledged alarm's state blinks until acknowledged.
const stateHtml = (a) =>
  `<span class="st st-state${a.state.startsWith('unack') ? ' unack' : ''}${a.active ? ' active' : ''}" data-state="${esc(a.state)}">${esc(STATE_TEXT[a.state] || a.state)}</span>`;

// A modal asking for a comment (and minutes for shelve); resolves null on cancel.
function ask(title, withMinutes) {
  return new Promise((resolve) => {
    const comment = h('textarea', { id: 'alarm-comment', required: withMinutes, placeholder: 'comment (who reads the history sees it)' });
    const minutes = h('input', { type: 'text', id: 'alarm-minutes', value: '60', size: 5, inputmode: 'numeric' });
    const dlg = h('dialog', { id: 'alarm-dialog' },
      h('form', { method: 'dialog' },
        h('h2', {}, title),
        withMinutes ? h('p', {}, h('label', {}, 'shelve for ', minutes, ' minutes')) : null,
        comment,
        h('p', {}, h('button', { value: 'ok', id: 'alarm-ok' }, title), ' ', h('button', { value: 'cancel', formnovalidate: true }, 'Cancel'))));
    dlg.addEventListener('close', () => {
      const ok = dlg.returnValue === 'ok';
      dlg.remove();
      resolve(ok ? { comment: comment.value.trim(), minutes: Number(minutes.value) } : null);
    });
    document.body.append(dlg);
    dlg.showModal();
    comment.focus();
  });
}

async function act(alarm, action) {
  const path = `/api/v1/alarms/${seg(String(alarm.alarm_id))}/${action}`;
  if (action === 'unshelve') return post(path, {});
  const answer = await ask(action === 'ack' ? 'Acknowledge' : 'Shelve', action === 'shelve');
  if (!answer) return null;
  const body = action === 'shelve' ? { minutes: answer.minutes, comment: answer.comment } : answer.comment ? { comment: answer.comment } : {};
  return post(path, body);
}

async function history(alarm, cell) {
  const { events } = await get(`/api/v1/alarms/${seg(String(alarm.alarm_id))}/history`);
  const t = h('table', { class: 'history' });
  t.innerHTML =
    '<thead><tr><th>seq</th><th>time</th><th>from</th><th>to</th><th>by</th><th>comment</th><th>run</th></tr></thead><tbody>' +
    events
      .map((e) => `<tr><td>${e.seq}</td><td>${esc(fmtTime(e.time))}</td><td>${esc(e.from)}</td><td>${esc(e.to)}</td><td>${esc(e.by)}</td><td>${esc(e.comment || '')}</td><td>${e.run_id ? `<a href="#/run/${esc(encodeURIComponent(e.run_id))}">${esc(e.run_id)}</a>` : ''}</td></tr>`)
      .join('') +
    '</tbody>';
  cell.replaceChildren(t);
}

// The acknowledge, shelve and unshelve buttons an alarm's state allows, as
// the session's role allows them (roles.js: operator).
function actions(a, session) {
  const b = (act, what, label) => gatedButton(session, 'operator', what, `data-act="${act}"`, label);
  return (
    (a.state.startsWith('unack') ? b('ack', 'acknowledge', 'Ack') : '') +
    (a.state === 'shelved' ? b('unshelve', 'unshelve', 'Unshelve') : a.state !== 'normal' ? b('shelve', 'shelve', 'Shelve') : '')
  );
}

// The alarms as a table with the actions the session may take.
export function alarmTable(alarms, { session, onChange, showPump = true }) {
  const t = h('table', { class: 'alarms' });
  t.innerHTML =
    `<thead><tr><th>severity</th><th>state</th>${showPump ? '<th>pump</th>' : ''}<th>rule</th><th>message</th><th>raised</th><th>cleared</th><th></th></tr></thead><tbody>` +
    alarms
      .map(
        (a, i) =>
          `<tr data-alarm="${esc(String(a.alarm_id))}" data-i="${i}"><td>${sevHtml(a.severity)}</td><td>${stateHtml(a)}</td>` +
          (showPump ? `<td><a href="#/pump/${esc(encodeURIComponent(a.pump_id))}">${esc(a.pump_id)}</a></td>` : '') +
          `<td>${esc(a.rule)}</td><td style="white-space:normal">${esc(a.message || '')}${a.fault ? ` <span class="tag">${esc(typeof a.fault === 'string' ? a.fault : a.fault.name || JSON.stringify(a.fault))}</span>` : ''}` +
          `${a.run_id ? ` <a href="#/run/${esc(encodeURIComponent(a.run_id))}">run</a>` : ''}</td>` +
          `<td>${esc(fmtTime(a.raised_at))}</td><td>${esc(a.cleared_at ? fmtTime(a.cleared_at) : '')}</td><td>` +
          actions(a, session) +
          '<button data-act="history">History</button></td></tr>',
      )
      .join('') +
    '</tbody>';
  t.addEventListener('click', async (e) => {
    const b = e.target.closest('button[data-act]');
    if (!b || b.disabled) return;
    const tr = b.closest('tr');
    const alarm = alarms[+tr.dataset.i];
    try {
      if (b.dataset.act === 'history') {
        const next = tr.nextElementSibling?.classList.contains('history-row') ? tr.nextElementSibling : null;
        if (next) return next.remove();
        const cell = h('td', { colspan: 8 });
        tr.after(h('tr', { class: 'history-row' }, cell));
        return await history(alarm, cell);
      }
      const after = await act(alarm, b.dataset.act);
      if (after) {
        toast(`alarm ${alarm.alarm_id} (${alarm.pump_id}, ${alarm.rule}): ${STATE_TEXT[after.state] || after.state || 'done'}`);
        onChange?.();
      }
    } catch (err) {
      toast(err.message, 8000);
    }
  });
  return t;
}

// Alarms of the fleet, or null where the server has no alarm routes yet.
export async function fetchAlarms(query = '') {
  try {
    return (await get('/api/v1/alarms' + query)).alarms;
  } catch (e) {
    if (missingRoute(e)) return null;
    throw e;
  }
}

export async function alarmsView({ main, crumbs, session }) {
  crumbs([['Fleet', '#/fleet'], ['Alarms']]);
  const counts = h('div', { class: 'summary', id: 'alarm-summary' });
  const state = h('select', { id: 'alarm-state', 'aria-label': 'state' }, h('option', { value: '' }, 'every state but normal'), ...STATES.map((s) => h('option', { value: s }, s)));
  const sev = h('select', { id: 'alarm-severity', 'aria-label': 'severity' }, h('option', { value: '' }, 'every severity'), ...SEVERITIES.map((s) => h('option', { value: s }, s)));
  const box = h('div', { class: 'scroll' });
  main.append(h('h1', {}, 'Alarms'), counts, h('div', { class: 'row panel' }, state, sev), box);
  async function load() {
    const all = await fetchAlarms();
    if (all === null) {
      box.replaceChildren(h('p', { class: 'note' }, 'This server has no alarms yet (rest.md "Alarms", issue 19).'));
      return;
    }
    const bySev = Object.fromEntries(SEVERITIES.map((s) => [s, 0]));
    const byState = {};
    for (const a of all) {
      if (a.active) bySev[a.severity] = (bySev[a.severity] || 0) + 1;
      byState[a.state] = (byState[a.state] || 0) + 1;
    }
    counts.innerHTML =
      SEVERITIES.map((s) => `<div class="box">${sevHtml(s, bySev[s] === 0)}<b>${bySev[s]}</b><span class="muted">active</span></div>`).join('') +
      STATES.filter((s) => byState[s]).map((s) => `<div class="box"><span class="muted">${esc(STATE_TEXT[s] || s)}</span><b data-state-count="${esc(s)}">${byState[s]}</b></div>`).join('');
    const shown = all.filter((a) => (state.value ? a.state === state.value : a.state !== 'normal') && (!sev.value || a.severity === sev.value));
    box.replaceChildren(
      shown.length
        ? alarmTable(shown, { session, onChange: load })
        : h('p', { class: 'muted' }, all.length ? 'No alarm in this selection.' : 'No alarm has been raised on this fleet yet.'),
      shown.length ? actionNote(session, 'operator', 'acknowledge or shelve alarms') ?? '' : '',
    );
  }
  state.addEventListener('change', () => load().catch((e) => box.replaceChildren(errorBox(e))));
  sev.addEventListener('change', () => load().catch((e) => box.replaceChildren(errorBox(e))));
  await load();
  const reload = debounce(() => load().catch(() => {}), 700);
  return { onEvent: reload, dispose: reload.cancel };
}
