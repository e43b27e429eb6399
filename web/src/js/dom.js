// Small DOM and formatting helpers (no framework: the views are few and
// the long lists are rendered as one HTML string, the fastest way).
export const $ = (sel, root = document) => root.querySelector(sel);

const ESC = { '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' };
export const esc = (s) => String(s ?? '').replace(/[&<>"']/g, (c) => ESC[c]);

// h('a', {href: '#'}, 'text', child): an element; attributes starting with
// "on" are listeners.
export function h(tag, attrs = {}, ...children) {
  const el = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (v === undefined || v === null || v === false) continue;
    if (k.startsWith('on')) el.addEventListener(k.slice(2), v);
    else if (k === 'class') el.className = v;
    else if (k === 'html') el.innerHTML = v;
    else el.setAttribute(k, v === true ? '' : v);
  }
  for (const c of children.flat()) if (c !== null && c !== undefined && c !== false) el.append(c instanceof Node ? c : String(c));
  return el;
}

export function fmtTime(iso) {
  if (!iso) return '–';
  const d = new Date(iso);
  if (Number.isNaN(d.getTime())) return iso;
  return d.toISOString().replace('T', ' ').replace(/\.\d+Z$|Z$/, ' UTC');
}

export function fmtNum(x, digits = 3) {
  if (x === null || x === undefined || Number.isNaN(x)) return '–';
  if (typeof x !== 'number') return String(x);
  const a = Math.abs(x);
  if (a !== 0 && (a < 1e-3 || a >= 1e5)) return x.toExponential(digits - 1);
  return x.toPrecision(digits).replace(/\.?0+$/, (m) => (m.includes('.') ? '' : m));
}

// Health as ISA-101 wants it: a word and a symbol, coloured only when abnormal.
const HEALTH = {
  ok: ['OK', 'st-ok', ''],
  warning: ['WARNING', 'st-warning', '◆ '],
  alarm: ['ALARM', 'st-alarm', '▲ '],
  unknown: ['UNKNOWN', 'st-unknown', '? '],
};
export function healthHtml(health) {
  const [word, cls, sym] = HEALTH[health] || HEALTH.unknown;
  return `<span class="st ${cls}" data-health="${esc(health)}">${sym}${word}</span>`;
}

const SEV_SYM = { critical: '▲▲ ', high: '▲ ', medium: '◆ ', low: '▽ ' };
export const sevHtml = (s) => `<span class="sev sev-${esc(s)}">${SEV_SYM[s] || ''}${esc(String(s).toUpperCase())}</span>`;

export function toast(msg, ms = 4000) {
  const box = document.getElementById('toast');
  const d = h('div', {}, msg);
  box.append(d);
  setTimeout(() => d.remove(), ms);
}

export const errorBox = (e) => h('p', { class: 'error' }, e.message || String(e));

// fn after `ms` without another call (live events come in bursts); .cancel().
export function debounce(fn, ms) {
  let timer = null;
  const d = () => {
    clearTimeout(timer);
    timer = setTimeout(fn, ms);
  };
  d.cancel = () => clearTimeout(timer);
  return d;
}
